"""Does the fixed order of ``benchmarks/test_ratios.py`` favour or handicap a plugin? (issue #25, stop 46)

The benchmark times every plugin on each image in one fixed (alphabetical) order, so each plugin always runs
right after the same one. This times the same images in that order and in ``N_ORDERS - 1`` random orders of
the same plugins (seeded), and prints tetra's, ptp's and triangle voting's medians and ratios with the plugin
each followed:

    python benchmarks/tools/order_effect.py real [N_ORDERS]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/
from test_ratios import NAMES, time_per_image  # noqa: E402

from starid import load_hipparcos  # noqa: E402
from starid.experiments import table6  # noqa: E402


def main(sky: str, n_orders: int = 8) -> None:
    catalog = load_hipparcos()
    camera = table6.experiment(trials=1).make_camera()
    rng = np.random.default_rng(1)
    for k in range(n_orders):
        names = list(NAMES) if k == 0 else [str(n) for n in rng.permutation(NAMES)]
        times = time_per_image(catalog, camera, sky, names=names, n_images=200, rounds=2)
        med = {n: float(np.median(t)) * 1e6 for n, t in times.items()}
        after = {n: names[(i - 1) % len(names)] for i, n in enumerate(names)}
        print(f"{'fixed' if k == 0 else 'random'} order: tetra {med['tetra']:.1f} us (after {after['tetra']}), "
              f"ptp {med['ptp']:.1f} (after {after['ptp']}) = {med['ptp'] / med['tetra']:.2f}x, triangle voting "
              f"{med['triangle_voting']:.1f} = {med['triangle_voting'] / med['tetra']:.2f}x", flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1], *(int(a) for a in sys.argv[2:3]))
