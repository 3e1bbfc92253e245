"""Where ptp's time per image goes when it is timed as ``benchmarks/test_ratios.py`` times it (issue #25,
fifth speed round): every registered plugin identifies the image in turn before each timed ptp call, so
ptp's tables are read from the memory the others evicted ("interleaved"), against the minimum of R
repeats of the same call ("warm"). Table 6's images (1 px / 0.5 Mv, seed 0), median over N images, µs.

Superseded: it calls ``identify_kernel`` with the tuple arguments ptp had before stop 42 (branch
ptpspeed5 passes one parameter array) and runs on that code only (``git checkout ab5f4bd``);
``ptpspeed5_split.py`` profiles the current kernel.

    python benchmarks/tools/ptpspeed4_profile.py N R [paper|real|both]

Stages (each includes the ones above; the search loop rebuilt in one pass, window by window, by
``ptpspeed3_profile.search_stage``): setup (selection, unit vectors, distances, slave lists, the triangle
loop), + windows (sides, projection, sigma, k-vector query), + three-side checks, + match records,
+ sharing-star validation;
then the whole kernel, and ``PTP.identify`` (the Python wrapper and the ``Identification``).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from starid_algorithms.ptp import kernels as K

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import available_algorithms, get_algorithm


def main(n: int, repeats: int, skies) -> None:
    sys.path.insert(0, "benchmarks/tools")
    from ptpspeed3_profile import search_stage  # the search loop in one pass, stage by stage
    from starid_algorithms.ptp.algorithm import _view
    cat, cam = load_hipparcos(), Camera()
    names = sorted(i.name for i in available_algorithms() if i.status == "ok")
    others = [get_algorithm(nm)() for nm in names if nm != "ptp"]
    other_dbs = [a.build(cat, cam) for a in others]
    ptp = get_algorithm("ptp")()
    db = ptp.build(cat, cam)
    tables, view = db.plain_tables, _view(cam)[1]
    packed = db.packed if hasattr(K, "pack_tables") else (tables,)    # the base commit: plain tables
    tol_t = K.plain(ptp.tolerances(db))
    print(f"db_mb {db.nbytes / 1e6:.3f}, rows {db.ids.shape[0]}")
    for sky in skies:
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(n)]
        for a, d in zip(others, other_dbs, strict=True):
            a.identify(d, obs[0])
        stages = [(f"stage {lv}", lambda o, lv=lv: search_stage(o.x_px, o.y_px, o.mag, view, tables, tol_t, lv))
                  for lv in range(5)]
        stages.append(("kernel", lambda o: K.identify_kernel(o.x_px, o.y_px, o.mag, view, *packed, tol_t)))
        stages.append(("identify", lambda o: ptp.identify(db, o)))
        labels = ["setup", "+ windows", "+ three-side checks", "+ match records", "+ validation", "whole kernel",
                  "PTP.identify"]
        for _, fn in stages:
            fn(obs[0])
        cold = np.zeros((len(stages), n))
        warm = np.zeros((len(stages), n))
        for i, o in enumerate(obs):
            for s, (_, fn) in enumerate(stages):
                for a, d in zip(others, other_dbs, strict=True):   # the others evict ptp's rows
                    a.identify(d, o)
                t0 = time.perf_counter_ns()
                fn(o)
                cold[s, i] = (time.perf_counter_ns() - t0) / 1e3
                best = np.inf
                for _ in range(repeats):
                    t0 = time.perf_counter_ns()
                    fn(o)
                    best = min(best, time.perf_counter_ns() - t0)
                warm[s, i] = best / 1e3
        print(f"{sky} sky, {n} images: median µs, interleaved (one call after the 13 others) / warm (min of {repeats})")
        for s, label in enumerate(labels):
            print(f"  {label:22s} {np.median(cold[s]):7.1f} {np.median(warm[s]):7.1f}   "
                  f"excess {np.median(cold[s] - warm[s]):6.1f}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    sk = sys.argv[3] if len(sys.argv) == 4 else "both"
    main(int(sys.argv[1]), int(sys.argv[2]), ("paper", "real") if sk == "both" else (sk,))
