"""numba kernel of the Composite Pyramid method (Galvizo & Lim 2018, after Toloei et al.).

Mortari's trio order, Cole & Crassidis' planar (area, moment) triangle features from the shared
``starid.kernels.triangles`` index, a fourth-star test with the same features, and the shared
direct-match test; the star selection is pyramid's plugin-agnostic ``select_stars``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from starid_algorithms.pyramid.kernels import select_stars
from starid_algorithms.spherical_triangle.kernels import WORK_NAMES, first_query_check, packed_params

from starid.kernels import backproject_px, wahba_rows
from starid.kernels.jit import inner, kernel
from starid.kernels.order import search_left, sort_int_prefix
from starid.kernels.params import FRAME_SIZE, frame_at
from starid.kernels.triangles import trio_confirm, trio_query


class ComTol(NamedTuple):
    """Tolerances and limits of one identification (chords ~ radians; see ``CompositePyramid``)."""

    kind: int  # starid.kernels.triangles.PLANAR (or SPHERICAL)
    depth: int  # moment subdivision depth (spherical features only)
    sigma_rad: float  # centroid noise the windows assume
    beta: float  # window half-width in sigmas
    fixed_area: float  # > 0: fixed area half-width, else from the noise
    fixed_moment: float  # > 0: fixed moment half-width, else from the noise
    chord_max: float  # largest side of a stored triangle
    max_hits: int  # area-window work bound
    truncate: bool  # over max_hits: search the first max_hits (SQL LIMIT) instead of skipping
    max_candidates: int  # a trio with more candidates is skipped
    eps: float  # side / reprojection match radius (chord)
    match_sides: bool  # a bijection's chords and chirality must agree
    eps_side: float  # > 0: a candidate's sorted chords must agree within this (query-time side filter)
    c_fov: float  # boresight-to-corner chord
    min_extra: int  # detections besides the trio the attitude must explain
    confirm_fraction: float  # fraction of predicted guide stars that must be seen
    max_stars: int  # brightest usable detections
    d_min: float  # detections closer than this to another are unused
    max_trios: int  # iteration cutoff
    unique: bool  # |R| = 1 required (paper)
    fourth_tries: int  # fourth stars tried per candidate (paper: one)


@inner   # kernels call it only
def _third_stars(stars, hits, n_hits, cat, out):
    """Sorted distinct third stars of the hit triangles containing exactly two stars of ``cat``."""
    m = 0
    for h in range(n_hits):
        t = hits[h]
        inside = 0
        other = -1
        for a in range(3):
            s = np.int64(stars[t, a])
            if s == cat[0] or s == cat[1] or s == cat[2]:
                inside += 1
            else:
                other = s
        if inside == 2:
            out[m] = other
            m += 1
    # sorted and distinct, as np.unique would (whose sort costs ~1 CPU s to compile); a copy, since
    # fourth_star keeps three results made in the same ``out``
    sort_int_prefix(out, np.int64(m))   # np.int64: not a literal (one signature)
    u = 0
    for i in range(m):
        if u == 0 or out[i] != out[u - 1]:
            out[u] = out[i]
            u += 1
    return out[:u].copy()


@inner   # kernels call it only
def _holds(values, e):
    """``e`` is in the ascending int64 ``values``: ``np.searchsorted`` (side left) and a comparison, through
    the core's bisection (numba's searchsorted overload costs ~0.25 CPU s of a cold compile)."""
    lo = search_left(values, e)
    return lo < values.shape[0] and values[lo] == e


@inner   # kernels call it only
def _fourth_star(stars, hits, counts, cat, buf):
    """The catalog star of the fourth image star beta: the stars E that complete, with two stars of the
    candidate ``cat``, a catalog triangle in the window of each of the three image trios (b1, b2, beta),
    (b1, b3, beta), (b2, b3, beta) (``hits[q, :counts[q]]``). Returns E when exactly one, else -1."""
    if counts[0] <= 0 or counts[1] <= 0 or counts[2] <= 0:
        return -1
    s0 = _third_stars(stars, hits[0], counts[0], cat, buf)
    s1 = _third_stars(stars, hits[1], counts[1], cat, buf)
    s2 = _third_stars(stars, hits[2], counts[2], cat, buf)
    found = -1
    n = 0
    for e in s0:
        if _holds(s1, e) and _holds(s2, e):
            found = e
            n += 1
    return found if n == 1 else -1


def composite_kernel(x_px, y_px, mag, index, guide_unit, tol, cam):
    """:func:`composite_packed` with the tolerances and camera frame as named tuples (tests,
    tools; not compiled): packs them (``packed_params``) and calls it, the same results."""
    return composite_packed(x_px, y_px, mag, index, guide_unit, packed_params(tol, cam))


@kernel
def composite_packed(x_px, y_px, mag, index, guide_unit, params):
    """Identify one image; ``params``: the tolerances and camera frame as one float64 array
    (``packed_params``, rebuilt here: numba's dispatch unboxes a named tuple field by field).
    Returns ``(rows, attitude, stars4, work)`` (``stars4``: the trio and the
    fourth star of the accepted identification, -1 when none; ``work``: the spherical triangle's
    counters ``WORK_NAMES`` -- trios tried, (area, moment) queries made (fourth-star queries included),
    and the first query step's (the three brightest selected stars') |R|, whether the identification
    names them, and whether R holds the catalog triangle it names them as; ``to_r``: the queries made
    up to the trio query that first returned exactly one candidate, 0 when none did).

    1. usable detections (isolated by ``d_min``), the ``max_stars`` brightest, brightest first;
    2. trios in Mortari's order ``for dj, for dk, for i: j = i + dj, k = j + dk``, at most ``max_trios``;
    3. R = catalog triangles in the area and moment windows; more than ``max_candidates``: skipped;
       ``unique``: only |R| = 1 goes on (the paper);
    4. the direct-match test (``trio_confirm``) of each candidate;
    5. the fourth-star test of a candidate that passed it: for up to ``fourth_tries`` other stars beta
       (brightest first), the three trios of beta with two trio stars are queried; it passes when exactly
       one catalog star completes all three (:func:`fourth_star`). The trio is accepted when exactly one
       candidate passes both (the paper runs 5 before 4; the conjunction is the same, 4 is cheaper).
    """
    tol = params_com(params)
    cam = frame_at(params, np.int64(0))
    n = x_px.shape[0]
    rows = np.full(n, -1, dtype=np.int64)
    out4 = np.full(4, -1, dtype=np.int64)
    work = np.zeros(len(WORK_NAMES), dtype=np.int64)
    if n < 3:
        return rows, np.zeros((3, 3)), out4, work
    v_cam = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(x_px, y_px, mag, v_cam, tol.d_min, tol.max_stars)
    m = sel.shape[0]
    nc_max = tol.max_candidates
    cand = np.empty(nc_max, dtype=np.int64)
    hits = np.empty((3, 4 * nc_max), dtype=np.int64)
    counts = np.zeros(3, dtype=np.int64)
    buf = np.empty(4 * nc_max, dtype=np.int64)
    trio = np.empty(3, dtype=np.int64)
    cat = np.empty(3, dtype=np.int64)
    try_rows = np.empty(n, dtype=np.int64)
    trial = np.empty(n, dtype=np.int64)
    stars = index.stars
    first_trio = np.full(3, -1, dtype=np.int64)
    first_cand = np.empty(nc_max, dtype=np.int64)
    for dj in range(1, m - 1):
        for dk in range(1, m - dj):
            for i in range(0, m - dj - dk):
                if work[0] >= tol.max_trios:
                    return np.full(n, -1, dtype=np.int64), np.zeros((3, 3)), np.full(4, -1, dtype=np.int64), work
                j = i + dj
                k = j + dk
                work[0] += 1
                trio[0] = sel[i]
                trio[1] = sel[j]
                trio[2] = sel[k]
                nc = trio_query(v_cam, trio[0], trio[1], trio[2], index, tol.kind, tol.depth, tol.sigma_rad,
                                tol.beta, tol.fixed_area, tol.fixed_moment, tol.chord_max, tol.max_hits,
                                tol.truncate, guide_unit, tol.eps_side, cand)
                work[1] += 1
                if work[0] == 1:
                    work[2] = max(nc, 0)
                    # plain loops: an array slice assignment compiles its shape-mismatch message (~2 CPU s)
                    for a in range(3):
                        first_trio[a] = trio[a]
                    for a in range(min(max(nc, 0), nc_max)):
                        first_cand[a] = cand[a]
                if nc == 1 and work[5] == 0:
                    work[5] = work[1]
                if nc <= 0 or (tol.unique and nc != 1):
                    continue
                n_ok = 0
                for c in range(nc):
                    # the direct-match test first (cheap, and it rejects nearly every chance candidate),
                    # then the fourth-star test; a candidate must pass both
                    seen = trio_confirm(v_cam, trio, stars[cand[c]], guide_unit, tol.eps, tol.match_sides,
                                        tol.c_fov, tol.min_extra, tol.confirm_fraction, cam, try_rows, trial)
                    if seen < 0:
                        continue
                    for a in range(3):
                        cat[a] = np.int64(stars[cand[c], a])
                    beta = -1
                    tries = 0
                    for b in range(m):
                        if b == i or b == j or b == k:
                            continue
                        if tries >= tol.fourth_tries:
                            break
                        tries += 1
                        counts[:] = 0
                        for q in range(3):
                            s0 = trio[0] if q < 2 else trio[1]
                            s1 = trio[1] if q == 0 else trio[2]
                            counts[q] = trio_query(v_cam, s0, s1, sel[b], index, tol.kind, tol.depth,
                                                   tol.sigma_rad, tol.beta, tol.fixed_area, tol.fixed_moment,
                                                   tol.chord_max, tol.max_hits, tol.truncate, guide_unit,
                                                   tol.eps_side, hits[q])
                            work[1] += 1
                            # no hit completes a pair of the candidate: this beta fails, skip its other queries
                            if counts[q] <= 0 or _third_stars(stars, hits[q], counts[q], cat, buf).shape[0] == 0:
                                break
                        if _fourth_star(stars, hits, counts, cat, buf) >= 0:
                            beta = sel[b]
                            break
                    if beta < 0:
                        continue
                    n_ok += 1
                    if n_ok > 1:
                        break
                    for a in range(n):
                        rows[a] = try_rows[a]
                    for a in range(3):
                        out4[a] = trio[a]
                    out4[3] = beta
                if n_ok == 1:
                    first_query_check(work, rows, first_trio, first_cand, stars)
                    return rows, wahba_rows(v_cam, rows, guide_unit), out4, work
                rows[:] = -1
                out4[:] = -1
    return rows, np.zeros((3, 3)), out4, work


@kernel
def fourth_star(stars, hits, counts, cat, buf):
    """:func:`_fourth_star` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _fourth_star(stars, hits, counts, cat, buf)


@inner   # kernels call it only
def params_com(p):
    """The :class:`ComTol` of a ``packed_params`` array (spherical_triangle's kernels; the types of the
    tuple made in Python: int64, float64, bool)."""
    q = p[FRAME_SIZE:]
    return ComTol(np.int64(q[0]), np.int64(q[1]), q[2], q[3], q[4], q[5], q[6], np.int64(q[7]), q[8] != 0.0,
                  np.int64(q[9]), q[10], q[11] != 0.0, q[12], q[13], np.int64(q[14]), q[15], np.int64(q[16]),
                  q[17], np.int64(q[18]), q[19] != 0.0, np.int64(q[20]))

