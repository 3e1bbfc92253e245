"""ptp's three-side check in isolation (issue #25, third speed round): the window scan of the base
(``kernels._side_check``, every row of the k-vector window) against the check through the second index
(``kernels._side_check_indexed``, only the rows of the side-a bins near the triangle's side a), over the
kernel's own windows (every master's triangles of its ``image_slaves`` nearest stars, one vertex order)
of Table 6's first N images (1 px / 0.5 Mv, seed 0), best of 9 passes, ns per window.

    python benchmarks/tools/ptpspeed3_sidecheck.py N [SKY]

Also prints the rows a window holds and the index entries / bins the indexed check reads, and asserts
that both return the same rows in the same order.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np
from numba import njit
from starid_algorithms.ptp import kernels as K

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm


@njit
def _scan(S, ST, db_sides, index, sigma, scale, side_beta, out):
    sides = np.empty(3)
    tot = 0
    for i in range(S.shape[0]):
        sides[0], sides[1], sides[2] = S[i, 0], S[i, 1], S[i, 2]
        tot += K._side_check(sides, ST[i, 0], ST[i, 1], db_sides, sigma, scale, side_beta, out)
    return tot


@njit
def _indexed(S, ST, db_sides, index, sigma, scale, side_beta, out):
    sides = np.empty(3)
    tot = 0
    for i in range(S.shape[0]):
        sides[0], sides[1], sides[2] = S[i, 0], S[i, 1], S[i, 2]
        tot += K._side_check_indexed(sides, ST[i, 0], ST[i, 1], index, sigma, scale, side_beta, out)
    return tot


@njit
def _same(S, ST, db_sides, index, sigma, scale, side_beta):
    a = np.empty(db_sides.shape[1] + 1, dtype=np.int64)
    b = np.empty(db_sides.shape[1] + 1, dtype=np.int64)
    for i in range(S.shape[0]):
        na = K._side_check(S[i], ST[i, 0], ST[i, 1], db_sides, sigma, scale, side_beta, a)
        nb = K._side_check_indexed(S[i], ST[i, 0], ST[i, 1], index, sigma, scale, side_beta, b)
        if na != nb:
            return False
        for k in range(na):
            if a[k] != b[k]:
                return False
    return True


@njit
def _read(S, ST, index, sigma, scale, side_beta):
    entries = 0
    bins = 0
    for i in range(S.shape[0]):
        if ST[i, 1] <= ST[i, 0]:
            continue
        a = np.float32(S[i, 0])
        ta = np.float32(side_beta * scale * K.side_sigma(S[i, 0] / scale, sigma))
        i0 = max(int(math.floor((float(a) - float(ta) - K.INDEX_MARGIN) / index.width)), 0)
        i1 = min(int(math.floor((float(a) + float(ta) + K.INDEX_MARGIN) / index.width)), index.offsets.shape[1] - 1)
        j0 = ST[i, 0] >> index.shift
        j1 = ((ST[i, 1] - 1) >> index.shift) + 1
        for b in range(i0, i1 + 1):
            bins += 1
            entries += index.offsets[j1, b] - index.offsets[j0, b]
    return entries, bins


def main(n: int, sky: str = "paper") -> None:
    from starid_algorithms.ptp.algorithm import _view
    cat, cam = load_hipparcos(), Camera()
    ptp = get_algorithm("ptp")()
    db = ptp.build(cat, cam)
    tol = ptp.tolerances(db)
    sigma = tol.sigma_px / _view(cam)[0].frame.f_px
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                    seed=0)
    trials = sim.generate(n)
    S, ST = [], []
    sides = np.empty(3)
    slaves = np.empty(max(tol.n_slaves, tol.image_slaves), dtype=np.int64)
    for i in range(n):
        o = trials.observation(i, truth=False)
        u = np.ascontiguousarray(cam.backproject(o.x_px, o.y_px))
        dist = tol.scale * np.linalg.norm(u[:, None] - u[None], axis=2)
        usable = np.ones(len(u), dtype=np.bool_)
        for m in range(len(u)):
            k = K.nearest_slaves(dist[m], u, usable, m, tol.d_min, tol.d_max, slaves.size, slaves)
            for x in range(k):
                for y in range(x + 1, k):
                    ST.append(K._window(u, m, slaves[x], slaves[y], sides, db.kv, db.mean, db.axis, sigma,
                                        tol.scale, tol.beta))
                    S.append(sides.copy())
    S, ST = np.array(S), np.array(ST, dtype=np.int64)
    args = (S, ST, db.sides, db.index, sigma, tol.scale, tol.side_beta)
    assert _same(*args), "the indexed check returned other rows"
    entries, bins = _read(S, ST, db.index, sigma, tol.scale, tol.side_beta)
    print(f"{sky} sky: {len(S)} windows of {n} images, median {np.median(ST[:, 1] - ST[:, 0]):.0f} rows each; "
          f"the index reads {entries / len(S):.1f} entries in {bins / len(S):.2f} bins per window")
    out = np.empty(db.sides.shape[1] + 1, dtype=np.int64)
    for name, fn in (("scan of the window (base)", _scan), ("through the second index", _indexed)):
        found = fn(*args, out)
        best = np.inf
        for _ in range(9):
            t0 = time.perf_counter_ns()
            fn(*args, out)
            best = min(best, time.perf_counter_ns() - t0)
        print(f"three-side check, {name:26s} {best / len(S):7.1f} ns/window  (rows found {found})")


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__)
    main(int(sys.argv[1]), *sys.argv[2:])
