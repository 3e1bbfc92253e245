"""What the slow images of ``lpt`` do (issue #25, branch lptspeed3).

    python benchmarks/tools/lptspeed3_tail.py SKY N R

Table 6's images (1 px / 0.5 Mv, seed 0), N of them; each identified R times, the minimum kept.
Prints the median and p95 of the minima, then for the images at or above the p95, and for all
images, the mean of: stars in the image, the work counters (``n_patterns``: reference strings
scanned, ``n_comparisons``: strings past the level bound, ``n_verifications``), identified or not,
and the time per string compared.
"""

import sys
import time

import numpy as np

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm


def main(sky: str, n: int, repeats: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    alg = get_algorithm("lpt")()
    db = alg.build(cat, cam)
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                    seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    alg.identify(db, obs[0])
    rows = []
    for o in obs:
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter_ns()
            ident = alg.identify(db, o)
            best = min(best, (time.perf_counter_ns() - t0) * 1e-3)
        c = ident.counters or {}
        rows.append((best, len(o.x_px), c.get("patterns", 0), c.get("comparisons", 0),
                     c.get("verifications", 0), float(ident.attitude is not None)))
    a = np.array(rows, dtype=float)
    med, p95 = np.median(a[:, 0]), np.percentile(a[:, 0], 95)
    print(f"{sky}: {len(a)} images, min of {repeats}: median {med:.1f} us, p95 {p95:.1f} us, "
          f"p95/median {p95 / med:.2f}")
    cols = ("time_us", "stars", "n_patterns", "n_comparisons", "n_verifications", "identified")
    print(f"{'images':>12s} " + " ".join(f"{x:>15s}" for x in cols) + "   us/comparison")
    for label, sel in (("all", np.ones(len(a), bool)), ("<= median", a[:, 0] <= med), (">= p95", a[:, 0] >= p95)):
        m = a[sel].mean(axis=0)
        print(f"{label:>12s} " + " ".join(f"{v:15.1f}" for v in m) + f"   {m[0] / max(m[3], 1):.3f}")


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
