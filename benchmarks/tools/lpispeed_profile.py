"""Where lpt_improved's time goes inside the reprojection check, per sky (issue #25, branch lpispeed).

    python benchmarks/tools/lpispeed_profile.py 60 5

A copy of ``lpt_improved``'s ``identify_kernel`` and of the acceptance it calls (``confirm_pair``,
``confirm``, the reprojection), same callees and arguments, with the CPU cycle counter read
between stages and work counted. Table 6's skies at 1 px / 0.5 Mv, seed 0, N images, the run of R
with the smallest total kept per image. Prints per sky the median and mean over images of:

* times (us): the kernel call from Python; begin; patterns; search; the pair check and seed
  Wahba of ``confirm_pair``; reprojection: the catalog band scan (rows tested against the
  field's cap) and the matching of each prediction against the detections; Wahba refinements;
  ``verify_pairwise``; the rest of ``confirm``;
* counts: detections, candidates reaching ``confirm_pair``, those past the pair check,
  reprojection passes, catalog rows scanned, rows inside the cap, accepted (0/1).

Then the same for a second copy, of the kernel as it is now (``confirm_pair_near``): begin,
patterns, search, the pair test (separation check, ``pair_attitude``, ``pair_first_pass``), the
full check (``confirm_near``, with the seed Wahba when the first pass was undecided) of the pairs
not rejected there; counts of both. Both copies
are checked against the plugin on every image (same rows, same verdict), and the largest
difference between the seed Wahba and ``pair_attitude`` over every candidate is printed, also
as a fraction of the bound ``pair_first_pass`` assumes. The first copy is the base commit's check
(``planar.confirm_pair``/``confirm``, still in planar.py for grid and lpt).
"""

import math
import sys
import time

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic
from starid_algorithms.lpt_improved import kernels as LI
from starid_algorithms.lpt_improved.planar import (
    SEPARATION_TOL,
    acceptance_at,
    begin_identify,
    confirm_near,
    frame_at,
    no_match,
    pair_attitude,
    pair_first_pass,
    pair_work,
    reference_pattern,
)

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import chord_rows, verify_pairwise, wahba_rows
from starid.kernels.verify import keep_unique, z_band_rows
from starid.registry import get_algorithm

# stage slots
BEGIN, PATTERNS, SEARCH, PAIR, BAND, MATCH, WAHBA, PAIRWISE, REST = range(9)
STAGES = ("begin", "patterns", "search", "pair+seed", "band scan", "match", "wahba", "pairwise", "rest")
# count slots (after the stages)
N_DET, N_CAND, N_PAST, N_PASS, N_BAND, N_CAP, N_OK = range(9, 16)
COUNTS = ("detections", "candidates", "past pair check", "reproj passes", "band rows", "cap rows", "accepted")


@intrinsic
def cycles(typingctx):
    def codegen(context, builder, sig, args):
        fnty = ir.FunctionType(ir.IntType(64), [])
        fn = builder.module.declare_intrinsic("llvm.readcyclecounter", fnty=fnty)
        return builder.call(fn, [])

    return types.int64(), codegen


@njit
def cyc():
    return cycles()


@njit
def reproject_timed(A, v_cam, unit, c_fov, eps, out_row, f_px, cx_px, cy_px, width_px, height_px, st):
    """``starid.kernels.reproject_assign`` with the band scan and the matching timed apart."""
    t0 = cycles()
    n = v_cam.shape[0]
    n_match = np.zeros(n, dtype=np.int64)
    for i in range(n):
        out_row[i] = -1
    bore = np.empty((1, 3))
    for a in range(3):
        bore[0, a] = A[2, a]
    b = np.empty((1, 3))
    n_predicted = 0
    g_start, g_stop = z_band_rows(unit, bore[0, 2], c_fov)
    st[N_BAND] += g_stop - g_start
    st[N_PASS] += 1
    match = 0
    for g in range(g_start, g_stop):
        if chord_rows(unit, g, bore, np.int64(0)) > c_fov:
            continue
        t1 = cycles()
        st[N_CAP] += 1
        for a in range(3):
            b[0, a] = A[a, 0] * unit[g, 0] + A[a, 1] * unit[g, 1] + A[a, 2] * unit[g, 2]
        if b[0, 2] > 0:
            x = cx_px + f_px * b[0, 0] / b[0, 2]
            y = cy_px + f_px * b[0, 1] / b[0, 2]
            if 0 <= x < width_px and 0 <= y < height_px:
                n_predicted += 1
        found = -1
        n_found = 0
        for i in range(n):
            if chord_rows(v_cam, i, b, np.int64(0)) <= eps:
                n_found += 1
                found = i
        if n_found == 1:
            n_match[found] += 1
            out_row[found] = g
        elif n_found > 1:
            for i in range(n):
                if chord_rows(v_cam, i, b, np.int64(0)) <= eps:
                    n_match[i] += 2
        match += cycles() - t1
    r = keep_unique(n_match, out_row)
    st[MATCH] += match
    st[BAND] += cycles() - t0 - match
    return r, n_predicted


@njit
def confirm_timed(unit, rows, attitude, guides_unit, sensor, acc, solved_from, st):
    """``planar.confirm`` with its stages timed."""
    t_in = cycles()
    n = unit.shape[0]
    A = attitude
    eps = acc.eps0
    n_prev = -1
    n_seen = 0
    n_pred = 0
    solved = solved_from.copy()
    stale = False
    inner = 0
    for it in range(5):
        t0 = cycles()
        n_seen, n_pred = reproject_timed(A, unit, guides_unit, acc.c_fov + eps, eps, rows, sensor.f_px,
                                         sensor.cx_px, sensor.cy_px, sensor.width_px, sensor.height_px, st)
        inner += cycles() - t0
        if n_seen < 2:
            st[REST] += cycles() - t_in - inner
            return False, A
        stale = True
        for i in range(n):
            if rows[i] != solved[i]:
                stale = False
                break
        if not stale:
            t0 = cycles()
            A = wahba_rows(unit, rows, guides_unit)
            dt = cycles() - t0
            st[WAHBA] += dt
            inner += dt
            solved[:] = rows
        elif it > 0 or acc.eps0 == acc.eps:
            break
        if it > 0 and n_seen <= n_prev and eps == acc.eps:
            break
        n_prev = n_seen
        eps = acc.eps
    if not stale:
        t0 = cycles()
        n_seen, n_pred = reproject_timed(A, unit, guides_unit, acc.c_fov + eps, eps, rows, sensor.f_px,
                                         sensor.cx_px, sensor.cy_px, sensor.width_px, sensor.height_px, st)
        inner += cycles() - t0
    t0 = cycles()
    keep = verify_pairwise(unit, rows, guides_unit, acc.eps, np.int64(2), 0.5)
    dt = cycles() - t0
    st[PAIRWISE] += dt
    inner += dt
    n_keep = 0
    for i in range(n):
        if not keep[i]:
            rows[i] = -1
        else:
            n_keep += 1
    if n_keep < acc.min_matches or n_keep < acc.fraction * n_pred:
        for i in range(n):
            rows[i] = -1
        st[REST] += cycles() - t_in - inner
        return False, A
    t0 = cycles()
    A = wahba_rows(unit, rows, guides_unit)
    st[WAHBA] += cycles() - t0
    inner += cycles() - t0
    st[REST] += cycles() - t_in - inner
    return True, A


@njit
def li_kernel(x_px, y_px, params, columns, total, count_start, guide, align, align_chord, guides_unit, z_start,
              by_chord, chords, trace, st, att):
    t0 = cycles()
    sensor = frame_at(params, np.int64(0))
    acc = acceptance_at(params, np.int64(5))
    search = LI.search_at(params, np.int64(10))
    table = LI.FeatureTable(columns, total, count_start, guide, align, align_chord)
    n = x_px.shape[0]
    st[N_DET] += n
    rows, unit, usable, order = begin_identify(x_px, y_px, sensor, search.double_px, trace)
    m = search.n_sectors
    nbrs = np.empty(n, dtype=np.int64)
    r_px = np.empty(n)
    phi = np.empty(n)
    vec = np.zeros(m, dtype=np.int64)
    nz_idx = np.empty(m, dtype=np.int64)
    best_row = np.empty(search.n_candidates, dtype=np.int64)
    best_sad = np.empty(search.n_candidates, dtype=np.int64)
    seed = np.full(n, -1, dtype=np.int64)
    sums = np.empty(table.total.shape[0], dtype=np.int32)
    chord_tol = SEPARATION_TOL * acc.eps0 if search.pair_filter else -1.0
    st[BEGIN] += cycles() - t0
    for t in range(min(search.max_refs, order.shape[0])):
        t1 = cycles()
        s = order[t]
        k = reference_pattern(unit, usable, x_px, y_px, s, search.cos_radius, sensor.f_px, nbrs, r_px, phi)
        st[PATTERNS] += cycles() - t1
        for a in range(min(search.image_alignments, k)):
            t1 = cycles()
            nz = LI.feature_vector(r_px, phi, k, a, m, search.log_scale, vec)
            q = 0
            for i in range(m):
                if vec[i] != 0:
                    nz_idx[q] = i
                    q += 1
            t2 = cycles()
            st[PATTERNS] += t2 - t1
            found = LI.sad_search(table, vec, nz_idx, nz, search.count_tol, search.n_candidates, best_row, best_sad,
                                  search.count_tol_above, sums, chord_rows(unit, s, unit, nbrs[a]), chord_tol)
            st[SEARCH] += cycles() - t2
            for c in range(found):
                r = best_row[c]
                st[N_CAND] += 1
                t3 = cycles()
                o = nbrs[a]
                gs = table.guide[r]
                go = table.align[r]
                if abs(chord_rows(unit, s, unit, o) - chord_rows(guides_unit, gs, guides_unit, go)) > \
                        SEPARATION_TOL * acc.eps0:
                    st[PAIR] += cycles() - t3
                    continue
                st[N_PAST] += 1
                seed[s] = gs
                seed[o] = go
                A = wahba_rows(unit, seed, guides_unit)
                st[PAIR] += cycles() - t3
                Ap = np.empty((3, 3))
                tol = pair_attitude(unit, s, o, guides_unit, gs, go, Ap)
                if tol > 0:   # largest column-sum difference (>= the 2-norm / sqrt(3)) and the 2-norm bound
                    diff = 0.0
                    for e in range(3):
                        for f in range(3):
                            diff += (A[e, f] - Ap[e, f]) ** 2
                    att[0] = max(att[0], math.sqrt(diff))   # Frobenius norm >= 2-norm
                    att[2] = max(att[2], math.sqrt(diff) / tol)
                else:
                    att[1] += 1
                ok, A = confirm_timed(unit, rows, A, guides_unit, sensor, acc, seed, st)
                seed[s] = -1
                seed[o] = -1
                if ok:
                    st[N_OK] += 1
                    return rows, A, True
    return no_match(rows)


NEW_STAGES = ("begin", "patterns", "search", "pair test", "full check")
NEW_COUNTS = ("rejected at pass 1", "full checks", "undecided (SVD)")


@njit
def li_kernel_new(x_px, y_px, params, columns, total, count_start, guide, align, align_chord, guides_unit, z_start,
                  by_chord, chords, trace, st):
    """The plugin's ``identify_kernel`` as it is now, with its stages timed: ``confirm_pair_near``
    split into the cheap part (separation check, ``pair_attitude``, ``pair_first_pass``) and the
    full check (``confirm_near``; the seed Wahba when the first pass was undecided)."""
    t0 = cycles()
    sensor = frame_at(params, np.int64(0))
    acc = acceptance_at(params, np.int64(5))
    search = LI.search_at(params, np.int64(10))
    table = LI.FeatureTable(columns, total, count_start, guide, align, align_chord)
    n = x_px.shape[0]
    rows, unit, usable, order = begin_identify(x_px, y_px, sensor, search.double_px, trace)
    m = search.n_sectors
    nbrs = np.empty(n, dtype=np.int64)
    r_px = np.empty(n)
    phi = np.empty(n)
    vec = np.zeros(m, dtype=np.int64)
    nz_idx = np.empty(m, dtype=np.int64)
    best_row = np.empty(search.n_candidates, dtype=np.int64)
    best_sad = np.empty(search.n_candidates, dtype=np.int64)
    seed = np.full(n, -1, dtype=np.int64)
    work, A0 = pair_work(n)
    sums = np.empty(table.total.shape[0], dtype=np.int32)
    chord_tol = SEPARATION_TOL * acc.eps0 if search.pair_filter else -1.0
    st[0] += cycles() - t0
    for t in range(min(search.max_refs, order.shape[0])):
        t1 = cycles()
        s = order[t]
        k = reference_pattern(unit, usable, x_px, y_px, s, search.cos_radius, sensor.f_px, nbrs, r_px, phi)
        st[1] += cycles() - t1
        for a in range(min(search.image_alignments, k)):
            t1 = cycles()
            nz = LI.feature_vector(r_px, phi, k, a, m, search.log_scale, vec)
            q = 0
            for i in range(m):
                if vec[i] != 0:
                    nz_idx[q] = i
                    q += 1
            t2 = cycles()
            st[1] += t2 - t1
            if chord_tol >= 0:
                found = LI.sad_search_pairs(table, vec, nz_idx, nz, search.count_tol, search.n_candidates, best_row,
                                            best_sad, search.count_tol_above, chord_rows(unit, s, unit, nbrs[a]),
                                            chord_tol, by_chord, chords)
            else:
                found = LI.sad_search(table, vec, nz_idx, nz, search.count_tol, search.n_candidates, best_row, best_sad,
                                      search.count_tol_above, sums, chord_rows(unit, s, unit, nbrs[a]), chord_tol)
            st[2] += cycles() - t2
            for c in range(found):
                r = best_row[c]
                o = nbrs[a]
                gs = table.guide[r]
                go = table.align[r]
                t3 = cycles()
                if abs(chord_rows(unit, s, unit, o) - chord_rows(guides_unit, gs, guides_unit, go)) > \
                        SEPARATION_TOL * acc.eps0:
                    st[3] += cycles() - t3
                    continue
                seed[s] = gs
                seed[o] = go
                n_first = np.int64(-1)
                A = A0
                if acc.eps0 == acc.eps:
                    tol = pair_attitude(unit, s, o, guides_unit, gs, go, A0)
                    if tol > 0:
                        n_first = pair_first_pass(A0, tol, unit, guides_unit, z_start, acc.c_fov + acc.eps0, acc.eps0,
                                                  work)
                if n_first >= 0:
                    first = work[3]
                    if n_first < 2 or n_first == 2 and first[s] == gs and first[o] == go:
                        seed[s] = -1
                        seed[o] = -1
                        st[3] += cycles() - t3
                        st[5] += 1
                        continue
                    rows[:] = first
                t4 = cycles()
                st[3] += t4 - t3
                if n_first < 0:
                    A = wahba_rows(unit, seed, guides_unit)
                    st[7] += 1
                ok, A = confirm_near(unit, rows, A, guides_unit, z_start, sensor, acc, seed, work, n_first)
                seed[s] = -1
                seed[o] = -1
                st[4] += cycles() - t4
                st[6] += 1
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


def main(n, repeats):
    cat, cam = load_hipparcos(), Camera()
    mhz = calib()
    alg = get_algorithm("lpt_improved")()
    db = alg.build(cat, cam)
    print(f"guide stars {db.guide_unit.shape[0]}; cycles per us {mhz:.0f}")
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        tr = sim.generate(n)
        obs = [tr.observation(i, truth=False) for i in range(n)]
        times, counts, new = [], [], []
        att = np.zeros(3)   # largest ||seed Wahba - pair_attitude|| (Frobenius), degenerate pairs, largest / tol
        for o in obs:
            args = alg._kernel_args(db, o.camera)
            best = None
            for _ in range(repeats):
                st = np.zeros(16, dtype=np.int64)
                trace = alg._run(db, o)[3]
                t0 = time.perf_counter_ns()
                rows, _, ok = li_kernel(o.x_px, o.y_px, *args, trace, st, att)
                call = (time.perf_counter_ns() - t0) / 1e3
                ref_rows, _, ref_ok, _ = alg._run(db, o)
                assert ok == ref_ok and np.array_equal(rows, ref_rows), "the copy disagrees with the plugin"
                if best is None or call < best[0]:
                    best = (call, st.copy())
            times.append(np.concatenate([[best[0]], best[1][:9] / mhz]))
            counts.append(best[1][9:16])
            best = None
            for _ in range(repeats):
                st = np.zeros(8, dtype=np.int64)
                t0 = time.perf_counter_ns()
                rows, _, ok = li_kernel_new(o.x_px, o.y_px, *args, trace, st)
                call = (time.perf_counter_ns() - t0) / 1e3
                assert ok == ref_ok and np.array_equal(rows, ref_rows), "the copy disagrees with the plugin"
                if best is None or call < best[0]:
                    best = (call, st.copy())
            new.append(np.concatenate([[best[0]], best[1][:5] / mhz, best[1][5:8]]))
        times, counts, new = np.array(times), np.array(counts, dtype=float), np.array(new)
        print(f"\n{sky} sky, {n} images, min of {repeats}: median / mean per image; the base commit's check")
        for name, col in zip(("kernel call", *STAGES), times.T, strict=True):
            print(f"  {name:18s} {np.median(col):8.1f} {col.mean():8.1f} us")
        for name, col in zip(COUNTS, counts.T, strict=True):
            print(f"  {name:18s} {np.median(col):8.1f} {col.mean():8.1f}")
        print("  the plugin now (confirm_pair_near)")
        for name, col in zip(("kernel call", *NEW_STAGES), new.T[:6], strict=True):
            print(f"  {name:18s} {np.median(col):8.1f} {col.mean():8.1f} us")
        for name, col in zip(NEW_COUNTS, new.T[6:], strict=True):
            print(f"  {name:18s} {np.median(col):8.1f} {col.mean():8.1f}")
        print(f"  seed Wahba vs pair_attitude: largest difference {att[0]:.2e} (Frobenius), degenerate {att[1]:.0f}, "
              f"largest difference / its bound {att[2]:.2e}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]))
