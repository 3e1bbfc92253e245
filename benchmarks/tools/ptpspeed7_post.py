"""The steps after ptp's sharing-star validation, timed alone, cold and warm (issue #25, eighth speed round).

    python benchmarks/tools/ptpspeed7_post.py N SKY

Table 6's images (1 px / 0.5 Mv, seed 0), N of them in SKY (paper or real). For each image the kernel's final
pairings (its guide rows of the detections that took part) stand in for the validated ones, and a numba kernel
runs the steps ``identify_kernel`` runs after validation on them, stopping after a given one: 0 nothing (the
call), 1 the core's ``verify_pairwise``, 2 + the attitude (the core's ``guide_rows_f64`` and ``wahba_rows``),
3 + the confirmation (the core's ``reproject_assign`` over the z band around the boresight), 4 + ptp's
``drop_displaced`` (``nearest_check``). Each stage timed once right after every other registered plugin
identified the image ("cold", as ``benchmarks/test_ratios.py``) and as the minimum of 3 repeats ("warm");
median µs over the images.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np
from numba import njit
from ptpspeed7_wrapper import setup  # benchmarks/tools
from starid_algorithms.ptp import kernels as K

from starid.kernels import backproject_px, guide_rows_f64, reproject_assign, verify_pairwise, wahba_rows


@njit(cache=True)
def post(unit, rows, guide_unit, tol_chord, min_fraction, c_fov, f_px, cx_px, cy_px, width_px, height_px, stage):
    n = unit.shape[0]
    result = rows.copy()
    if stage == 0:
        return 0
    keep = verify_pairwise(unit, result, guide_unit, tol_chord, np.int64(2), min_fraction)
    for s in range(n):
        if not keep[s]:
            result[s] = -1
    if stage == 1:
        return 1
    w_idx = np.empty(n, dtype=np.int64)
    w_cat = np.empty((n, 3))
    guide_rows_f64(result, guide_unit, w_idx, w_cat)
    attitude = wahba_rows(unit, w_idx, w_cat)
    if stage == 2:
        return 2
    seen = np.empty(n, dtype=np.int64)
    n_seen, n_predicted = reproject_assign(attitude, unit, guide_unit, c_fov + tol_chord, tol_chord, seen,
                                           f_px, cx_px, cy_px, width_px, height_px)
    if stage == 3:
        return n_seen
    return K.drop_displaced(unit, result, guide_unit, tol_chord, attitude)


def main(n: int, sky: str) -> None:
    cam, ptp, db, rest, obs, (tol, params, (narrow, wide), view) = setup(n, sky)
    fr = view.frame
    tol_chord = tol.side_beta * math.sqrt(2.0) * tol.sigma_px / fr.f_px
    args = []
    for o in obs:
        _, _, tail = K.identify_kernel(o.x_px, o.y_px, o.mag, params, narrow, wide)
        sel, rows = K.unpack_tail(tail)
        unit = backproject_px(o.x_px[sel], o.y_px[sel], fr.f_px, fr.cx_px, fr.cy_px)
        args.append((unit, np.ascontiguousarray(rows)))
    for a, d in rest:
        a.identify(d, obs[0])
    stages = range(5)
    cold = {s: [] for s in stages}
    warm = {s: [] for s in stages}
    for o, (unit, rows) in zip(obs, args, strict=True):
        if np.count_nonzero(rows >= 0) < 3:
            continue

        def call(s, unit=unit, rows=rows):
            return post(unit, rows, db.guide_unit, tol_chord, tol.verify_min_fraction, view.c_fov, fr.f_px,
                        fr.cx_px, fr.cy_px, fr.width_px, fr.height_px, s)
        for s in stages:
            call(s)
            for a, d in rest:
                a.identify(d, o)
            t0 = time.perf_counter_ns()
            call(s)
            cold[s].append(time.perf_counter_ns() - t0)
            best = np.inf
            for _ in range(3):
                t0 = time.perf_counter_ns()
                call(s)
                best = min(best, time.perf_counter_ns() - t0)
            warm[s].append(best)
    label = ["the call", "+ verify_pairwise", "+ guide_rows_f64, wahba_rows", "+ reproject_assign",
             "+ drop_displaced"]
    print(f"{sky} sky, {len(cold[0])} identified images of {n}; median µs: cold (after the other plugins) / warm")
    for s in stages:
        print(f"  {label[s]:32s} {np.median(cold[s]) / 1e3:7.1f} {np.median(warm[s]) / 1e3:7.1f}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), sys.argv[2])
