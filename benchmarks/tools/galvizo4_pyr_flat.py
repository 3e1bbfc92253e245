"""PYR at 12 false stars: hoku's flattened-candidate triangle query against our catalog-triangle join.

Galvizo & Lim print 0.995 for Pyramid at 12 false stars; ``pyramid:galvizo2018`` gets 1.000. hoku's
``Pyramid::find_catalog_stars`` does not join the three pair windows into catalog triangles: it
flattens each window's pairs into a sorted list of stars and takes T_i = ij & ik, T_j = (ij & jk) - T_i,
T_k = (ik & jk) - T_i - T_j (multiset intersections, ``std::set_intersection``), accepting the triad
when each holds one star -- a trio that need not be a catalog triangle, and with no chirality test.

This script runs the reading's own loop in Python on the experiment's images (the false-star study,
no noise, seed 0: the same images as ``starid reproduce galvizo2018``) with the triangle step swapped:

* ``join``: pyramid's ``triad_triangles`` (the plugin; checked to give the plugin's ids image by image);
* ``flat``: hoku's flattened sets (one candidate trio when |T_i| = |T_j| = |T_k| = 1), then the
  reading's own fourth star and confirmation;
* ``flat_hoku``: hoku's flattened sets and hoku's verification (``Pyramid::verification``): one
  random other image star E, T_e = the stars common to the flattened IE, JE and KE windows; accepted
  when |T_e| = 1 and I, J, K, T_e lie within the field of view; only the trio is reported.

    python benchmarks/tools/galvizo4_pyr_flat.py TRIALS FALSE_STARS [ORDER]

ORDER ``mag`` (default): the stars brightest first, as the reading; ``random``: the triads run over
the detections in a random order (hoku's images list their stars unsorted; the plugin row is then
the plugin's own, brightest-first run).
"""

from __future__ import annotations

import math
import sys
from collections import Counter

import numpy as np
from starid_algorithms.pyramid.algorithm import _bundles
from starid_algorithms.pyramid.kernels import _confirm, fourth_star, pair_windows, select_stars, triad_triangles

from starid import SimConfig, Simulator
from starid.catalog import load_hipparcos
from starid.experiment import Variant
from starid.experiment.spec import sim_settings
from starid.experiments import galvizo2018 as g
from starid.kernels import backproject_px
from starid.scoring import bijection_accuracy


def flat_common(*windows):
    """Multiset intersection of the flattened (sorted) star lists of the given pair windows."""
    out = None
    for w in windows:
        c = Counter(w.ravel().tolist())
        out = c if out is None else out & c
    return out


def minus(c, removed):
    return [s for s, k in sorted(c.items()) for _ in range(k) if s not in removed]


def run(obs, algo, db, mode, rng, rank):
    cam = obs.camera
    tol, frame, max_tri = _bundles(algo, cam, db.c_max, db.d_min_deg)
    n = len(obs)
    rows = np.full(n, -1, dtype=np.int64)
    v = backproject_px(obs.x_px, obs.y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(obs.x_px, obs.y_px, rank, v, tol.d_min, tol.max_stars)
    m = sel.size
    if m < 4:
        return rows
    start, stop = pair_windows(v, sel, db.kv, tol)

    def win(a, b):
        return db.pairs[start[a, b]:stop[a, b]].astype(np.int64)

    n_guide = db.guide_unit.shape[0]
    cap = 2 * max(tol.max_window, 1)
    lists = (np.full(n_guide, -1, np.int32), np.zeros(n_guide, np.int32), np.empty(cap, np.int32),
             np.empty(cap, np.int32))
    out = np.empty((max(max_tri, 1), 3), dtype=np.int64)
    fov = 2.0 * cam.half_diagonal_rad
    n_triads = 0
    for dj in range(1, m - 1):
        for dk in range(1, m - dj):
            for i in range(0, m - dj - dk):
                if n_triads >= tol.max_triads:
                    return np.full(n, -1, dtype=np.int64)
                j, k = i + dj, i + dj + dk
                n_triads += 1
                if not (stop[i, j] > start[i, j] and stop[j, k] > start[j, k] and stop[i, k] > start[i, k]):
                    continue
                if mode == "join":
                    n_tri = triad_triangles(v, sel[i], sel[j], sel[k], (start[i, j], stop[i, j]),
                                            (start[i, k], stop[i, k]), db.pairs, db.guide_unit, tol.eps, lists,
                                            n_triads, out)
                    if n_tri != 1 or n_tri > max_tri:      # the reading: unique_triangle
                        continue
                    tri = out[:1].copy()
                else:
                    t_i = minus(flat_common(win(i, j), win(i, k)), set())
                    t_j = minus(flat_common(win(i, j), win(j, k)), set(t_i))
                    t_k = minus(flat_common(win(i, k), win(j, k)), set(t_i) | set(t_j))
                    if len(t_i) != 1 or len(t_j) != 1 or len(t_k) != 1:
                        continue
                    tri = np.array([[t_i[0], t_j[0], t_k[0]]], dtype=np.int64)
                if mode == "flat_hoku":
                    others = [q for q in range(m) if q not in (i, j, k)]
                    e = others[rng.integers(len(others))]
                    ws = []
                    for a in (i, j, k):
                        lo, hi = (a, e) if a < e else (e, a)
                        ws.append(win(lo, hi))
                    t_e = minus(flat_common(*ws), set())
                    if len(t_e) != 1:
                        continue
                    four = db.guide_unit[[*tri[0], t_e[0]]]
                    ang = np.arccos(np.clip(four @ four.T, -1.0, 1.0))
                    if ang.max() > fov:                         # hoku's within_angle(fov)
                        continue
                    for a, p in enumerate((i, j, k)):
                        rows[sel[p]] = tri[0, a]
                    return rows
                tri_pos = np.array([i, j, k], dtype=np.int64)
                n_ok, found = 0, None
                for t in range(tri.shape[0]):
                    r, big_r = fourth_star(v, sel, tri_pos, tri[t], db.nbr, db.nbr_chord, db.nbr_start,
                                           db.guide_unit, tol.eps)
                    if r < 0:
                        continue
                    star = np.array([sel[i], sel[j], sel[k], sel[r]], dtype=np.int64)
                    row = np.array([*tri[t], big_r], dtype=np.int64)
                    trial = np.empty(n, dtype=np.int64)
                    ok, _ = _confirm(v, star, row, db.guide_unit, tol, frame, trial)
                    if ok:
                        n_ok += 1
                        found = trial
                if n_ok == 1:
                    return found
    return rows


def first_r(obs, algo, db, rank):
    """|R| of the first triad (the three first stars of ``rank``): the join's catalog triangles, and
    hoku's ``Pyramid::query`` (every combination of T_i, T_j, T_k: |T_i| |T_j| |T_k|)."""
    cam = obs.camera
    tol, _, _ = _bundles(algo, cam, db.c_max, db.d_min_deg)
    v = backproject_px(obs.x_px, obs.y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(obs.x_px, obs.y_px, rank, v, tol.d_min, tol.max_stars)
    start, stop = pair_windows(v, sel[:3], db.kv, tol)
    ij, ik, jk = (db.pairs[start[a, b]:stop[a, b]].astype(np.int64) for a, b in ((0, 1), (0, 2), (1, 2)))
    n_guide = db.guide_unit.shape[0]
    cap = 2 * max(tol.max_window, 1)
    lists = (np.full(n_guide, -1, np.int32), np.zeros(n_guide, np.int32), np.empty(cap, np.int32),
             np.empty(cap, np.int32))
    out = np.empty((64, 3), dtype=np.int64)
    join = 0
    if len(ij) and len(ik) and len(jk):
        join = triad_triangles(v, sel[0], sel[1], sel[2], (start[0, 1], stop[0, 1]), (start[0, 2], stop[0, 2]),
                               db.pairs, db.guide_unit, tol.eps, lists, 1, out)
    t_i = minus(flat_common(ij, ik), set())
    t_j = minus(flat_common(ij, jk), set(t_i))
    t_k = minus(flat_common(ik, jk), set(t_i) | set(t_j))
    return join, len(t_i) * len(t_j) * len(t_k)


def main() -> None:
    trials, false_stars = int(sys.argv[1]), int(sys.argv[2])
    order = sys.argv[3] if len(sys.argv) > 3 else "mag"
    exp = g.experiment(trials=trials, seed=0)
    camera = exp.make_camera()
    catalog = load_hipparcos()
    config = SimConfig(**sim_settings(exp.sim, {"false_stars": false_stars, "sigma_px": 0.0}))
    sim = Simulator(catalog, camera, config, seed=0)
    images = sim.generate(trials, 0)
    algo = Variant.as_reading("pyramid", "galvizo2018").make().resolved(sim.config)
    db = algo.build(catalog, camera)
    rng = np.random.default_rng(0)
    if false_stars == 0:
        sizes = np.array([first_r(images.observation(t), algo, db, images.observation(t).mag) for t in range(trials)])
        for name, col in (("join", 0), ("hoku's query", 1)):
            r = sizes[:, col]
            one, none, more = int((r == 1).sum()), int((r == 0).sum()), int((r > 1).sum())
            print(f"first triad (brightest three), {name}: |R| = 1 in {one} of {trials} (S = "
                  f"{2000 * one / trials:.0f} of 2,000; printed 1501), |R| = 0 in {none}, |R| > 1 in {more}")
    acc = {mode: [] for mode in ("plugin", "join", "flat", "flat_hoku")}
    wrong = {mode: 0 for mode in acc}
    differ = {mode: 0 for mode in acc}  # images whose ids differ from the join's
    for t in range(trials):
        obs = images.observation(t)
        hips = {"plugin": algo.identify(db, obs).hip}
        rank = obs.mag if order == "mag" else rng.permutation(len(obs)).astype(np.float64)
        for mode in ("join", "flat", "flat_hoku"):
            rows = run(obs, algo, db, mode, rng, rank)
            hips[mode] = np.where(rows >= 0, db.guide_hip[np.maximum(rows, 0)], -1)
        if order == "mag":
            assert np.array_equal(hips["join"], hips["plugin"]), f"image {t}: the Python loop is not the plugin's"
        for mode, hip in hips.items():
            named = hip >= 0
            correct = named & (hip == obs.truth_hip)
            acc[mode].append(bijection_accuracy([correct.sum()], [named.sum()])[0])
            wrong[mode] += int(np.any(named & ~correct))
            differ[mode] += int(not np.array_equal(hip, hips["join"]))
    print(f"{trials} images, {false_stars} false stars, no noise, order {order} (seed 0; printed PYR at 0 / 6 / 12 "
          "false stars: 0.999 / 0.999 / 0.995)")
    for mode, a in acc.items():
        a = np.asarray(a)
        half = 1.96 * a.std(ddof=1) / math.sqrt(a.size)
        print(f"{mode:10s} paper accuracy {a.mean():.4f} +-{half:.4f}; images with a wrong id {wrong[mode]}, "
              f"with other ids than join's {differ[mode]}")


if __name__ == "__main__":
    main()
