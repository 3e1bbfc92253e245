"""numba kernels of the two-star angle method (Galvizo & Lim 2018, their "ANG"; see ``docs/algorithms/angle.md``).

The search runs over pyramid's star-pair database (``starid_algorithms.pyramid``): the k-vector over
the pair chords and each guide star's partners sorted by chord. :func:`confirm_pattern` (attitude
from a matched pattern, the rest by reprojection, the confirmation test) is shared with the
interior-angle plugin.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from starid_algorithms.pyramid.kernels import _adjacency, _neighbours_within, pair_windows, select_stars, triple

from starid.kernels import Frame, backproject_px, chord_rows, reproject_assign, wahba_rows
from starid.kernels.jit import inline_inner, inner, kernel
from starid.kernels.params import FRAME_SIZE, frame_at, pack_with_frame


class AngleTol(NamedTuple):
    """Tolerances and limits of one identification (chords of unit vectors, ~radians).

    eps : half-width of the pair-angle window (the catalog query).
    eps_match : distance tolerance of the direct-match test and of reprojection.
    d_min : detections closer than this to another are not used.
    c_max : largest catalog pair chord stored.
    c_fov : chord from the boresight to the farthest image corner.
    max_window : an image pair whose window holds more catalog pairs is not used.
    max_stars : the brightest detections the pairs are formed from.
    max_pairs : iteration cutoff (image pairs tried; hoku's nu_max).
    unique_window : only a window holding exactly one catalog pair is used (hoku's |R| = 1).
    n_check : other stars the direct-match test looks at (brightest first).
    min_support : of them, how many must overlay a catalog star for the pairing to stand.
    compare : hoku's direct-match test: of the two orientations keep the one with more support.
    chirality : a supporting star must also have the same handedness as its catalog star.
    confirm_fraction, min_extra : reprojection confirmation (both 0: off).
    widen : first reprojection pass within ``widen`` x ``eps_match`` (see :func:`confirm_pattern`).
    max_triangles : an anchor star supporting more pairings than this is skipped (starid's test).
    """

    eps: float
    eps_match: float
    d_min: float
    c_max: float
    c_fov: float
    max_window: int
    max_stars: int
    max_pairs: int
    unique_window: bool
    n_check: int
    min_support: int
    compare: bool
    chirality: bool
    confirm_fraction: float
    min_extra: int
    max_triangles: int
    widen: float


#: Slots of :func:`params_of`' array: the camera :class:`~starid.kernels.Frame` (``FRAME_SIZE`` numbers, rebuilt by
#: ``starid.kernels.params.frame_at``), then the tolerances' fields in their order (:class:`AngleTol`, or
#: interior_angle's ``InteriorTol``).
#: Largest integer parameter the array holds (exact in float64); no count in a search comes near it.
INT_CAP = 1 << 52


def params_of(frame: Frame, tol: tuple) -> np.ndarray:
    """``frame`` and ``tol`` (:class:`AngleTol` or interior_angle's ``InteriorTol``) as one float64 array, the
    ``identify_kernel``s' argument: numba unboxes a named tuple field by field, an array at once (issue #25:
    the 17-field tolerances and the frame took 3.6 us of dispatch, the array 1.6). Integers above
    :data:`INT_CAP` are capped (iteration limits no search reaches); every value is exact in float64
    (``frame_at`` and :func:`params_tol` rebuild the same numbers, ints and bools)."""
    values = [min(v, INT_CAP) if isinstance(v, int) and not isinstance(v, bool) else v for v in tol]
    return pack_with_frame(frame, values, "the kernel parameters")


@inner   # kernels call it only
def params_tol(p):
    """The :class:`AngleTol` of :func:`params_of`' array (the types of the named tuple from Python: float64,
    int64, bool)."""
    q = p[FRAME_SIZE:]
    return AngleTol(q[0], q[1], q[2], q[3], q[4], np.int64(q[5]), np.int64(q[6]), np.int64(q[7]), q[8] != 0.0,
                    np.int64(q[9]), np.int64(q[10]), q[11] != 0.0, q[12] != 0.0, q[13], np.int64(q[14]),
                    np.int64(q[15]), q[16])


@inner   # kernels call it only
def _support(v_cam, sel, a, b, big_i, big_j, nbr, nbr_chord, nbr_start, guide_unit, eps, n_check, need, chirality):
    """Direct-match test of the pairing ``sel[a] -> I``, ``sel[b] -> J``: how many of the next
    ``n_check`` selected stars k (brightness order) have a guide star K within ``eps`` of the right
    distance from both I and J (and, with ``chirality``, the same sign of the triple product).

    K runs over I's neighbours at chord(b_a, b_k) +- eps (bisection in the partner list). Stops as
    soon as ``need`` stars agree or ``need`` can no longer be reached; ``need`` < 0 counts them all.
    """
    m = sel.shape[0]
    sa = sel[a]
    sb = sel[b]
    count = 0
    tried = 0
    for k in range(m):
        if k == a or k == b:
            continue
        if tried == n_check:
            break
        tried += 1
        sk = sel[k]
        ci = chord_rows(v_cam, sa, v_cam, sk)
        cj = chord_rows(v_cam, sb, v_cam, sk)
        t_obs = triple(v_cam, sa, v_cam, sb, v_cam, sk)
        lo, hi = _neighbours_within(nbr_chord, nbr_start, big_i, ci - eps, ci + eps)
        for e in range(lo, hi):
            big_k = np.int64(nbr[e])
            if big_k == big_j or abs(chord_rows(guide_unit, big_j, guide_unit, big_k) - cj) > eps:
                continue
            if chirality and triple(guide_unit, big_i, guide_unit, big_j, guide_unit, big_k) * t_obs <= 0.0:
                continue
            count += 1
            break
        if need >= 0 and (count >= need or count + (n_check - tried) < need):
            return count
    return count


@inner   # kernels call it only
def _confirm_pattern(v_cam, pat_star, pat_row, guide_unit, c_fov, eps, widen, cam, min_extra, confirm_fraction, rows):
    """Attitude of a matched pattern (Wahba), the other stars by reprojection, and the confirmation.

    ``reproject_assign`` identifies every detection within the radius of exactly one predicted
    guide star: first ``widen`` x ``eps`` (with ``widen`` > 1: a pattern of close stars gives an
    attitude whose error grows across the field; this pass only gathers stars to re-solve it),
    then three times ``eps``, re-solving the attitude from all stars found before each pass (the
    last pass checks the pattern against the attitude of every star found: a pattern star matched
    to the wrong one of two close guide stars is caught there). With the
    confirmation on (``min_extra`` or ``confirm_fraction`` above 0) the pattern stands when, in
    the ``eps`` passes, every pattern star keeps its row, at least ``min_extra`` stars besides the
    pattern are identified and at least ``confirm_fraction`` of the guide stars the attitude puts on
    the sensor are seen; off, the pattern's own rows are kept whatever reprojection says. Fills
    ``rows``; returns whether it stands.
    """
    n = v_cam.shape[0]
    k = pat_star.shape[0]
    strict = min_extra > 0 or confirm_fraction > 0.0
    rows[:] = -1
    for a in range(k):
        rows[pat_star[a]] = pat_row[a]
    attitude = wahba_rows(v_cam, rows, guide_unit)
    for step in range(4 if widen > 1.0 else 3):
        first = widen > 1.0 and step == 0
        radius = widen * eps if first else eps
        n_seen, n_predicted = reproject_assign(attitude, v_cam, guide_unit, c_fov + radius, radius, rows,
                                               cam.f_px, cam.cx_px, cam.cy_px, cam.width_px, cam.height_px)
        for a in range(k):
            if rows[pat_star[a]] != pat_row[a]:
                if strict and not first:
                    return False
                for s in range(n):                      # the pattern's own pairing wins
                    if rows[s] == pat_row[a]:
                        rows[s] = -1
                rows[pat_star[a]] = pat_row[a]
        if strict and not first and (n_seen - k < min_extra or n_seen < confirm_fraction * n_predicted):
            return False
        if step < (3 if widen > 1.0 else 2):
            attitude = wahba_rows(v_cam, rows, guide_unit)
    return True


#: the work counters of :func:`identify_kernel`, in the order of its ``work`` array
WORK_NAMES = ("pairs", "windows", "candidates", "tests", "confirms", "first_R", "first_named", "first_in_R", "to_r")


def angle_kernel(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, cam):
    """:func:`identify_kernel`'s ``(rows, pair, work)`` from Python with the named tuples ``angle_kernel``
    took before stop 45 (tests and tools): packs them as the plugin does (:func:`params_of`); not compiled."""
    no_hip = np.zeros(guide_unit.shape[0], dtype=np.int64)
    rows, pair, work, _, _, _ = identify_kernel(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit,
                                                no_hip, params_of(cam, tol))
    return rows, pair, work


@inline_inner   # inlined into the kernels that call it (angle's and interior_angle's identify_kernel)
def ids_attitude(x_px, y_px, cam, rows, guide_unit, guide_hip):
    """``(hip, attitude, found)`` of a kernel's ``rows``: catalog ids (-1 = none), whether any
    detection is identified, and then the attitude from all of them (``wahba_rows`` on the
    back-projection of every detection, the arithmetic the Python wrappers ran after the kernel
    until stop 45; zeros when none is)."""
    hip = rows.copy()       # not pyramid's _hip: its np.full under inner's flags costs 0.14 CPU s cold
    found = False
    for s in range(rows.shape[0]):
        if rows[s] >= 0:
            hip[s] = guide_hip[rows[s]]
            found = True
        else:
            hip[s] = -1
    if not found:
        return hip, np.zeros((3, 3)), False
    v = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    return hip, wahba_rows(v, rows, guide_unit), True


# The search's body is here, not in an inline function that this kernel and angle_kernel share: one more
# level of inlining (numba IR) cost 0.45 CPU s of cold compile (2.71 against 2.24 s for the kernel itself).
@kernel
def identify_kernel(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, guide_hip, params):
    """The angle method on one image (``params``: :func:`params_of` the camera frame and the
    :class:`AngleTol`). Returns ``(rows, pair, work, hip, attitude, found)``.

    ``rows[s]`` is the guide row of detection ``s`` (-1 = none); ``pair`` the two detections of the
    accepted pairing (-1 when none); ``work`` the counters :data:`WORK_NAMES`: image pairs examined,
    pair windows computed (one k-vector search each, at most), catalog pairs (or, with ``compare``
    off, catalog triangles) taken from the windows, direct-match tests, attitude confirmations, and
    the first query step's (the two brightest selected stars'): |R|, whether the identification
    names both stars, and whether R holds the catalog pair it names them as; and ``to_r``, the image
    pairs (in the order of step 2) up to the first whose window holds exactly one catalog pair (all of
    them when none does): hoku's reduction step, its count of catalog accesses to obtain r.
    ``hip``, ``attitude`` and ``found`` are :func:`ids_attitude`'s: what ``Angle.identify`` reports,
    so that it and ``explain`` make one numba call (issue #25, stop 45: the ids and the attitude were
    three numba calls and numpy from Python, 7.6 of 51 us per image).

    1. isolated detections, brightest first, at most ``tol.max_stars``;
    2. image pairs in hoku's order ``for i: for j > i``, at most ``tol.max_pairs``;
    3. the pair's k-vector window: catalog pairs whose chord is within ``tol.eps``
       (``tol.unique_window``: the window must hold exactly one);
    4. for each catalog pair and each orientation, the direct-match test (:func:`support`);
       ``tol.compare``: only the orientation with more support (ties: the second, as hoku);
    5. a pairing with at least ``tol.min_support`` supporting stars goes through
       :func:`confirm_pattern`; the first that stands is the answer.
    """
    tol = params_tol(params)
    cam = frame_at(params, np.int64(0))
    n = x_px.shape[0]
    work = np.zeros(len(WORK_NAMES), dtype=np.int64)
    if n < 2:
        rows = np.full(n, -1, dtype=np.int64)
        return rows, np.full(2, -1, dtype=np.int64), work, rows.copy(), np.zeros((3, 3)), False
    v_cam = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(x_px, y_px, mag, v_cam, tol.d_min, tol.max_stars)
    m = sel.shape[0]
    start, stop = pair_windows(v_cam, sel, kv, tol)
    work[1] = m * (m - 1) // 2
    work[8] = _pairs_to_r(start, stop)
    rows, pair = _search(v_cam, sel, start, stop, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, cam, work)
    if m >= 2:
        lo, hi = start[0, 1], stop[0, 1]
        work[5] = hi - lo
        r0 = rows[sel[0]]
        r1 = rows[sel[1]]
        if r0 >= 0 and r1 >= 0:
            work[6] = 1
            for p in range(lo, hi):
                if (pairs[p, 0] == r0 and pairs[p, 1] == r1) or (pairs[p, 0] == r1 and pairs[p, 1] == r0):
                    work[7] = 1
                    break
    hip, attitude, found = ids_attitude(x_px, y_px, cam, rows, guide_unit, guide_hip)
    return rows, pair, work, hip, attitude, found


@inner   # kernels call it only
def _pairs_to_r(start, stop):
    """Image pairs, in the order ``for a: for b > a``, up to the first whose window holds one catalog pair."""
    m = start.shape[0]
    k = 0
    for a in range(m - 1):
        for b in range(a + 1, m):
            k += 1
            if stop[a, b] - start[a, b] == 1:
                return k
    return k


@inner   # kernels call it only
def _triangles_by_ik(v_cam, si, sj, sk, win_ij, win_ik, pairs, guide_unit, eps, scratch, tick, out):
    """pyramid's ``triad_triangles`` of the image triad (i, j, k), the join taken the other way round.

    ``triad_triangles`` builds the partner lists of window ik and walks them for each entry of
    window ij; here the partner lists are those of window ij (built by the caller with
    ``_adjacency`` and stamp ``tick``, once for every anchor k of the pair ij) and each entry of
    window ik walks them. The tests are the same expressions on the same rows (third side
    ``|chord(r_J, r_K) - chord(b_j, b_k)| <= eps``, then the handedness), so the triangles are the
    same set; they are then sorted into ``triad_triangles``' order: by the position of the (I, J)
    entry in window ij, 2 (p - start) + o (``out[t, 3]``), then the (I, K) entry's insertion index in
    window ik descending (``out[t, 4]``; its list is walked newest first). Rows (I, J, K) in
    ``out[:, :3]``; returns the count, ``out.shape[0] + 1`` when there are more (as
    ``triad_triangles``).
    """
    head, stamp, nxt, val = scratch
    c_jk = chord_rows(v_cam, sj, v_cam, sk)
    t_obs = triple(v_cam, si, v_cam, sj, v_cam, sk)
    count = 0
    lo = win_ik[0]
    for p in range(lo, win_ik[1]):
        for o in range(2):
            big_i = np.int64(pairs[p, o])
            big_k = np.int64(pairs[p, 1 - o])
            if stamp[big_i] != tick:
                continue
            e = head[big_i]
            while e >= 0:
                big_j = np.int64(val[e])
                e_here = e
                e = nxt[e]
                if big_k == big_j:
                    continue
                if abs(chord_rows(guide_unit, big_j, guide_unit, big_k) - c_jk) > eps:
                    continue
                if triple(guide_unit, big_i, guide_unit, big_j, guide_unit, big_k) * t_obs <= 0.0:
                    continue
                if count == out.shape[0]:
                    return count + 1
                # insertion sort on (ij entry ascending, ik entry descending)
                k_ij = np.int64(e_here)
                k_ik = 2 * (p - lo) + o
                u = count
                while u > 0 and (out[u - 1, 3] > k_ij or (out[u - 1, 3] == k_ij and out[u - 1, 4] < k_ik)):
                    for c in range(5):
                        out[u, c] = out[u - 1, c]
                    u -= 1
                out[u, 0] = big_i
                out[u, 1] = big_j
                out[u, 2] = big_k
                out[u, 3] = k_ij
                out[u, 4] = k_ik
                count += 1
    return count


@inner   # kernels call it only
def _swap_cached(store, first, count, out):
    """The triangles of triad (a, k, j) from those computed for (a, j, k) (``store[first:first + count]``,
    rows of :func:`_triangles_by_ik`), in ``triad_triangles``' order for (a, k, j): rows
    (I, K, J) by the (I, K) entry's position in window ak, then the (I, J) entry's insertion index
    in window aj descending (its adjacency list is walked newest first). The side tests and the
    handedness are the same numbers for both orders (chords are symmetric, a swapped triple product
    is the exact negative), so the set is the one ``triad_triangles`` finds."""
    for t in range(count):
        q = first + t
        k1 = store[q, 4]
        k2 = store[q, 3]
        # insertion sort on (k1 ascending, k2 descending)
        u = t
        while u > 0:
            w1 = out[u - 1, 3]
            w2 = out[u - 1, 4]
            if w1 < k1 or (w1 == k1 and w2 > k2):
                break
            for c in range(5):
                out[u, c] = out[u - 1, c]
            u -= 1
        out[u, 0] = store[q, 0]
        out[u, 1] = store[q, 2]
        out[u, 2] = store[q, 1]
        out[u, 3] = k1
        out[u, 4] = k2


@inner   # kernels call it only
def _keep(store, n_store, tri, count):
    """``store`` with ``tri[:count]`` written from row ``n_store`` on (grown when full)."""
    if n_store + count > store.shape[0]:
        grown = np.empty((max(2 * store.shape[0], n_store + count), 5), dtype=np.int64)
        for q in range(n_store):
            for c in range(5):
                grown[q, c] = store[q, c]
        store = grown
    for q in range(count):
        for c in range(5):
            store[n_store + q, c] = tri[q, c]
    return store


# inlined (numba IR) into identify_kernel, its one caller: one level less whose module re-optimises and re-emits
# support, confirm_pattern and the core's Wahba and reprojection (the plugin's kernels cold, core warm:
# 7.5-7.7 -> 7.0-7.2 CPU s). confirm_pattern inlined too (two call sites) cost 0.8 s more.
@inline_inner
def _search(v_cam, sel, start, stop, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, cam, work):
    """Steps 2-5 of :func:`identify_kernel`; returns ``(rows, pair)`` and adds to ``work``."""
    n = v_cam.shape[0]
    rows = np.full(n, -1, dtype=np.int64)
    pair = np.full(2, -1, dtype=np.int64)
    m = sel.shape[0]
    pat_star = np.empty(2, dtype=np.int64)
    pat_row = np.empty(2, dtype=np.int64)
    n_guide = guide_unit.shape[0]
    cap = 2 * max(tol.max_window, 1)
    scratch = (np.full(n_guide, -1, dtype=np.int32), np.zeros(n_guide, dtype=np.int32),
               np.empty(cap, dtype=np.int32), np.empty(cap, dtype=np.int32))
    tri = np.empty((max(tol.max_triangles, 1), 5), dtype=np.int64)
    cap_tri = tri.shape[0]
    # the triangles of triad (a, b, k) found for pair (a, b) with anchor k > b, kept for pair (a, k)
    # with anchor b (the same triangles, :func:`_swap_cached`); per a, stars below n_check + 2
    n_slot = 0 if (tol.compare or tol.min_support < 1) else min(m, tol.n_check + 2)
    slot_a = np.full((n_slot, n_slot), -1, dtype=np.int64)
    slot_first = np.zeros((n_slot, n_slot), dtype=np.int64)
    slot_count = np.zeros((n_slot, n_slot), dtype=np.int64)
    store = np.empty((64 if n_slot > 0 else 0, 5), dtype=np.int64)
    n_store = np.int64(0)
    tick = 0
    for a in range(m - 1):
        n_store = np.int64(0)
        for b in range(a + 1, m):
            if work[0] >= tol.max_pairs:
                rows[:] = -1
                return rows, pair
            work[0] += 1
            lo, hi = start[a, b], stop[a, b]
            if hi == lo or (tol.unique_window and hi - lo != 1):
                continue
            pat_star[0] = sel[a]
            pat_star[1] = sel[b]
            if tol.compare:                         # hoku's test: every candidate, the better orientation
                for p in range(lo, hi):
                    work[2] += 1
                    best = -1
                    s_best = -1
                    for o in range(2):
                        work[3] += 1
                        s = _support(v_cam, sel, a, b, np.int64(pairs[p, o]), np.int64(pairs[p, 1 - o]), nbr,
                                    nbr_chord, nbr_start, guide_unit, tol.eps_match, tol.n_check, np.int64(-1),
                                    tol.chirality)
                        if s >= s_best:
                            s_best = s
                            best = o
                    if s_best < tol.min_support:
                        continue
                    pat_row[0] = pairs[p, best]
                    pat_row[1] = pairs[p, 1 - best]
                    work[4] += 1
                    if _confirm_pattern(v_cam, pat_star, pat_row, guide_unit, tol.c_fov, tol.eps_match, tol.widen, cam,
                                       tol.min_extra, tol.confirm_fraction, rows):
                        pair[0] = pat_star[0]
                        pair[1] = pat_star[1]
                        return rows, pair
                continue
            # starid's test: each of the first n_check other stars k in turn anchors the test; the
            # pairings it supports are the catalog triangles of (a, b, k) (pyramid's join of the
            # windows ab and ak, with the handedness test), then counted over the other stars
            tried = 0
            built = False
            for k in range(m):
                if k == a or k == b:
                    continue
                if tried == tol.n_check:
                    break
                tried += 1
                if stop[a, k] == start[a, k] or tol.min_support < 1:
                    continue
                if k < b and b < n_slot and slot_a[k, b] == a:    # found for pair (a, k), anchor b
                    n_tri = slot_count[k, b]
                    if n_tri <= cap_tri:
                        _swap_cached(store, slot_first[k, b], n_tri, tri)
                else:
                    if not built:                       # window ab's partner lists, once for all anchors
                        tick += 1
                        _adjacency(pairs, lo, hi, scratch[0], scratch[1], tick, scratch[2], scratch[3])
                        built = True
                    n_tri = _triangles_by_ik(v_cam, sel[a], sel[b], sel[k], (lo, hi), (start[a, k], stop[a, k]),
                                             pairs, guide_unit, tol.eps_match, scratch, tick, tri)
                    if b < k < n_slot:
                        slot_a[b, k] = a
                        slot_first[b, k] = n_store
                        slot_count[b, k] = n_tri
                        store = _keep(store, n_store, tri, n_tri if n_tri <= cap_tri else 0)
                        n_store += n_tri if n_tri <= cap_tri else 0
                if n_tri > cap_tri:
                    continue
                work[2] += n_tri
                for t in range(n_tri):
                    big_i = tri[t, 0]
                    big_j = tri[t, 1]
                    work[3] += 1
                    if _support(v_cam, sel, a, b, big_i, big_j, nbr, nbr_chord, nbr_start, guide_unit, tol.eps_match,
                               tol.n_check, tol.min_support, tol.chirality) < tol.min_support:
                        continue
                    pat_row[0] = big_i
                    pat_row[1] = big_j
                    work[4] += 1
                    if _confirm_pattern(v_cam, pat_star, pat_row, guide_unit, tol.c_fov, tol.eps_match, tol.widen, cam,
                                       tol.min_extra, tol.confirm_fraction, rows):
                        pair[0] = pat_star[0]
                        pair[1] = pat_star[1]
                        return rows, pair
    rows[:] = -1
    return rows, pair


@kernel
def support(v_cam, sel, a, b, big_i, big_j, nbr, nbr_chord, nbr_start, guide_unit, eps, n_check, need, chirality):
    """:func:`_support` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _support(v_cam, sel, a, b, big_i, big_j, nbr, nbr_chord, nbr_start, guide_unit, eps, n_check, need,
                    chirality)


@kernel
def confirm_pattern(v_cam, pat_star, pat_row, guide_unit, c_fov, eps, widen, cam, min_extra, confirm_fraction, rows):
    """:func:`_confirm_pattern` from Python (tests and tools); the kernels call that one, so this entry point
    is compiled only when Python calls it."""
    return _confirm_pattern(v_cam, pat_star, pat_row, guide_unit, c_fov, eps, widen, cam, min_extra, confirm_fraction,
                            rows)
