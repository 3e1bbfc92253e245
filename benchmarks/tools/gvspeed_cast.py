"""Vote-casting layouts of geometric voting compared on the same windows (issue #25, branch gvspeed).

    python benchmarks/tools/gvspeed_cast.py [N] [R]

Table 6's two skies at 1 px / 0.5 Mv (seed 0), N images (100): the k-vector windows of every pair of
selected stars are searched once, then each variant casts the first round's votes (the 5 brightest
voters, the median image) and all rounds' (every selected star), R times (20), minimum kept; prints
the median over images in µs and checks every variant's counts against the one-loop ``cast_votes`` before this change.
Each variant allocates its counters as the kernel does (that is part of the cost).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from numba import njit
from starid_algorithms.geometric_voting import kernels as gk
from starid_algorithms.geometric_voting.algorithm import _bundles, _saturates, _vote_window

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px
from starid.registry import get_algorithm


@njit(cache=True)
def v_kernel(start, stop, pairs, k, n_guide):
    m = start.shape[0]
    stamp = np.zeros(n_guide, dtype=np.uint16)
    tally = np.zeros((m, n_guide), dtype=np.uint8)
    listed = np.empty((m, n_guide), dtype=pairs.dtype)
    n_listed = np.zeros(m, dtype=np.int64)
    gk.cast_votes(start, stop, pairs, np.int64(0), k, True, stamp, tally, np.int64(min(3, k - 1)), listed, n_listed)
    return tally, n_listed


@njit(cache=True)
def v_one_loop(start, stop, pairs, k, n_guide):
    """``cast_votes`` before gvspeed: each star of each pair tested, stamped and counted in one loop."""
    m = start.shape[0]
    stamp = np.zeros(n_guide, dtype=np.uint16)
    tally = np.zeros((m, n_guide), dtype=np.uint8)
    listed = np.empty((m, n_guide), dtype=pairs.dtype)
    n_listed = np.zeros(m, dtype=np.int64)
    level = min(3, k - 1)
    for b in range(k):
        for a in range(b):
            lo = start[a, b]
            hi = stop[a, b]
            if hi <= lo:
                continue
            pair_id = np.uint16(a * 256 + b + 1)
            for p in range(lo, hi):
                for o in range(2):
                    g = pairs[p, o]
                    if stamp[g] == pair_id:
                        continue
                    stamp[g] = pair_id
                    tally[a, g] += 1
                    tally[b, g] += 1
                    if tally[a, g] == level:
                        listed[a, n_listed[a]] = g
                        n_listed[a] += 1
                    if tally[b, g] == level:
                        listed[b, n_listed[b]] = g
                        n_listed[b] += 1
    return tally, n_listed


@njit(cache=True)
def v_branchless(start, stop, pairs, k, n_guide):
    """One loop, the once-per-pair test as a 0/1 increment, no unpredictable branch."""
    m = start.shape[0]
    stamp = np.zeros(n_guide, dtype=np.uint16)
    tally = np.zeros((m, n_guide), dtype=np.uint8)
    listed = np.empty((m, n_guide), dtype=pairs.dtype)
    n_listed = np.zeros(m, dtype=np.int64)
    level = np.uint8(min(3, k - 1))
    for b in range(k):
        for a in range(b):
            lo = start[a, b]
            hi = stop[a, b]
            pair_id = np.uint16(a * 256 + b + 1)
            ta = tally[a]
            tb = tally[b]
            for p in range(lo, hi):
                for o in range(2):
                    g = pairs[p, o]
                    inc = np.uint8(stamp[g] != pair_id)
                    stamp[g] = pair_id
                    x = ta[g] + inc
                    y = tb[g] + inc
                    ta[g] = x
                    tb[g] = y
                    if x == level and inc:
                        listed[a, n_listed[a]] = g
                        n_listed[a] += 1
                    if y == level and inc:
                        listed[b, n_listed[b]] = g
                        n_listed[b] += 1
    return tally, n_listed


@njit(cache=True)
def v_unique(start, stop, pairs, k, n_guide):
    """Each window first reduced to its distinct catalog stars (stamp), then one pass per star."""
    m = start.shape[0]
    stamp = np.zeros(n_guide, dtype=np.uint16)
    tally = np.zeros((m, n_guide), dtype=np.uint8)
    listed = np.empty((m, n_guide), dtype=pairs.dtype)
    n_listed = np.zeros(m, dtype=np.int64)
    level = np.uint8(min(3, k - 1))
    uniq = np.empty(n_guide, dtype=pairs.dtype)
    for b in range(k):
        for a in range(b):
            lo = start[a, b]
            hi = stop[a, b]
            pair_id = np.uint16(a * 256 + b + 1)
            n = 0
            for p in range(lo, hi):
                g = pairs[p, 0]
                uniq[n] = g
                n += stamp[g] != pair_id
                stamp[g] = pair_id
                g = pairs[p, 1]
                uniq[n] = g
                n += stamp[g] != pair_id
                stamp[g] = pair_id
            for s in (a, b):
                t = tally[s]
                nl = n_listed[s]
                for i in range(n):
                    g = uniq[i]
                    x = t[g] + np.uint8(1)
                    t[g] = x
                    if x == level:
                        listed[s, nl] = g
                        nl += 1
                n_listed[s] = nl
    return tally, n_listed


@njit(cache=True)
def v_unique_flat(start, stop, pairs, k, n_guide):
    """``unique first`` reading the window as one flat run of catalog stars, both stars' counters in
    one pass."""
    m = start.shape[0]
    stamp = np.zeros(n_guide, dtype=np.uint16)
    tally = np.zeros((m, n_guide), dtype=np.uint8)
    listed = np.empty((m, n_guide), dtype=pairs.dtype)
    n_listed = np.zeros(m, dtype=np.int64)
    level = np.uint8(min(3, k - 1))
    uniq = np.empty(n_guide, dtype=pairs.dtype)
    ends = pairs.reshape(-1)
    for b in range(k):
        for a in range(b):
            lo = 2 * start[a, b]
            hi = 2 * stop[a, b]
            pair_id = np.uint16(a * 256 + b + 1)
            n = 0
            for p in range(lo, hi):
                g = ends[p]
                uniq[n] = g
                n += stamp[g] != pair_id
                stamp[g] = pair_id
            ta = tally[a]
            tb = tally[b]
            for i in range(n):
                g = uniq[i]
                x = ta[g] + np.uint8(1)
                y = tb[g] + np.uint8(1)
                ta[g] = x
                tb[g] = y
                if x == level:
                    listed[a, n_listed[a]] = g
                    n_listed[a] += 1
                if y == level:
                    listed[b, n_listed[b]] = g
                    n_listed[b] += 1
    return tally, n_listed


@njit(cache=True)
def v_unique_nobranch(start, stop, pairs, k, n_guide):
    """``unique flat`` with the listing as a store and a 0/1 step instead of a branch."""
    m = start.shape[0]
    stamp = np.zeros(n_guide, dtype=np.uint16)
    tally = np.zeros((m, n_guide), dtype=np.uint8)
    listed = np.empty((m, n_guide + 1), dtype=pairs.dtype)
    n_listed = np.zeros(m, dtype=np.int64)
    level = np.uint8(min(3, k - 1))
    uniq = np.empty(n_guide + 1, dtype=pairs.dtype)
    ends = pairs.reshape(-1)
    for b in range(k):
        for a in range(b):
            lo = 2 * start[a, b]
            hi = 2 * stop[a, b]
            pair_id = np.uint16(a * 256 + b + 1)
            n = 0
            for p in range(lo, hi):
                g = ends[p]
                uniq[n] = g
                n += stamp[g] != pair_id
                stamp[g] = pair_id
            ta = tally[a]
            tb = tally[b]
            la = listed[a]
            lb = listed[b]
            na = n_listed[a]
            nb = n_listed[b]
            for i in range(n):
                g = uniq[i]
                x = ta[g] + np.uint8(1)
                y = tb[g] + np.uint8(1)
                ta[g] = x
                tb[g] = y
                la[na] = g
                na += x == level
                lb[nb] = g
                nb += y == level
            n_listed[a] = na
            n_listed[b] = nb
    return tally[:, :], n_listed


@njit(cache=True)
def v_hybrid(start, stop, pairs, k, n_guide, first_branchless):
    """``no-branch listing`` for the pairs whose fainter star is ``first_branchless`` or later."""
    m = start.shape[0]
    stamp = np.zeros(n_guide, dtype=np.uint16)
    tally = np.zeros((m, n_guide), dtype=np.uint8)
    listed = np.empty((m, n_guide + 1), dtype=pairs.dtype)
    n_listed = np.zeros(m, dtype=np.int64)
    level = np.uint8(min(3, k - 1))
    uniq = np.empty(n_guide + 1, dtype=pairs.dtype)
    ends = pairs.reshape(-1)
    for b in range(k):
        for a in range(b):
            lo = 2 * start[a, b]
            hi = 2 * stop[a, b]
            pair_id = np.uint16(a * 256 + b + 1)
            n = 0
            for p in range(lo, hi):
                g = ends[p]
                uniq[n] = g
                n += stamp[g] != pair_id
                stamp[g] = pair_id
            ta = tally[a]
            tb = tally[b]
            la = listed[a]
            lb = listed[b]
            na = n_listed[a]
            nb = n_listed[b]
            if b >= first_branchless:
                for i in range(n):
                    g = uniq[i]
                    x = ta[g] + np.uint8(1)
                    y = tb[g] + np.uint8(1)
                    ta[g] = x
                    tb[g] = y
                    la[na] = g
                    na += x == level
                    lb[nb] = g
                    nb += y == level
            else:
                for i in range(n):
                    g = uniq[i]
                    x = ta[g] + np.uint8(1)
                    y = tb[g] + np.uint8(1)
                    ta[g] = x
                    tb[g] = y
                    if x == level:
                        la[na] = g
                        na += 1
                    if y == level:
                        lb[nb] = g
                        nb += 1
            n_listed[a] = na
            n_listed[b] = nb
    return tally[:, :], n_listed


@njit(cache=True)
def v_alloc_only(start, stop, pairs, k, n_guide):
    m = start.shape[0]
    stamp = np.zeros(n_guide, dtype=np.uint16)
    tally = np.zeros((m, n_guide), dtype=np.uint8)
    listed = np.empty((m, n_guide), dtype=pairs.dtype)
    n_listed = np.zeros(m, dtype=np.int64)
    listed[0, 0] = stamp[0]
    return tally, n_listed


VARIANTS = {"one loop (before)": v_one_loop, "kernel cast_votes": v_kernel, "branchless": v_branchless,
            "unique first": v_unique, "unique flat": v_unique_flat,
            "no-branch listing": v_unique_nobranch, "alloc only": v_alloc_only}


def main(n: int, repeats: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    alg = get_algorithm("geometric_voting")()
    db = alg.build(cat, cam)
    tol, fr, rule, vtol = _bundles(alg, cam, db.c_max, db.d_min_deg, _saturates(db), _vote_window(db))
    ng = np.int64(db.degree.shape[0])
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        inputs = []
        for i in range(n):
            o = trials.observation(i, truth=False)
            v = backproject_px(o.x_px, o.y_px, fr.f_px, fr.cx_px, fr.cy_px)
            sel = gk.select_stars(o.x_px, o.y_px, o.mag, v, tol.d_min, tol.max_stars)
            m = sel.shape[0]
            if m < 5:
                continue
            start, stop = np.zeros((m, m), dtype=np.int64), np.zeros((m, m), dtype=np.int64)
            gk.extend_windows(v, sel, db.kv, vtol, start, stop, np.int64(0), np.int64(m))
            inputs.append((start, stop, m))
        for label, first in (("first round (5 voters)", True), ("every selected star", False)):
            print(f"{sky} sky, {len(inputs)} images, {label}: median of the min of {repeats} (µs)")
            ref = [v_one_loop(s, t, db.pairs, np.int64(5 if first else m), ng) for s, t, m in inputs]
            for name, fn in VARIANTS.items():
                times = []
                for (s, t, m), (rt, rn) in zip(inputs, ref, strict=True):
                    k = np.int64(5 if first else m)
                    tal, nl = fn(s, t, db.pairs, k, ng)
                    assert name == "alloc only" or (np.array_equal(tal, rt) and np.array_equal(nl, rn)), name
                    best = np.inf
                    for _ in range(repeats):
                        t0 = time.perf_counter_ns()
                        fn(s, t, db.pairs, k, ng)
                        best = min(best, time.perf_counter_ns() - t0)
                    times.append(best / 1e3)
                print(f"  {name:16s} {np.median(times):8.1f}  mean {np.mean(times):8.1f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100, int(sys.argv[2]) if len(sys.argv) > 2 else 20)
