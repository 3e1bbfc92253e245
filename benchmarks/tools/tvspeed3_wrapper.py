"""Where triangle_voting's Python wrapper around its one kernel call spends its time (issue #25, tvspeed3).

    python benchmarks/tools/tvspeed3_wrapper.py [N] [R]

Table 6's two skies at 1 px / 0.5 Mv (seed 0), N images (40), each call timed R times (200, minimum kept),
median over images in us: ``identify``; ``identify_image`` called directly with the bundles ``identify``
passes; the bundle look-ups (``_tolerances``, ``_kernel_tables``, ``_finish_tables``); the photometry check
and the ``Identification``. Warm caches (each call repeated): the interleaved benchmark reads higher.
"""

# ruff: noqa: B023  (each lambda is called at once, inside its loop iteration)
from __future__ import annotations

import sys
import time

import numpy as np
from starid_algorithms.triangle_voting import algorithm as tva
from starid_algorithms.triangle_voting import kernels as tvk

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.plugin import Identification
from starid.registry import get_algorithm


def _best(fn, repeats):
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best * 1e6


def main(n: int, repeats: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(n)]
        alg = get_algorithm("triangle_voting")()
        db = alg.build(cat, cam)
        alg.identify(db, obs[0])
        rows = []
        for o in obs:
            x, y, mag = o.x_px, o.y_px, o.mag
            _, ktol, fin_cam = alg._tolerances(o.camera)
            kt, fin_db = tva._kernel_tables(db), tva._finish_tables(db)
            out = tvk.identify_image(x, y, mag, kt, ktol, fin_db, fin_cam)
            hip, att = out[1], out[2]
            counters = {"a": 1, "b": 2, "c": 3, "d": 4}
            rows.append({
                "identify": _best(lambda o=o: alg.identify(db, o), repeats),
                "identify_image": _best(lambda: tvk.identify_image(x, y, mag, kt, ktol, fin_db, fin_cam), repeats),
                "bundles": _best(lambda o=o: (alg._tolerances(o.camera), tva._kernel_tables(db),
                                              tva._finish_tables(db)), repeats),
                "photometry": _best(lambda: alg._photometry_agrees(db, hip, mag), repeats),
                "Identification": _best(lambda: Identification(hip, att, counters=counters), repeats),
            })
        for k in rows[0]:
            v = np.array([r[k] for r in rows])
            print(f"{sky:5s} {k:15s} median {np.median(v):7.1f} us  mean {np.mean(v):7.1f} us", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40, int(sys.argv[2]) if len(sys.argv) > 2 else 200)
