"""numba kernel of the spherical-triangle method (Cole & Crassidis 2004, as Galvizo & Lim 2018 ran it).

The triangle catalog, its (area, moment) index, the windows and the direct-match test are the shared
``starid.kernels.triangles``; the star selection is pyramid's plugin-agnostic ``select_stars``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from starid_algorithms.pyramid.kernels import select_stars

from starid.kernels import Frame, backproject_px, wahba_rows
from starid.kernels.jit import inner, kernel
from starid.kernels.params import FRAME_SIZE, frame_at, pack_with_frame
from starid.kernels.triangles import trio_confirm, trio_query


class SphTol(NamedTuple):
    """Tolerances and limits of one identification (chords ~ radians; see ``SphericalTriangle``)."""

    kind: int  # starid.kernels.triangles.SPHERICAL or PLANAR
    depth: int  # moment subdivision depth
    sigma_rad: float  # centroid noise the windows assume
    beta: float  # window half-width in sigmas
    fixed_area: float  # > 0: fixed area half-width (sr), else from the noise
    fixed_moment: float  # > 0: fixed moment half-width, else from the noise
    chord_max: float  # largest side of a stored triangle
    max_hits: int  # area-window work bound
    truncate: bool  # over max_hits: search the first max_hits (SQL LIMIT) instead of skipping
    max_candidates: int  # a trio with more (area, moment) candidates is skipped
    eps: float  # side / reprojection match radius (chord)
    match_sides: bool  # a bijection's chords and chirality must agree
    eps_side: float  # > 0: a candidate's sorted chords must agree within this (query-time side filter)
    c_fov: float  # boresight-to-corner chord
    min_extra: int  # detections besides the trio the attitude must explain
    confirm_fraction: float  # fraction of predicted guide stars that must be seen
    max_stars: int  # brightest usable detections
    d_min: float  # detections closer than this to another are unused
    max_trios: int  # iteration cutoff
    pivot: bool  # Cole's pivoting when |R| != 1
    unique: bool  # |R| = 1 required before the direct-match test


@inner   # kernels call it only
def _share_two(stars, p, q):
    """True when catalog triangles ``p`` and ``q`` (rows of ``stars``) have at least two stars in common."""
    n = 0
    for a in range(3):
        for b in range(3):
            if stars[p, a] == stars[q, b]:
                n += 1
    return n >= 2


#: the work counters of :func:`spherical_kernel` and the composite pyramid's kernel (``work``)
WORK_NAMES = ("trios", "queries", "first_R", "first_named", "first_in_R", "to_r")


@kernel
def identified_hip(guide_hip, rows, work):
    """What ``identify`` reports after a kernel: the catalog ids of ``rows`` (-1 stays -1, as ``hip_of``),
    whether any star is identified, and ``work[5]`` (``to_r``) set to every query made (``work[1]``) when
    none left one candidate. One compiled call for what cost ``hip_of`` and ``rows.max`` in Python."""
    n = rows.shape[0]
    hip = np.empty(n, dtype=np.int64)
    found = False
    for q in range(n):
        r = rows[q]
        if r >= 0:
            hip[q] = guide_hip[r]
            found = True
        else:
            hip[q] = -1
    if work[5] == 0:
        work[5] = work[1]
    return hip, found


@inner   # kernels call it only
def first_query_check(work, rows, first_trio, first_cand, stars):
    """``work[3]`` / ``work[4]``: whether ``rows`` names the three stars of the first queried trio, and
    whether its first R (``first_cand[:work[2]]``, triangles as rows of ``stars``) holds their set."""
    if first_trio[0] < 0:
        return
    r0 = rows[first_trio[0]]
    r1 = rows[first_trio[1]]
    r2 = rows[first_trio[2]]
    if r0 < 0 or r1 < 0 or r2 < 0:
        return
    work[3] = 1
    for c in range(min(work[2], first_cand.shape[0])):
        t = first_cand[c]
        hit = 0
        for a in range(3):
            s = np.int64(stars[t, a])
            if s == r0 or s == r1 or s == r2:
                hit += 1
        if hit == 3:
            work[4] = 1
            return


def spherical_kernel(x_px, y_px, mag, index, guide_unit, tol, cam):
    """:func:`spherical_packed` with the tolerances and camera frame as named tuples (tests,
    tools; not compiled): packs them (``packed_params``) and calls it, the same results."""
    return spherical_packed(x_px, y_px, mag, index, guide_unit, packed_params(tol, cam))


@kernel
def spherical_packed(x_px, y_px, mag, index, guide_unit, params):
    """Identify one image; ``params``: the tolerances and camera frame as one float64 array
    (``packed_params``, rebuilt here: numba's dispatch unboxes a named tuple field by field).
    Returns ``(rows, attitude, trio, work)``; ``work``: the counters
    :data:`WORK_NAMES` -- image trios tried, (area, moment) queries made (pivots included), and the
    first query step's (the three brightest selected stars'): |R| (0 when the window was skipped),
    whether the identification names its stars, whether R holds the catalog triangle it names them as;
    ``to_r``: the queries made up to the one that first left exactly one candidate (after pivoting; 0
    when none did, which ``identify`` reports as every query made): hoku's catalog accesses to obtain r.

    1. usable detections (isolated by ``d_min``), the ``max_stars`` brightest, brightest first;
    2. trios (i, j, k) in the naive order i < j < k (Galvizo & Lim's C(n, 3) loop), at most ``max_trios``;
    3. R = catalog triangles in the area and moment windows (``trio_query``); more than
       ``max_candidates``: skipped;
    4. ``pivot`` and |R| != 1: Cole's pivot -- the third star is replaced by the next unused one and
       R keeps the new trio's candidates sharing two stars with an old one, until |R| <= 1;
    5. the direct-match test (``trio_confirm``) of each candidate; the trio is accepted when exactly
       one stands (``unique``: only with |R| = 1).
    """
    tol = params_sph(params)
    cam = frame_at(params, np.int64(0))
    n = x_px.shape[0]
    rows = np.full(n, -1, dtype=np.int64)
    trio_out = np.full(3, -1, dtype=np.int64)
    work = np.zeros(len(WORK_NAMES), dtype=np.int64)
    if n < 3:
        return rows, np.zeros((3, 3)), trio_out, work
    v_cam = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(x_px, y_px, mag, v_cam, tol.d_min, tol.max_stars)
    m = sel.shape[0]
    cand = np.empty(tol.max_candidates, dtype=np.int64)
    cand2 = np.empty(tol.max_candidates, dtype=np.int64)
    cand3 = np.empty(tol.max_candidates, dtype=np.int64)
    trio = np.empty(3, dtype=np.int64)
    try_rows = np.empty(n, dtype=np.int64)
    trial = np.empty(n, dtype=np.int64)
    stars = index.stars
    first_trio = np.full(3, -1, dtype=np.int64)
    first_cand = np.empty(tol.max_candidates, dtype=np.int64)
    for i in range(m):
        for j in range(i + 1, m):
            for k in range(j + 1, m):
                if work[0] >= tol.max_trios:
                    return np.full(n, -1, dtype=np.int64), np.zeros((3, 3)), trio_out, work
                work[0] += 1
                nc = trio_query(v_cam, sel[i], sel[j], sel[k], index, tol.kind, tol.depth, tol.sigma_rad,
                                tol.beta, tol.fixed_area, tol.fixed_moment, tol.chord_max, tol.max_hits,
                                tol.truncate, guide_unit, tol.eps_side, cand)
                work[1] += 1
                if work[0] == 1:
                    work[2] = max(nc, 0)
                    first_trio[0] = sel[i]
                    first_trio[1] = sel[j]
                    first_trio[2] = sel[k]
                    for c in range(min(max(nc, 0), first_cand.shape[0])):  # loops, not slices: compile
                        first_cand[c] = cand[c]
                if nc <= 0:
                    continue
                trio[0] = sel[i]
                trio[1] = sel[j]
                trio[2] = sel[k]
                if tol.pivot and nc > 1:
                    for b in range(m):
                        if b == i or b == j or b == k:
                            continue
                        n2 = trio_query(v_cam, sel[i], sel[j], sel[b], index, tol.kind, tol.depth,
                                        tol.sigma_rad, tol.beta, tol.fixed_area, tol.fixed_moment, tol.chord_max,
                                        tol.max_hits, tol.truncate, guide_unit, tol.eps_side, cand2)
                        work[1] += 1
                        kept = 0
                        for c2 in range(max(n2, 0)):
                            for c in range(nc):
                                if _share_two(stars, cand2[c2], cand[c]):
                                    cand3[kept] = cand2[c2]
                                    kept += 1
                                    break
                        for c in range(kept):
                            cand[c] = cand3[c]
                        nc = kept
                        trio[2] = sel[b]
                        if nc <= 1:
                            break
                if nc == 1 and work[5] == 0:
                    work[5] = work[1]
                if nc == 0 or (tol.unique and nc != 1):
                    continue
                n_ok = 0
                for c in range(nc):
                    seen = trio_confirm(v_cam, trio, stars[cand[c]], guide_unit, tol.eps, tol.match_sides,
                                        tol.c_fov, tol.min_extra, tol.confirm_fraction, cam, try_rows, trial)
                    if seen < 0:
                        continue
                    n_ok += 1
                    if n_ok > 1:
                        break
                    for q in range(n):
                        rows[q] = try_rows[q]
                    for q in range(3):
                        trio_out[q] = trio[q]
                if n_ok == 1:
                    first_query_check(work, rows, first_trio, first_cand, stars)
                    return rows, wahba_rows(v_cam, rows, guide_unit), trio_out, work
                rows[:] = -1
                trio_out[:] = -1
    return rows, np.zeros((3, 3)), trio_out, work


def packed_params(tol, frame: Frame) -> np.ndarray:
    """``frame`` then ``tol`` (a :class:`SphTol`, or composite_pyramid's ``ComTol``) as one float64 array,
    the argument of :func:`spherical_packed` / ``composite_packed``: numba's dispatch unboxes a named tuple
    field by field, an array at once (about 5 us of every call for the two tuples, measured at stop 45).
    Every value is exact in float64 (``pack_with_frame``); the kernels rebuild the same numbers, ints and
    bools (``starid.kernels.params.frame_at``, :func:`params_sph`)."""
    return pack_with_frame(frame, tol, "triangle kernels' parameters")


@inner   # kernels call it only
def params_sph(p):
    """The :class:`SphTol` of a :func:`packed_params` array (the types of the tuple made in Python: int64,
    float64, bool)."""
    q = p[FRAME_SIZE:]
    return SphTol(np.int64(q[0]), np.int64(q[1]), q[2], q[3], q[4], q[5], q[6], np.int64(q[7]), q[8] != 0.0,
                  np.int64(q[9]), q[10], q[11] != 0.0, q[12], q[13], np.int64(q[14]), q[15], np.int64(q[16]),
                  q[17], np.int64(q[18]), q[19] != 0.0, q[20] != 0.0)

