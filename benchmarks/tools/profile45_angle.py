"""Where angle's time per image goes, whole identify included (issue #25, stop 45).

    python benchmarks/tools/profile45_angle.py N R

Table 6's images (``Simulator(catalog, Camera(), SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0,
min_stars=6, **SKIES[sky]), seed=0)``), both skies, N images each, every image run R times in turn and
the minimum of the R kept per quantity (the stages: the run with the smallest in-kernel total). Per sky it
prints the median and the mean over images, in µs, of:

* ``tetra identify`` and ``angle identify``: ``time.perf_counter_ns`` around ``algorithm.identify(db, obs)``
  (as ``benchmarks/test_ratios.py`` times it);
* ``kernel call``: ``angle_kernel`` called from Python with the arguments the wrapper passes (tolerances and
  camera frame prepared outside the timed region): numba's dispatch (unboxing the 17-field ``AngleTol``
  and the camera ``Frame``, boxing the three arrays returned) and the kernel;
* ``Identification``: what the wrapper does after the kernel returns, timed alone on the kernel's output:
  ``hip_of`` (guide rows to catalog ids), the counters' dict, the attitude (``backproject_px`` and
  ``wahba_rows``, only when a star is identified) and ``Identification(...)``; its pieces apart as well;
* ``wrapper``: identify - kernel call - Identification (``tolerances()``, ``camera_frame()`` and the
  attribute look-ups; the first two also timed alone);
* inside the kernel, read with the CPU cycle counter (``llvm.readcyclecounter``, converted to µs against
  ``perf_counter``) in a copy of ``angle_kernel``'s body (``_search`` inlined as numba inlines it) that
  calls the plugin's own inner kernels: the set-up (back-projection, ``select_stars``), the pair windows
  (k-vector searches, ``pair_windows``), the search's allocations, window ab's partner lists
  (``_adjacency``), the triangle searches (``_triangles_by_ik`` and ``_keep``), the cached triangles of the
  swapped triad (``_swap_cached``), the direct-match tests (``_support``), the confirmations (a copy of
  ``_confirm_pattern``'s body calling the core's ``wahba_rows`` and ``reproject_assign``, which are timed apart),
  the counters (``_pairs_to_r`` and the first query step), and the rest (loop
  bookkeeping and the cycle reads themselves); and the copy's total. Kernel call - copy total is the
  dispatch.

On every image and every repeat the copy's ``(rows, pair, work)`` must equal the plugin kernel's exactly
(asserted), so the stages are those of the real code; the copy must follow ``angle_kernel`` when it
changes. Also printed: the medians of the work counters (``Identification.counters``) and of the copy's own
counts, and the slowest 5 % of images by identify time (their mean stages and counters).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from cyclecounter import cycles, cycles_per_us  # benchmarks/tools
from numba import njit
from starid_algorithms.angle.kernels import (
    WORK_NAMES,
    _keep,
    _pairs_to_r,
    _support,
    _swap_cached,
    _triangles_by_ik,
    angle_kernel,
)
from starid_algorithms.pyramid.algorithm import hip_of
from starid_algorithms.pyramid.kernels import _adjacency, pair_windows, select_stars

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, camera_frame, reproject_assign, wahba_rows
from starid.plugin import Identification
from starid.registry import get_algorithm

TABLE6_SIM = {"sigma_px": 1.0, "sigma_mag": 0.5, "mag_limit": 6.0, "min_stars": 6}
#: cycle slots of the copy (first N_STAGES + 1), then counts
SLOTS = ("total", "set-up", "pair windows", "search allocations", "partner lists", "triangle searches",
         "cached triangles", "direct-match tests", "confirmations", "counters",
         "n_lists", "n_searches", "n_cached", "  Wahba solves", "  reprojections")
N_STAGES = 9
#: cycle slots after the counts: the confirmations' parts
SUB = (13, 14)


@njit
def noop_kernel(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, cam):
    """``angle_kernel``'s arguments in, arrays of its outputs' shapes out, nothing done: numba's dispatch."""
    n = x_px.shape[0]
    return np.full(n, -1, dtype=np.int64), np.full(2, -1, dtype=np.int64), np.zeros(len(WORK_NAMES), dtype=np.int64)


@njit
def _noop9(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit):
    return 0


@njit
def _noop10(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, extra):
    return 0


@njit
def _noop11(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, cam):
    return 0


@njit
def _noop9_out(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit):
    n = x_px.shape[0]
    return np.full(n, -1, dtype=np.int64), np.full(2, -1, dtype=np.int64), np.zeros(len(WORK_NAMES), dtype=np.int64)


def dispatch_split(args, repeats=2000):
    """Minimum over ``repeats`` calls (µs) of no-op kernels taking parts of ``angle_kernel``'s arguments."""
    arrays, tol, frame = args[:9], args[9], args[10]
    tol_arr = np.array([float(v) for v in tol])
    frame_arr = np.array([float(v) for v in frame])
    cases = {"the 9 array / k-vector arguments": lambda: _noop9(*arrays),
             "  + AngleTol (17 fields)": lambda: _noop10(*arrays, tol),
             "  + camera Frame (5 fields)": lambda: _noop10(*arrays, frame),
             "  + both (the kernel's arguments)": lambda: _noop11(*arrays, tol, frame),
             "  + both as float64 arrays instead": lambda: _noop11(*arrays, tol_arr, frame_arr),
             "the 9, returning the kernel's three arrays": lambda: _noop9_out(*arrays),
             "the kernel's arguments and returns (noop_kernel)": lambda: noop_kernel(*args)}
    out = {}
    for label, f in cases.items():
        f()
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter_ns()
            f()
            best = min(best, time.perf_counter_ns() - t0)
        out[label] = best / 1e3
    return out


@njit
def confirm_profiled(v_cam, pat_star, pat_row, guide_unit, c_fov, eps, widen, cam, min_extra, confirm_fraction, rows,
                     st):
    """``_confirm_pattern``'s body, the Wahba solves and the reprojection passes timed into ``st[13]``, ``st[14]``."""
    n = v_cam.shape[0]
    k = pat_star.shape[0]
    strict = min_extra > 0 or confirm_fraction > 0.0
    rows[:] = -1
    for a in range(k):
        rows[pat_star[a]] = pat_row[a]
    t0 = cycles()
    attitude = wahba_rows(v_cam, rows, guide_unit)
    st[13] += cycles() - t0
    for step in range(4 if widen > 1.0 else 3):
        first = widen > 1.0 and step == 0
        radius = widen * eps if first else eps
        t0 = cycles()
        n_seen, n_predicted = reproject_assign(attitude, v_cam, guide_unit, c_fov + radius, radius, rows,
                                               cam.f_px, cam.cx_px, cam.cy_px, cam.width_px, cam.height_px)
        st[14] += cycles() - t0
        for a in range(k):
            if rows[pat_star[a]] != pat_row[a]:
                if strict and not first:
                    return False
                for s in range(n):
                    if rows[s] == pat_row[a]:
                        rows[s] = -1
                rows[pat_star[a]] = pat_row[a]
        if strict and not first and (n_seen - k < min_extra or n_seen < confirm_fraction * n_predicted):
            return False
        if step < (3 if widen > 1.0 else 2):
            t0 = cycles()
            attitude = wahba_rows(v_cam, rows, guide_unit)
            st[13] += cycles() - t0
    return True


@njit
def profiled(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, cam, st):
    """``angle_kernel`` with ``_search`` inlined, the cycle counter read between stages into ``st``."""
    t_all = cycles()
    n = x_px.shape[0]
    work = np.zeros(len(WORK_NAMES), dtype=np.int64)
    if n < 2:
        st[0] += cycles() - t_all
        return np.full(n, -1, dtype=np.int64), np.full(2, -1, dtype=np.int64), work
    v_cam = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(x_px, y_px, mag, v_cam, tol.d_min, tol.max_stars)
    m = sel.shape[0]
    t0 = cycles()
    st[1] += t0 - t_all
    start, stop = pair_windows(v_cam, sel, kv, tol)
    t1 = cycles()
    st[2] += t1 - t0
    work[1] = m * (m - 1) // 2
    work[8] = _pairs_to_r(start, stop)
    t0 = cycles()
    st[9] += t0 - t1
    # ---- _search (inlined into angle_kernel by numba), same statements
    rows = np.full(n, -1, dtype=np.int64)
    pair = np.full(2, -1, dtype=np.int64)
    pat_star = np.empty(2, dtype=np.int64)
    pat_row = np.empty(2, dtype=np.int64)
    n_guide = guide_unit.shape[0]
    cap = 2 * max(tol.max_window, 1)
    scratch = (np.full(n_guide, -1, dtype=np.int32), np.zeros(n_guide, dtype=np.int32),
               np.empty(cap, dtype=np.int32), np.empty(cap, dtype=np.int32))
    tri = np.empty((max(tol.max_triangles, 1), 5), dtype=np.int64)
    cap_tri = tri.shape[0]
    n_slot = 0 if (tol.compare or tol.min_support < 1) else min(m, tol.n_check + 2)
    slot_a = np.full((n_slot, n_slot), -1, dtype=np.int64)
    slot_first = np.zeros((n_slot, n_slot), dtype=np.int64)
    slot_count = np.zeros((n_slot, n_slot), dtype=np.int64)
    store = np.empty((64 if n_slot > 0 else 0, 5), dtype=np.int64)
    n_store = np.int64(0)
    tick = 0
    t1 = cycles()
    st[3] += t1 - t0
    done = False
    for a in range(m - 1):
        if done:
            break
        n_store = np.int64(0)
        for b in range(a + 1, m):
            if done:
                break
            if work[0] >= tol.max_pairs:
                rows[:] = -1
                done = True
                break
            work[0] += 1
            lo, hi = start[a, b], stop[a, b]
            if hi == lo or (tol.unique_window and hi - lo != 1):
                continue
            pat_star[0] = sel[a]
            pat_star[1] = sel[b]
            if tol.compare:                         # hoku's test (angle:paper); not the default
                for p in range(lo, hi):
                    work[2] += 1
                    best = -1
                    s_best = -1
                    for o in range(2):
                        work[3] += 1
                        t0 = cycles()
                        s = _support(v_cam, sel, a, b, np.int64(pairs[p, o]), np.int64(pairs[p, 1 - o]), nbr,
                                     nbr_chord, nbr_start, guide_unit, tol.eps_match, tol.n_check, np.int64(-1),
                                     tol.chirality)
                        st[7] += cycles() - t0
                        if s >= s_best:
                            s_best = s
                            best = o
                    if s_best < tol.min_support:
                        continue
                    pat_row[0] = pairs[p, best]
                    pat_row[1] = pairs[p, 1 - best]
                    work[4] += 1
                    t0 = cycles()
                    good = confirm_profiled(v_cam, pat_star, pat_row, guide_unit, tol.c_fov, tol.eps_match,
                                            tol.widen, cam, tol.min_extra, tol.confirm_fraction, rows, st)
                    st[8] += cycles() - t0
                    if good:
                        pair[0] = pat_star[0]
                        pair[1] = pat_star[1]
                        done = True
                        break
                continue
            tried = 0
            built = False
            for k in range(m):
                if done:
                    break
                if k == a or k == b:
                    continue
                if tried == tol.n_check:
                    break
                tried += 1
                if stop[a, k] == start[a, k] or tol.min_support < 1:
                    continue
                if k < b and b < n_slot and slot_a[k, b] == a:
                    n_tri = slot_count[k, b]
                    if n_tri <= cap_tri:
                        t0 = cycles()
                        _swap_cached(store, slot_first[k, b], n_tri, tri)
                        st[6] += cycles() - t0
                        st[12] += 1
                else:
                    if not built:
                        tick += 1
                        t0 = cycles()
                        _adjacency(pairs, lo, hi, scratch[0], scratch[1], tick, scratch[2], scratch[3])
                        st[4] += cycles() - t0
                        st[10] += 1
                        built = True
                    t0 = cycles()
                    n_tri = _triangles_by_ik(v_cam, sel[a], sel[b], sel[k], (lo, hi), (start[a, k], stop[a, k]),
                                             pairs, guide_unit, tol.eps_match, scratch, tick, tri)
                    if b < k < n_slot:
                        slot_a[b, k] = a
                        slot_first[b, k] = n_store
                        slot_count[b, k] = n_tri
                        store = _keep(store, n_store, tri, n_tri if n_tri <= cap_tri else 0)
                        n_store += n_tri if n_tri <= cap_tri else 0
                    st[5] += cycles() - t0
                    st[11] += 1
                if n_tri > cap_tri:
                    continue
                work[2] += n_tri
                for t in range(n_tri):
                    big_i = tri[t, 0]
                    big_j = tri[t, 1]
                    work[3] += 1
                    t0 = cycles()
                    s = _support(v_cam, sel, a, b, big_i, big_j, nbr, nbr_chord, nbr_start, guide_unit,
                                 tol.eps_match, tol.n_check, tol.min_support, tol.chirality)
                    st[7] += cycles() - t0
                    if s < tol.min_support:
                        continue
                    pat_row[0] = big_i
                    pat_row[1] = big_j
                    work[4] += 1
                    t0 = cycles()
                    good = confirm_profiled(v_cam, pat_star, pat_row, guide_unit, tol.c_fov, tol.eps_match,
                                            tol.widen, cam, tol.min_extra, tol.confirm_fraction, rows, st)
                    st[8] += cycles() - t0
                    if good:
                        pair[0] = pat_star[0]
                        pair[1] = pat_star[1]
                        done = True
                        break
    if not done:
        rows[:] = -1
    # ---- back in angle_kernel: the first query step's counters
    t0 = cycles()
    if m >= 2:
        lo, hi = start[0, 1], stop[0, 1]
        work[5] = hi - lo
        r0 = rows[sel[0]]
        r1 = rows[sel[1]]
        if r0 >= 0 and r1 >= 0:
            work[6] = 1
            for p in range(lo, hi):
                if (pairs[p, 0] == r0 and pairs[p, 1] == r1) or (pairs[p, 0] == r1 and pairs[p, 1] == r0):
                    work[7] = 1
                    break
    t1 = cycles()
    st[9] += t1 - t0
    st[0] += t1 - t_all
    return rows, pair, work



def ident_parts(db, o, rows, work, timed):
    """The wrapper's tail after the kernel (``Angle.identify``'s statements), each piece timed into ``timed``."""
    t0 = time.perf_counter_ns()
    hip = hip_of(db, rows)
    t1 = time.perf_counter_ns()
    counters = dict(zip(WORK_NAMES, work.tolist(), strict=True))
    t2 = time.perf_counter_ns()
    attitude = None
    if (rows >= 0).any():
        cam = o.camera
        v = backproject_px(o.x_px, o.y_px, cam.f_px, cam.cx_px, cam.cy_px)
        attitude = wahba_rows(v, rows, db.guide_unit)
    t3 = time.perf_counter_ns()
    out = Identification(hip, attitude, counters=counters)
    t4 = time.perf_counter_ns()
    timed[:] = (t1 - t0, t2 - t1, t3 - t2, t4 - t3)
    return out


def ident_whole(db, o, rows, work):
    """The same statements untimed inside (the whole tail timed from outside)."""
    hip = hip_of(db, rows)
    counters = dict(zip(WORK_NAMES, work.tolist(), strict=True))
    if not (rows >= 0).any():
        return Identification(hip, None, counters=counters)
    cam = o.camera
    v = backproject_px(o.x_px, o.y_px, cam.f_px, cam.cx_px, cam.cy_px)
    return Identification(hip, wahba_rows(v, rows, db.guide_unit), counters=counters)


#: Python-side columns (ns, then µs)
PY = ("tetra identify", "angle identify", "kernel call", "Identification", "  hip_of", "  counters dict",
      "  attitude (Wahba)", "  Identification()", "tolerances()", "camera_frame()", "angle identify, warm",
      "kernel call, warm", "no-op kernel call (dispatch)", "copy call, warm")


def run_sky(cat, cam, sky, n, rounds, mhz, alg, db, tetra, tdb):
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    n = len(obs)
    py = np.full((n, len(PY)), np.inf)
    stages = np.full((n, len(SLOTS)), np.inf)
    counters = np.zeros((n, len(WORK_NAMES)))
    named = np.zeros(n)
    timed = [0, 0, 0, 0]
    for i, o in enumerate(obs):
        tol = alg.tolerances(o.camera, db)
        frame = camera_frame(o.camera)
        args = (o.x_px, o.y_px, o.mag, db.kv, db.pairs, db.nbr, db.nbr_chord, db.nbr_start, db.guide_unit, tol, frame)
        for _ in range(rounds):
            row = np.empty(len(PY))
            t0 = time.perf_counter_ns()
            tetra.identify(tdb, o)
            row[0] = time.perf_counter_ns() - t0
            t0 = time.perf_counter_ns()
            ident = alg.identify(db, o)                     # right after tetra, as test_ratios times it
            row[1] = time.perf_counter_ns() - t0
            tetra.identify(tdb, o)
            t0 = time.perf_counter_ns()
            rows, pair, work = angle_kernel(*args)          # right after tetra too
            row[2] = time.perf_counter_ns() - t0
            t0 = time.perf_counter_ns()
            alg.identify(db, o)                             # right after itself (warm caches)
            row[10] = time.perf_counter_ns() - t0
            t0 = time.perf_counter_ns()
            angle_kernel(*args)
            row[11] = time.perf_counter_ns() - t0
            # the copy's own code run once first, as the kernel's ran inside identify just before its warm call
            # (without this the copy ran ~6 µs slower than the kernel it copies; with it, within ~1-2 µs)
            profiled(*args, np.zeros(len(SLOTS), dtype=np.int64))
            st = np.zeros(len(SLOTS), dtype=np.int64)
            t0 = time.perf_counter_ns()
            c_rows, c_pair, c_work = profiled(*args, st)
            row[13] = time.perf_counter_ns() - t0
            t0 = time.perf_counter_ns()
            ident_whole(db, o, rows, work)
            row[3] = time.perf_counter_ns() - t0
            t0 = time.perf_counter_ns()
            noop_kernel(*args)
            row[12] = time.perf_counter_ns() - t0
            ident_parts(db, o, rows, work, timed)
            row[4:8] = timed
            t0 = time.perf_counter_ns()
            alg.tolerances(o.camera, db)
            row[8] = time.perf_counter_ns() - t0
            t0 = time.perf_counter_ns()
            camera_frame(o.camera)
            row[9] = time.perf_counter_ns() - t0
            py[i] = np.minimum(py[i], row)
            # the copy is the real code: same rows, pair and counters as the plugin's kernel on this image
            assert (c_rows == rows).all() and (c_pair == pair).all() and (c_work == work).all(), (sky, i)
            assert (ident.hip == hip_of(db, rows)).all(), (sky, i)
            if st[0] < stages[i, 0]:
                stages[i] = st
        counters[i] = work
        named[i] = (rows >= 0).sum()
    py_us = py / 1e3
    st_us = stages.copy()
    st_us[:, :N_STAGES + 1] /= mhz
    st_us[:, SUB] /= mhz
    return obs, py_us, st_us, counters, named


def report(sky, n, rounds, py_us, st_us, counters, named):
    ident = py_us[:, 1]
    total = st_us[:, 0]
    rest = total - st_us[:, 1:N_STAGES + 1].sum(axis=1)
    print(f"\n== {sky} sky, {n} images, min of {rounds} per image; µs median (mean), share of the kernel's "
          "copy total (medians)")
    med_tot = np.median(total)

    def line(label, v, share=True):
        s = f"{100 * np.median(v) / med_tot:5.1f} %" if share else ""
        print(f"  {label:52s} {np.median(v):9.2f} ({v.mean():9.2f})  {s}")

    line(PY[0], py_us[:, 0], False)
    for label, c_id, c_k in (("after tetra", 1, 2), ("warm", 10, 11)):
        line(f"angle identify, {label}", py_us[:, c_id], False)
        line(f"  wrapper, {label} (identify - kernel call - Identification)",
             py_us[:, c_id] - py_us[:, c_k] - py_us[:, 3], False)
        line(f"  kernel call, {label}", py_us[:, c_k], False)
        line(f"    kernel call, {label} - no-op call (the kernel's work)", py_us[:, c_k] - py_us[:, 12], False)
    line("  no-op kernel call (dispatch: arguments, returned arrays)", py_us[:, 12], False)
    line("  copy call, warm (perf_counter)", py_us[:, 13], False)
    line("  copy call - copy total (the copy's dispatch)", py_us[:, 13] - total, False)
    for c in (8, 9):
        line("  wrapper's " + PY[c], py_us[:, c], False)
    line("  copy total (cycles, warm)", total)
    for c in range(1, N_STAGES + 1):
        line("      " + SLOTS[c], st_us[:, c])
        if c == 8:
            for c2 in SUB:
                line("      " + SLOTS[c2], st_us[:, c2])
    line("      rest (loops, cycle reads)", rest)
    for c in range(3, 8):
        line(("  " if c > 3 else "") + PY[c], py_us[:, c], False)
    print("  ratio angle / tetra identify (medians, after tetra): "
          f"{np.median(ident) / np.median(py_us[:, 0]):.2f}")
    print("  counters, median (mean): " + ", ".join(
        f"{nm} {np.median(counters[:, c]):.0f} ({counters[:, c].mean():.1f})" for c, nm in enumerate(WORK_NAMES)))
    print("  copy's counts, median (mean): " + ", ".join(
        f"{SLOTS[c]} {np.median(st_us[:, c]):.0f} ({st_us[:, c].mean():.1f})" for c in range(N_STAGES + 1,
                                                                                             SUB[0])))
    print(f"  images with no star named: {(named == 0).sum()}; images whose to_r counts every window (no window of "
          f"one catalog pair before the last): {(counters[:, 8] == counters[:, 1]).sum()}")
    k = max(1, int(round(0.05 * len(ident))))
    tail = np.argsort(-ident)[:k]
    print(f"  slowest 5 % by identify ({k} images: {sorted(tail.tolist())}), mean µs: identify "
          f"{ident[tail].mean():.1f}, copy total {total[tail].mean():.1f}; " + ", ".join(
              f"{SLOTS[c]} {st_us[tail, c].mean():.1f}" for c in range(1, N_STAGES + 1)))
    print("    their share of all identify time: "
          f"{ident[tail].sum() / ident.sum():.2f}; no star named: {(named[tail] == 0).sum()}; counters mean: "
          + ", ".join(f"{nm} {counters[tail, c].mean():.1f}" for c, nm in enumerate(WORK_NAMES[:5])) + "; "
          + ", ".join(f"{SLOTS[c].strip()} {st_us[tail, c].mean():.1f}" for c in range(N_STAGES + 1, len(SLOTS))))
    rest_ = np.setdiff1d(np.arange(len(ident)), tail)
    print("    the other 95 %, mean µs: " + ", ".join(
        f"{SLOTS[c]} {st_us[rest_, c].mean():.1f}" for c in range(0, N_STAGES + 1)))
    p95 = np.percentile(ident, 95)
    print(f"  identify p95 {p95:.1f} µs = {p95 / np.median(ident):.1f} x median")


def main(n: int, rounds: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    mhz = cycles_per_us()
    print(f"cycle counter: {mhz:.1f} cycles per µs")
    alg = get_algorithm("angle")()
    db = alg.build(cat, cam)
    tetra = get_algorithm("tetra")()
    tdb = tetra.build(cat, cam)
    for sky in ("paper", "real"):
        sim_obs = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0).generate(1)
        o = sim_obs.observation(0, truth=False)
        alg.identify(db, o)                                 # compile apart (not timed)
        noop_kernel(o.x_px, o.y_px, o.mag, db.kv, db.pairs, db.nbr, db.nbr_chord, db.nbr_start, db.guide_unit,
                    alg.tolerances(o.camera, db), camera_frame(o.camera))
        tetra.identify(tdb, o)
        st = np.zeros(len(SLOTS), dtype=np.int64)
        tol = alg.tolerances(o.camera, db)
        profiled(o.x_px, o.y_px, o.mag, db.kv, db.pairs, db.nbr, db.nbr_chord, db.nbr_start, db.guide_unit, tol,
                 camera_frame(o.camera), st)
        obs, py_us, st_us, counters, named = run_sky(cat, cam, sky, n, rounds, mhz, alg, db, tetra, tdb)
        report(sky, len(obs), rounds, py_us, st_us, counters, named)
        if sky == "paper":
            tol = alg.tolerances(o.camera, db)
            args = (o.x_px, o.y_px, o.mag, db.kv, db.pairs, db.nbr, db.nbr_chord, db.nbr_start, db.guide_unit, tol,
                    camera_frame(o.camera))
            print("  numba dispatch of no-op kernels, minimum of 2,000 calls (µs):")
            for label, us in dispatch_split(args).items():
                print(f"    {label:52s} {us:6.2f}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]))
