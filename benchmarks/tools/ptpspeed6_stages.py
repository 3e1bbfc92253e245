"""Where a ptp call's time goes, stage by stage (issue #25, branch ptpspeed6): the kernel's setup and its
passes over the windows rebuilt as one numba kernel that stops after a given stage (without the kernel's
prefetches), beside the real kernel with parts switched off.

    python benchmarks/tools/ptpspeed6_stages.py N R [paper|real] [others]

Table 6's images (1 px / 0.5 Mv, seed 0), N of them; each stage's minimum over R repeats per image, then
the median over the images, µs ("warm"); with ``others``, also each stage timed once after every other
registered plugin identified the image, as ``benchmarks/test_ratios.py`` times it ("cold"). Stages (each
includes the ones above): -2 the call and the parameters, -1 with the packed tables unpacked, 0 the setup
(selection, unit vectors, distances, slave lists), 1 the windows' bounds (sides, projection, sigma, k-vector
ends), 2 the k-vector's slices, 3 their trim and the bins of side a, 4 the entries' prefetch, 5 the
three-side checks, 6 the match records and their guide rows, 7 sharing-star validation, 8 the same with
validation run 11 times (validate's own time: (stage 8 - stage 7) / 10); then the kernel with
``max_candidates=0`` and without the steps after validation, the kernel without those steps, and the whole
kernel.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from numba import njit
from starid_algorithms.ptp import kernels as K
from starid_algorithms.ptp.kernels import (
    _index_bins,
    _prefetch_entries,
    _projection_window,
    _side_check_entries,
    _triple_key,
    nearest_slaves,
    params_tol,
    params_view,
    select_stars,
    side_sigma,
    tables_of,
    validate,
)

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, chord_rows
from starid.kernels.kvector import kvector_ends, kvector_rows, kvector_trim
from starid.registry import available_algorithms, get_algorithm


@njit
def stages(x_px, y_px, mag, params, narrow, wide, stage):
    view = params_view(params)
    db = tables_of(narrow, wide)
    tol = params_tol(params)
    if stage == -2:
        return 0.0
    if stage == -1:
        return db.kv.m + db.index.width + db.guide_unit[0, 0]
    sel = select_stars(x_px, y_px, mag, tol.max_stars)
    k = 0
    while k < sel.shape[0] and mag[sel[k]] <= tol.star_mag_max:
        k += 1
    sel = sel[:k]
    frame = view.frame
    unit = backproject_px(x_px[sel], y_px[sel], frame.f_px, frame.cx_px, frame.cy_px)
    sigma = tol.sigma_px / frame.f_px
    scale, d_min, d_max, n_slaves = tol.scale, tol.d_min, tol.d_max, tol.n_slaves
    side_beta = tol.side_beta
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
    n_img_slaves = max(n_slaves, tol.image_slaves)
    slave_of = np.empty((n, n_img_slaves), dtype=np.int64)
    n_slave = np.zeros(n, dtype=np.int64)
    cap_w = 1
    for master in range(n):
        if usable[master]:
            n_slave[master] = nearest_slaves(dist[master], unit, usable, master, d_min, d_max, n_img_slaves,
                                             slave_of[master])
            cap_w += n_slave[master] * (n_slave[master] - 1)
    acc = 0.0
    if stage == 0:
        return cap_w + acc
    kv = db.kv
    index = db.index
    n_rows = kv.values.shape[0]
    w_int = np.empty((cap_w, 8), dtype=np.int64)
    w_flt = np.empty((cap_w, 2))
    w_side = np.empty((cap_w, 6), dtype=np.float32)
    nw = 0
    for master in range(n):
        if not usable[master]:
            continue
        k = n_slave[master]
        for ia in range(k):
            for ib in range(ia + 1, k):
                s1 = slave_of[master, ia]
                s2 = slave_of[master, ib]
                d1 = dist[master, s1]
                d2 = dist[master, s2]
                if dist[s1, s2] <= 0.0:
                    continue
                d12 = dist[s1, s2]
                t1 = side_beta * scale * side_sigma(d1 / scale, sigma)
                t2 = side_beta * scale * side_sigma(d2 / scale, sigma)
                t12 = side_beta * scale * side_sigma(d12 / scale, sigma)
                tol_swap = t1 if d1 >= d2 else t2
                n_orders = 2 if (tol.swap_slaves and abs(d2 - d1) <= tol_swap) else 1
                key = _triple_key(master, s1, s2, n)
                for o in range(n_orders):
                    sa, sc, ta, tc = (d1, d2, t1, t2) if o == 0 else (d2, d1, t2, t1)
                    w_int[nw, 0] = master
                    w_int[nw, 1] = s1 if o == 0 else s2
                    w_int[nw, 2] = s2 if o == 0 else s1
                    w_int[nw, 3] = key
                    lo, hi = _projection_window(unit, master, w_int[nw, 1], w_int[nw, 2], sa, d12, sc, db.mean,
                                                db.axis, sigma, scale, tol.beta)
                    w_flt[nw, 0] = lo
                    w_flt[nw, 1] = hi
                    w_side[nw, 0] = np.float32(sa)
                    w_side[nw, 1] = np.float32(d12)
                    w_side[nw, 2] = np.float32(sc)
                    w_side[nw, 3] = np.float32(ta)
                    w_side[nw, 4] = np.float32(t12)
                    w_side[nw, 5] = np.float32(tc)
                    jb, jt = kvector_ends(kv.m, kv.q, lo, hi)
                    w_int[nw, 4] = jb
                    w_int[nw, 5] = jt
                    nw += 1
    if stage == 1:
        return w_int[:nw, 4].sum() + w_flt[:nw, 0].sum()
    for w in range(nw):
        start, stop = kvector_rows(kv.k, n_rows, w_int[w, 4], w_int[w, 5])
        w_int[w, 4] = start
        w_int[w, 5] = stop
    if stage == 2:
        return w_int[:nw, 4].sum()
    for w in range(nw):
        lo = w_flt[w, 0]
        hi = w_flt[w, 1]
        start, stop = kvector_trim(kv.values, n_rows, w_int[w, 4], w_int[w, 5], lo, hi)
        w_int[w, 4] = start
        w_int[w, 5] = stop
        if stop > start:
            i0, i1 = _index_bins(w_side[w, 0], w_side[w, 3], index)
            w_int[w, 6] = i0
            w_int[w, 7] = i1
    if stage == 3:
        return w_int[:nw, 4].sum() + w_int[:nw, 6].sum()
    for w in range(nw):
        start = w_int[w, 4]
        stop = w_int[w, 5]
        if stop > start:
            _prefetch_entries(start, stop, w_int[w, 6], w_int[w, 7], index)
    if stage == 4:
        return w_int[:nw, 4].sum()
    tot = 0
    m_cap = 256
    m_tri = np.empty(m_cap, dtype=np.int64)
    m_img = np.empty((m_cap, 3), dtype=np.int64)
    m_cat = np.empty((m_cap, 3), dtype=np.int64)
    n_match = np.int64(0)
    for w in range(nw):
        start = w_int[w, 4]
        stop = w_int[w, 5]
        nc = _side_check_entries(w_side[w, 0], w_side[w, 1], w_side[w, 2], w_side[w, 3], w_side[w, 4],
                                 w_side[w, 5], w_int[w, 6], w_int[w, 7], start, stop, index, cand)
        tot += nc
        if stage == 5 or nc > tol.max_candidates:
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
            m_tri[n_match] = w_int[w, 3]
            for v in range(3):
                m_img[n_match, v] = w_int[w, v]
            m_cat[n_match, 0] = cand[c]
            n_match += 1
    if stage == 5:
        return float(tot)
    for r in range(n_match):
        row = m_cat[r, 0]
        for v in range(3):
            m_cat[r, v] = db.ids[row, v]
    if stage == 6:
        return float(m_cat[:n_match].sum())
    result = np.full(n, -1, dtype=np.int64)
    for _ in range(1 if stage == 7 else 11):
        validate(n, db.guide_unit.shape[0], n_match, m_tri, m_img, m_cat, tol, tol.min_shared,
                           tol.conflict_fails, result)
    return float(result.sum())


def main(n: int, repeats: int, sky: str, others: bool) -> None:
    cat, cam = load_hipparcos(), Camera()
    rest = []
    if others:
        names = sorted(i.name for i in available_algorithms() if i.status == "ok")
        rest = [(a, a.build(cat, cam)) for a in (get_algorithm(nm)() for nm in names if nm != "ptp")]
    alg = get_algorithm("ptp")()
    db = alg.build(cat, cam)
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                    seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(n)]
    alg.identify(db, obs[0])
    tol, params, (narrow, wide), view = alg._kernel_call(db, cam)
    post_off = {"verify": False, "confirm_fraction": 0.0, "nearest_check": False, "hypotheses": 0}
    variants = {"kernel, no records": K.params_of(view, tol._replace(max_candidates=0, **post_off)),
                "kernel, no post": K.params_of(view, tol._replace(**post_off))}
    calls = {f"stage {s}": (lambda o, s=s: stages(o.x_px, o.y_px, o.mag, params, narrow, wide, s))
             for s in range(-2, 9)}
    for k, p in variants.items():
        calls[k] = lambda o, p=p: K.identify_kernel(o.x_px, o.y_px, o.mag, p, narrow, wide)
    calls["whole kernel"] = lambda o: K.identify_kernel(o.x_px, o.y_px, o.mag, params, narrow, wide)
    for f in calls.values():
        f(obs[0])
    best = {k: np.full(n, np.inf) for k in calls}
    cold = {k: np.zeros(n) for k in calls}
    for a, d in rest:
        a.identify(d, obs[0])
    for i, o in enumerate(obs if others else []):
        for k, f in calls.items():
            for a, d in rest:
                a.identify(d, o)
            t0 = time.perf_counter_ns()
            f(o)
            cold[k][i] = (time.perf_counter_ns() - t0) / 1e3
    for _ in range(repeats):
        for i, o in enumerate(obs):
            for k, f in calls.items():
                t0 = time.perf_counter_ns()
                f(o)
                best[k][i] = min(best[k][i], (time.perf_counter_ns() - t0) / 1e3)
    for k, v in best.items():
        print(f"{sky:5s} {k:20s} warm median {np.median(v):8.1f} us  mean {v.mean():8.1f}"
              + (f"   cold median {np.median(cold[k]):8.1f} us  mean {cold[k].mean():8.1f}" if others else ""))


if __name__ == "__main__":
    if len(sys.argv) not in (4, 5):
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], len(sys.argv) == 5 and sys.argv[4] == "others")
