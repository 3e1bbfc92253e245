"""Where pyramid's and geometric voting's per-image time goes (issue #25), stage by stage.

    python benchmarks/tools/pyramid_profile.py [N] [R]

Table 6's paper's sky at 1 px / 0.5 Mv (seed 0), N images (100), each stage called R times (5)
from Python on the same inputs and the minimum kept; prints the median over images, in µs. The
stages are the kernels ``pyramid_kernel`` / ``voting_kernel`` call, run one by one on the inputs
the full call gives them (pyramid: images decided by their first triad, the median case), so each
includes one numba dispatch (~0.3-1 µs) that the full kernel does not pay; "wrapper" is
``identify`` minus the kernel called directly.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from starid_algorithms.geometric_voting import kernels as gk
from starid_algorithms.geometric_voting.algorithm import _bundles as gv_bundles
from starid_algorithms.geometric_voting.algorithm import _saturates, _vote_window
from starid_algorithms.pyramid import kernels as pk
from starid_algorithms.pyramid.algorithm import _bundles as pyr_bundles

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, reproject_assign, verify_pairwise, wahba_rows
from starid.registry import get_algorithm


def tmin(fn, items, repeats):
    out = []
    for item in items:
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter_ns()
            fn(item)
            best = min(best, time.perf_counter_ns() - t0)
        out.append(best / 1e3)
    return float(np.median(out))


def pyramid_stages(cat, cam, obs, repeats):
    alg = get_algorithm("pyramid")()
    db = alg.build(cat, cam)
    alg = alg.derived(cat, cam)
    alg.identify(db, obs[0])
    tol, fr, cap = pyr_bundles(alg, cam, db.c_max, db.d_min_deg)

    def kernel(o):
        return pk.pyramid_kernel(o.x_px, o.y_px, o.mag, db.kv, db.pairs, db.nbr, db.nbr_chord, db.nbr_start,
                                 db.guide_unit, db.guide_hip, tol, fr, alg.unique_triangle, alg.accept_triangle, cap)

    first = [o for o in obs if kernel(o)[4][0] == 1 and kernel(o)[3][0] >= 0]
    prep = {}
    for o in first:
        v = backproject_px(o.x_px, o.y_px, fr.f_px, fr.cx_px, fr.cy_px)
        sel = pk.select_stars(o.x_px, o.y_px, o.mag, v, tol.d_min, tol.max_stars)
        m = sel.shape[0]
        start, stop = np.full((m, m), -1, dtype=np.int64), np.zeros((m, m), dtype=np.int64)
        w = np.zeros(5, dtype=np.int64)
        for a, b in ((0, 1), (1, 2), (0, 2)):
            pk._window(v, sel, np.int64(a), np.int64(b), db.kv, tol, start, stop, w)
        ng = db.guide_unit.shape[0]
        lists = (np.full(ng, -1, np.int32), np.zeros(ng, np.int32), np.empty(2 * tol.max_window, np.int32),
                 np.empty(2 * tol.max_window, np.int32))
        tri = np.empty((cap, 3), dtype=np.int64)
        n_tri = pk.triad_triangles(v, sel[0], sel[1], sel[2], (start[0, 1], stop[0, 1]), (start[0, 2], stop[0, 2]),
                                   db.pairs, db.guide_unit, tol.eps, lists, np.int64(1), tri)
        pos = np.arange(3, dtype=np.int64)
        fourth = [pk.fourth_star(v, sel, pos, tri[t], db.nbr, db.nbr_chord, db.nbr_start, db.guide_unit, tol.eps)
                  for t in range(n_tri)]
        cands = [(np.array([sel[0], sel[1], sel[2], sel[r]], dtype=np.int64),
                  np.array([tri[t, 0], tri[t, 1], tri[t, 2], big_r], dtype=np.int64))
                 for t, (r, big_r) in enumerate(fourth) if r >= 0]
        prep[id(o)] = (v, sel, start, stop, lists, tri, n_tri, pos, cands)
    rows_buf = {id(o): np.empty(o.x_px.shape[0], dtype=np.int64) for o in first}

    def windows(o):
        v, sel = prep[id(o)][:2]
        m = sel.shape[0]
        start, stop = np.full((m, m), -1, dtype=np.int64), np.zeros((m, m), dtype=np.int64)
        w = np.zeros(5, dtype=np.int64)
        for a, b in ((0, 1), (1, 2), (0, 2)):
            pk._window(v, sel, np.int64(a), np.int64(b), db.kv, tol, start, stop, w)

    tick = [1]

    def triangles(o):
        v, sel, start, stop, lists, tri = prep[id(o)][:6]
        tick[0] += 1        # a new stamp per call: the scratch lists are valid only where stamp == tick
        pk.triad_triangles(v, sel[0], sel[1], sel[2], (start[0, 1], stop[0, 1]), (start[0, 2], stop[0, 2]), db.pairs,
                           db.guide_unit, tol.eps, lists, np.int64(tick[0]), tri)

    def dispatch(o):
        v, sel, start, stop = prep[id(o)][:4]
        pk._window(v, sel, np.int64(0), np.int64(1), db.kv, tol, start, stop, np.zeros(5, dtype=np.int64))

    def fourth(o):
        v, sel, _, _, _, tri, n_tri, pos, _ = prep[id(o)]
        for t in range(n_tri):
            pk.fourth_star(v, sel, pos, tri[t], db.nbr, db.nbr_chord, db.nbr_start, db.guide_unit, tol.eps)

    def confirm(o):
        v = prep[id(o)][0]
        for star, row in prep[id(o)][8]:
            pk._confirm(v, star, row, db.guide_unit, tol, fr, rows_buf[id(o)])

    stages = [
        ("identify (all)", lambda o: alg.identify(db, o)),
        ("pyramid_kernel", kernel),
        ("back-projection", lambda o: backproject_px(o.x_px, o.y_px, fr.f_px, fr.cx_px, fr.cy_px)),
        ("star selection", lambda o: pk.select_stars(o.x_px, o.y_px, o.mag, prep[id(o)][0], tol.d_min,
                                                     tol.max_stars)),
        ("k-vector searches (3 windows)", windows),
        ("  of which: one call's dispatch alone", dispatch),
        ("triangle search (triad_triangles)", triangles),
        ("fourth star (each triangle)", fourth),
        ("confirmation (Wahba, 2 reprojections)", confirm),
    ]
    n_cands = np.median([len(prep[id(o)][8]) for o in first])
    print(f"pyramid: {len(first)} of {len(obs)} images decided by their first triad; median candidate "
          f"pyramids {n_cands:.0f}, triangles {np.median([prep[id(o)][6] for o in first]):.0f}")
    for name, fn in stages:
        print(f"  {name:40s} {tmin(fn, first, repeats):8.1f} µs")


def voting_stages(cat, cam, obs, repeats):
    alg = get_algorithm("geometric_voting")()
    db = alg.build(cat, cam)
    alg.identify(db, obs[0])
    tol, fr, rule, vtol = gv_bundles(alg, cam, db.c_max, db.d_min_deg, _saturates(db), _vote_window(db))
    like = gk.tally_like(rule)

    def kernel(o):
        return gk.voting_kernel(o.x_px, o.y_px, o.mag, db.kv, db.pairs, db.degree, db.guide_unit, db.guide_hip, tol,
                                fr, rule, vtol, like)

    one = [o for o in obs if kernel(o)[5][0] == 1 and kernel(o)[4]]
    ng = db.degree.shape[0]
    k = rule.round_voters
    prep = {}
    for o in one:
        v = backproject_px(o.x_px, o.y_px, fr.f_px, fr.cx_px, fr.cy_px)
        sel = gk.select_stars(o.x_px, o.y_px, o.mag, v, tol.d_min, tol.max_stars)
        m = sel.shape[0]
        start, stop = np.zeros((m, m), dtype=np.int64), np.zeros((m, m), dtype=np.int64)
        gk.extend_windows(v, sel, db.kv, vtol, start, stop, np.int64(0), np.int64(k))
        tally = np.zeros((m, ng), dtype=like.dtype)
        listed = np.empty((m, ng), dtype=db.pairs.dtype)
        n_listed = np.zeros(m, dtype=np.int64)
        gk.cast_votes(start, stop, db.pairs, np.int64(0), np.int64(k), rule.once_per_pair,
                      np.zeros(ng, dtype=np.uint16), tally, np.int64(3), listed, n_listed)
        cand_row, cand_votes = gk.rank_votes(v, sel, np.int64(k), start, stop, tally, db.degree, vtol, rule.expected,
                                             rule.once_per_pair and rule.saturate, rule.n_candidates, np.int64(3),
                                             listed, n_listed)
        best_row, _ = gk.pick_candidates(v, sel[:k], cand_row, cand_votes, db.guide_unit, tol.eps)
        cand = np.full(v.shape[0], -1, dtype=np.int64)
        cand[sel[:k]] = best_row
        keep = verify_pairwise(v, cand, db.guide_unit, tol.eps, rule.min_support, rule.min_fraction)
        rows = np.where(keep, cand, -1)
        att = wahba_rows(v, rows, db.guide_unit)
        prep[id(o)] = (v, sel, start, stop, tally, listed, n_listed, cand_row, cand_votes, cand, rows, att)

    def windows(o):
        v, sel = prep[id(o)][:2]
        m = sel.shape[0]
        gk.extend_windows(v, sel, db.kv, vtol, np.zeros((m, m), dtype=np.int64), np.zeros((m, m), dtype=np.int64),
                          np.int64(0), np.int64(k))

    def cast(o):
        v, sel, start, stop = prep[id(o)][:4]
        m = sel.shape[0]
        gk.cast_votes(start, stop, db.pairs, np.int64(0), np.int64(k), rule.once_per_pair,
                      np.zeros(ng, dtype=np.uint16), np.zeros((m, ng), dtype=like.dtype), np.int64(3),
                      np.empty((m, ng), dtype=db.pairs.dtype), np.zeros(m, dtype=np.int64))

    def rank(o):
        v, sel, start, stop, tally, listed, n_listed = prep[id(o)][:7]
        gk.rank_votes(v, sel, np.int64(k), start, stop, tally, db.degree, vtol, rule.expected,
                      rule.once_per_pair and rule.saturate, rule.n_candidates, np.int64(3), listed, n_listed)

    def pick(o):
        v, sel = prep[id(o)][:2]
        gk.pick_candidates(v, sel[:k], prep[id(o)][7], prep[id(o)][8], db.guide_unit, tol.eps)

    def verify(o):
        v = prep[id(o)][0]
        verify_pairwise(v, prep[id(o)][9], db.guide_unit, tol.eps, rule.min_support, rule.min_fraction)

    def confirm(o):
        v, rows = prep[id(o)][0], prep[id(o)][10]
        seen = np.empty(v.shape[0], dtype=np.int64)
        a = wahba_rows(v, rows, db.guide_unit)
        for _ in range(2):
            reproject_assign(a, v, db.guide_unit, tol.c_fov + tol.eps, tol.eps, seen, fr.f_px, fr.cx_px, fr.cy_px,
                             fr.width_px, fr.height_px)
            a = wahba_rows(v, seen, db.guide_unit)

    stages = [
        ("identify (all)", lambda o: alg.identify(db, o)),
        ("voting_kernel", kernel),
        ("star selection", lambda o: gk.select_stars(o.x_px, o.y_px, o.mag, prep[id(o)][0], tol.d_min,
                                                     tol.max_stars)),
        ("k-vector searches (10 windows)", windows),
        ("voting (cast_votes, incl. counters)", cast),
        ("ranking (rank_votes)", rank),
        ("shortlist choice (pick_candidates)", pick),
        ("verification (verify_pairwise)", verify),
        ("confirmation (Wahba x3, 2 reprojections)", confirm),
    ]
    print(f"geometric_voting: {len(one)} of {len(obs)} images decided in the first round ({k} voters)")
    for name, fn in stages:
        print(f"  {name:40s} {tmin(fn, one, repeats):8.1f} µs")


def main(n: int, repeats: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES["paper"]),
                    seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(n)]
    pyramid_stages(cat, cam, obs, repeats)
    voting_stages(cat, cam, obs, repeats)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100, int(sys.argv[2]) if len(sys.argv) > 2 else 5)
