"""numba kernels of geometric voting (Kolomenkin, Pollak, Shimshoni & Lindenbaum 2008).

The star selection and the k-vector windows of the image pairs are the Pyramid plugin's
(:mod:`starid_algorithms.pyramid.kernels`), over the same star-pair database.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from starid.kernels import backproject_px, chord_rows, reproject_assign, verify_pairwise, wahba_rows
from starid_algorithms.pyramid.kernels import pair_windows, select_stars


@njit(cache=True)
def vote(v_cam, sel, start, stop, pairs, degree, tol, once_per_pair, expected, n_keep):
    """Votes of the catalog stars for each selected star; returns ``(cand_row, cand_votes)``.

    For star a, every other star b gives its pair's window: each catalog pair (I, J) in it is a
    possible identity of the image pair, so I and J each get a vote for star a (the paper's
    voting: both catalog stars of a matching pair vote for both image stars). With
    ``once_per_pair`` one image pair gives a catalog star at most one vote, however many pairs of
    the window contain it (a star with many neighbours at about that distance is one possible
    identity, not several). Star a keeps its ``n_keep`` best catalog stars, most votes first,
    ties to the lowest guide row (``cand_row[a, 0]`` is the paper's choice, the "first
    maximum"); unused slots are -1. With ``expected`` (reconstruction) "best" is the excess
    over the votes a catalog star collects by chance, ``votes - degree[g] * w_a``:
    ``w_a = sum_b 4 eps c_ab / c_max^2`` is the probability that one given neighbour of a
    catalog star falls in the windows of star a's pairs (pair distances spread as in a disc of
    radius ``c_max``), ``degree[g]`` the star's number of neighbours -- so a star in dense sky
    does not win on its many neighbours alone. One vote row at a time (``n_guide`` counters,
    cache-resident), zeroed between stars; at most 32,767 selected stars and 65,535 votes.
    """
    m = sel.shape[0]
    n_guide = degree.shape[0]
    # one int32 per catalog star: votes in the low 16 bits, the last voting image pair above
    tally = np.zeros(n_guide, dtype=np.int32)
    cand_row = np.full((m, n_keep), -1, dtype=np.int64)
    cand_votes = np.zeros((m, n_keep), dtype=np.int64)
    score = np.empty(n_keep)
    for a in range(m):
        tally[:] = 0
        w_a = 0.0
        if expected:
            for b in range(m):
                if b != a and stop[a, b] > start[a, b]:
                    w_a += 4.0 * tol.eps * chord_rows(v_cam, sel[a], v_cam, sel[b]) / (tol.c_max * tol.c_max)
        for b in range(m):
            if b == a:
                continue
            stamp = np.int32((b + 1) << 16)
            for p in range(start[a, b], stop[a, b]):
                for o in range(2):
                    g = pairs[p, o]
                    x = tally[g]
                    if once_per_pair:
                        if (x & np.int32(-65536)) == stamp:
                            continue
                        tally[g] = stamp | ((x & np.int32(65535)) + np.int32(1))
                    else:
                        tally[g] = x + np.int32(1)
        for g in range(n_guide):
            tally[g] &= np.int32(65535)
        score[:] = -np.inf
        for g in range(n_guide):          # keep the n_keep best (rows ascend, so ties keep the lowest)
            c = tally[g]
            if c == 0:
                continue
            x = c - w_a * degree[g]
            if x <= score[n_keep - 1]:
                continue
            t = n_keep - 1
            while t > 0 and score[t - 1] < x:
                score[t] = score[t - 1]
                cand_votes[a, t] = cand_votes[a, t - 1]
                cand_row[a, t] = cand_row[a, t - 1]
                t -= 1
            score[t] = x
            cand_votes[a, t] = c
            cand_row[a, t] = g
    return cand_row, cand_votes


@njit(cache=True)
def pick_candidates(v_cam, sel, cand_row, cand_votes, guide_unit, eps):
    """Each star's candidate with the most support (reconstruction, ``n_candidates > 1``).

    The support of candidate (a -> I) is the number of other stars b with some candidate J such
    that |chord(b_a, b_b) - chord(r_I, r_J)| <= ``eps`` -- the verification vote of the paper,
    counted over every star's shortlist instead of its single winner. Ties: more first-round
    votes, then the earlier (lower) shortlist slot. Returns ``(row, votes)`` per selected star.
    """
    m, k = cand_row.shape
    row = np.full(m, -1, dtype=np.int64)
    got = np.zeros(m, dtype=np.int64)
    for a in range(m):
        best_support = -1
        for s in range(k):
            big_i = cand_row[a, s]
            if big_i < 0:
                break
            support = 0
            for b in range(m):
                if b == a:
                    continue
                c = chord_rows(v_cam, sel[a], v_cam, sel[b])
                for t in range(k):
                    big_j = cand_row[b, t]
                    if big_j < 0:
                        break
                    if big_j != big_i and abs(chord_rows(guide_unit, big_i, guide_unit, big_j) - c) <= eps:
                        support += 1
                        break
            if support > best_support or (support == best_support and cand_votes[a, s] > got[a]):
                best_support = support
                row[a] = big_i
                got[a] = cand_votes[a, s]
    return row, got


@njit(cache=True)
def voting_kernel(x_px, y_px, mag, kv, pairs, degree, guide_unit, tol, cam, min_support, min_fraction,
                  once_per_pair, expected, n_candidates):
    """Geometric voting on one image. Returns ``(rows, votes, attitude)``.

    ``rows[s]``: guide row of detection ``s`` (-1 = unidentified); ``votes[s]``: the votes its
    chosen catalog star received (-1 for detections that did not vote); ``attitude``: Wahba's
    ICRS -> camera rotation of the identified stars (zeros when none).

    1. detections with a neighbour closer than ``tol.d_min`` are set aside, the rest sorted
       brightest first and cut to ``tol.max_stars``;
    2. each image pair's angle +- ``tol.eps`` selects catalog pairs (k-vector) and votes
       (:func:`vote`, ``once_per_pair``); each star takes its most-voted catalog star
       (``n_candidates`` = 1, the paper) or, of its ``n_candidates`` most-voted, the one most
       consistent with the other stars' shortlists (:func:`pick_candidates`, reconstruction);
    3. verification (``starid.kernels.verify_pairwise``): the pair of assignments (i -> I,
       j -> J) agrees when |chord(b_i, b_j) - chord(r_I, r_J)| <= ``tol.eps``; the least
       supported assignment is dropped until each agrees with at least ``min_support`` and a
       fraction ``min_fraction`` of the others;
    4. confirmation (starid's extension): the attitude of the verified stars must see, by
       reprojection, at least ``tol.confirm_fraction`` of the guide stars it puts on the sensor,
       every verified star must keep its catalog star, and at least 3 + ``tol.min_extra`` stars
       must be seen in all -- else nothing is reported.
    """
    n = x_px.shape[0]
    rows = np.full(n, -1, dtype=np.int64)
    votes = np.full(n, -1, dtype=np.int64)
    if n < 3:
        return rows, votes, np.zeros((3, 3))
    v_cam = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(x_px, y_px, mag, v_cam, tol.d_min, tol.max_stars)
    if sel.shape[0] < 3:
        return rows, votes, np.zeros((3, 3))
    start, stop = pair_windows(v_cam, sel, kv, tol)
    cand_row, cand_votes = vote(v_cam, sel, start, stop, pairs, degree, tol, once_per_pair, expected, n_candidates)
    if n_candidates == 1:
        best_row, best_votes = cand_row[:, 0].copy(), cand_votes[:, 0].copy()
    else:
        best_row, best_votes = pick_candidates(v_cam, sel, cand_row, cand_votes, guide_unit, tol.eps)
    cand = np.full(n, -1, dtype=np.int64)
    for a in range(sel.shape[0]):
        cand[sel[a]] = best_row[a]
        votes[sel[a]] = best_votes[a]
    keep = verify_pairwise(v_cam, cand, guide_unit, tol.eps, min_support, min_fraction)
    n_kept = 0
    for s in range(n):
        if keep[s]:
            rows[s] = cand[s]
            n_kept += 1
    if n_kept < 3:
        rows[:] = -1
        return rows, votes, np.zeros((3, 3))
    attitude = wahba_rows(v_cam, rows, guide_unit)
    seen = np.empty(n, dtype=np.int64)
    n_seen, n_predicted = reproject_assign(attitude, v_cam, guide_unit, tol.c_fov + tol.eps, tol.eps, seen,
                                           cam.f_px, cam.cx_px, cam.cy_px, cam.width_px, cam.height_px)
    n_agree = 0
    for s in range(n):
        if rows[s] >= 0 and seen[s] == rows[s]:
            n_agree += 1
    if n_agree < n_kept or n_seen < tol.confirm_fraction * n_predicted or n_seen < 3 + tol.min_extra:
        rows[:] = -1
        return rows, votes, np.zeros((3, 3))
    return rows, votes, attitude
