"""Where angle's time goes on its tail images (issue #25, branch tailspeed).

    python benchmarks/tools/tailspeed_profile.py 200 3

A copy of ``angle``'s ``_search`` (default reading), same callees and arguments, with the CPU cycle
counter read around the triangle search (``triad_triangles``), the direct-match test (``support``)
and the confirmation (``confirm_pattern``), and two repeat counts: pairings (I, J) tested again
for the same image pair (found by another anchor) and confirmations of a pairing already
confirmed (and failed) for that image pair. Table 6's real sky at 1 px / 0.5 Mv, seed 0, N images,
the run of R with the smallest total kept per image; the copy is checked against the plugin's rows.
Prints the 10 % slowest images and the totals over them, in thousand cycles.
"""

import sys

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic
from starid_algorithms.angle.kernels import confirm_pattern, support
from starid_algorithms.pyramid.kernels import pair_windows, select_stars, triad_triangles

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, camera_frame
from starid.registry import get_algorithm

TABLE6_SIM = {"sigma_px": 1.0, "sigma_mag": 0.5, "mag_limit": 6.0, "min_stars": 6}
SLOTS = ("total", "windows", "triangles", "support", "confirm", "n_tri_calls", "n_tests", "n_repeat_tests",
         "n_confirms", "n_repeat_confirms")


@intrinsic
def cycles(typingctx):
    def codegen(context, builder, sig, args):
        fnty = ir.FunctionType(ir.IntType(64), [])
        fn = builder.module.declare_intrinsic("llvm.readcyclecounter", fnty=fnty)
        return builder.call(fn, [])

    return types.int64(), codegen


@njit
def profiled(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, cam, st):
    t_all = cycles()
    n = x_px.shape[0]
    rows = np.full(n, -1, dtype=np.int64)
    v_cam = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(x_px, y_px, mag, v_cam, tol.d_min, tol.max_stars)
    m = sel.shape[0]
    t0 = cycles()
    start, stop = pair_windows(v_cam, sel, kv, tol)
    st[1] += cycles() - t0
    pat_star = np.empty(2, dtype=np.int64)
    pat_row = np.empty(2, dtype=np.int64)
    n_guide = guide_unit.shape[0]
    cap = 2 * max(tol.max_window, 1)
    scratch = (np.full(n_guide, -1, dtype=np.int32), np.zeros(n_guide, dtype=np.int32),
               np.empty(cap, dtype=np.int32), np.empty(cap, dtype=np.int32))
    tri = np.empty((max(tol.max_triangles, 1), 3), dtype=np.int64)
    seen_i = np.empty(4096, dtype=np.int64)
    seen_j = np.empty(4096, dtype=np.int64)
    seen_ok = np.empty(4096, dtype=np.int64)
    tick = 0
    npairs = 0
    for a in range(m - 1):
        for b in range(a + 1, m):
            if npairs >= tol.max_pairs:
                rows[:] = -1
                st[0] += cycles() - t_all
                return rows
            npairs += 1
            lo, hi = start[a, b], stop[a, b]
            if hi == lo:
                continue
            pat_star[0] = sel[a]
            pat_star[1] = sel[b]
            n_seen = 0
            tried = 0
            for k in range(m):
                if k == a or k == b:
                    continue
                if tried == tol.n_check:
                    break
                tried += 1
                if stop[a, k] == start[a, k] or tol.min_support < 1:
                    continue
                tick += 1
                t0 = cycles()
                n_tri = triad_triangles(v_cam, sel[a], sel[b], sel[k], (lo, hi), (start[a, k], stop[a, k]), pairs,
                                        guide_unit, tol.eps_match, scratch, tick, tri)
                st[2] += cycles() - t0
                st[5] += 1
                if n_tri > tri.shape[0]:
                    continue
                for t in range(n_tri):
                    big_i = tri[t, 0]
                    big_j = tri[t, 1]
                    st[6] += 1
                    prev = -1
                    for q in range(n_seen):
                        if seen_i[q] == big_i and seen_j[q] == big_j:
                            prev = q
                            break
                    if prev >= 0:
                        st[7] += 1
                    t0 = cycles()
                    s = support(v_cam, sel, a, b, big_i, big_j, nbr, nbr_chord, nbr_start, guide_unit, tol.eps_match,
                                tol.n_check, tol.min_support, tol.chirality)
                    st[3] += cycles() - t0
                    ok = s >= tol.min_support
                    if prev < 0 and n_seen < seen_i.shape[0]:
                        seen_i[n_seen] = big_i
                        seen_j[n_seen] = big_j
                        seen_ok[n_seen] = ok
                        n_seen += 1
                    if not ok:
                        continue
                    pat_row[0] = big_i
                    pat_row[1] = big_j
                    st[8] += 1
                    if prev >= 0:
                        st[9] += 1
                    t0 = cycles()
                    good = confirm_pattern(v_cam, pat_star, pat_row, guide_unit, tol.c_fov, tol.eps_match, tol.widen,
                                           cam, tol.min_extra, tol.confirm_fraction, rows)
                    st[4] += cycles() - t0
                    if good:
                        st[0] += cycles() - t_all
                        return rows
    rows[:] = -1
    st[0] += cycles() - t_all
    return rows


def main(n, rounds):
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES["real"]}), seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    alg = get_algorithm("angle")()
    db = alg.build(cat, cam)
    best = np.full((n, len(SLOTS)), np.inf)
    for _ in range(rounds):
        for k, o in enumerate(obs):
            st = np.zeros(len(SLOTS), dtype=np.int64)
            tol = alg.tolerances(o.camera, db)
            rows = profiled(o.x_px, o.y_px, o.mag, db.kv, db.pairs, db.nbr, db.nbr_chord, db.nbr_start, db.guide_unit,
                            tol, camera_frame(o.camera), st)
            ref, _, _ = alg._run(db, o)
            assert (rows == ref).all(), k
            if st[0] < best[k, 0]:
                best[k] = st
    order = np.argsort(-best[:, 0])
    tail = order[: max(1, n // 10)]
    print("trial " + " ".join(f"{s:>14s}" for s in SLOTS))
    for k in tail:
        print(f"{k:5d} " + " ".join(f"{(v / 1e3 if c < 5 else v):14.1f}" for c, v in enumerate(best[k])))
    tot = best[tail].sum(axis=0)
    print("tail  " + " ".join(f"{(v / 1e3 if c < 5 else v):14.1f}" for c, v in enumerate(tot)))
    print("all   " + " ".join(f"{(v / 1e3 if c < 5 else v):14.1f}" for c, v in enumerate(best.sum(axis=0))))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]))
