"""numba kernels of the interior-angle method (Galvizo & Lim 2018, their "INT"; see
``docs/algorithms/interior_angle.md``).

The permutation table of the paper (every catalog trio (C, C1, C2) with its two angles from the
central star C and the interior angle at C) is searched without being stored: the first angle
through pyramid's pair k-vector (either end of a pair may be C), the second through C's partner
list sorted by chord, and the interior angle is then computed. Attitude, reprojection and the
confirmation test are the angle plugin's :func:`~starid_algorithms.angle.kernels.confirm_pattern`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from starid_algorithms.angle.kernels import _confirm_pattern, ids_attitude, params_of
from starid_algorithms.pyramid.kernels import _neighbours_within, select_stars, triple

from starid.kernels import backproject_px, chord_rows, kvector_query
from starid.kernels.jit import inner, kernel
from starid.kernels.params import FRAME_SIZE, frame_at

#: numba: float() of a float32 stays a float32; np.float64 casts (one signature for image and catalog)
f64 = np.float64


class InteriorTol(NamedTuple):
    """Tolerances and limits (chords of unit vectors, ~radians; ``eps_phi*`` in radians).

    eps : half-width of both angle windows.
    eps_phi : fixed half-width of the interior-angle window; 0 = from ``phi_sigma`` (below).
    phi_sigma : per-axis position noise (chord) the interior-angle window follows:
        ``phi_beta`` phi_sigma sqrt(2/t1^2 + 2/t2^2 + 2/(t1 t2)).
    phi_beta : its multiplier.
    d_min, c_max, c_fov, max_window, max_stars : as in pyramid's ``PairTol``.
    max_centres : iteration cutoff: central stars tried.
    unique : only a query returning exactly one trio is used (the paper's |R| = 1).
    ordered : the catalog trio must have theta(C, C1) < theta(C, C2) (the paper's fourth predicate).
    chirality : the catalog trio must have the image trio's handedness (signed interior angle).
    max_candidates : a query returning more trios is skipped.
    confirm_fraction, min_extra : reprojection confirmation (both 0: off).
    widen : first reprojection pass within ``widen`` x ``eps`` (``confirm_pattern``).
    """

    eps: float
    eps_phi: float
    phi_sigma: float
    phi_beta: float
    d_min: float
    c_max: float
    c_fov: float
    max_window: int
    max_stars: int
    max_centres: int
    unique: bool
    ordered: bool
    chirality: bool
    max_candidates: int
    confirm_fraction: float
    min_extra: int
    widen: float


@inner   # kernels call it only
def _angle_at(cx, cy, cz, ix, iy, iz, jx, jy, jz):
    """Angle at unit vector c between the great circles to i and j (radians, in [0, pi]).

    Scalars (float64) so that image (float64) and catalog (float32) vectors share one signature:
    atan2(|c . (i x j)|, i . j - (i . c)(j . c)), the tangent-plane angle.
    """
    t = abs(cx * (iy * jz - iz * jy) + cy * (iz * jx - ix * jz) + cz * (ix * jy - iy * jx))
    return math.atan2(t, ix * jx + iy * jy + iz * jz - (ix * cx + iy * cy + iz * cz) * (jx * cx + jy * cy + jz * cz))


@inner   # kernels call it only
def _interior_angle(u, c, i, j):
    """:func:`angle_at` of rows ``c``, ``i``, ``j`` of the (n, 3) image vectors ``u`` (float64)."""
    return _angle_at(f64(u[c, 0]), f64(u[c, 1]), f64(u[c, 2]), f64(u[i, 0]), f64(u[i, 1]), f64(u[i, 2]), f64(u[j, 0]),
                    f64(u[j, 1]), f64(u[j, 2]))


@inner   # kernels call it only
def _nearest_two(v_cam, sel, c):
    """Positions in ``sel`` of the two stars nearest to ``sel[c]`` (Liebe's choice; ties by position)."""
    best1 = -1
    best2 = -1
    d1 = np.inf
    d2 = np.inf
    for k in range(sel.shape[0]):
        if k == c:
            continue
        d = chord_rows(v_cam, sel[c], v_cam, sel[k])
        if d < d1:
            best2, d2 = best1, d1
            best1, d1 = k, d
        elif d < d2:
            best2, d2 = k, d
    return best1, best2


#: the second side's window is marked this much wider (chords) than ``tol.eps``: a pair whose chord
#: the partner-list bisection finds in the window is certainly marked (both are the same float32 chords)
MARK_MARGIN = 1e-6


@kernel
def trio_query(v_cam, sc, s1, s2, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, out):
    """Catalog trios (C, C1, C2) matching the image trio (central ``sc``, nearest ``s1``, second ``s2``).

    |theta(C, C1) - t1| and |theta(C, C2) - t2| within ``tol.eps`` (chords), the interior angle at
    C within its window, and the ``ordered`` / ``chirality`` rules. Writes up to ``out.shape[0]`` trios;
    returns their count (``out.shape[0] + 1`` when there were more, -1 when the window was unusable).
    (:func:`trio_query_marked` with a fresh mark array: for tests and tools; the kernel keeps one per image.)
    """
    mark = np.zeros(nbr_start.shape[0], dtype=np.int32)
    return trio_query_marked(v_cam, sc, s1, s2, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, out, mark,
                             np.int32(1))


@inner   # kernels call it only
def trio_query_marked(v_cam, sc, s1, s2, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, out, mark, stamp):
    """:func:`trio_query`, its partner-list searches filtered: the catalog stars with a pair in the
    second side's window (``t2 +- tol.eps``, widened by :data:`MARK_MARGIN`) get ``mark[g] = stamp``
    first (one k-vector search), and a candidate C that is not marked has no partner in the window,
    so its bisection (a cache miss into a partner list, for every end of every pair of the first
    window; 70 % of them empty on the real sky's 20 slowest of 200 images) is skipped. The same trios in the same
    order. ``stamp`` differs per call on one ``mark`` array (> 0; ``mark`` starts at zeros).
    """
    t1 = chord_rows(v_cam, sc, v_cam, s1)
    t2 = chord_rows(v_cam, sc, v_cam, s2)
    if t2 - tol.eps > tol.c_max:
        return -1
    lo, hi = kvector_query(kv, t1 - tol.eps, t1 + tol.eps)
    if hi == lo or hi - lo > tol.max_window:
        return -1
    lo2, hi2 = kvector_query(kv, t2 - tol.eps - MARK_MARGIN, t2 + tol.eps + MARK_MARGIN)
    for p in range(lo2, hi2):
        mark[pairs[p, 0]] = stamp
        mark[pairs[p, 1]] = stamp
    phi = _interior_angle(v_cam, sc, s1, s2)
    t_obs = triple(v_cam, sc, v_cam, s1, v_cam, s2)
    eps_phi = tol.eps_phi
    if eps_phi <= 0.0:
        eps_phi = tol.phi_beta * tol.phi_sigma * math.sqrt(2.0 / (t1 * t1) + 2.0 / (t2 * t2) + 2.0 / (t1 * t2))
    count = 0
    for p in range(lo, hi):
        for o in range(2):
            big_c = np.int64(pairs[p, o])
            if mark[big_c] != stamp:
                continue    # no partner of C in the second window: the bisection would find none
            big_1 = np.int64(pairs[p, 1 - o])
            c1 = chord_rows(guide_unit, big_c, guide_unit, big_1)
            a, b = _neighbours_within(nbr_chord, nbr_start, big_c, t2 - tol.eps, t2 + tol.eps)
            for e in range(a, b):
                big_2 = np.int64(nbr[e])
                if big_2 == big_1:
                    continue
                if tol.ordered and not nbr_chord[e] > c1:
                    continue
                if tol.chirality and triple(guide_unit, big_c, guide_unit, big_1, guide_unit, big_2) * t_obs <= 0.0:
                    continue
                g = guide_unit
                phi_cat = _angle_at(f64(g[big_c, 0]), f64(g[big_c, 1]), f64(g[big_c, 2]), f64(g[big_1, 0]),
                                   f64(g[big_1, 1]), f64(g[big_1, 2]), f64(g[big_2, 0]), f64(g[big_2, 1]),
                                   f64(g[big_2, 2]))
                if abs(phi_cat - phi) > eps_phi:
                    continue
                if count == out.shape[0]:
                    return count + 1
                out[count, 0] = big_c
                out[count, 1] = big_1
                out[count, 2] = big_2
                count += 1
    return count


@inner   # kernels call it only
def _pairing_key(pat_star, pat_row, key):
    """The pairing {pat_star[a] -> pat_row[a]} as (star, row, star, row, star, row), stars ascending."""
    for a in range(3):
        r = 0
        for b in range(3):
            if pat_star[b] < pat_star[a]:
                r += 1
        key[2 * r] = pat_star[a]
        key[2 * r + 1] = pat_row[a]


@inner   # kernels call it only
def _seen_before(pat_star, pat_row, failed, n_failed):
    """Whether the pairing of ``pat_star`` to ``pat_row`` is one of ``failed[:n_failed]``.

    ``confirm_pattern``'s answer depends on the pairing only, not on the order of the three stars: its
    attitudes are Wahba's of the rows array (indexed by detection), and the pattern's own rows are put
    back (first pass) or checked (later passes) star by star with distinct stars and rows, so in any
    order the same rows result. A pairing refused once is refused again.
    """
    key = np.empty(6, dtype=np.int64)
    _pairing_key(pat_star, pat_row, key)
    for i in range(n_failed):
        same = True
        for j in range(6):
            if failed[i, j] != key[j]:
                same = False
                break
        if same:
            return True
    return False


@inner   # kernels call it only
def _remember(pat_star, pat_row, failed, n_failed):
    """Store the pairing in ``failed[n_failed]`` (it is about to be confirmed; kept only if refused, as
    an accepted one ends the search); returns the new count."""
    key = np.empty(6, dtype=np.int64)
    _pairing_key(pat_star, pat_row, key)
    for j in range(6):
        failed[n_failed, j] = key[j]
    return n_failed + 1


@inner   # kernels call it only
def params_tol(p):
    """The :class:`InteriorTol` of angle's ``params_of`` array (the types of the named tuple from Python:
    float64, int64, bool)."""
    q = p[FRAME_SIZE:]
    return InteriorTol(q[0], q[1], q[2], q[3], q[4], q[5], q[6], np.int64(q[7]), np.int64(q[8]), np.int64(q[9]),
                       q[10] != 0.0, q[11] != 0.0, q[12] != 0.0, np.int64(q[13]), q[14], np.int64(q[15]), q[16])


#: the work counters of :func:`identify_kernel`, in the order of its ``work`` array
WORK_NAMES = ("centres", "queries", "candidates", "confirms", "first_R", "first_named", "first_in_R")


def interior_kernel(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, cam):
    """:func:`identify_kernel`'s ``(rows, trio, work)`` from Python with the named tuples ``interior_kernel``
    took before stop 45 (tests and tools): packs them as the plugin does (angle's ``params_of``); not compiled."""
    no_hip = np.zeros(guide_unit.shape[0], dtype=np.int64)
    rows, trio, work, _, _, _ = identify_kernel(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit,
                                                no_hip, params_of(cam, tol))
    return rows, trio, work


# The search's body is here, not in an inline function that this kernel and interior_kernel share: as in
# angle's identify_kernel, one more level of inlining costs cold-compile CPU.
@kernel
def identify_kernel(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, guide_hip, params):
    """The interior-angle method on one image (``params``: angle's ``params_of`` the camera frame and the
    :class:`InteriorTol`). Returns ``(rows, trio, work, hip, attitude, found)``.

    ``work`` holds the counters :data:`WORK_NAMES`: central stars tried, trio queries made (one per
    central star), catalog trios the queries returned (a query over ``tol.max_candidates`` counts
    ``max_candidates + 1``, an unusable window 0), attitude confirmations, and the first query
    step's (the brightest star as the centre): |R| (same caps), whether the identification names its
    three stars, and whether R holds the catalog trio it names them as. ``hip``, ``attitude`` and
    ``found`` are angle's :func:`~starid_algorithms.angle.kernels.ids_attitude`: the catalog ids, and
    the attitude from every identified detection, that the Python wrapper computed after the kernel
    until stop 45; ``InteriorAngle.identify`` and ``explain`` make this one numba call.

    1. isolated detections, brightest first, at most ``tol.max_stars``;
    2. each in turn is the central star (at most ``tol.max_centres``), with its two nearest
       selected stars (:func:`nearest_two`);
    3. the query (:func:`trio_query`); ``tol.unique``: exactly one trio, else the next central star;
    4. each returned trio goes through ``confirm_pattern``; the first that stands is the answer.
    """
    tol = params_tol(params)
    cam = frame_at(params, np.int64(0))
    n = x_px.shape[0]
    rows = np.full(n, -1, dtype=np.int64)
    trio = np.full(3, -1, dtype=np.int64)
    work = np.zeros(len(WORK_NAMES), dtype=np.int64)
    if n < 3:
        return rows, trio, work, rows.copy(), np.zeros((3, 3)), False
    v_cam = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(x_px, y_px, mag, v_cam, tol.d_min, tol.max_stars)
    m = sel.shape[0]
    if m < 3:
        return rows, trio, work, rows.copy(), np.zeros((3, 3)), False
    out = np.empty((max(tol.max_candidates, 1), 3), dtype=np.int64)
    first = np.empty_like(out)
    first_star = np.full(3, -1, dtype=np.int64)
    pat_star = np.empty(3, dtype=np.int64)
    pat_row = np.empty(3, dtype=np.int64)
    # the pairings (star -> row, sorted by star) confirm_pattern refused: a trio's pairing found again
    # from another central star (c's two nearest are k1, k2 and k1's are c, k2) is refused again
    failed = np.empty((min(tol.max_centres, m) * out.shape[0], 6), dtype=np.int64)
    n_failed = np.int64(0)   # not a literal: one signature of seen_before and remember
    mark = np.zeros(nbr_start.shape[0], dtype=np.int32)   # trio_query_marked's marks, stamp = central star + 1
    found = False
    for c in range(m):
        if work[0] >= tol.max_centres:
            break
        work[0] += 1
        k1, k2 = _nearest_two(v_cam, sel, c)
        pat_star[0] = sel[c]
        pat_star[1] = sel[k1]
        pat_star[2] = sel[k2]
        count = trio_query_marked(v_cam, sel[c], sel[k1], sel[k2], kv, pairs, nbr, nbr_chord, nbr_start, guide_unit,
                                  tol, out, mark, np.int32(c + 1))
        work[1] += 1
        work[2] += max(count, 0)
        if c == 0:
            work[4] = max(count, 0)
            # plain loops: an array slice assignment compiles its shape-mismatch message (~2 CPU s)
            for a in range(3):
                first_star[a] = pat_star[a]
            kept = min(max(count, 0), first.shape[0])
            for t in range(kept):
                for a in range(3):
                    first[t, a] = out[t, a]
        if count <= 0 or count > tol.max_candidates or (tol.unique and count != 1):
            continue
        for t in range(count):
            for a in range(3):
                pat_row[a] = out[t, a]
            work[3] += 1
            if _seen_before(pat_star, pat_row, failed, n_failed):
                continue    # the same star -> row pairing already failed (from another central star)
            if n_failed < failed.shape[0]:
                n_failed = _remember(pat_star, pat_row, failed, n_failed)
            if _confirm_pattern(v_cam, pat_star, pat_row, guide_unit, tol.c_fov, tol.eps, tol.widen, cam, tol.min_extra,
                               tol.confirm_fraction, rows):
                for a in range(3):
                    trio[a] = pat_star[a]
                found = True
                break
        if found:
            break
    if not found:
        rows[:] = -1
        return rows, trio, work, rows.copy(), np.zeros((3, 3)), False
    if first_star[0] >= 0 and rows[first_star[0]] >= 0 and rows[first_star[1]] >= 0 and rows[first_star[2]] >= 0:
        work[5] = 1
        for t in range(min(work[4], first.shape[0])):
            if first[t, 0] == rows[first_star[0]] and first[t, 1] == rows[first_star[1]] \
                    and first[t, 2] == rows[first_star[2]]:
                work[6] = 1
                break
    hip, attitude, found = ids_attitude(x_px, y_px, cam, rows, guide_unit, guide_hip)
    return rows, trio, work, hip, attitude, found


@kernel
def angle_at(cx, cy, cz, ix, iy, iz, jx, jy, jz):
    """:func:`_angle_at` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _angle_at(cx, cy, cz, ix, iy, iz, jx, jy, jz)


@kernel
def interior_angle(u, c, i, j):
    """:func:`_interior_angle` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _interior_angle(u, c, i, j)


@kernel
def nearest_two(v_cam, sel, c):
    """:func:`_nearest_two` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _nearest_two(v_cam, sel, c)


@kernel
def seen_before(pat_star, pat_row, failed, n_failed):
    """:func:`_seen_before` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _seen_before(pat_star, pat_row, failed, n_failed)


@kernel
def remember(pat_star, pat_row, failed, n_failed):
    """:func:`_remember` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _remember(pat_star, pat_row, failed, n_failed)
