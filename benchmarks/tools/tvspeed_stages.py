"""Where triangle_voting's ``vote`` spends its time (issue #25, branch tvspeed).

Describes ``vote`` before branch tvspeed2 (records by cell then height, the hash-table tally); the
current stages are ``tvspeed2_stages.py`` (and, since branch tvspeed3, ``vote`` itself).

    python benchmarks/tools/tvspeed_stages.py [N] [R]

Table 6's two skies at 1 px / 0.5 Mv (seed 0), N images (40), each call timed R times (5, minimum
kept). Three cut-down copies of ``vote``'s loops, each a superset of the one before: ``triangles``
(neighbour choice, features, grid cells of every image triangle, no record read), ``scan`` (+ the
records of the cells read and tested against both windows and the float32 side pre-filter, counted
only), ``side_checks`` (+ the records near a side match listed and checked exactly, counted only;
``n_near`` per triangle must stay below 4096), and the plugin's own ``vote`` (+ the votes, candidate
lists, scores); then
``identify_rows`` (+ selection, verification, confirmation / fallback), ``finish`` and ``identify``
(+ the Python wrapper and the ``Identification``). Prints the median over images in us.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np
from numba import njit
from starid_algorithms.planar_triangle import kernels as ptk
from starid_algorithms.triangle_voting import algorithm as tva
from starid_algorithms.triangle_voting import kernels as tvk

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, camera_frame, chord_rows
from starid.registry import get_algorithm


@njit(cache=True)
def _loops(v_cam, base_db, height_db, side_i_db, side_j_db, cell_start, n_cells_b, n_cells_h, cell_b, cell_h,
           pr_chord, dmin_chord, n_nbr, sigma_chord, k_sigma, main_db, ni_db, nj_db, cat_unit, scan):
    """``vote``'s triangle loop; with ``scan`` 1 also its record tests (counted), with 2 also the
    listing of the records near a side match and their exact side check (counted, no vote)."""
    n = v_cam.shape[0]
    eps_b = k_sigma * math.sqrt(2.0) * sigma_chord
    eps_side = eps_b + tvk.SIDE_ROUNDING
    lo_d = dmin_chord - eps_b
    hi_d = pr_chord + eps_b
    nbr = np.empty(n_nbr, dtype=np.int64)
    listed = np.empty(4096, dtype=np.int64)
    count = 0
    for i in range(n):
        k = 0
        for j in range(n):
            if k == n_nbr:
                break
            if j == i:
                continue
            d = chord_rows(v_cam, i, v_cam, j)
            if d >= lo_d and d <= hi_d:
                nbr[k] = j
                k += 1
        for p in range(k):
            a = nbr[p]
            for q in range(p + 1, k):
                b = nbr[q]
                base, height, t = tvk.triangle_features(v_cam[i], v_cam[a], v_cam[b])
                if base < lo_d:
                    continue
                eps_h = k_sigma * sigma_chord * math.sqrt(1.0 + (1.0 - t) * (1.0 - t) + t * t)
                d_ia = chord_rows(v_cam, i, v_cam, a)
                d_ib = chord_rows(v_cam, i, v_cam, b)
                cb0 = max(int(math.floor((base - eps_b) / cell_b)), 0)
                cb1 = min(int(math.floor((base + eps_b) / cell_b)), n_cells_b - 1)
                ch0 = max(int(math.floor((height - eps_h) / cell_h)), 0)
                ch1 = min(int(math.floor((height + eps_h) / cell_h)), n_cells_h - 1)
                if scan == 0:
                    count += cb1 - cb0 + ch1 - ch0
                    continue
                n_near = 0
                for cb in range(cb0, cb1 + 1):
                    for r in range(cell_start[cb * n_cells_h + ch0], cell_start[cb * n_cells_h + ch1 + 1]):
                        in_windows = (abs(base_db[r] - base) <= eps_b) & (abs(height_db[r] - height) <= eps_h)
                        s_i = float(side_i_db[r])
                        s_j = float(side_j_db[r])
                        near = min(max(abs(d_ia - s_i), abs(d_ib - s_j)),
                                   max(abs(d_ia - s_j), abs(d_ib - s_i))) <= eps_side
                        if scan == 1:
                            count += in_windows & near
                        else:
                            listed[n_near] = r
                            n_near += in_windows & near
                for e in range(n_near):
                    r = listed[e]
                    c = main_db[r]
                    ci = ni_db[r]
                    cj = nj_db[r]
                    d_ci = chord_rows(cat_unit, c, cat_unit, ci)
                    d_cj = chord_rows(cat_unit, c, cat_unit, cj)
                    e_straight = min(max(abs(d_ia - d_ci), abs(d_ib - d_cj)), max(abs(d_ia - d_cj), abs(d_ib - d_ci)))
                    count += e_straight <= eps_b
    return count


def _best(fn, repeats):
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        fn()
        best = min(best, time.perf_counter_ns() - t0)
    return best / 1e3


def _steps(alg, db, o, repeats):
    x, y, mag = o.x_px, o.y_px, o.mag
    out = {"identify": _best(lambda: alg.identify(db, o), repeats)}
    order = np.lexsort((y, x, mag))
    order = order[mag[order] <= alg.mag_limit + alg.mag_margin][:alg.max_stars]
    if order.size < 3:
        return out
    cam = o.camera
    v_cam = backproject_px(x[order], y[order], cam.f_px, cam.cx_px, cam.cy_px)
    tol = alg._tolerance(cam)
    tb = tva._tables(db)
    args = (v_cam, tb.base, tb.height, tb.side_i, tb.side_j, tb.cell_start, tb.n_cells_b, tb.n_cells_h, tb.cell_b,
            tb.cell_h, tb.pr_chord, tb.dmin_chord, tol.n_nbr, tol.sigma_chord, tol.k_sigma, tb.main, tb.n_i, tb.n_j,
            tb.unit)
    kt, ktol = tva._kernel_tables(db), tuple(tol)  # as identify calls the kernels
    votes, mark = tva._scratch(db, order.size)
    out["triangles"] = _best(lambda: _loops(*args, 0), repeats)
    out["scan"] = _best(lambda: _loops(*args, 1), repeats)
    out["side_checks"] = _best(lambda: _loops(*args, 2), repeats)
    out["vote"] = _best(lambda: tvk.vote(v_cam, kt, ktol, votes, mark), repeats)
    out["identify_rows"] = _best(lambda: tvk.identify_rows(v_cam, kt, ktol, votes, mark), repeats)
    rows, _ = tvk.identify_rows(v_cam, kt, ktol, votes, mark)
    if rows.max() >= 0:
        all_rows = np.full(len(x), -1, dtype=np.int64)
        all_rows[order] = rows
        rules = ptk.Finish(tol.eps_chord, float(alg.mag_margin), float(alg.mag_limit),
                           float(alg.coverage_mag_margin), float(alg.max_missed_fraction), bool(alg.assign_all))
        frame = camera_frame(cam)
        unit = tva._unit_f64(db)
        out["finish"] = _best(lambda: ptk.finish(x, y, mag, all_rows, unit, db.hip, db.deep, db.deep_v_mag,
                                                 frame, rules), repeats)
    return out


def main(n: int, repeats: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(n)]
        for name in ("tetra", "triangle_voting"):
            alg = get_algorithm(name)()
            db = alg.build(cat, cam)
            alg.identify(db, obs[0])
            if name == "tetra":
                rows = [{"identify": _best(lambda o=o: alg.identify(db, o), repeats)} for o in obs]  # noqa: B023
            else:
                rows = [_steps(alg, db, o, repeats) for o in obs]
            for k in ("triangles", "scan", "side_checks", "vote", "identify_rows", "finish", "identify"):
                v = np.array([r.get(k, 0.0) for r in rows])
                if v.any():
                    print(f"{sky:5s} {name:16s} {k:14s} median {np.median(v):8.1f} us  mean {v.mean():8.1f} us",
                          flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40, int(sys.argv[2]) if len(sys.argv) > 2 else 5)
