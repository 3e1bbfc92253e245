"""Stage times inside grid's kernel (issue #25 profile tables).

lpt_improved's kernel changed at stop 38 (its first pass without the SVD, ``assign_near``); its stages
are in ``benchmarks/tools/lpispeed_profile.py``, and its copy here was removed. This tool's copy of
lpt's kernel (the string scan before branch lptspeed2's exact string tests, which no longer ran
against today's kernels) was removed at stop 45 with ``lpt.kernels.order_by_count``, which only it
called; lpt's current stages: ``lptspeed3_stages.py``.

    python benchmarks/tools/lptspeed_stages.py 40 5

A copy of grid's ``identify_kernel`` body (same callees, same arguments) with the CPU cycle
counter read between stages (``llvm.readcyclecounter``, converted to us against ``perf_counter``);
Table 6's skies at 1 px / 0.5 Mv, seed 0, N images, the run of R with the smallest total kept per
image; prints per sky the median (and mean) over images of: the kernel call from Python
(perf_counter, dispatch included), then begin (back-projection, double mask, reference order),
patterns (neighbours and image pattern), search (database comparison), verify (confirm of every
candidate), select (ranking the patterns whose credit reached min_score, and the reset;
the copy assumes min_score > 0). Call minus the stages is numba's argument handling and the
kernel's allocations. The copy must follow the kernel when it changes.
"""

import math
import sys
import time

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic
from starid_algorithms.grid import kernels as GK
from starid_algorithms.lpt_improved.planar import (
    acceptance_at,
    begin_identify,
    confirm_pair,
    frame_at,
    keep_best,
    no_match,
    reference_pattern,
)

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm


@intrinsic
def cycles(typingctx):
    def codegen(context, builder, sig, args):
        fnty = ir.FunctionType(ir.IntType(64), [])
        fn = builder.module.declare_intrinsic("llvm.readcyclecounter", fnty=fnty)
        return builder.call(fn, [])

    return types.int64(), codegen


@njit
def grid_kernel(x_px, y_px, params, patterns, cell_start, start, guide, orient, guides_unit, trace, st):
    t0 = cycles()
    sensor = frame_at(params, np.int64(0))
    acc = acceptance_at(params, np.int64(5))
    spec = GK.spec_at(params, np.int64(10))
    table = GK.GridTable(patterns, cell_start, start, guide, orient)
    n = x_px.shape[0]
    rows, unit, usable, order = begin_identify(x_px, y_px, sensor, spec.double_px, trace)
    nbrs = np.empty(n, dtype=np.int64)
    r_px = np.empty(n)
    phi = np.empty(n)
    cand = np.empty(n, dtype=np.int64)
    cells = np.empty(n, dtype=np.int64)
    weight = np.zeros(spec.g * spec.g)
    touched = np.empty(spec.g * spec.g, dtype=np.int64)
    n_pat = table.guide.shape[0]
    raw = np.zeros(n_pat)
    hot = np.empty(n_pat, dtype=np.int64)
    n_best = spec.n_candidates
    best_p = np.empty(n_best, dtype=np.int64)
    best_sc = np.empty(n_best)
    seed = np.full(n, -1, dtype=np.int64)
    t1 = cycles()
    st[0] += t1 - t0
    for t in range(min(spec.max_refs, order.shape[0])):
        t1 = cycles()
        s = order[t]
        k = reference_pattern(unit, usable, x_px, y_px, s, spec.cos_radius, sensor.f_px, nbrs, r_px, phi)
        if k < 1:
            continue
        n_or = GK.orientation_candidates(r_px, k, spec.buffer_px, spec.half_px, cand)
        t2 = cycles()
        st[1] += t2 - t1
        for a in range(min(spec.image_orientations, n_or)):
            t1 = cycles()
            o = cand[a]
            nc = GK.grid_cells(r_px, phi, k, o, spec, cells)
            nt = GK.image_weights(cells, nc, spec, weight, touched)
            touched[:nt] = np.sort(touched[:nt])
            t2 = cycles()
            st[1] += t2 - t1
            nh = 0
            for i in range(nt):
                c = touched[i]
                w = weight[c]
                for q in range(np.uint64(table.cell_start[c]), np.uint64(table.cell_start[c + 1])):
                    p = table.patterns[q]
                    before = raw[p]
                    raw[p] = before + w
                    if before < spec.min_score <= raw[p]:
                        hot[nh] = p
                        nh += 1
            t3 = cycles()
            st[2] += t3 - t2
            found = np.int64(0)
            if nh > 1:
                hot[:nh] = np.sort(hot[:nh])
            for i in range(nh):
                p = hot[i]
                score = raw[p]
                sc = score / math.sqrt(nc * (table.start[p + 1] - table.start[p])) if spec.normalise else score
                if found == n_best and sc <= best_sc[n_best - 1]:
                    continue
                found = keep_best(best_sc, best_p, found, n_best, sc, p)
            raw[:] = 0.0
            for i in range(nt):
                weight[touched[i]] = 0.0
            t4 = cycles()
            st[4] += t4 - t3
            for c in range(found):
                p = best_p[c]
                t4 = cycles()
                ok, A = confirm_pair(
                    unit, rows, seed, s, nbrs[o], table.guide[p], table.orient[p], guides_unit, sensor, acc
                )
                t5 = cycles()
                st[3] += t5 - t4
                if ok:
                    return rows, A, True
    return no_match(rows)


def calib():
    cyc()
    t0 = time.perf_counter()
    c0 = cyc()
    time.sleep(0.2)
    c1 = cyc()
    t1 = time.perf_counter()
    return (c1 - c0) / (t1 - t0) / 1e6  # cycles per us


@njit
def cyc():
    return cycles()


def main(n, R):
    cat, cam = load_hipparcos(), Camera()
    mhz = calib()
    for sky in ("paper", "real"):
        sim = Simulator(
            cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]), seed=0
        )
        tr = sim.generate(n)
        obs = [tr.observation(i, truth=False) for i in range(n)]
        for name, kern in (("grid", grid_kernel),):
            alg = get_algorithm(name)()
            db = alg.build(cat, cam)
            per = []
            for o in obs:
                args = alg._kernel_args(db, o.camera)
                best = None
                for _ in range(R):
                    st = np.zeros(5, dtype=np.int64)
                    tr_ = alg._run(db, o)[3]
                    t0 = time.perf_counter_ns()
                    kern(o.x_px, o.y_px, *args, tr_, st)
                    tot = (time.perf_counter_ns() - t0) / 1e3 * mhz
                    if best is None or tot < best[0]:
                        best = (tot, st.copy())
                per.append(np.concatenate([[best[0]], best[1]]) / mhz)
            per = np.array(per)
            print(
                sky,
                name,
                "median us: call (perf_counter), begin, patterns, search, verify, select",
                *(f"{v:.1f}" for v in np.median(per, axis=0)),
                "| mean",
                *(f"{v:.1f}" for v in per.mean(axis=0)),
            )


main(int(sys.argv[1]), int(sys.argv[2]))
