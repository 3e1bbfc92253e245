"""ptp's and tetra's median per image as ``benchmarks/test_ratios.py`` measures them (every registered
plugin timed image by image in turn, Table 6's settings), with fewer images and rounds (issue #25).

    python benchmarks/tools/ptpspeed4_ratio.py N_IMAGES ROUNDS [paper|real|both]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from starid import Camera, load_hipparcos


def main(n: int, rounds: int, skies) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from benchmarks.test_ratios import time_per_image
    cat, cam = load_hipparcos(), Camera()
    for sky in skies:
        t = time_per_image(cat, cam, sky, n_images=n, rounds=rounds)
        tetra, ptp = float(np.median(t["tetra"])) * 1e6, float(np.median(t["ptp"])) * 1e6
        p95 = float(np.percentile(t["ptp"], 95)) * 1e6
        print(f"{sky:5s} tetra {tetra:7.1f}  ptp {ptp:7.1f}  ratio {ptp / tetra:5.2f}x  "
              f"ptp p95/median {p95 / ptp:5.2f}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    sk = sys.argv[3] if len(sys.argv) == 4 else "both"
    main(int(sys.argv[1]), int(sys.argv[2]), ("paper", "real") if sk == "both" else (sk,))
