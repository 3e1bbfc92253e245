"""benchmarks/test_ratios.py's measurement for a few plugins: median and p95 per image, ratio to tetra.

    python benchmarks/tools/lpispeed_ratios.py tetra,lpt_improved 200 3

The same timing as the benchmark (``time_per_image``: Table 6's skies at 1 px / 0.5 Mv, seed 0, N
images, each plugin's ``identify`` timed image by image in turn, R rounds, one warm-up call), only
for the plugins named (the benchmark interleaves all of them, so its absolute numbers differ); the
first name is the reference. Prints per sky and plugin the median and p95 in us, the median's
ratio to the reference and p95 / median.
"""

import sys
from pathlib import Path

import numpy as np

from starid import Camera, load_hipparcos

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from test_ratios import time_per_image  # noqa: E402


def main(names: list[str], n: int, rounds: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    for sky in ("paper", "real"):
        times = time_per_image(cat, cam, sky, names=names, n_images=n, rounds=rounds)
        ref = float(np.median(times[names[0]]))
        for name, t in times.items():
            med, p95 = float(np.median(t)), float(np.percentile(t, 95))
            print(f"{sky:5s} {name:14s} median {med * 1e6:8.1f} us  p95 {p95 * 1e6:8.1f} us  "
                  f"{med / ref:5.2f}x {names[0]}  p95/median {p95 / med:5.2f}")


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(sys.argv[1].split(","), int(sys.argv[2]), int(sys.argv[3]))
