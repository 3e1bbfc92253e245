"""Where a tetra identify's time goes, per image (issue #25's profile table, stop 45).

    python benchmarks/tools/profile45_tetra.py N R [paper|real ...]

Table 6's images (1 px / 0.5 Mv, V <= 6, more than five stars, seed 0), N per sky; every image is timed R
times per measurement and the minimum kept (the least disturbed run on this shared machine). Per sky,
the median and mean over the images, in µs, of:

* ``identify``: ``algorithm.identify(db, observation)`` between two ``perf_counter_ns`` reads, as
  ``benchmarks/test_ratios.py`` times it;
* ``kernel``: the bare ``identify_kernel`` call with the arguments the wrapper passes (the bundles of
  ``_bundles`` and the 12-slot ``record`` prepared outside the timed region);
* ``Identification``: ``Identification(hip, counters=counters)`` alone, as the wrapper builds it;
* numba's dispatch: an empty kernel called with the kernel's six arguments, the same returning two new
  (n,) arrays, and an empty kernel taking only the four array arguments (no named tuples);
* ``wrapper`` = identify - kernel - Identification, split into ``_bundles``' cache lookup timed alone,
  the rest of ``_run`` (``_run`` timed alone, minus kernel and lookup: the method call, ``record``'s
  allocation) and the rest of ``identify`` (identify - ``_run`` - Identification: the counters dict);
* inside the kernel, a copy of ``identify_kernel``'s body (same callees, same arguments) reading the CPU
  cycle counter (``llvm.readcyclecounter``, calibrated against ``perf_counter``) between its stages:
  set-up (record reset, back-projection, brightness order, scratch arrays), pattern edges (each
  4-subset's six sorted chords and the span check), key window (ratio bins of the tolerance window,
  canonical order, image edge matrix), hash search (every key of the window looked up in the table,
  slots kept on the stored largest edge), candidate check (``_match_order``: the six edges in canonical
  order), verification (``_verify``: Wahba on the four pairs, reprojection, mismatch probability),
  report (refined attitude, reassignment, double-star and magnitude checks, catalog ids). The copy's
  call minus its stages is numba's dispatch (argument unboxing, result boxing) and the cycle reads.
  The stages are those of the copy's fastest call of the R.

On every image the copy's ``(hip, rows, record)`` must equal the plugin kernel's (asserted), so the stage
table is of the real code. Also printed: the work counters' medians (``Identification.counters``), the
same table for the slowest 5 % of images by identify time, and what those images do. The copy must
follow ``algorithms/tetra/kernels.py:identify_kernel`` when it changes.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np
from cyclecounter import cycles, cycles_per_us  # benchmarks/tools
from numba import njit
from starid_algorithms.tetra.algorithm import _bundles
from starid_algorithms.tetra.kernels import (
    EDGE_MASK,
    _match_order,
    binom_sf,
    canonical_order,
    identify_kernel,
    ratio_bin,
    sorted_edges,
    table_lookup,
)

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, chord_rows, order_by, reproject_assign, wahba_rows
from starid.plugin import Identification
from starid.registry import get_algorithm

STAGES = ("set-up", "pattern edges", "key window", "hash search", "candidate check", "verification: Wahba",
          "verification: reprojection", "verification: test", "report: Wahba (refine)", "report: reprojection",
          "report: checks, ids")


@njit
def verify_staged(unit, rows, guide_unit, tol, n_stars, out_row, st):
    """``_verify``'s body (``starid_algorithms.tetra.kernels``) with stages 5 (Wahba), 6 (reprojection) and
    7 (the pattern's own stars, extra count and mismatch probability)."""
    t = cycles()
    A = wahba_rows(unit, rows, guide_unit)
    t1 = cycles()
    st[5] += t1 - t
    t = t1
    n_seen, n_predicted = reproject_assign(A, unit, guide_unit, tol.c_fov + tol.eps, tol.eps, out_row,
                                           tol.f_px, tol.cx_px, tol.cy_px, float(tol.width_px),
                                           float(tol.height_px))
    t1 = cycles()
    st[6] += t1 - t
    t = t1
    ok = True
    for i in range(rows.shape[0]):
        if rows[i] >= 0 and out_row[i] != rows[i]:
            ok = False
            break
    extra = n_seen - 4
    if ok and extra < tol.min_extra:
        ok = False
    if ok:
        r_px = tol.eps * tol.f_px
        q = min(1.0, n_stars * math.pi * r_px * r_px / (tol.width_px * tol.height_px))
        ok = binom_sf(extra, max(n_predicted - 4, extra), q) <= tol.max_mismatch
    st[7] += cycles() - t
    return ok, n_seen


@njit
def staged_kernel(x_px, y_px, mag, table, tol, record, st):
    """``identify_kernel``'s body with ``st[k] +=`` the cycles of stage k (see ``STAGES``)."""
    t = cycles()
    n = x_px.shape[0]
    result = np.full(n, -1, dtype=np.int64)
    hip = np.full(n, -1, dtype=np.int64)
    for k in range(record.shape[0]):
        record[k] = -1 if k < 9 else 0
    counting = record.shape[0] >= 12
    if n < 4:
        t1 = cycles()
        st[0] += t1 - t
        return hip, result
    unit = backproject_px(x_px, y_px, tol.f_px, tol.cx_px, tol.cy_px)
    order = order_by(mag, x_px, y_px)
    m = min(n, tol.n_image)
    edge_tol = tol.beta * math.sqrt(2.0) * tol.sigma
    bins = table.bins
    slots = np.empty(4096, dtype=np.int64)
    rows4 = np.empty(4, dtype=np.int64)
    img4 = np.empty(4, dtype=np.int64)
    edges = np.empty(6)
    img_edge = np.empty((4, 4))
    lo = np.empty(5, dtype=np.int64)
    hi = np.empty(5, dtype=np.int64)
    digit = np.empty(5, dtype=np.int64)
    perm = np.empty(4, dtype=np.int64)
    cat4 = np.empty(4, dtype=np.int64)
    img_dist = np.empty(4)
    cat_edge = np.empty((4, 4))
    edge_unit = table.edge_scale / 65535.0
    edge_window = edge_tol + edge_unit
    trial_rows = np.full(n, -1, dtype=np.int64)
    out_row = np.empty(n, dtype=np.int64)
    tried = 0
    t1 = cycles()
    st[0] += t1 - t
    t = t1
    for li in range(3, m):
        for kk in range(2, li):
            for j in range(1, kk):
                for i in range(0, j):
                    rows4[0] = order[i]
                    rows4[1] = order[j]
                    rows4[2] = order[kk]
                    rows4[3] = order[li]
                    emax = sorted_edges(unit, rows4, edges)
                    if emax < tol.min_edge - edge_tol or emax > tol.max_edge + edge_tol or emax <= 0.0:
                        t1 = cycles()
                        st[1] += t1 - t
                        t = t1
                        continue
                    tried += 1
                    t1 = cycles()
                    st[1] += t1 - t
                    t = t1
                    n_keys = 1
                    for p in range(5):
                        r = edges[4 - p] / emax
                        tw = tol.beta * math.sqrt(2.0) * tol.sigma * math.sqrt(1.0 + r * r) / emax
                        lo[p] = ratio_bin(r - tw, bins)
                        hi[p] = ratio_bin(r + tw, bins)
                        n_keys *= hi[p] - lo[p] + 1
                    if n_keys > tol.max_keys:
                        t1 = cycles()
                        st[2] += t1 - t
                        t = t1
                        continue
                    canonical_order(unit, rows4, img4, img_dist)
                    for a in range(4):
                        for b in range(4):
                            img_edge[a, b] = chord_rows(unit, img4[a], unit, img4[b])
                    for p in range(5):
                        digit[p] = lo[p]
                    t1 = cycles()
                    st[2] += t1 - t
                    t = t1
                    n_slot = np.int64(0)
                    while True:
                        key = np.int64(0)
                        for p in range(5):
                            key = key * bins + digit[p]
                        first = n_slot
                        n_slot = table_lookup(table.word, key, slots, n_slot)
                        if counting:
                            record[9] += 1
                        kept = first
                        for s in range(first, n_slot):
                            if abs(float(table.word[slots[s]] & EDGE_MASK) * edge_unit - emax) <= edge_window:
                                slots[kept] = slots[s]
                                kept += 1
                        n_slot = kept
                        p = 4
                        while p >= 0 and digit[p] == hi[p]:
                            digit[p] = lo[p]
                            p -= 1
                        if p < 0:
                            break
                        digit[p] += 1
                    t1 = cycles()
                    st[3] += t1 - t
                    t = t1
                    for s in range(n_slot):
                        for a in range(4):
                            cat4[a] = table.pattern[slots[s], a]
                        if counting:
                            record[10] += 1
                        matched = _match_order(img_edge, img_dist, table.unit, cat4, edge_tol, perm, cat_edge)
                        t1 = cycles()
                        st[4] += t1 - t
                        t = t1
                        if not matched:
                            continue
                        if counting:
                            record[11] += 1
                        for a in range(n):
                            trial_rows[a] = -1
                        for a in range(4):
                            trial_rows[img4[perm[a]]] = cat4[a]
                        t1 = cycles()
                        st[7] += t1 - t
                        t = t1
                        ok, n_seen = verify_staged(unit, trial_rows, table.unit, tol, n, out_row, st)
                        t = cycles()
                        if not ok:
                            continue
                        if tol.report_eps > 0:
                            A = wahba_rows(unit, out_row, table.unit)
                            t1 = cycles()
                            st[8] += t1 - t
                            t = t1
                            reproject_assign(A, unit, table.unit, tol.c_fov + tol.report_eps, tol.report_eps, result,
                                             tol.f_px, tol.cx_px, tol.cy_px, float(tol.width_px),
                                             float(tol.height_px))
                            t1 = cycles()
                            st[9] += t1 - t
                            t = t1
                        else:
                            for a in range(n):
                                result[a] = out_row[a]
                        for a in range(n):
                            if result[a] >= 0 and not table.reportable[result[a]]:
                                result[a] = -1
                            if (result[a] >= 0 and tol.mag_window > 0
                                    and abs(mag[a] - float(table.v_mag[result[a]])) > tol.mag_window):
                                result[a] = -1
                            if result[a] >= 0:
                                hip[a] = table.hip[result[a]]
                        for a in range(4):
                            record[a] = img4[perm[a]]
                            record[4 + a] = cat4[a]
                        record[8] = tried
                        t1 = cycles()
                        st[10] += t1 - t
                        return hip, result
    record[8] = tried
    t1 = cycles()
    st[1] += t1 - t
    return hip, result


@njit
def noop_same_args(x_px, y_px, mag, table, tol, record):
    """The kernel's arguments in, nothing done: numba's dispatch of this call (unboxing, typing)."""
    return 0


@njit
def noop_same_args_two_out(x_px, y_px, mag, table, tol, record):
    """As ``noop_same_args``, returning two new int64 (n,) arrays as the kernel does (their boxing)."""
    n = x_px.shape[0]
    return np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64)


@njit
def noop_arrays(x_px, y_px, mag, record):
    """Only the four array arguments (no ``Tables`` / ``Settings`` named tuples)."""
    return 0


@njit
def read_cost(k):
    """Cycles of ``k`` back-to-back counter reads (the instrument's own cost)."""
    t0 = cycles()
    s = 0
    for _ in range(k):
        s += cycles() & 1
    return cycles() - t0 + s * 0



def timed_min(f, args: tuple, repeats: int) -> float:
    """The least of ``repeats`` timed calls ``f(*args)``, µs."""
    best = None
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        f(*args)
        dt = time.perf_counter_ns() - t0
        best = dt if best is None or dt < best else best
    return best / 1e3


def show(label: str, cols: dict[str, np.ndarray], counters: dict[str, np.ndarray]) -> None:
    kern_med = np.median(cols["kernel copy (call)"])
    kern_mean = cols["kernel copy (call)"].mean()
    print(f"  {label}")
    print(f"    {'':34s} {'median':>9s} {'mean':>9s} {'med/kernel':>10s} {'mean/kernel':>11s}")
    for k, v in cols.items():
        share = ""
        if k in STAGES or k in ("dispatch + reads", "kernel copy (call)"):
            share = f"{np.median(v) / kern_med:10.0%} {v.mean() / kern_mean:11.0%}"
        print(f"    {k:34s} {np.median(v):9.2f} {v.mean():9.2f} {share}")
    print("    counters median / mean / p95: " + "; ".join(
        f"{k} {np.median(v):g} / {v.mean():.1f} / {np.percentile(v, 95):g}" for k, v in counters.items()))


def main(n: int, repeats: int, skies: list[str]) -> None:
    cat, cam = load_hipparcos(), Camera()
    mhz = cycles_per_us()
    reads = min(read_cost(1000) for _ in range(20)) / 1000.0
    print(f"cycle counter: {mhz:.1f} ticks/µs; one read ~{reads:.0f} ticks ({reads / mhz * 1e3:.1f} ns)")
    alg = get_algorithm("tetra")()
    db = alg.build(cat, cam)
    for sky in skies:
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(n)]
        alg.identify(db, obs[0])                     # compile apart
        tables, settings = _bundles(alg, db, cam)
        st0 = np.zeros(len(STAGES), dtype=np.int64)
        staged_kernel(obs[0].x_px, obs[0].y_px, obs[0].mag, tables, settings, np.empty(12, dtype=np.int64), st0)
        names = ("identify", "kernel", "Identification", "bundles", "_run", "kernel copy (call)",
                 "noop", "noop2", "noopa")
        noop_same_args(obs[0].x_px, obs[0].y_px, obs[0].mag, tables, settings, st0)
        noop_same_args_two_out(obs[0].x_px, obs[0].y_px, obs[0].mag, tables, settings, st0)
        noop_arrays(obs[0].x_px, obs[0].y_px, obs[0].mag, st0)
        t_us = {k: np.empty(n) for k in names}
        stage_us = np.empty((n, len(STAGES)))
        cnt = {k: np.empty(n) for k in ("patterns", "hash_lookups", "candidates", "verifications")}
        identified = np.empty(n, dtype=bool)
        for i, o in enumerate(obs):
            rec = np.empty(12, dtype=np.int64)
            hip, rows = identify_kernel(o.x_px, o.y_px, o.mag, tables, settings, rec)
            rec2 = np.empty(12, dtype=np.int64)
            hip2, rows2 = staged_kernel(o.x_px, o.y_px, o.mag, tables, settings, rec2, st0)
            assert np.array_equal(hip, hip2) and np.array_equal(rows, rows2) and np.array_equal(rec, rec2), i
            ident = alg.identify(db, o)
            assert np.array_equal(ident.hip, hip), i
            for k in cnt:
                cnt[k][i] = ident.counters[k]
            identified[i] = bool((hip >= 0).any())
            counters = dict(ident.counters)
            x, y, mag = o.x_px, o.y_px, o.mag
            kargs = (x, y, mag, tables, settings, rec)
            t_us["identify"][i] = timed_min(alg.identify, (db, o), repeats)
            t_us["kernel"][i] = timed_min(identify_kernel, kargs, repeats)
            t_us["Identification"][i] = timed_min(lambda h, c: Identification(h, counters=c), (hip, counters), repeats)
            t_us["bundles"][i] = timed_min(_bundles, (alg, db, o.camera), repeats)
            t_us["_run"][i] = timed_min(alg._run, (db, o), repeats)
            t_us["noop"][i] = timed_min(noop_same_args, kargs, repeats)
            t_us["noop2"][i] = timed_min(noop_same_args_two_out, kargs, repeats)
            t_us["noopa"][i] = timed_min(noop_arrays, (x, y, mag, rec), repeats)
            best = None
            for _ in range(repeats):
                st = np.zeros(len(STAGES), dtype=np.int64)
                t0 = time.perf_counter_ns()
                staged_kernel(x, y, mag, tables, settings, rec2, st)
                dt = time.perf_counter_ns() - t0
                if best is None or dt < best[0]:
                    best = (dt, st)
            t_us["kernel copy (call)"][i] = best[0] / 1e3
            stage_us[i] = best[1] / mhz
        cols = {k: t_us[k] for k in ("identify", "kernel", "Identification")}
        cols["wrapper (identify - kernel - Id.)"] = t_us["identify"] - t_us["kernel"] - t_us["Identification"]
        cols["  _bundles (lru_cache hit)"] = t_us["bundles"]
        cols["  _run - kernel - _bundles"] = t_us["_run"] - t_us["kernel"] - t_us["bundles"]
        cols["  identify - _run - Id."] = t_us["identify"] - t_us["_run"] - t_us["Identification"]
        cols["kernel copy (call)"] = t_us["kernel copy (call)"]
        for s, name in enumerate(STAGES):
            cols[name] = stage_us[:, s]
        cols["dispatch + reads"] = t_us["kernel copy (call)"] - stage_us.sum(axis=1)
        cols["empty kernel, same arguments"] = t_us["noop"]
        cols["  + two (n,) arrays returned"] = t_us["noop2"]
        cols["empty kernel, the 4 arrays only"] = t_us["noopa"]
        print(f"{sky} sky: {n} images, min of {repeats} per image, {np.mean(identified):.1%} with an id")
        show("all images", cols, cnt)
        slow = t_us["identify"] >= np.percentile(t_us["identify"], 95)
        show(f"slowest 5 % by identify ({slow.sum()} images; {identified[slow].mean():.0%} with an id)",
             {k: v[slow] for k, v in cols.items()}, {k: v[slow] for k, v in cnt.items()})
        print("    slowest images (identify µs, patterns, lookups, candidates, verifications, stars, id):")
        for i in np.argsort(-t_us["identify"])[: max(1, slow.sum())]:
            print(f"      {t_us['identify'][i]:8.1f} {cnt['patterns'][i]:4.0f} {cnt['hash_lookups'][i]:5.0f} "
                  f"{cnt['candidates'][i]:4.0f} {cnt['verifications'][i]:3.0f} {len(obs[i]):3d} {identified[i]}")
        print("  every image: the copy's hip, rows and record equal the plugin kernel's")


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3:] or ["paper", "real"])
