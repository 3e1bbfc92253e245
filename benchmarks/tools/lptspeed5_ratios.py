"""The benchmark's interleaved per-image timing of lpt, lpt_improved and grid (issue #25, branch lptspeed5).

    python benchmarks/tools/lptspeed5_ratios.py SKY N ROUNDS [NAMES]

Calls ``benchmarks.test_ratios.time_per_image`` exactly as the benchmark does (every registered
plugin timed image by image in turn, so each call starts with the caches the other plugins left),
on SKY (paper / real), N images x ROUNDS; prints the median and p95 (us) of tetra, lpt,
lpt_improved and grid (or NAMES, comma-separated) and each median's ratio to tetra's.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))   # the benchmarks package

from benchmarks.test_ratios import NAMES, time_per_image  # noqa: E402
from starid import Camera, load_hipparcos  # noqa: E402


def main(sky: str, n: int, rounds: int, shown: list[str]) -> None:
    times = time_per_image(load_hipparcos(), Camera(), sky, NAMES, n, rounds)
    ref = float(np.median(times["tetra"]))
    for name in shown:
        t = times[name]
        med = float(np.median(t))
        print(f"{sky:5s} {name:14s} median {med * 1e6:8.1f} us  p95 {np.percentile(t, 95) * 1e6:8.1f} us  "
              f"{med / ref:6.2f}x tetra")


if __name__ == "__main__":
    if len(sys.argv) not in (4, 5):
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]),
         sys.argv[4].split(",") if len(sys.argv) == 5 else ["tetra", "lpt", "lpt_improved", "grid"])
