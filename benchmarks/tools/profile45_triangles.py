"""Where spherical_triangle's and composite_pyramid's ``identify`` spends its time (issue #25, stop 45).

    python benchmarks/tools/profile45_triangles.py N R [spherical_triangle|composite_pyramid[:paper|:galvizo2018] ...]

Table 6's images (``Simulator(catalog, Camera(), SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0,
min_stars=6, **SKIES[sky]), seed=0)``), both skies, N images; per image each measurement is repeated R times
back to back and its minimum kept. Per plugin and sky, the median and mean over the images, in us, of:

* ``identify``: the plugin's ``identify(db, observation)`` from Python (``time.perf_counter_ns`` around it, as
  ``benchmarks/test_ratios.py`` times it);
* ``kernel call``: the plugin's kernel called from Python with the arguments the wrapper passes (the
  tolerances and the camera frame made outside the timed region);
* ``Identification``: the wrapper's lines after the kernel (``to_r``, ``hip_of``, the counters' dict and the
  ``Identification``) on the kernel's output;
* ``wrapper`` = identify - kernel call - Identification (the tolerances' NamedTuple, ``camera_frame``);
* ``dispatch``: the kernel called on the image's first two stars (it returns before any work): numba's
  argument handling and the return;
* the kernel's stages, from a copy of its body in this file (``spherical_copy`` / ``composite_copy``) that
  calls the plugin's own inner kernels and reads the CPU cycle counter between stages (``llvm.readcyclecounter``
  through a numba intrinsic, converted to us against ``perf_counter``, as ``lptspeed_stages.py`` does): setup
  (back-projection, ``select_stars``, scratch arrays), the trio queries' windows (``tri_features`` and the
  finite-difference half-widths of ``tri_windows``, the side check) and searches (``tri_query``: area k-vector,
  moment-sorted blocks, side filter), Cole's pivot (spherical_triangle with ``pivot``), the direct-match test
  (``trio_confirm``: bijections, Wahba, reprojection), composite_pyramid's fourth-star queries (windows,
  searches) and matching (``_third_stars``, ``_fourth_star``), the final step (``first_query_check``,
  ``wahba_rows``); ``rest`` = the copy's whole time - its stages (the loops, the counters);
* tetra's ``identify`` on the same images in the same loop, for scale.

On every image and every repeat the copy's output (rows, attitude, trio, work counters) is asserted equal to
the plugin kernel's, and the built ``Identification`` to ``identify``'s. Also printed: the work counters'
medians (``Identification.counters`` and the copy's counts of direct-match tests and candidates) and the
slowest 5 % of images by ``identify`` (their mean stages and counters). The copies must follow the kernels
when they change.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from cyclecounter import cycles, cycles_per_us  # benchmarks/tools
from numba import njit
from starid_algorithms.composite_pyramid import kernels as cpk
from starid_algorithms.pyramid.kernels import select_stars
from starid_algorithms.spherical_triangle import algorithm as sta
from starid_algorithms.spherical_triangle import kernels as stk

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, camera_frame, wahba_rows
from starid.kernels.kvector import kvector_query
from starid.kernels.triangles import (
    BLOCK,
    _chord,
    _sides_agree,
    _sorted3,
    tri_features,
    tri_query,
    tri_windows,
    trio_confirm,
    trio_query,
)
from starid.plugin import Identification
from starid.registry import get_algorithm

#: stage slots of ``st`` (cycles); TOTAL is the copy's whole time
SETUP, WIN, SEARCH, PIVOT, CONFIRM, WIN4, SEARCH4, MATCH4, FINAL, TOTAL, OVER, S_BISECT, S_FULL = range(13)
STAGES = ("setup: back-projection, select_stars, scratch", "trio windows (features, FD half-widths)",
          "trio searches (tri_query)", "Cole's pivot (queries, two-star filter)", "direct-match test (trio_confirm)",
          "fourth-star windows", "fourth-star searches", "fourth-star matching", "final: first_query_check, wahba")
#: the copy's own counts (``cnt``)
COUNTS = ("confirm_calls", "confirm_passed", "candidates", "skipped_queries", "fourth_tries", "area_hits",
          "blocks", "moment_hits", "side_pass")



@njit
def _search_counts(index, a_lo, a_hi, m_lo, m_hi, max_hits, truncate, unit, sides, eps_side, cnt, scan):
    """``tri_query``'s loops without the output: adds to ``cnt`` the area-window hits, the moment-sorted
    blocks visited, the entries in the moment window, and those passing the area and side checks; returns
    what ``tri_query`` returns, short of its ``out`` overflow (checked against it by the caller). Without
    ``scan``, only the k-vector query and each block's bisection (timed apart: the search's split)."""
    start, stop = kvector_query(index.kv, a_lo, a_hi)
    if stop - start > max_hits:
        if not truncate:
            return -1
        stop = start + max_hits
        a_hi = index.kv.values[stop - 1]
    if stop <= start:
        return 0
    cnt[5] += stop - start
    mom = index.moment
    area = index.area
    count = 0
    b0 = start // BLOCK
    b1 = (stop - 1) // BLOCK
    n = mom.shape[0]
    cnt[6] += b1 - b0 + 1
    for b in range(b0, b1 + 1):
        x = b * BLOCK
        y = min(x + BLOCK, n)
        edge = b == b0 or b == b1
        lo, hi = x, y
        while lo < hi:
            mid = (lo + hi) // 2
            if mom[mid] < m_lo:
                lo = mid + 1
            else:
                hi = mid
        p = lo
        if not scan:
            cnt[7] += p
            continue
        while p < y and mom[p] <= m_hi:
            cnt[7] += 1
            if (not edge or (a_lo <= area[p] <= a_hi)) and (eps_side <= 0.0 or _sides_agree(
                    unit, index.stars[p, 0], index.stars[p, 1], index.stars[p, 2], sides, eps_side)):
                count += 1
            p += 1
    cnt[8] += count
    return count


@njit
def _query(v_cam, a, b, c, index, tol, unit, out, st, s_win, s_search, cnt):
    """``trio_query``'s body, its windows and its search timed apart."""
    t0 = cycles()
    c_ab = _chord(v_cam, a, v_cam, b)
    c_ac = _chord(v_cam, a, v_cam, c)
    c_bc = _chord(v_cam, b, v_cam, c)
    if c_ab > tol.chord_max or c_ac > tol.chord_max or c_bc > tol.chord_max:
        st[s_win] += cycles() - t0
        return 0
    x, y, z = _sorted3(c_ab, c_ac, c_bc)
    sides = np.array([x, y, z])
    if tol.fixed_area > 0.0:
        area, moment = tri_features(v_cam[a], v_cam[b], v_cam[c], tol.kind, tol.depth)
        ha = tol.fixed_area
        hm = tol.fixed_moment
    else:
        area, moment, ha, hm = tri_windows(v_cam[a], v_cam[b], v_cam[c], tol.kind, tol.depth, tol.sigma_rad,
                                           tol.beta)
    t1 = cycles()
    st[s_win] += t1 - t0
    r = tri_query(index, area - ha, area + ha, moment - hm, moment + hm, tol.max_hits, tol.truncate, unit, sides,
                  tol.eps_side, out)
    t2 = cycles()
    st[s_search] += t2 - t1
    # the counts (not timed: their cycles are taken off the copy's total)
    r2 = _search_counts(index, area - ha, area + ha, moment - hm, moment + hm, tol.max_hits, tol.truncate, unit,
                        sides, tol.eps_side, cnt, True)
    if r >= 0 and r2 != r:
        raise AssertionError("search counts")
    # the search's split: k-vector and bisections alone, then the whole copy (both warm, after tri_query)
    scratch = np.zeros(cnt.shape[0], dtype=np.int64)
    t3 = cycles()
    _search_counts(index, area - ha, area + ha, moment - hm, moment + hm, tol.max_hits, tol.truncate, unit, sides,
                   tol.eps_side, scratch, False)
    t4 = cycles()
    _search_counts(index, area - ha, area + ha, moment - hm, moment + hm, tol.max_hits, tol.truncate, unit, sides,
                   tol.eps_side, scratch, True)
    t5 = cycles()
    st[S_BISECT] += t4 - t3
    st[S_FULL] += t5 - t4
    st[OVER] += cycles() - t2
    return r


@njit
def spherical_copy(x_px, y_px, mag, index, guide_unit, tol, cam, st, cnt):
    """``spherical_kernel``'s body with the cycle counter read between stages (``st``) and counts (``cnt``)."""
    t_begin = cycles()
    n = x_px.shape[0]
    rows = np.full(n, -1, dtype=np.int64)
    trio_out = np.full(3, -1, dtype=np.int64)
    work = np.zeros(len(stk.WORK_NAMES), dtype=np.int64)
    if n < 3:
        st[TOTAL] += cycles() - t_begin
        return rows, np.zeros((3, 3)), trio_out, work
    v_cam = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(x_px, y_px, mag, v_cam, tol.d_min, tol.max_stars)
    m = sel.shape[0]
    cand = np.empty(tol.max_candidates, dtype=np.int64)
    cand2 = np.empty(tol.max_candidates, dtype=np.int64)
    cand3 = np.empty(tol.max_candidates, dtype=np.int64)
    trio = np.empty(3, dtype=np.int64)
    try_rows = np.empty(n, dtype=np.int64)
    trial = np.empty(n, dtype=np.int64)
    stars = index.stars
    first_trio = np.full(3, -1, dtype=np.int64)
    first_cand = np.empty(tol.max_candidates, dtype=np.int64)
    st[SETUP] += cycles() - t_begin
    for i in range(m):
        for j in range(i + 1, m):
            for k in range(j + 1, m):
                if work[0] >= tol.max_trios:
                    st[TOTAL] += cycles() - t_begin
                    return np.full(n, -1, dtype=np.int64), np.zeros((3, 3)), trio_out, work
                work[0] += 1
                nc = _query(v_cam, sel[i], sel[j], sel[k], index, tol, guide_unit, cand, st, WIN, SEARCH, cnt)
                work[1] += 1
                if nc < 0:
                    cnt[3] += 1
                if work[0] == 1:
                    work[2] = max(nc, 0)
                    first_trio[0] = sel[i]
                    first_trio[1] = sel[j]
                    first_trio[2] = sel[k]
                    for c in range(min(max(nc, 0), first_cand.shape[0])):
                        first_cand[c] = cand[c]
                if nc <= 0:
                    continue
                trio[0] = sel[i]
                trio[1] = sel[j]
                trio[2] = sel[k]
                if tol.pivot and nc > 1:
                    t_p = cycles()
                    for b in range(m):
                        if b == i or b == j or b == k:
                            continue
                        n2 = trio_query(v_cam, sel[i], sel[j], sel[b], index, tol.kind, tol.depth,
                                        tol.sigma_rad, tol.beta, tol.fixed_area, tol.fixed_moment, tol.chord_max,
                                        tol.max_hits, tol.truncate, guide_unit, tol.eps_side, cand2)
                        work[1] += 1
                        kept = 0
                        for c2 in range(max(n2, 0)):
                            for c in range(nc):
                                if stk._share_two(stars, cand2[c2], cand[c]):
                                    cand3[kept] = cand2[c2]
                                    kept += 1
                                    break
                        for c in range(kept):
                            cand[c] = cand3[c]
                        nc = kept
                        trio[2] = sel[b]
                        if nc <= 1:
                            break
                    st[PIVOT] += cycles() - t_p
                if nc == 1 and work[5] == 0:
                    work[5] = work[1]
                if nc == 0 or (tol.unique and nc != 1):
                    continue
                cnt[2] += nc
                t_c = cycles()
                n_ok = 0
                for c in range(nc):
                    cnt[0] += 1
                    seen = trio_confirm(v_cam, trio, stars[cand[c]], guide_unit, tol.eps, tol.match_sides,
                                        tol.c_fov, tol.min_extra, tol.confirm_fraction, cam, try_rows, trial)
                    if seen < 0:
                        continue
                    cnt[1] += 1
                    n_ok += 1
                    if n_ok > 1:
                        break
                    for q in range(n):
                        rows[q] = try_rows[q]
                    for q in range(3):
                        trio_out[q] = trio[q]
                st[CONFIRM] += cycles() - t_c
                if n_ok == 1:
                    t_f = cycles()
                    stk.first_query_check(work, rows, first_trio, first_cand, stars)
                    att = wahba_rows(v_cam, rows, guide_unit)
                    t_e = cycles()
                    st[FINAL] += t_e - t_f
                    st[TOTAL] += t_e - t_begin
                    return rows, att, trio_out, work
                rows[:] = -1
                trio_out[:] = -1
    st[TOTAL] += cycles() - t_begin
    return rows, np.zeros((3, 3)), trio_out, work


@njit
def composite_copy(x_px, y_px, mag, index, guide_unit, tol, cam, st, cnt):
    """``composite_kernel``'s body with the cycle counter read between stages (``st``) and counts (``cnt``)."""
    t_begin = cycles()
    n = x_px.shape[0]
    rows = np.full(n, -1, dtype=np.int64)
    out4 = np.full(4, -1, dtype=np.int64)
    work = np.zeros(len(stk.WORK_NAMES), dtype=np.int64)
    if n < 3:
        st[TOTAL] += cycles() - t_begin
        return rows, np.zeros((3, 3)), out4, work
    v_cam = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(x_px, y_px, mag, v_cam, tol.d_min, tol.max_stars)
    m = sel.shape[0]
    nc_max = tol.max_candidates
    cand = np.empty(nc_max, dtype=np.int64)
    hits = np.empty((3, 4 * nc_max), dtype=np.int64)
    counts = np.zeros(3, dtype=np.int64)
    buf = np.empty(4 * nc_max, dtype=np.int64)
    trio = np.empty(3, dtype=np.int64)
    cat = np.empty(3, dtype=np.int64)
    try_rows = np.empty(n, dtype=np.int64)
    trial = np.empty(n, dtype=np.int64)
    stars = index.stars
    first_trio = np.full(3, -1, dtype=np.int64)
    first_cand = np.empty(nc_max, dtype=np.int64)
    st[SETUP] += cycles() - t_begin
    for dj in range(1, m - 1):
        for dk in range(1, m - dj):
            for i in range(0, m - dj - dk):
                if work[0] >= tol.max_trios:
                    st[TOTAL] += cycles() - t_begin
                    return np.full(n, -1, dtype=np.int64), np.zeros((3, 3)), np.full(4, -1, dtype=np.int64), work
                j = i + dj
                k = j + dk
                work[0] += 1
                trio[0] = sel[i]
                trio[1] = sel[j]
                trio[2] = sel[k]
                nc = _query(v_cam, trio[0], trio[1], trio[2], index, tol, guide_unit, cand, st, WIN, SEARCH, cnt)
                work[1] += 1
                if nc < 0:
                    cnt[3] += 1
                if work[0] == 1:
                    work[2] = max(nc, 0)
                    for a in range(3):
                        first_trio[a] = trio[a]
                    for a in range(min(max(nc, 0), nc_max)):
                        first_cand[a] = cand[a]
                if nc == 1 and work[5] == 0:
                    work[5] = work[1]
                if nc <= 0 or (tol.unique and nc != 1):
                    continue
                cnt[2] += nc
                n_ok = 0
                for c in range(nc):
                    t_c = cycles()
                    cnt[0] += 1
                    seen = trio_confirm(v_cam, trio, stars[cand[c]], guide_unit, tol.eps, tol.match_sides,
                                        tol.c_fov, tol.min_extra, tol.confirm_fraction, cam, try_rows, trial)
                    st[CONFIRM] += cycles() - t_c
                    if seen < 0:
                        continue
                    cnt[1] += 1
                    for a in range(3):
                        cat[a] = np.int64(stars[cand[c], a])
                    beta = -1
                    tries = 0
                    for b in range(m):
                        if b == i or b == j or b == k:
                            continue
                        if tries >= tol.fourth_tries:
                            break
                        tries += 1
                        cnt[4] += 1
                        counts[:] = 0
                        for q in range(3):
                            s0 = trio[0] if q < 2 else trio[1]
                            s1 = trio[1] if q == 0 else trio[2]
                            counts[q] = _query(v_cam, s0, s1, sel[b], index, tol, guide_unit, hits[q], st, WIN4,
                                               SEARCH4, cnt)
                            work[1] += 1
                            t_m = cycles()
                            fail = counts[q] <= 0 or cpk._third_stars(stars, hits[q], counts[q], cat, buf).shape[0] == 0
                            st[MATCH4] += cycles() - t_m
                            if fail:
                                break
                        t_m = cycles()
                        e = cpk._fourth_star(stars, hits, counts, cat, buf)
                        st[MATCH4] += cycles() - t_m
                        if e >= 0:
                            beta = sel[b]
                            break
                    if beta < 0:
                        continue
                    n_ok += 1
                    if n_ok > 1:
                        break
                    for a in range(n):
                        rows[a] = try_rows[a]
                    for a in range(3):
                        out4[a] = trio[a]
                    out4[3] = beta
                if n_ok == 1:
                    t_f = cycles()
                    stk.first_query_check(work, rows, first_trio, first_cand, stars)
                    att = wahba_rows(v_cam, rows, guide_unit)
                    t_e = cycles()
                    st[FINAL] += t_e - t_f
                    st[TOTAL] += t_e - t_begin
                    return rows, att, out4, work
                rows[:] = -1
                out4[:] = -1
    st[TOTAL] += cycles() - t_begin
    return rows, np.zeros((3, 3)), out4, work


KERNELS = {"spherical_triangle": (stk.spherical_kernel, spherical_copy),
           "composite_pyramid": (cpk.composite_kernel, composite_copy)}


def build_identification(db, rows, attitude, work):
    """The wrapper's lines after the kernel (``SphericalTriangle.identify`` / ``CompositePyramid.identify``)."""
    work[5] = work[5] or work[1]
    found = rows.max(initial=-1) >= 0
    return Identification(sta.hip_of(db, rows), attitude if found else None,
                          counters=dict(zip(stk.WORK_NAMES, work.tolist(), strict=True)))


def measure(name, alg, db, tetra, tetra_db, obs, R, mhz):
    """Per image: [identify, kernel call, Identification, dispatch, tetra, tolerances, camera_frame] in us (the
    minimum over R), the copy's stages (us, the repeat with the smallest copy total), the counters and counts."""
    kern, copy = KERNELS[name.split(":")[0]]
    per, stages, counters, counts = [], [], [], []
    for o in obs:
        cam = o.camera
        tol, frame = alg.tolerances(cam, db), camera_frame(cam)
        x, y, mag = o.x_px, o.y_px, o.mag
        x2, y2, m2 = x[:2], y[:2], mag[:2]      # views: read-only as the observation's (one signature)
        best = np.full(7, np.inf)
        best_st = None
        for _ in range(R):
            t = np.empty(7)
            t0 = time.perf_counter_ns()
            ident = alg.identify(db, o)
            t[0] = time.perf_counter_ns() - t0
            t0 = time.perf_counter_ns()
            rows, att, trio, work = kern(x, y, mag, db.index, db.guide_unit, tol, frame)
            t[1] = time.perf_counter_ns() - t0
            w = work.copy()
            t0 = time.perf_counter_ns()
            built = build_identification(db, rows, att, w)
            t[2] = time.perf_counter_ns() - t0
            t0 = time.perf_counter_ns()
            kern(x2, y2, m2, db.index, db.guide_unit, tol, frame)
            t[3] = time.perf_counter_ns() - t0
            t0 = time.perf_counter_ns()
            tetra.identify(tetra_db, o)
            t[4] = time.perf_counter_ns() - t0
            t0 = time.perf_counter_ns()
            alg.tolerances(cam, db)
            t[5] = time.perf_counter_ns() - t0
            t0 = time.perf_counter_ns()
            camera_frame(cam)
            t[6] = time.perf_counter_ns() - t0
            st = np.zeros(13, dtype=np.int64)
            cnt = np.zeros(len(COUNTS), dtype=np.int64)
            c_rows, c_att, c_trio, c_work = copy(x, y, mag, db.index, db.guide_unit, tol, frame, st, cnt)
            # the copy is the real code: the same answer, bit for bit, on every image and repeat
            assert np.array_equal(c_rows, rows) and np.array_equal(c_att, att), name
            assert np.array_equal(c_trio, trio) and np.array_equal(c_work, work), name
            assert np.array_equal(built.hip, ident.hip) and built.counters == ident.counters, name
            assert (built.attitude is None) == (ident.attitude is None), name
            best = np.minimum(best, t / 1e3)
            st[TOTAL] -= st[OVER]
            if best_st is None or st[TOTAL] < best_st[TOTAL]:
                best_st = st
        per.append(best)
        stages.append(best_st / mhz)
        counters.append([ident.counters[k] for k in stk.WORK_NAMES])
        counts.append(cnt)
    return np.array(per), np.array(stages), np.array(counters), np.array(counts)


def report(name, sky, per, stages, counters, counts, n_stars):
    med, mean = np.median(per, axis=0), per.mean(axis=0)
    k_mean = stages[:, TOTAL].mean()
    print(f"\n== {name}, {sky} sky, {per.shape[0]} images: median / mean us (share of the copy's mean total)")
    rows = [("identify", 0), ("  wrapper = identify - kernel - Identification", None), ("  Identification", 2),
            ("    tolerances (in the wrapper)", 5), ("    camera_frame (in the wrapper)", 6),
            ("  kernel call", 1), ("    dispatch (2-star call)", 3)]
    wrap = per[:, 0] - per[:, 1] - per[:, 2]
    for label, c in rows:
        v = wrap if c is None else per[:, c]
        print(f"  {label:58s} {np.median(v):9.1f} {v.mean():9.1f}")
    for s, label in enumerate(STAGES):
        v = stages[:, s]
        if not v.any():
            continue
        print(f"    {label:56s} {np.median(v):9.1f} {v.mean():9.1f}  {100 * v.mean() / k_mean:5.1f} %")
    rest = stages[:, TOTAL] - stages[:, :TOTAL].sum(axis=1)
    print(f"    {'rest (loops, counters)':56s} {np.median(rest):9.1f} {rest.mean():9.1f}  "
          f"{100 * rest.mean() / k_mean:5.1f} %")
    print(f"    {'copy total (cycles)':56s} {np.median(stages[:, TOTAL]):9.1f} {k_mean:9.1f}")
    for label, s in (("search split: k-vector + bisections (all queries)", S_BISECT),
                     ("search split: whole counting copy (all queries)", S_FULL)):
        v = stages[:, s]
        print(f"    {label:56s} {np.median(v):9.1f} {v.mean():9.1f}")
    answered = stages[:, FINAL] > 0
    first = counters[:, 0] == 1
    print(f"  answered {answered.sum()} of {answered.size}; first trio answered {(answered & first).sum()}; "
          f"identify median answered {np.median(per[answered, 0]):.1f}, not answered "
          f"{np.median(per[~answered, 0]) if (~answered).any() else float('nan'):.1f} us")
    print(f"  {'tetra identify':58s} {med[4]:9.1f} {mean[4]:9.1f}")
    p95 = np.percentile(per[:, 0], 95)
    print(f"  identify p95 {p95:.1f} us = {p95 / med[0]:.2f}x median; max {per[:, 0].max():.1f}")
    names = list(stk.WORK_NAMES) + list(COUNTS)
    allc = np.concatenate([counters, counts], axis=1)
    print("  counters median / mean:", ", ".join(f"{k} {np.median(allc[:, a]):g} / {allc[:, a].mean():.1f}"
                                                 for a, k in enumerate(names)))
    print(f"  stars per image median {np.median(n_stars):g}")
    tail = per[:, 0] >= p95
    print(f"  slowest 5 % ({tail.sum()} images, identify >= {p95:.1f} us): mean identify {per[tail, 0].mean():.1f}, "
          "stages " + ", ".join(f"{STAGES[s].split(' ')[0]}{s} {stages[tail, s].mean():.1f}"
                                for s in range(TOTAL) if stages[:, s].any()))
    print("    counters mean:", ", ".join(f"{k} {allc[tail, a].mean():.1f}" for a, k in enumerate(names)))


def make(name):
    """The plugin ``NAME`` or a published variant ``NAME:paper`` / ``NAME:galvizo2018``."""
    base, _, reading = name.partition(":")
    cls = get_algorithm(base)
    if not reading:
        return cls()
    return cls(**(cls.published if reading == "paper" else cls.published_readings[reading]))


def main(n, R, names):
    cat, cam = load_hipparcos(), Camera()
    mhz = cycles_per_us()
    print(f"cycle counter: {mhz:.1f} cycles/us; N={n} R={R}")
    plugins = {name: make(name) for name in names}
    dbs = {name: alg.build(cat, cam) for name, alg in plugins.items()}
    tetra = get_algorithm("tetra")()
    tetra_db = tetra.build(cat, cam)
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        tr = sim.generate(n)
        obs = [tr.observation(i, truth=False) for i in range(n)]
        n_stars = np.array([o.x_px.shape[0] for o in obs])
        tetra.identify(tetra_db, obs[0])
        for name, alg in plugins.items():
            alg.identify(dbs[name], obs[0])       # JIT warm-up, not timed
            t0 = time.time()
            out = measure(name, alg, dbs[name], tetra, tetra_db, obs, R, mhz)
            report(name, sky, *out, n_stars)
            print(f"  ({time.time() - t0:.0f} s wall)")


if __name__ == "__main__":
    main(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3:] or list(KERNELS))
