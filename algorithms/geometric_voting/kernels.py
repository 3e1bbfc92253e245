"""numba kernels of geometric voting (Kolomenkin, Pollak, Shimshoni & Lindenbaum 2008).

The star selection is the Pyramid plugin's (:mod:`starid_algorithms.pyramid.kernels`), and the
k-vector windows of the image pairs are its ``pair_windows`` searched round by round
(:func:`extend_windows`), over the same star-pair database.

Bundles (``typing.NamedTuple``, passed to numba as tuples): ``kv`` (:class:`starid.kernels.KVector`),
:class:`~starid_algorithms.pyramid.kernels.PairTol` (tolerances and work limits),
:class:`~starid.kernels.Frame` (camera geometry) and :class:`VoteRule` (the
voting and verification choices).

Vote counters: one ``(m, n_guide)`` array per call (``m`` = selected stars, one row per star, so
the rows of a first round of few voters stay in the L1 cache), uint8 with ``once_per_pair`` (at
most ``m - 1 <= 254`` votes), int32 otherwise; uint16 marks of the last voting image pair per
catalog star. Everything is allocated per call, nothing is kept between calls.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from starid_algorithms.pyramid.kernels import PairTol, select_stars

from starid.kernels import (
    Frame,
    KVector,
    backproject_px,
    chord_rows,
    kvector_query,
    reproject_assign,
    verify_pairwise,
    wahba_rows,
)
from starid.kernels.jit import inline_inner, inline_kernel, kernel

#: names of the per-image work counters :func:`voting_kernel` returns (``Identification.counters``):
#: voting rounds (each one choice, verification and confirmation), image pairs with a non-empty
#: k-vector window, and the catalog pairs read from those windows (each gives up to four votes)
WORK_COUNTERS = ("rounds", "windows", "pairs")


class VoteRule(NamedTuple):
    """The voting and verification choices of one identification (see ``GeometricVoting``).

    once_per_pair : one image pair gives a catalog star at most one vote.
    expected : rank catalog stars by their votes above chance (degree x w).
    n_candidates : shortlist per image star (1 = the paper's single winner).
    round_voters : the selected stars vote in rounds, the brightest ``round_voters`` first and
        ``round_step`` more in each further round; the first verified and confirmed result is
        returned (``round_voters`` 0 = one round of all).
    round_step : stars joining in each further round.
    min_support, min_fraction : ``starid.kernels.verify_pairwise``'s agreement rule.
    report_all : report every star the confirming reprojection identified (else only the
        verified voters).
    saturate : with ``expected`` and ``once_per_pair``, a catalog star's chance votes are
        ``sum_b 1 - exp(-degree p_b)`` (at most one vote per image pair) instead of the linear
        ``degree sum_b p_b`` (see :func:`rank_votes`).
    """

    once_per_pair: bool
    expected: bool
    n_candidates: int
    round_voters: int
    round_step: int
    min_support: int
    min_fraction: float
    report_all: bool
    saturate: bool


@kernel
def cast_votes(start, stop, pairs, b_lo, b_hi, once_per_pair, stamp, tally, level, listed, n_listed):
    """Add the votes of the image pairs (a, b), a < b, ``b_lo <= b < b_hi`` to ``tally``.

    Each catalog pair (I, J) in the k-vector window ``[start[a, b], stop[a, b])`` is a possible
    identity of the image pair, so I and J each get a vote for a and for b (the paper's voting:
    both catalog stars of a matching pair vote for both image stars) -- ``tally[a, g]`` counts
    the votes of guide row g for selected star a. With ``once_per_pair`` one image pair gives a
    catalog star at most one vote, however many pairs of its window contain it: ``stamp[g]``
    holds the last image pair (``256 a + b + 1``, unique per pair: at most 255 stars) that voted for g. A window is
    read once for both of its stars: first reduced to its distinct catalog stars (the stamp test as
    a 0/1 step of the write position, no branch), then their votes counted, which is 1.7x faster
    than testing, stamping and counting each pair's stars in one loop
    (``benchmarks/tools/gvspeed_cast.py``). The calls over ``[0, m1)`` then ``[m1, m)`` add up to
    the votes of all pairs of the first ``m`` stars.

    A catalog star whose votes for star a reach ``level`` (> 0) is appended to
    ``listed[a, :n_listed[a]]`` (votes grow by one, so once), so that :func:`rank_votes` need not
    scan every catalog star; ``level`` = 0 lists nothing. ``listed`` with one column more than
    ``tally`` lets the pairs of a star that has voted with ``level`` others or more list without a
    branch (a store to the next free place, always, and a 0/1 step).
    """
    one = tally.dtype.type(1)       # counts stay in the counters' dtype
    lvl = tally.dtype.type(level)
    # the store-and-step listing writes one place past the last listed star: only with a spare column
    spare = level > 0 and listed.shape[1] > tally.shape[1]
    ends = pairs.reshape(-1)        # the window [lo, hi) of pairs is the run [2 lo, 2 hi) of their stars
    # + 1: the distinct-star pass writes one place past the last distinct star
    uniq = np.empty(tally.shape[1] + 1 if once_per_pair else 0, dtype=pairs.dtype)
    for b in range(b_lo, b_hi):
        tb = tally[b]
        for a in range(b):
            lo = 2 * start[a, b]
            hi = 2 * stop[a, b]
            if hi <= lo:
                continue
            ta = tally[a]
            if once_per_pair:
                # first the window's distinct catalog stars, then their votes: two short loops run
                # faster than one that tests, stamps and counts each star in turn
                pair_id = np.uint16(a * 256 + b + 1)
                n_uniq = 0
                for p in range(lo, hi):
                    g = ends[p]
                    uniq[n_uniq] = g
                    n_uniq += stamp[g] != pair_id
                    stamp[g] = pair_id
                if b > level and spare:
                    # b has voted with ``level`` stars or more, so a count often reaches the level
                    # here: the listing is a store to the next free place and a 0/1 step
                    # (a branch taken this often is mispredicted: 2x slower over all rounds)
                    la = listed[a]
                    lb = listed[b]
                    na = n_listed[a]
                    nb = n_listed[b]
                    for i in range(n_uniq):
                        g = uniq[i]
                        x = ta[g] + one
                        y = tb[g] + one
                        ta[g] = x
                        tb[g] = y
                        la[na] = g
                        na += x == lvl
                        lb[nb] = g
                        nb += y == lvl
                    n_listed[a] = na
                    n_listed[b] = nb
                    continue
                for i in range(n_uniq):
                    g = uniq[i]
                    x = ta[g] + one
                    y = tb[g] + one
                    ta[g] = x
                    tb[g] = y
                    if x == lvl:
                        listed[a, n_listed[a]] = g
                        n_listed[a] += 1
                    if y == lvl:
                        listed[b, n_listed[b]] = g
                        n_listed[b] += 1
            else:
                for p in range(lo, hi):
                    g = ends[p]
                    x = ta[g] + one
                    y = tb[g] + one
                    ta[g] = x
                    tb[g] = y
                    if x == lvl:
                        listed[a, n_listed[a]] = g
                        n_listed[a] += 1
                    if y == lvl:
                        listed[b, n_listed[b]] = g
                        n_listed[b] += 1


@inline_kernel
def chance_votes(chance, p_b, n_b, d):
    """The votes a catalog star with ``d`` neighbours collects by chance when one image pair gives it
    at most one vote (``once_per_pair``): ``sum_b 1 - exp(-d p_b)`` over the star's image pairs b,
    ``p_b`` = the chance that one given neighbour falls in pair b's window. Memoised per degree in
    ``chance`` (-1 = not yet computed)."""
    if chance[d] < 0.0:
        e = 0.0
        for i in range(n_b):
            e -= np.expm1(-(p_b[i] * d))
        chance[d] = e
    return chance[d]


@kernel
def rank_votes(v_cam, sel, n_voters, start, stop, tally, degree, tol, expected, saturate, n_keep, level,
               listed, n_listed):
    """Each of the first ``n_voters`` selected stars' ``n_keep`` best catalog stars, from ``tally``.

    Returns ``(cand_row, cand_votes)``, shape ``(n_voters, n_keep)``: most votes first, ties to the
    lowest guide row (``cand_row[a, 0]`` is the paper's choice, the "first maximum"); unused slots
    are -1. With ``expected`` (reconstruction) "best" is the excess over the votes a catalog star
    collects by chance, ``votes - degree[g] * w_a``: ``w_a = sum_b 4 eps c_ab / c_max^2`` (over the
    voters b whose pair with a has a window) is the probability that one given neighbour of a
    catalog star falls in the windows of star a's pairs (pair distances spread as in a disc of
    radius ``c_max``), ``degree[g]`` the star's number of neighbours -- so a star in dense sky does
    not win on its many neighbours alone.
    With ``saturate`` the chance votes are ``sum_b 1 - exp(-degree[g] p_b)``, ``p_b = 4 eps c_ab /
    c_max^2`` (:func:`chance_votes`): with ``once_per_pair`` a star gets at most one vote per image
    pair, and the linear ``degree[g] * w_a`` overstates its chance votes once ``degree p_b`` is not
    small (wide windows: noise beyond the 1 px floor on coarse pixels).

    With ``level`` > 0 only the stars :func:`cast_votes` listed (votes >= ``level``) are ranked
    first; as a score never exceeds the votes, that is the exact answer when the list fills all
    ``n_keep`` places with scores above ``level - 1`` -- or, with linear chance votes, above
    ``level - 1 - w_a min(degree)``, the most an unlisted star can score. Otherwise the unlisted
    voted stars are offered to the same shortlist (one scan of the counters; ``level`` = 0: every
    voted star, in row order). The shortlist is a top-``n_keep`` under (score, then lowest row), so
    the order the stars are offered in does not change it.
    """
    n_guide = tally.shape[1]
    cand_row = np.full((n_voters, n_keep), -1, dtype=np.int64)
    cand_votes = np.zeros((n_voters, n_keep), dtype=np.int64)
    score = np.full((n_voters, n_keep), -np.inf)
    last = n_keep - 1
    saturate = expected and saturate
    p_b = np.empty(n_voters)
    n_chance = 1
    if saturate and n_guide > 0:    # np.max(degree) + 1, a loop: numpy's reduction costs ~0.3 CPU s to compile
        deg_max = np.int64(degree[0])
        for g in range(1, degree.shape[0]):
            deg_max = max(deg_max, np.int64(degree[g]))
        n_chance = deg_max + 1
    chance = np.empty(n_chance)
    deg_min = -1                    # the catalog's smallest degree, found when first needed
    for a in range(n_voters):
        w_a = 0.0
        n_b = 0
        if expected:
            for b in range(n_voters):
                if b != a and stop[a, b] > start[a, b]:
                    p = 4.0 * tol.eps * chord_rows(v_cam, sel[a], v_cam, sel[b]) / (tol.c_max * tol.c_max)
                    w_a += p
                    p_b[n_b] = p
                    n_b += 1
        if saturate:
            chance[:] = -1.0
        if level > 0:
            for i in range(n_listed[a]):
                g = np.int64(listed[a, i])
                c = np.int64(tally[a, g])
                if c < score[a, last]:          # the score is at most the votes
                    continue
                x = c - (chance_votes(chance, p_b, n_b, degree[g]) if saturate else w_a * degree[g])
                if x < score[a, last] or (x == score[a, last] and g > cand_row[a, last]):
                    continue
                t = last
                while t > 0 and (score[a, t - 1] < x or (score[a, t - 1] == x and cand_row[a, t - 1] > g)):
                    score[a, t] = score[a, t - 1]
                    cand_votes[a, t] = cand_votes[a, t - 1]
                    cand_row[a, t] = cand_row[a, t - 1]
                    t -= 1
                score[a, t] = x
                cand_votes[a, t] = c
                cand_row[a, t] = g
            if cand_row[a, last] >= 0 and score[a, last] > level - 1:
                continue
            # a tighter bound, linear chance votes only: an unlisted star has at most level - 1
            # votes and at least the catalog's smallest degree, so it scores at most
            # (level - 1) - w_a * min(degree) (IEEE products and differences are monotone)
            if cand_row[a, last] >= 0 and not saturate:
                if deg_min < 0:
                    deg_min = np.int64(degree[0])
                    for g in range(1, n_guide):
                        deg_min = min(deg_min, np.int64(degree[g]))
                if score[a, last] > (level - 1) - w_a * deg_min:
                    continue
        # the voted stars not offered yet -- the unlisted ones (0 < votes < level), or with
        # ``level`` = 0 every voted star -- offered to the same shortlist, which holds the best
        # listed ones: the shortlist of every voted star
        for g in range(n_guide):
            c = np.int64(tally[a, g])
            if c == 0 or (level > 0 and c >= level) or c < score[a, last]:     # the score is at most the votes
                continue
            x = c - (chance_votes(chance, p_b, n_b, degree[g]) if saturate else w_a * degree[g])
            if x < score[a, last] or (x == score[a, last] and g > cand_row[a, last]):
                continue
            t = last
            while t > 0 and (score[a, t - 1] < x or (score[a, t - 1] == x and cand_row[a, t - 1] > g)):
                score[a, t] = score[a, t - 1]
                cand_votes[a, t] = cand_votes[a, t - 1]
                cand_row[a, t] = cand_row[a, t - 1]
                t -= 1
            score[a, t] = x
            cand_votes[a, t] = c
            cand_row[a, t] = g
    return cand_row, cand_votes


@kernel
def vote(v_cam, sel, start, stop, pairs, degree, tol, once_per_pair, expected, n_keep, level, saturate=False):
    """All selected stars vote in one round: :func:`cast_votes` then :func:`rank_votes`.

    Returns ``(cand_row, cand_votes)`` of every selected star (see :func:`rank_votes`; ``level``
    changes the work, not the result).
    """
    m = sel.shape[0]
    n_guide = degree.shape[0]
    stamp = np.zeros(n_guide, dtype=np.uint16)
    listed = np.empty((m, n_guide + 1), dtype=pairs.dtype)   # + 1: cast_votes' spare slot
    n_listed = np.zeros(m, dtype=np.int64)
    if once_per_pair:
        tally8 = np.zeros((m, n_guide), dtype=np.uint8)
        cast_votes(start, stop, pairs, np.int64(0), m, True, stamp, tally8, level, listed, n_listed)
        return rank_votes(v_cam, sel, m, start, stop, tally8, degree, tol, expected, saturate, n_keep, level, listed,
                          n_listed)
    tally32 = np.zeros((m, n_guide), dtype=np.int32)
    cast_votes(start, stop, pairs, np.int64(0), m, False, stamp, tally32, level, listed, n_listed)
    return rank_votes(v_cam, sel, m, start, stop, tally32, degree, tol, expected, False, n_keep, level, listed,
                      n_listed)


@kernel
def pick_candidates(v_cam, sel, cand_row, cand_votes, guide_unit, eps):
    """Each star's candidate with the most support (reconstruction, ``n_candidates > 1``).

    The support of candidate (a -> I) is the number of other stars b with some candidate J such
    that |chord(b_a, b_b) - chord(r_I, r_J)| <= ``eps`` -- the verification vote of the paper,
    counted over every star's shortlist instead of its single winner. Ties: more first-round
    votes, then the earlier (lower) shortlist slot. Returns ``(row, votes)`` per star of ``cand_row``.
    """
    m, k = cand_row.shape
    # the shortlists' unit vectors, float64 in one block (rows of a shortlist are read m - 1 times)
    n_c = np.zeros(m, dtype=np.int64)
    u = np.empty((m, 3, k))
    for a in range(m):
        for s in range(k):
            big_i = cand_row[a, s]
            if big_i < 0:
                break
            for d in range(3):
                u[a, d, s] = float(guide_unit[big_i, d])
            n_c[a] += 1
    # the match of (a -> I, b -> J) is that of (b -> J, a -> I): each unordered pair of stars is
    # tested once, every shortlist pair without stopping at the first match, which numba vectorises
    support = np.zeros((m, k), dtype=np.int64)
    col = np.empty(k, dtype=np.bool_)
    for a in range(m):
        for b in range(a + 1, m):
            c_ab = chord_rows(v_cam, sel[a], v_cam, sel[b])
            n_b = n_c[b]
            for t in range(n_b):
                col[t] = False
            for s in range(n_c[a]):
                big_i = cand_row[a, s]
                xi = u[a, 0, s]
                yi = u[a, 1, s]
                zi = u[a, 2, s]
                hit_any = False
                for t in range(n_b):
                    dx = xi - u[b, 0, t]
                    dy = yi - u[b, 1, t]
                    dz = zi - u[b, 2, t]
                    hit = (cand_row[b, t] != big_i) & (abs(math.sqrt(dx * dx + dy * dy + dz * dz) - c_ab) <= eps)
                    hit_any |= hit
                    col[t] |= hit
                support[a, s] += hit_any
            for t in range(n_b):
                support[b, t] += col[t]
    row = np.full(m, -1, dtype=np.int64)
    got = np.zeros(m, dtype=np.int64)
    for a in range(m):
        best_support = -1
        for s in range(n_c[a]):
            if support[a, s] > best_support or (support[a, s] == best_support and cand_votes[a, s] > got[a]):
                best_support = support[a, s]
                row[a] = cand_row[a, s]
                got[a] = cand_votes[a, s]
    return row, got


# inlined (numba IR) into vote_rounds, and vote_rounds into voting_kernel: two fewer levels whose modules
# re-optimise and re-emit every callee linked below them (wahba_rows, reproject_assign, verify_pairwise,
# rank_votes, ...); the plugin's own kernels cold, core warm: 10.0-10.3 -> 7.2-7.3 CPU s
# (benchmarks/tools/compilecut3b_one.py geometric_voting @plugins)
@inline_kernel
def decide(v_cam, sel, n_voters, start, stop, tally, degree, guide_unit, tol, cam, rule, level, listed, n_listed,
           rows, votes, vtol):
    """Choice, verification and confirmation from the votes of the first ``n_voters`` selected stars.

    The ranking's chance votes use the voting window ``vtol.eps``; everything after it ``tol.eps``.
    Fills ``rows`` (guide row per detection, -1 = unidentified) and ``votes`` (the chosen
    catalog star's votes, -1 for detections that did not vote); returns ``(ok, attitude)``, and
    on failure leaves every row at -1.
    """
    n = v_cam.shape[0]
    cand_row, cand_votes = rank_votes(v_cam, sel, n_voters, start, stop, tally, degree, vtol, rule.expected,
                                      rule.once_per_pair and rule.saturate, rule.n_candidates, level, listed,
                                      n_listed)
    voters = sel[:n_voters]
    if rule.n_candidates == 1:
        best_row, best_votes = cand_row[:, 0].copy(), cand_votes[:, 0].copy()
    else:
        best_row, best_votes = pick_candidates(v_cam, voters, cand_row, cand_votes, guide_unit, tol.eps)
    cand = np.full(n, -1, dtype=np.int64)
    for s in range(n):
        rows[s] = -1
        votes[s] = -1
    for a in range(n_voters):
        cand[voters[a]] = best_row[a]
        votes[voters[a]] = best_votes[a]
    keep = verify_pairwise(v_cam, cand, guide_unit, tol.eps, rule.min_support, rule.min_fraction)
    n_kept = 0
    for s in range(n):
        if keep[s]:
            rows[s] = cand[s]
            n_kept += 1
    if n_kept < 3:
        rows[:] = -1
        return False, np.zeros((3, 3))
    attitude = wahba_rows(v_cam, rows, guide_unit)
    seen = np.empty(n, dtype=np.int64)
    for _ in range(2 if rule.report_all else 1):
        n_seen, n_predicted = reproject_assign(attitude, v_cam, guide_unit, tol.c_fov + tol.eps, tol.eps, seen,
                                               cam.f_px, cam.cx_px, cam.cy_px, cam.width_px, cam.height_px)
        n_agree = 0
        for s in range(n):
            if rows[s] >= 0 and seen[s] == rows[s]:
                n_agree += 1
        if n_agree < n_kept or n_seen < tol.confirm_fraction * n_predicted or n_seen < 3 + tol.min_extra:
            rows[:] = -1
            return False, np.zeros((3, 3))
        if rule.report_all:         # the attitude of every star reprojection identified, once more
            attitude = wahba_rows(v_cam, seen, guide_unit)
    if rule.report_all:
        for s in range(n):
            rows[s] = seen[s]
    return True, attitude


@kernel
def extend_windows(v_cam, sel, kv, tol, start, stop, b_lo, b_hi):
    """The k-vector windows of the image pairs (a, b), a < b, ``b_lo <= b < b_hi``, written into the
    symmetric (m, m) arrays ``start``, ``stop`` as ``starid_algorithms.pyramid.kernels.pair_windows``
    computes them (empty beyond ``tol.c_max`` or above ``tol.max_window`` pairs): each round of
    :func:`vote_rounds` searches only the pairs its new stars form, not again those of the earlier ones."""
    for b in range(b_lo, b_hi):
        for a in range(b):
            c = chord_rows(v_cam, sel[a], v_cam, sel[b])
            if c - tol.eps > tol.c_max:
                continue
            lo, hi = kvector_query(kv, c - tol.eps, c + tol.eps)
            if hi - lo > tol.max_window:
                continue
            start[a, b] = lo
            start[b, a] = lo
            stop[a, b] = hi
            stop[b, a] = hi


@inline_inner   # inlined: see decide
def vote_rounds(v_cam, sel, kv, pairs, degree, guide_unit, tol, cam, rule, tally, vtol, work):
    """Voting in rounds: the ``rule.round_voters`` brightest selected stars vote, their choice is
    verified and confirmed (:func:`decide`); if that fails, the next ``rule.round_step`` stars
    join, their pairs with every earlier star add votes to the same counters, and the choice is
    made again -- until a round succeeds or every selected star has voted (that last round has
    exactly the votes of one round of all). Each round searches the windows of its new pairs only
    (:func:`extend_windows`). The windows that vote are ``vtol``'s (see
    :func:`voting_kernel`). ``tally`` is one row of counters per selected star, cleared here when
    its star joins (its contents on entry do not matter). Returns ``(rows, votes, attitude)``;
    counts into ``work`` (:data:`WORK_COUNTERS`)."""
    n = v_cam.shape[0]
    m = sel.shape[0]
    rows = np.full(n, -1, dtype=np.int64)
    votes = np.full(n, -1, dtype=np.int64)
    n_guide = degree.shape[0]
    stamp = np.zeros(n_guide, dtype=np.uint16)
    listed = np.empty((m, n_guide + 1), dtype=pairs.dtype)   # + 1: cast_votes' spare slot
    n_listed = np.zeros(m, dtype=np.int64)
    start = np.zeros((m, m), dtype=np.int64)
    stop = np.zeros((m, m), dtype=np.int64)
    step = rule.round_voters if rule.round_voters >= 3 else m
    done = np.int64(0)   # not a literal: one signature of cast_votes
    last_level = 0
    while True:
        upto = min(m, done + (step if done == 0 else rule.round_step))
        extend_windows(v_cam, sel, kv, vtol, start, stop, done, upto)
        work[0] += 1
        for b in range(done, upto):     # the new image pairs (a, b), a < b, of this round
            for a in range(b):
                if stop[a, b] > start[a, b]:
                    work[1] += 1
                    work[2] += stop[a, b] - start[a, b]
        # list the stars with `level` votes or more: 3 (2 in a round of 3), rising with the voters
        # (4 from 10, 5 from 13) so that later rounds rank shorter lists; any level gives the same
        # shortlists (rank_votes' bounds and scan), the level only moves work (measured: (upto - 1)
        # // 3 + 1 against // 2 and // 4, gvspeed_profile.py / min_time.py)
        level = max(min(3, upto - 1), (upto - 1) // 3 + 1)
        if level != last_level:
            for a in range(done):   # keep the listed stars that still reach the new level
                k = 0
                for i in range(n_listed[a]):
                    if tally[a, listed[a, i]] >= level:
                        listed[a, k] = listed[a, i]
                        k += 1
                n_listed[a] = k
            last_level = level
        tally[done:upto] = 0        # the new stars' counters (a first round of 5 need not clear all 15 rows)
        cast_votes(start, stop, pairs, done, upto, rule.once_per_pair, stamp, tally, level, listed, n_listed)
        ok, attitude = decide(v_cam, sel, upto, start, stop, tally, degree, guide_unit, tol, cam, rule, level, listed,
                              n_listed, rows, votes, vtol)
        if ok or upto == m:
            return rows, votes, attitude
        done = upto


_TALLY_ONCE = np.empty((0, 0), dtype=np.uint8)
_TALLY_MANY = np.empty((0, 0), dtype=np.int32)


def tally_like(rule):
    """An empty array of the vote counters' dtype for ``rule`` (see :func:`voting_kernel`)."""
    return _TALLY_ONCE if rule.once_per_pair else _TALLY_MANY


@kernel
def voting_kernel(x_px, y_px, mag, kv, pairs, degree, guide_unit, guide_hip, tol, cam, rule, vtol, tally_like):
    """Geometric voting on one image. Returns ``(rows, votes, hip, attitude, found, work)``.

    ``rows[s]``: guide row of detection ``s`` (-1 = unidentified); ``votes[s]``: the votes its
    chosen catalog star received (-1 for detections that did not vote); ``hip[s]``: the catalog id
    of its row (``guide_hip[rows[s]]``, -1 = unidentified); ``attitude``: Wahba's
    ICRS -> camera rotation of the identified stars (zeros when none); ``found``: some star
    identified; ``work``: int64 counters
    of :data:`WORK_COUNTERS` (all zero when nothing voted).

    1. detections with a neighbour closer than ``tol.d_min`` are set aside, the rest sorted
       brightest first and cut to ``tol.max_stars``;
    2. each image pair's angle +- ``tol.eps`` selects catalog pairs (k-vector) and votes
       (:func:`cast_votes`, ``once_per_pair``); each star takes its most-voted catalog star
       (``n_candidates`` = 1, the paper) or, of its ``n_candidates`` best (:func:`rank_votes`),
       the one most consistent with the other stars' shortlists (:func:`pick_candidates`);
    3. verification (``starid.kernels.verify_pairwise``): the pair of assignments (i -> I,
       j -> J) agrees when |chord(b_i, b_j) - chord(r_I, r_J)| <= ``tol.eps``; the least
       supported assignment is dropped until each agrees with at least ``min_support`` and a
       fraction ``min_fraction`` of the others;
    4. confirmation (starid's extension): the attitude of the verified stars must see, by
       reprojection, at least ``tol.confirm_fraction`` of the guide stars it puts on the sensor,
       every verified star must keep its catalog star, and at least 3 + ``tol.min_extra`` stars
       must be seen in all -- else nothing is reported.

    Steps 2-4 run first with the ``rule.round_voters`` brightest stars and, only when that finds
    nothing, again with more of them (:func:`vote_rounds`; starid's extension, for speed).

    ``vtol`` is ``tol`` with the voting window: its ``eps`` (at most ``tol.eps``) sets the pair
    windows that vote and the chance votes of the ranking; the shortlist agreement, verification and
    reprojection use ``tol.eps`` (``GeometricVoting``'s derived ``vote_window_px``).

    ``tally_like`` (:func:`tally_like`: an empty uint8 array when ``rule.once_per_pair``, whose
    votes stay below 255, else int32) gives the vote counters' dtype, so the kernels below are
    compiled for the one dtype the rule uses instead of both.

    The catalog ids are mapped here rather than in a wrapper kernel: numba re-optimises every callee
    linked into each kernel above it, and a ten-line wrapper cost 1.4 CPU s of cold compile.

    ``kv``, ``tol``, ``cam``, ``rule`` and ``vtol`` may be given as plain tuples of their fields
    (``GeometricVoting`` does): they are rebuilt into their named bundles here. Numba types a named
    tuple argument in Python, about 0.8 µs each per call (3.4 µs for these five), a plain tuple in
    its C dispatcher (0.1-0.2 µs).
    """
    kv = KVector(*kv)
    tol = PairTol(*tol)
    cam = Frame(*cam)
    rule = VoteRule(*rule)
    vtol = PairTol(*vtol)
    n = x_px.shape[0]
    work = np.zeros(len(WORK_COUNTERS), dtype=np.int64)
    hip = np.full(n, -1, dtype=np.int64)
    if n < 3:
        return np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64), hip, np.zeros((3, 3)), False, work
    v_cam = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(x_px, y_px, mag, v_cam, tol.d_min, tol.max_stars)
    if sel.shape[0] < 3:
        return np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64), hip, np.zeros((3, 3)), False, work
    tally = np.empty((sel.shape[0], degree.shape[0]), dtype=tally_like.dtype)   # rows zeroed as stars join
    rows, votes, attitude = vote_rounds(v_cam, sel, kv, pairs, degree, guide_unit, tol, cam, rule, tally, vtol, work)
    found = False
    for s in range(n):
        if rows[s] >= 0:
            hip[s] = guide_hip[rows[s]]
            found = True
    return rows, votes, hip, attitude, found, work
