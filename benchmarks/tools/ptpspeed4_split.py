"""Where ptp's kernel time goes, interleaved and warm, by switching stages off (issue #25, fifth speed round).

Superseded: it calls ``identify_kernel`` with the tuple arguments ptp had before stop 42 (branch
ptpspeed5 passes one parameter array) and runs on that code only (``git checkout ab5f4bd``);
``ptpspeed5_split.py`` profiles the current kernel.

    python benchmarks/tools/ptpspeed4_split.py N SKY

Table 6's images (1 px / 0.5 Mv, seed 0), N of them in the sky SKY (paper or real). Before each timed call
every other registered plugin identifies the image (its tables and Python objects evict ptp's, as in
``benchmarks/test_ratios.py``): "cold"; then the minimum of 3 repeats of the same call: "warm". Median over
the images, µs, of ``identify_kernel`` (the numba call from Python, arguments and result included) with:

* full: the plugin's tolerances;
* no post: ``verify``, ``confirm_fraction``, ``nearest_check`` and ``hypotheses`` off (the steps after
  sharing-star validation);
* no records: also ``max_candidates=0`` (windows and three-side checks only: no match records, no validation);
* no windows: ``d_max`` of one scaled-chord unit (no slave, so no triangle: selection, unit vectors,
  distances, the call itself).

Runs on the base commit's kernel too (plain tables, four returned arrays).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from starid_algorithms.ptp import kernels as K
from starid_algorithms.ptp.algorithm import _view

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import available_algorithms, get_algorithm


def main(n: int, sky: str) -> None:
    cat, cam = load_hipparcos(), Camera()
    names = sorted(i.name for i in available_algorithms() if i.status == "ok")
    others = [get_algorithm(nm)() for nm in names if nm != "ptp"]
    other_dbs = [a.build(cat, cam) for a in others]
    ptp = get_algorithm("ptp")()
    db = ptp.build(cat, cam)
    tables = db.packed if hasattr(K, "pack_tables") else (db.plain_tables,)
    view = _view(cam)[1]
    tol = ptp.tolerances(db)
    post_off = {"verify": False, "confirm_fraction": 0.0, "nearest_check": False, "hypotheses": 0}
    variants = {
        "full": K.plain(tol),
        "no post (verify, confirm, nearest, hypotheses)": K.plain(tol._replace(**post_off)),
        "no records (windows and checks only)": K.plain(tol._replace(max_candidates=0, **post_off)),
        "no windows (the call, selection, distances)": K.plain(tol._replace(d_max=1.0, **post_off)),
    }
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                    seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(n)]
    for a, d in zip(others, other_dbs, strict=True):
        a.identify(d, obs[0])
    for t in variants.values():
        K.identify_kernel(obs[0].x_px, obs[0].y_px, obs[0].mag, view, *tables, t)
    cold = {k: [] for k in variants}
    warm = {k: [] for k in variants}
    for o in obs:
        for k, t in variants.items():
            for a, d in zip(others, other_dbs, strict=True):
                a.identify(d, o)
            t0 = time.perf_counter_ns()
            K.identify_kernel(o.x_px, o.y_px, o.mag, view, *tables, t)
            cold[k].append(time.perf_counter_ns() - t0)
            best = np.inf
            for _ in range(3):
                t0 = time.perf_counter_ns()
                K.identify_kernel(o.x_px, o.y_px, o.mag, view, *tables, t)
                best = min(best, time.perf_counter_ns() - t0)
            warm[k].append(best)
    print(f"{sky} sky, {n} images, identify_kernel median µs: cold (after the 13 others) / warm (min of 3)")
    for k in variants:
        print(f"  {k:48s} {np.median(cold[k]) / 1e3:7.1f} {np.median(warm[k]) / 1e3:7.1f}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), sys.argv[2])
