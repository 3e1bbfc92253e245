"""Where geometric voting's per-image time goes, every round included (issue #25, branch gvspeed).

    python benchmarks/tools/gvspeed_profile.py [N] [R]

Table 6's two skies at 1 px / 0.5 Mv (seed 0), N images (100). Each image is identified R times (5)
by ``identify`` and by ``voting_kernel`` directly (minimum kept), and ``vote_rounds`` is replayed
from Python stage by stage (minimum of R per stage and round, summed over the image's rounds): star
selection, k-vector searches (``extend_windows``), vote casting (``cast_votes``), ranking
(``rank_votes``), shortlist choice (``pick_candidates``), verification (``verify_pairwise``) and
confirmation (Wahba and reprojection, the rest of ``decide``: ``decide`` minus its ranking, choice
and verification). Each replayed stage pays one numba dispatch (~0.3-1 µs) that the kernel does not;
"wrapper" is ``identify`` minus ``voting_kernel`` (argument bundles, ``Identification``). Prints the
median and mean over images, for all images and for those needing more than one round, in µs.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from starid_algorithms.geometric_voting import kernels as gk
from starid_algorithms.geometric_voting.algorithm import _bundles, _saturates, _vote_window

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, verify_pairwise
from starid.registry import get_algorithm

STAGES = ("identify", "voting_kernel", "wrapper", "selection", "searches", "casting", "ranking", "choice",
          "verification", "confirmation", "rounds")


def _best(fn, repeats):
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        out = fn()
        best = min(best, time.perf_counter_ns() - t0)
    return best / 1e3, out


def image_stages(alg, db, o, bundles, repeats):
    """Stage times of one image (µs, summed over its rounds) as ``vote_rounds`` runs them."""
    tol, fr, rule, vtol = bundles
    like = gk.tally_like(rule)
    t = dict.fromkeys(STAGES, 0.0)
    t["identify"], _ = _best(lambda: alg.identify(db, o), repeats)
    kv, ptol, pfr, prule, pvtol = tuple(db.kv), tuple(tol), tuple(fr), tuple(rule), tuple(vtol)   # as identify
    t["voting_kernel"], _ = _best(lambda: gk.voting_kernel(o.x_px, o.y_px, o.mag, kv, db.pairs, db.degree,
                                                           db.guide_unit, db.guide_hip, ptol, pfr, prule, pvtol, like),
                                  repeats)
    t["wrapper"] = t["identify"] - t["voting_kernel"]
    v = backproject_px(o.x_px, o.y_px, fr.f_px, fr.cx_px, fr.cy_px)
    t["selection"], sel = _best(lambda: gk.select_stars(o.x_px, o.y_px, o.mag, v, tol.d_min, tol.max_stars), repeats)
    m, n, ng = sel.shape[0], v.shape[0], db.degree.shape[0]
    if m < 3:
        return t
    start, stop = np.zeros((m, m), dtype=np.int64), np.zeros((m, m), dtype=np.int64)
    tally = np.zeros((m, ng), dtype=like.dtype)
    stamp = np.zeros(ng, dtype=np.uint16)
    listed, n_listed = np.empty((m, ng + 1), dtype=db.pairs.dtype), np.zeros(m, dtype=np.int64)   # as the kernel
    rows, votes = np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64)
    step = rule.round_voters if rule.round_voters >= 3 else m
    done, last_level = 0, 0
    while True:
        upto = min(m, done + (step if done == 0 else rule.round_step))
        t["rounds"] += 1
        dt, _ = _best(lambda: gk.extend_windows(v, sel, db.kv, vtol, start.copy(), stop.copy(),  # noqa: B023
                                                 np.int64(done), np.int64(upto)), repeats)  # noqa: B023
        t["searches"] += dt
        gk.extend_windows(v, sel, db.kv, vtol, start, stop, np.int64(done), np.int64(upto))
        level = max(min(3, upto - 1), (upto - 1) // 3 + 1)     # as vote_rounds
        if level != last_level:
            for a in range(done):
                keep = [g for g in listed[a, :n_listed[a]] if tally[a, g] >= level]
                listed[a, :len(keep)] = keep
                n_listed[a] = len(keep)
            last_level = level

        def cast(copy=True):
            ta, st, li, nl = (tally.copy(), stamp.copy(), listed.copy(), n_listed.copy()) if copy else \
                (tally, stamp, listed, n_listed)
            t0 = time.perf_counter_ns()
            gk.cast_votes(start, stop, db.pairs, np.int64(done), np.int64(upto),  # noqa: B023
                          rule.once_per_pair, st, ta, np.int64(level), li, nl)  # noqa: B023
            return time.perf_counter_ns() - t0
        t["casting"] += min(cast() for _ in range(repeats)) / 1e3
        cast(copy=False)
        args = (v, sel, np.int64(upto), start, stop, tally, db.degree, vtol, rule.expected,
                rule.once_per_pair and rule.saturate, rule.n_candidates, np.int64(level), listed, n_listed)
        dt, (cand_row, cand_votes) = _best(lambda: gk.rank_votes(*args), repeats)      # noqa: B023
        t["ranking"] += dt
        voters = sel[:upto]
        if rule.n_candidates > 1:
            dt, (best_row, _) = _best(lambda: gk.pick_candidates(v, voters, cand_row, cand_votes,  # noqa: B023
                                                                 db.guide_unit, tol.eps), repeats)
            t["choice"] += dt
        else:
            best_row = cand_row[:, 0].copy()
        cand = np.full(n, -1, dtype=np.int64)
        cand[voters] = best_row
        dt, _ = _best(lambda: verify_pairwise(v, cand, db.guide_unit, tol.eps, rule.min_support,  # noqa: B023
                                              rule.min_fraction), repeats)
        t["verification"] += dt
        dt, (ok, _) = _best(lambda: gk.decide(v, sel, np.int64(upto), start, stop, tally, db.degree,  # noqa: B023
                                               db.guide_unit, tol, fr, rule, np.int64(level),  # noqa: B023
                                               listed, n_listed,
                                               rows, votes, vtol), repeats)
        t["confirmation"] += dt      # decide's whole time; main() subtracts its ranking, choice and verification
        if ok or upto == m:
            break
        done = upto
    return t


def main(n: int, repeats: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    alg = get_algorithm("geometric_voting")()
    db = alg.build(cat, cam)
    alg.identify(db, Simulator(cat, cam, SimConfig(), seed=1).generate(1).observation(0))
    bundles = _bundles(alg, cam, db.c_max, db.d_min_deg, _saturates(db), _vote_window(db))
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        rows = [image_stages(alg, db, trials.observation(i, truth=False), bundles, repeats) for i in range(n)]
        for r in rows:
            r["confirmation"] -= r["ranking"] + r["choice"] + r["verification"]
        many = [r for r in rows if r["rounds"] > 1]
        print(f"{sky} sky, {n} images ({len(many)} need more than one round): median / mean µs "
              f"(all images) | median / mean (more than one round)")
        for s in STAGES:
            a = np.array([r[s] for r in rows])
            b = np.array([r[s] for r in many]) if many else np.zeros(1)
            print(f"  {s:14s} {np.median(a):8.1f} {a.mean():8.1f} | {np.median(b):8.1f} {b.mean():8.1f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100, int(sys.argv[2]) if len(sys.argv) > 2 else 5)
