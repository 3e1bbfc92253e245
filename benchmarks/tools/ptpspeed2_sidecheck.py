"""ptp's per-window cost in isolation (issue #25, second speed round): the three-side check and the
window (sides, projection, eqs. 6-14 sigma, k-vector query), over the image triangles of Table 6's first
N images (paper's sky, 1 px / 0.5 Mv, seed 0), each variant timed as the best of 5 passes over the same
windows, in ns per window.

    python benchmarks/tools/ptpspeed2_sidecheck.py N

Side-check variants (each returns the same rows as ``kernels._side_check`` except the two lower bounds):
``kernel`` (the plugin's two-pass check), ``side a, compacted`` (rows whose side a agrees appended in one
pass, then sides b and c), ``blocks of 16`` (a block is scanned only when a row's side a agrees),
and two lower bounds that return only a count: ``count, side a`` (one float32 row, vectorised) and
``count, 3 sides``. Window variants: ``window`` (``kernels._window``), ``projection + sigma`` (no k-vector
query) and ``k-vector query`` alone.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from numba import njit
from numba.typed import List
from starid_algorithms.ptp import kernels as K

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import chord_rows, kvector_query
from starid.registry import get_algorithm


@njit
def _tols(sides, sigma, scale, side_beta):
    ta = np.float32(side_beta * scale * K.side_sigma(sides[0] / scale, sigma))
    tb = np.float32(side_beta * scale * K.side_sigma(sides[1] / scale, sigma))
    tc = np.float32(side_beta * scale * K.side_sigma(sides[2] / scale, sigma))
    return np.float32(sides[0]), np.float32(sides[1]), np.float32(sides[2]), ta, tb, tc


@njit
def kernel(sides, start, stop, db_sides, sigma, scale, side_beta, out):
    return K._side_check(sides, start, stop, db_sides, sigma, scale, side_beta, out)


@njit
def compacted(sides, start, stop, db_sides, sigma, scale, side_beta, out):
    a, b, c, ta, tb, tc = _tols(sides, sigma, scale, side_beta)
    n_a = 0
    for r in range(np.uint64(start), np.uint64(stop)):
        if abs(db_sides[0, r] - a) - ta <= 0:
            out[n_a] = r
            n_a += 1
    n_out = 0
    for i in range(n_a):
        r = out[i]
        if abs(db_sides[1, r] - b) - tb <= 0 and abs(db_sides[2, r] - c) - tc <= 0:
            out[n_out] = r
            n_out += 1
    return n_out


@njit
def blocks16(sides, start, stop, db_sides, sigma, scale, side_beta, out):
    a, b, c, ta, tb, tc = _tols(sides, sigma, scale, side_beta)
    n_out = 0
    r0 = np.uint64(start)
    end = np.uint64(stop)
    while r0 < end:
        r1 = min(r0 + np.uint64(16), end)
        hit = 0
        for r in range(r0, r1):
            hit += abs(db_sides[0, r] - a) - ta <= 0
        if hit:
            for r in range(r0, r1):
                if (abs(db_sides[0, r] - a) - ta <= 0 and abs(db_sides[1, r] - b) - tb <= 0
                        and abs(db_sides[2, r] - c) - tc <= 0):
                    out[n_out] = r
                    n_out += 1
        r0 = r1
    return n_out


@njit
def count_a(sides, start, stop, db_sides, sigma, scale, side_beta, out):
    a, b, c, ta, tb, tc = _tols(sides, sigma, scale, side_beta)
    sa = db_sides[0]
    n = 0
    for r in range(np.uint64(start), np.uint64(stop)):     # unsigned: no wrap-around test, so it vectorises
        n += abs(sa[r] - a) - ta <= 0
    return n


@njit
def count_3(sides, start, stop, db_sides, sigma, scale, side_beta, out):
    a, b, c, ta, tb, tc = _tols(sides, sigma, scale, side_beta)
    sa, sb, sc = db_sides[0], db_sides[1], db_sides[2]
    n = 0
    for r in range(np.uint64(start), np.uint64(stop)):
        n += (abs(sa[r] - a) - ta <= 0) & (abs(sb[r] - b) - tb <= 0) & (abs(sc[r] - c) - tc <= 0)
    return n


def _side_runner(fn):
    @njit
    def run(S, ST, db_sides, sigma, scale, side_beta):
        out = np.empty(100_000, dtype=np.int64)
        tot = 0
        for i in range(S.shape[0]):
            tot += fn(S[i], ST[i, 0], ST[i, 1], db_sides, sigma, scale, side_beta, out)
        return tot
    return run


@njit
def window(U, T, kv, mean, w, sigma, scale, beta):
    sides = np.empty(3)
    tot = 0
    for i in range(T.shape[0]):
        s, e = K._window(U[T[i, 0]], T[i, 1], T[i, 2], T[i, 3], sides, kv, mean, w, sigma, scale, beta)
        tot += e - s
    return tot


@njit
def projection(U, T, kv, mean, w, sigma, scale, beta):
    tot = 0.0
    for i in range(T.shape[0]):
        t = U[T[i, 0]]
        i1, i2, i3 = T[i, 1], T[i, 2], T[i, 3]
        a = scale * chord_rows(t, i1, t, i2)
        b = scale * chord_rows(t, i2, t, i3)
        c = scale * chord_rows(t, i1, t, i3)
        p = w[0] * (a - mean[0]) + w[1] * (b - mean[1]) + w[2] * (c - mean[2])
        tot += p + beta * K.projection_sigma(t, i1, i2, i3, a, b, c, w, sigma, scale)
    return tot


@njit
def query(P, kv):
    tot = 0
    for i in range(P.shape[0]):
        s, e = kvector_query(kv, P[i, 0], P[i, 1])
        tot += e - s
    return tot


def _best_ns(f, args, count):
    out = f(*args)
    best = np.inf
    for _ in range(5):
        t0 = time.perf_counter_ns()
        f(*args)
        best = min(best, time.perf_counter_ns() - t0)
    return best / count, out


def main(n: int) -> None:
    from starid_algorithms.ptp.algorithm import _view
    cat, cam = load_hipparcos(), Camera()
    ptp = get_algorithm("ptp")()
    db = ptp.build(cat, cam)
    tol = ptp.tolerances(db)
    sigma = tol.sigma_px / _view(cam)[0].frame.f_px
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES["paper"]),
                    seed=0)
    trials = sim.generate(n)
    units, tri = [], []
    for i in range(n):
        o = trials.observation(i, truth=False)
        u = np.ascontiguousarray(cam.backproject(o.x_px, o.y_px))
        units.append(u)
        m = len(u)
        for a in range(m):
            for b in range(m):
                for c in range(b + 1, m):
                    if a not in (b, c):
                        tri.append((i, a, b, c))
    T = np.array(tri, dtype=np.int64)
    S, ST, P = np.empty((len(T), 3)), np.empty((len(T), 2), dtype=np.int64), np.empty((len(T), 2))
    sides = np.empty(3)
    for r, (i, a, b, c) in enumerate(T):
        ST[r] = K._window(units[i], a, b, c, sides, db.kv, db.mean, db.axis, sigma, tol.scale, tol.beta)
        S[r] = sides
        p = float(db.axis @ (sides - db.mean))
        P[r] = p - 7.0, p + 7.0
    keep = (S.max(axis=1) <= tol.d_max) & (S.min(axis=1) >= tol.d_min)
    T, S, ST, P = T[keep], S[keep], ST[keep], P[keep]
    print(f"{len(T)} windows, median {np.median(ST[:, 1] - ST[:, 0]):.0f} database rows each")
    args = (S, ST, db.sides, sigma, tol.scale, tol.side_beta)
    for name, fn in (("kernel", kernel), ("side a, compacted", compacted), ("blocks of 16", blocks16),
                     ("count, side a (bound)", count_a), ("count, 3 sides (bound)", count_3)):
        ns, out = _best_ns(_side_runner(fn), args, len(S))
        print(f"side check  {name:24s} {ns:7.1f} ns/window  (rows found {out})")
    ul = List(units)
    for name, fn, a in (("window", window, (ul, T, db.kv, db.mean, db.axis, sigma, tol.scale, tol.beta)),
                        ("projection + sigma", projection, (ul, T, db.kv, db.mean, db.axis, sigma, tol.scale,
                                                            tol.beta)),
                        ("k-vector query", query, (P, db.kv))):
        ns, _ = _best_ns(fn, a, len(T))
        print(f"window      {name:24s} {ns:7.1f} ns/window")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(int(sys.argv[1]))
