"""numba kernels of the Pyramid algorithm (Mortari, Samaan, Bruccoleri & Junkins 2004).

The pair-angle helpers at the top (:func:`isolated`, :func:`pair_windows`) are shared with the
geometric-voting plugin, which searches the same kind of star-pair k-vector.

Bundles (``typing.NamedTuple``, passed to numba as tuples):

* ``kv`` -- :class:`starid.kernels.KVector` over the sorted chords of the catalog pairs;
* :class:`PairTol` -- the tolerances and work limits of one identification;
* the camera geometry reprojection needs is the core's :class:`starid.kernels.Frame`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from starid.kernels import backproject_px, chord_rows, kvector_query, order_by, reproject_assign, wahba_rows
from starid.kernels.jit import inner, kernel

#: catalog triangles kept per image triad on :data:`starid.camera.REFERENCE_CAMERA` at the 1 px window
#: floor (a triad matching more is skipped); scaled with the window's volume on other cameras and noise
#: levels (``starid_algorithms.pyramid.algorithm.max_triangles_for``)
TRIANGLE_CAP = 64


class PairTol(NamedTuple):
    """Tolerances and limits (chords of unit vectors, i.e. ~radians).

    eps : half-width of every pair-angle window (and of the reprojection match radius).
    d_min : detections closer than this to another detection are not used (double stars).
    c_max : largest catalog pair chord stored (no image pair beyond it can match).
    c_fov : chord from the boresight to the farthest image corner.
    max_window : an image pair whose window holds more catalog pairs than this is not used.
    max_stars : only the ``max_stars`` brightest usable detections form triads / vote.
    max_triads : iteration cutoff (triads examined).
    confirm_fraction : reprojection confirmation: fraction of the guide stars predicted on the
        sensor that must be seen.
    min_extra : stars besides the pattern's own that reprojection must identify.
    """

    eps: float
    d_min: float
    c_max: float
    c_fov: float
    max_window: int
    max_stars: int
    max_triads: int
    confirm_fraction: float
    min_extra: int


# --------------------------------------------------------------------------------------------
# shared pair-angle helpers


@inner   # kernels call it only
def isolated(v_cam, d_min):
    """True for detections with no other detection within chord ``d_min`` (doubles, coincident)."""
    n = v_cam.shape[0]
    ok = np.ones(n, dtype=np.bool_)
    for i in range(n):
        for j in range(i + 1, n):
            if chord_rows(v_cam, i, v_cam, j) < d_min:
                ok[i] = False
                ok[j] = False
    return ok


@kernel
def select_stars(x_px, y_px, mag, v_cam, d_min, max_stars):
    """The usable detections (isolated), brightest first, at most ``max_stars`` of them."""
    order = order_by(mag, x_px, y_px)
    ok = isolated(v_cam, d_min)
    sel = np.empty(min(order.shape[0], max_stars), dtype=np.int64)
    m = 0
    for a in range(order.shape[0]):
        if m == sel.shape[0]:
            break
        if ok[order[a]]:
            sel[m] = order[a]
            m += 1
    return sel[:m]


@kernel
def pair_windows(v_cam, sel, kv, tol):
    """k-vector window ``[start, stop)`` of every pair of selected stars (symmetric (m, m) arrays).

    The catalog pairs whose chord lies within ``tol.eps`` of the observed chord; a window is
    left empty when it holds more than ``tol.max_window`` pairs (a too-wide tolerance, e.g. a
    fish-eye camera: such a pair carries no information and would only cost time).
    """
    m = sel.shape[0]
    start = np.zeros((m, m), dtype=np.int64)
    stop = np.zeros((m, m), dtype=np.int64)
    for a in range(m):
        for b in range(a + 1, m):
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
    return start, stop


# --------------------------------------------------------------------------------------------
# Pyramid


@inner   # kernels call it only
def triple(u, i, v, j, w, k):
    """Triple product ``u_i . (v_j x w_k)`` of rows of three (n, 3) arrays (float64)."""
    ax, ay, az = float(u[i, 0]), float(u[i, 1]), float(u[i, 2])
    bx, by, bz = float(v[j, 0]), float(v[j, 1]), float(v[j, 2])
    cx, cy, cz = float(w[k, 0]), float(w[k, 1]), float(w[k, 2])
    return ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)


@inner   # kernels call it only
def _adjacency(pairs, start, stop, head, stamp, tick, nxt, val):
    """Linked lists of the catalog pairs in ``[start, stop)``: partners of each guide row.

    ``head[g]`` is valid only where ``stamp[g] == tick`` (no clearing between triads).
    """
    cnt = 0
    for p in range(start, stop):
        for o in range(2):
            x = np.int64(pairs[p, o])
            if stamp[x] != tick:
                stamp[x] = tick
                head[x] = -1
            val[cnt] = pairs[p, 1 - o]
            nxt[cnt] = head[x]
            head[x] = cnt
            cnt += 1


@inner   # kernels call it only
def _triad_triangles(v_cam, si, sj, sk, win_ij, win_ik, pairs, guide_unit, eps, work, tick, out):
    """Catalog triangles (I, J, K) matching the image triad (i, j, k) (the paper's triangle step).

    (I, J) runs over the k-vector window of side ij, K over the partners of I in the window of
    side ik (linked lists built in ``work`` = (head, stamp, next, partner) scratch arrays, valid
    where ``stamp == tick``), and the third side must agree too:
    ``|chord(r_J, r_K) - chord(b_j, b_k)| <= eps`` -- the same as (J, K) lying in the window of
    side jk, without building it. The triple products ``b_i . (b_j x b_k)`` and
    ``r_I . (r_J x r_K)`` must have the same sign (the chirality or "spectral" test that rejects
    mirror images). Writes up to ``out.shape[0]`` triangles into ``out`` and returns their count
    (``out.shape[0] + 1`` when there were more).
    """
    head, stamp, nxt, val = work
    _adjacency(pairs, win_ik[0], win_ik[1], head, stamp, tick, nxt, val)
    c_jk = chord_rows(v_cam, sj, v_cam, sk)
    t_obs = triple(v_cam, si, v_cam, sj, v_cam, sk)
    count = 0
    for p in range(win_ij[0], win_ij[1]):
        for o in range(2):
            big_i = np.int64(pairs[p, o])
            big_j = np.int64(pairs[p, 1 - o])
            if stamp[big_i] != tick:
                continue
            e = head[big_i]
            while e >= 0:
                big_k = np.int64(val[e])
                e = nxt[e]
                if big_k == big_j:
                    continue
                if abs(chord_rows(guide_unit, big_j, guide_unit, big_k) - c_jk) > eps:
                    continue
                if triple(guide_unit, big_i, guide_unit, big_j, guide_unit, big_k) * t_obs <= 0.0:
                    continue
                if count == out.shape[0]:
                    return count + 1
                out[count, 0] = big_i
                out[count, 1] = big_j
                out[count, 2] = big_k
                count += 1
    return count


@inner   # kernels call it only
def _neighbours_within(nbr_chord, nbr_start, big_i, lo, hi):
    """Index range of guide row ``big_i``'s neighbours whose chord lies in ``[lo, hi]`` (bisection)."""
    a = nbr_start[big_i]
    b = nbr_start[big_i + 1]
    x, y = a, b
    while x < y:
        mid = (x + y) // 2
        if nbr_chord[mid] < lo:
            x = mid + 1
        else:
            y = mid
    first = x
    y = b
    while x < y:
        mid = (x + y) // 2
        if nbr_chord[mid] <= hi:
            x = mid + 1
        else:
            y = mid
    return first, x


@inner   # kernels call it only
def _fourth_star(v_cam, sel, tri_pos, tri_rows, nbr, nbr_chord, nbr_start, guide_unit, eps):
    """The pyramid's confirming star: the first selected star r (brightness order) with exactly
    one catalog star R at the right distance (+- ``eps``) from all three triangle stars.

    R runs over the neighbours of I (``nbr``: every guide star's pair partners sorted by chord,
    the same pairs as the k-vector's) at distance chord(b_i, b_r) +- eps; its distances to J and
    K are then checked. Returns ``(position of r in sel, R)`` or ``(-1, -1)``.
    """
    pi, pj, pk = tri_pos[0], tri_pos[1], tri_pos[2]
    big_i, big_j, big_k = tri_rows[0], tri_rows[1], tri_rows[2]
    for r in range(sel.shape[0]):
        if r == pi or r == pj or r == pk:
            continue
        sr = sel[r]
        ci = chord_rows(v_cam, sel[pi], v_cam, sr)
        cj = chord_rows(v_cam, sel[pj], v_cam, sr)
        ck = chord_rows(v_cam, sel[pk], v_cam, sr)
        found = -1
        n_found = 0
        lo, hi = _neighbours_within(nbr_chord, nbr_start, big_i, ci - eps, ci + eps)
        for e in range(lo, hi):
            big_r = np.int64(nbr[e])
            if big_r == big_j or big_r == big_k:
                continue
            if abs(chord_rows(guide_unit, big_j, guide_unit, big_r) - cj) > eps:
                continue
            if abs(chord_rows(guide_unit, big_k, guide_unit, big_r) - ck) > eps:
                continue
            found = big_r
            n_found += 1
        if n_found == 1:
            return r, found
    return -1, -1


@inner   # kernels call it only
def _confirm_pyramid(v_cam, pyr_star, pyr_row, guide_unit, tol, cam, rows):
    """Attitude of the pyramid, the other stars by reprojection, and the confirmation test.

    Wahba on the four pyramid stars; ``reproject_assign`` identifies every detection lying
    within ``tol.eps`` of exactly one predicted guide star; repeated once with the attitude of
    all stars found. The pyramid stands when every pyramid star keeps its row, at least
    ``tol.min_extra`` stars besides the pyramid's four are identified, and at least a fraction
    ``tol.confirm_fraction`` of the guide stars the attitude puts on the sensor are seen.
    Fills ``rows`` and returns ``(True, attitude)`` (the attitude of every star found, the one the
    kernel reports), or ``(False, _)`` (``rows`` then undefined).
    """
    sub = np.empty((4, 3))
    for a in range(4):
        for c in range(3):
            sub[a, c] = v_cam[pyr_star[a], c]
    attitude = wahba_rows(sub, pyr_row, guide_unit)
    for _ in range(2):
        n_seen, n_predicted = reproject_assign(attitude, v_cam, guide_unit, tol.c_fov + tol.eps, tol.eps, rows,
                                               cam.f_px, cam.cx_px, cam.cy_px, cam.width_px, cam.height_px)
        for a in range(4):
            if rows[pyr_star[a]] != pyr_row[a]:
                return False, attitude
        if n_seen - 4 < tol.min_extra or n_seen < tol.confirm_fraction * n_predicted:
            return False, attitude
        attitude = wahba_rows(v_cam, rows, guide_unit)
    return True, attitude


#: names of the per-image work counters :func:`pyramid_kernel` returns (``Identification.counters``):
#: triads examined, k-vector range queries (pair windows searched, each at most once per image),
#: catalog pairs read from the windows of the triangle searches (sides ij and ik of each triad
#: whose three windows are non-empty), catalog triangles matched (passing the third side and the
#: chirality test; a triad over the cap counts cap + 1), and candidate pyramids confirmed by
#: reprojection (a fourth star found, :func:`_confirm` run); then the first query step's (the first
#: triad, the three brightest selected stars): |R| = its catalog triangles (0 when a window is empty
#: or skipped; over ``max_triangles``: ``max_triangles + 1``), whether the identification names its
#: three stars, and whether R holds the catalog set it names them as (``first_R``, ``first_named``,
#: ``first_in_R``: Galvizo & Lim's f and S, docs/experiments.md)
WORK_COUNTERS = ("triads", "pair_searches", "pairs_read", "triangles", "confirmations", "first_R", "first_named",
                 "first_in_R")


@inner   # kernels call it only
def first_query_check(work, rows, first_trio, first_tri):
    """``work[6]`` / ``work[7]``: whether ``rows`` names the three stars of the first triad
    (``first_trio``), and whether its R (the first ``min(work[5], len(first_tri))`` rows of
    ``first_tri``, catalog triangles) holds the set of guide rows they are named as."""
    if first_trio[0] < 0:
        return
    r0 = rows[first_trio[0]]
    r1 = rows[first_trio[1]]
    r2 = rows[first_trio[2]]
    if r0 < 0 or r1 < 0 or r2 < 0:
        return
    work[6] = 1
    for c in range(min(work[5], first_tri.shape[0])):
        hit = 0
        for a in range(3):
            s = first_tri[c, a]
            if s == r0 or s == r1 or s == r2:
                hit += 1
        if hit == 3:
            work[7] = 1
            return


@kernel
def _window(v_cam, sel, a, b, kv, tol, start, stop, work):
    """True when the k-vector window of selected stars ``a < b`` holds catalog pairs; computed on
    first use (``start[a, b] < 0`` = not yet) exactly as :func:`pair_windows` does (empty when the
    chord is beyond ``tol.c_max`` or the window holds more than ``tol.max_window`` pairs), so that
    an image whose first triad is accepted searches three windows instead of all m (m - 1) / 2."""
    if start[a, b] < 0:
        start[a, b] = 0
        stop[a, b] = 0
        c = chord_rows(v_cam, sel[a], v_cam, sel[b])
        if c - tol.eps <= tol.c_max:
            work[1] += 1
            lo, hi = kvector_query(kv, c - tol.eps, c + tol.eps)
            if hi - lo <= tol.max_window:
                start[a, b] = lo
                stop[a, b] = hi
    return stop[a, b] > start[a, b]


@kernel
def pyramid_kernel(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, guide_hip, tol, cam,
                   unique_triangle, accept_triangle, max_triangles):
    """Pyramid identification of one image. Returns ``(rows, hip, attitude, pyramid, work)``.

    ``rows[s]`` is the guide row of detection ``s`` (-1 = unidentified), ``hip[s]`` its catalog
    id (``guide_hip[rows[s]]``, -1 = unidentified); ``attitude`` the ICRS -> camera rotation of the
    identified stars (Wahba; all zeros when none); ``pyramid`` the four
    detections of the accepted pyramid (i, j, k, r; -1 when none; with ``accept_triangle`` and
    three stars, r = -1); ``work`` the int64 counters of :data:`WORK_COUNTERS` (``work[0]``: how
    many triads were examined).

    1. detections with a neighbour closer than ``tol.d_min`` are set aside; the others are
       sorted brightest first and the first ``tol.max_stars`` kept;
    2. every pair a triad uses gets its k-vector window of catalog pairs (chord +- ``tol.eps``;
       searched on first use, :func:`_window`: the same windows as :func:`pair_windows`);
    3. triads in Mortari's order: ``for dj: for dk: for i: j = i + dj, k = j + dk``, so that
       consecutive triads share few stars and a spurious star does not spoil a whole run;
       at most ``tol.max_triads`` of them;
    4. the triad's catalog triangles (:func:`triad_triangles`, with the chirality test); a triad
       matching more than ``max_triangles`` is skipped; ``unique_triangle``: go on only if exactly
       one survives (the paper);
    5. the fourth star (:func:`fourth_star`) completes each candidate triangle's pyramid;
    6. attitude, the remaining stars by reprojection and the confirmation test
       (:func:`_confirm`) for each candidate pyramid; the triad is accepted when exactly one of
       them is confirmed, else the search goes on. (Counting candidates before confirmation let
       random fourth stars of false triangles veto the true pyramid on coarse-pixel cameras.)
    """
    n = x_px.shape[0]
    rows = np.full(n, -1, dtype=np.int64)
    pyramid = np.full(4, -1, dtype=np.int64)
    work = np.zeros(len(WORK_COUNTERS), dtype=np.int64)
    if n < 3:
        return rows, _hip(rows, guide_hip), np.zeros((3, 3)), pyramid, work
    v_cam = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(x_px, y_px, mag, v_cam, tol.d_min, tol.max_stars)
    m = sel.shape[0]
    if m < 3:
        return rows, _hip(rows, guide_hip), np.zeros((3, 3)), pyramid, work
    start = np.full((m, m), -1, dtype=np.int64)
    stop = np.zeros((m, m), dtype=np.int64)
    n_guide = guide_unit.shape[0]
    cap = 2 * max(tol.max_window, 1)
    work_lists = (np.full(n_guide, -1, dtype=np.int32), np.zeros(n_guide, dtype=np.int32),
                  np.empty(cap, dtype=np.int32), np.empty(cap, dtype=np.int32))
    tri = np.empty((max(max_triangles, 1), 3), dtype=np.int64)
    tri_pos = np.empty(3, dtype=np.int64)
    pyr_star = np.empty(4, dtype=np.int64)
    cand_star = np.empty(4, dtype=np.int64)
    cand_row = np.empty(4, dtype=np.int64)
    trial_rows = np.empty(n, dtype=np.int64)
    attitude = np.zeros((3, 3))
    first_trio = np.full(3, -1, dtype=np.int64)  # the first triad's stars and R (the work counters only)
    first_tri = np.empty((0, 3), dtype=np.int64)
    n_triads = 0
    for dj in range(1, m - 1):
        for dk in range(1, m - dj):
            for i in range(0, m - dj - dk):
                if n_triads >= tol.max_triads:
                    return rows, _hip(rows, guide_hip), np.zeros((3, 3)), pyramid, work
                j = i + dj
                k = j + dk
                n_triads += 1
                work[0] = n_triads
                if n_triads == 1:
                    first_trio[0] = sel[i]
                    first_trio[1] = sel[j]
                    first_trio[2] = sel[k]
                if not (_window(v_cam, sel, i, j, kv, tol, start, stop, work)
                        and _window(v_cam, sel, j, k, kv, tol, start, stop, work)
                        and _window(v_cam, sel, i, k, kv, tol, start, stop, work)):
                    continue
                work[2] += stop[i, j] - start[i, j] + stop[i, k] - start[i, k]
                n_tri = _triad_triangles(v_cam, sel[i], sel[j], sel[k], (start[i, j], stop[i, j]),
                                        (start[i, k], stop[i, k]), pairs, guide_unit, tol.eps, work_lists, n_triads,
                                        tri)
                work[3] += n_tri
                if n_triads == 1:
                    work[5] = n_tri
                    first_tri = tri[:min(n_tri, tri.shape[0])].copy()
                if n_tri == 0 or n_tri > max_triangles or (unique_triangle and n_tri != 1):
                    continue
                tri_pos[0] = i
                tri_pos[1] = j
                tri_pos[2] = k
                if m == 3:
                    if accept_triangle and n_tri == 1:
                        for a in range(3):
                            rows[sel[tri_pos[a]]] = tri[0, a]
                            pyramid[a] = sel[tri_pos[a]]
                    if pyramid[0] < 0:  # no star named (rows.max() < 0; numpy's max costs ~0.4 CPU s to compile)
                        return rows, _hip(rows, guide_hip), np.zeros((3, 3)), pyramid, work
                    first_query_check(work, rows, first_trio, first_tri)
                    return rows, _hip(rows, guide_hip), wahba_rows(v_cam, rows, guide_unit), pyramid, work
                n_ok = 0
                for t in range(n_tri):
                    r, big_r = _fourth_star(v_cam, sel, tri_pos, tri[t], nbr, nbr_chord, nbr_start, guide_unit,
                                           tol.eps)
                    if r < 0:
                        continue
                    for a in range(3):
                        cand_star[a] = sel[tri_pos[a]]
                        cand_row[a] = tri[t, a]
                    cand_star[3] = sel[r]
                    cand_row[3] = big_r
                    work[4] += 1
                    ok, cand_attitude = _confirm_pyramid(v_cam, cand_star, cand_row, guide_unit, tol, cam, trial_rows)
                    if not ok:
                        continue
                    n_ok += 1
                    if n_ok > 1:
                        break
                    for q in range(pyr_star.shape[0]):  # loops, not array slices: cheaper to compile
                        pyr_star[q] = cand_star[q]
                    for q in range(rows.shape[0]):
                        rows[q] = trial_rows[q]
                    attitude = cand_attitude
                if n_ok == 1:
                    for q in range(pyramid.shape[0]):
                        pyramid[q] = pyr_star[q]
                    first_query_check(work, rows, first_trio, first_tri)
                    return rows, _hip(rows, guide_hip), attitude, pyramid, work
                rows[:] = -1
    return rows, _hip(rows, guide_hip), np.zeros((3, 3)), pyramid, work


@inner   # kernels call it only
def _hip(rows, guide_hip):
    """Catalog id of each detection's guide row (-1 stays -1)."""
    hip = np.full(rows.shape[0], -1, dtype=np.int64)
    for s in range(rows.shape[0]):
        if rows[s] >= 0:
            hip[s] = guide_hip[rows[s]]
    return hip


@kernel
def triad_triangles(v_cam, si, sj, sk, win_ij, win_ik, pairs, guide_unit, eps, work, tick, out):
    """:func:`_triad_triangles` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _triad_triangles(v_cam, si, sj, sk, win_ij, win_ik, pairs, guide_unit, eps, work, tick, out)


@kernel
def neighbours_within(nbr_chord, nbr_start, big_i, lo, hi):
    """:func:`_neighbours_within` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _neighbours_within(nbr_chord, nbr_start, big_i, lo, hi)


@kernel
def fourth_star(v_cam, sel, tri_pos, tri_rows, nbr, nbr_chord, nbr_start, guide_unit, eps):
    """:func:`_fourth_star` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _fourth_star(v_cam, sel, tri_pos, tri_rows, nbr, nbr_chord, nbr_start, guide_unit, eps)


@kernel
def _confirm(v_cam, pyr_star, pyr_row, guide_unit, tol, cam, rows):
    """:func:`_confirm_pyramid` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _confirm_pyramid(v_cam, pyr_star, pyr_row, guide_unit, tol, cam, rows)
