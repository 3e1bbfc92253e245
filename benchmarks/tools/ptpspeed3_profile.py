"""Where ptp's search stage goes (issue #25, third speed round: ``ptpspeed2_profile.py`` for the database
with the second index, :class:`~starid_algorithms.ptp.kernels.SideIndex`): the kernel's search loop rebuilt
stage by stage on Table 6's images (1 px / 0.5 Mv, seed 0), timed as the minimum of R repeats per image,
median over N images, in microseconds.

Superseded: it calls ``identify_kernel`` with the tuple arguments ptp had before stop 42 (branch
ptpspeed5 passes one parameter array) and runs on that code only (``git checkout ab5f4bd``);
``ptpspeed5_split.py`` profiles the current kernel.

    python benchmarks/tools/ptpspeed3_profile.py N R

Stages (each includes the ones above): setup (selection, unit vectors, distances, slave lists, the
triangle loop without windows), + windows (sides, projection, eqs. 6-14 sigma, k-vector query),
+ three-side checks through the second index (the full search stage of ``identify_kernel``); then the whole kernel.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from numba import njit
from starid_algorithms.ptp import kernels as K

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, chord_rows
from starid.registry import get_algorithm


@njit(cache=False)   # not cached: numba does not see a change in the kernels it calls
def search_stage(x_px, y_px, mag, view_t, db_t, tol_t, level):
    view = K.View(K.Frame(*view_t[0]), view_t[1])
    db = K.Tables(K.KVector(*db_t[0]), db_t[1], db_t[2], db_t[3], db_t[4], db_t[5], db_t[6], K.SideIndex(*db_t[7]))
    tol = K.Tolerances(*tol_t)
    sel = K.select_stars(x_px, y_px, mag, tol.max_stars)
    k = 0
    while k < sel.shape[0] and mag[sel[k]] <= tol.star_mag_max:
        k += 1
    sel = sel[:k]
    frame = view.frame
    unit = backproject_px(x_px[sel], y_px[sel], frame.f_px, frame.cx_px, frame.cy_px)
    sigma = tol.sigma_px / frame.f_px
    scale, d_min, d_max = tol.scale, tol.d_min, tol.d_max
    n = unit.shape[0]
    dist = np.empty((n, n))
    usable = np.ones(n, dtype=np.bool_)
    for i in range(n):
        dist[i, i] = 0.0
        for j in range(i + 1, n):
            d = scale * chord_rows(unit, i, unit, j)
            dist[i, j] = d
            dist[j, i] = d
            if d < d_min and tol.exclude_doubles:
                usable[i] = False
                usable[j] = False
    cand = np.empty(1024, dtype=np.int64)
    n_img = max(tol.n_slaves, tol.image_slaves)
    slaves = np.empty(n_img, dtype=np.int64)
    sides = np.empty(3)
    total = 0
    m_cap = 256
    m_tri = np.empty(m_cap, dtype=np.int64)
    m_img = np.empty((m_cap, 3), dtype=np.int64)
    m_cat = np.empty((m_cap, 3), dtype=np.int64)
    n_match = 0
    for master in range(n):
        if not usable[master]:
            continue
        kk = K.nearest_slaves(dist[master], unit, usable, master, d_min, d_max, n_img, slaves)
        for ia in range(kk):
            for ib in range(ia + 1, kk):
                s1 = slaves[ia]
                s2 = slaves[ib]
                d1 = dist[master, s1]
                d2 = dist[master, s2]
                if dist[s1, s2] <= 0.0:
                    continue
                tol_swap = tol.side_beta * scale * K.side_sigma(max(d1, d2) / scale, sigma)
                n_orders = 2 if (tol.swap_slaves and abs(d2 - d1) <= tol_swap) else 1
                for o in range(n_orders):
                    a = s1 if o == 0 else s2
                    b = s2 if o == 0 else s1
                    if level == 0:
                        total += a + b
                        continue
                    start, stop = K._window(unit, master, a, b, sides, db.kv, db.mean, db.axis, sigma, scale,
                                            tol.beta)
                    if level == 1:
                        total += stop - start
                        continue
                    if stop - start >= cand.shape[0]:
                        cand = np.empty(2 * (stop - start) + 1, dtype=np.int64)
                    nc = K._side_check_indexed(sides, start, stop, db.index, sigma, scale, tol.side_beta, cand)
                    total += nc
                    if level == 2 or nc > tol.max_candidates:
                        continue
                    for c in range(nc):
                        if n_match == m_cap:
                            m_cap *= 2
                            new_tri = np.empty(m_cap, dtype=np.int64)
                            new_img = np.empty((m_cap, 3), dtype=np.int64)
                            new_cat = np.empty((m_cap, 3), dtype=np.int64)
                            for r in range(n_match):
                                new_tri[r] = m_tri[r]
                                for v in range(3):
                                    new_img[r, v] = m_img[r, v]
                                    new_cat[r, v] = m_cat[r, v]
                            m_tri, m_img, m_cat = new_tri, new_img, new_cat
                        m_tri[n_match] = K._triple_key(master, s1, s2, n)
                        m_img[n_match, 0] = master
                        m_img[n_match, 1] = a
                        m_img[n_match, 2] = b
                        for v in range(3):
                            m_cat[n_match, v] = db.ids[cand[c], v]
                        n_match += 1
    if level >= 4 and n_match > 0:
        result = np.full(n, -1, dtype=np.int64)
        K.validate(n, db.guide_unit.shape[0], n_match, m_tri, m_img, m_cat, tol, tol.min_shared,
                   tol.conflict_fails, result)
    return total + n_match


def _min_us(fn, obs, repeats):
    out = np.empty(len(obs))
    for i, o in enumerate(obs):
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter_ns()
            fn(o)
            best = min(best, time.perf_counter_ns() - t0)
        out[i] = best / 1e3
    return out


def main(n: int, repeats: int) -> None:
    from starid_algorithms.ptp.algorithm import _view
    cat, cam = load_hipparcos(), Camera()
    ptp = get_algorithm("ptp")()
    db = ptp.build(cat, cam)
    tables, view = db.plain_tables, _view(cam)[1]
    narrow, wide = db.packed    # the whole kernel takes the tables packed (ptp speed round 4)
    tol_t = K.plain(ptp.tolerances(db))
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(n)]
        for level, label in ((0, "setup"), (1, "+ windows"), (2, "+ three-side checks"),
                             (3, "+ match records"), (4, "+ validation")):
            o = obs[0]
            search_stage(o.x_px, o.y_px, o.mag, view, tables, tol_t, level)
            t = _min_us(lambda o, lv=level: search_stage(o.x_px, o.y_px, o.mag, view, tables, tol_t, lv), obs,
                        repeats)
            print(f"{sky:5s} {label:24s} median {np.median(t):7.1f}  p95 {np.percentile(t, 95):7.1f}", flush=True)
        K.identify_kernel(o.x_px, o.y_px, o.mag, view, narrow, wide, tol_t)
        t = _min_us(lambda o: K.identify_kernel(o.x_px, o.y_px, o.mag, view, narrow, wide, tol_t), obs, repeats)
        print(f"{sky:5s} {'whole kernel':24s} median {np.median(t):7.1f}  p95 {np.percentile(t, 95):7.1f}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]))
