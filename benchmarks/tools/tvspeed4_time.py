"""benchmarks/test_ratios.py's timing, every registered plugin interleaved, printing tetra and triangle_voting.

    python benchmarks/tools/tvspeed4_time.py [N] [R]

``time_per_image`` (Table 6's two skies at 1 px / 0.5 Mv, V <= 6, seed 0; N images (200), R rounds (2), every
plugin's ``identify`` timed image by image in turn after one warm-up call) with all the benchmark's plugins, so
that each triangle_voting call runs after the other 13 as in the benchmark; prints per sky tetra's and
triangle_voting's median and p95 (us) and the ratio of the medians. Run base and branch back to back.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from starid import Camera, load_hipparcos

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from test_ratios import time_per_image  # noqa: E402


def main(n: int, rounds: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    for sky in ("paper", "real"):
        times = time_per_image(cat, cam, sky, n_images=n, rounds=rounds)
        te, tv = (float(np.median(times[k])) * 1e6 for k in ("tetra", "triangle_voting"))
        p95 = float(np.percentile(times["triangle_voting"], 95)) * 1e6
        print(f"{sky:5s} tetra {te:7.1f} us  triangle_voting {tv:7.1f} us (p95 {p95:7.1f})  {tv / te:5.2f}x",
              flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200, int(sys.argv[2]) if len(sys.argv) > 2 else 2)
