"""Numba kernels of the P-vector plugin: triangle selection, k-vector candidate search, verification.

Everything identify does happens in :func:`identify_rows` (one call per image). Conventions:
observed stars are camera-frame unit vectors, guide stars ICRS unit vectors stored float32 and
sorted by their z component (so a declination band is a binary search); triangle sides are
angles in radians, other comparisons use chords (``|d chord| <= |d angle|``, so a chord test
with an angular tolerance is at least as loose as the angular test).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from starid.kernels import (
    DeepSky,
    Frame,
    KVector,
    backproject_px,
    chord_rows,
    chord_to_rad,
    explained,
    field_chord,
    guide_rows_f64,
    identity3,
    keep_unique,
    kvector_slice,
    refine_explained,
    reproject_assign,
    triple_product,
    verify_pairwise,
    wahba_rows,
    z_band_rows,
)
from starid.kernels.jit import inner, kernel

# The six vertex correspondences (observed vertex j -> database vertex PERMS[p, j]).
PERMS = np.array([[0, 1, 2], [1, 2, 0], [2, 0, 1], [0, 2, 1], [2, 1, 0], [1, 0, 2]], dtype=np.int64)


class Tables(NamedTuple):
    """What identify reads from :class:`~starid_algorithms.pvector.PVectorDatabase`, as one argument.

    p_axis : (3,) the P vector; kv : :class:`starid.kernels.KVector` over the keys P (its ``values``,
    float32, are stored only for ``search='linear'``; the k-vector search slices without them);
    tri_sides : uint16 (m, 3) side vectors in units of ``side_step`` rad; tri_rows : (m, 3) guide rows of (S, N1, N2);
    unit : float32 (n, 3) guide unit vectors (ICRS, z-sorted); hip : int64 (n,) their ids.
    deep : :class:`starid.kernels.DeepSky`, the deeper catalog for ``assign_all`` (may be empty).
    extra_unit : float32 (e, 3) ICRS unit vectors, z-sorted, of the non-guide stars to V <=
        ``check_mag_limit`` (the whole-image check; empty when it is off).
    """

    p_axis: np.ndarray
    kv: KVector
    tri_sides: np.ndarray
    side_step: float
    tri_rows: np.ndarray
    unit: np.ndarray
    hip: np.ndarray
    deep: DeepSky
    extra_unit: np.ndarray


class Tolerances(NamedTuple):
    """The parameters identify uses (see :class:`~starid_algorithms.pvector.PVector`).

    mag_limit : guide-star limit applied to the measured magnitudes; c_rmin, c_r : chords of r_min
    and R; r_rad : R in radians; sigma_px : assumed centroid noise; beta : tolerance factor
    (eps_d = beta sqrt(2) sigma_px / f_px); k_min : confirmations beyond the triangle; sorted_sides,
    brightest, centre_first, inside_only : the switches of the class parameters.
    """

    mag_limit: float
    c_rmin: float
    c_r: float
    r_rad: float
    sigma_px: float
    beta: float
    k_min: int
    sorted_sides: bool
    brightest: bool
    centre_first: bool
    inside_only: bool
    max_stars: int
    max_candidates: int
    confirm_fraction: float
    triangles_per_star: int
    linear_search: bool
    assign_all: bool
    mag_margin: float
    hypotheses: int
    image_neighbours: int
    check_min_stars: int
    check_fraction: float
    chance_tail: float
    eps_ref: float
    max_candidates_wide: int


def plain(t):
    """A named tuple as a plain tuple, its named-tuple fields likewise (for :func:`identify_rows`)."""
    return tuple(plain(v) if hasattr(v, "_fields") else v for v in t)


@inner   # kernels call it only
def _precedes(a_key, a_x, a_y, b_key, b_x, b_y):
    """Lexicographic (key, x, y) comparison, the geometric tie-break used everywhere."""
    if a_key != b_key:
        return a_key < b_key
    if a_x != b_x:
        return a_x < b_x
    return a_y < b_y


@inner   # kernels call it only
def _ranks_before(x_px, y_px, a, ka, da, b, kb, db):
    """Neighbour ``a`` (rank key ``ka``, chord ``da``) ranks before ``b``: key, then chord, then position."""
    if ka != kb:
        return ka < kb
    if da != db:
        return da < db
    return _precedes(x_px[a], y_px[a], 0.0, x_px[b], y_px[b], 0.0)


@inner   # kernels call it only
def _sort_by(key, x_px, y_px):
    """Order of the stars by ``key``, ties broken on position (insertion sort; images are small)."""
    n = key.shape[0]
    order = np.empty(n, dtype=np.int64)   # np.arange(n), a loop: one numpy overload less to compile
    for i in range(n):
        order[i] = i
    for i in range(1, n):
        j = i
        while j > 0 and _precedes(key[order[j]], x_px[order[j]], y_px[order[j]],
                                  key[order[j - 1]], x_px[order[j - 1]], y_px[order[j - 1]]):
            t = order[j]
            order[j] = order[j - 1]
            order[j - 1] = t
            j -= 1
    return order


@inner   # kernels call it only
def select_neighbours(v, mag, eligible, centre, c_rmin, c_r, brightest, x_px, y_px):
    """The two neighbours of star ``centre`` that form its triangle, or (-1, -1).

    Candidates: ``eligible`` stars whose chord to the centre lies in ``[c_rmin, c_r]``. Ranked by
    magnitude (``brightest``) or by distance, ties broken by distance, then position. The
    brighter/nearer one is N1.
    """
    best1 = -1
    best2 = -1
    k1 = 0.0
    d1 = 0.0
    k2 = 0.0
    d2 = 0.0
    for j in range(v.shape[0]):
        if j == centre or not eligible[j]:
            continue
        d = chord_rows(v, centre, v, j)
        if d < c_rmin or d > c_r or d <= 0.0:   # a coincident detection is never a neighbour
            continue
        k = mag[j] if brightest else d
        if best1 < 0 or _ranks_before(x_px, y_px, j, k, d, best1, k1, d1):
            best2, k2, d2 = best1, k1, d1
            best1, k1, d1 = j, k, d
        elif best2 < 0 or _ranks_before(x_px, y_px, j, k, d, best2, k2, d2):
            best2, k2, d2 = j, k, d
    return best1, best2


@inner   # kernels call it only
def select_top(v, mag, eligible, centre, c_rmin, c_r, brightest, x_px, y_px, out):
    """The ``len(out)`` neighbours of star ``centre`` that form its triangles, best first; returns how many.

    Same candidates and ranking as :func:`select_neighbours` (which is the ``len(out) == 2`` case).
    """
    k_max = out.shape[0]
    keys = np.empty(k_max)
    chords = np.empty(k_max)
    m = 0
    for j in range(v.shape[0]):
        if j == centre or not eligible[j]:
            continue
        d = chord_rows(v, centre, v, j)
        if d < c_rmin or d > c_r or d <= 0.0:
            continue
        k = mag[j] if brightest else d
        pos = m
        while pos > 0 and _ranks_before(x_px, y_px, j, k, d, out[pos - 1], keys[pos - 1], chords[pos - 1]):
            pos -= 1
        if pos >= k_max:
            continue
        last = min(m, k_max - 1)
        for t in range(last, pos, -1):
            out[t] = out[t - 1]
            keys[t] = keys[t - 1]
            chords[t] = chords[t - 1]
        out[pos] = j
        keys[pos] = k
        chords[pos] = d
        m = min(m + 1, k_max)
    return m


@inner   # kernels call it only
def linear_range(values, lo, hi):
    """``[start, stop)`` of ascending ``values`` in ``[lo, hi]`` by a linear scan from the start: the
    search a sorted table without an index gets (``search='linear'``), O(m) per query."""
    n = values.shape[0]
    start = 0
    while start < n and values[start] < lo:
        start += 1
    stop = start
    while stop < n and values[stop] <= hi:
        stop += 1
    return start, stop


@inner   # kernels call it only
def triangle_feature(s_len01, s_len02, s_len12, sorted_sides):
    """Feature vector of a triangle from its role-ordered sides (S-N1, S-N2, N1-N2)."""
    d = np.empty(3)
    a, b, c = s_len01, s_len02, s_len12
    if sorted_sides:    # a three-element sorting network, not np.sort (whose quicksort costs 1.6 s to compile)
        if b < a:
            a, b = b, a
        if c < b:
            b, c = c, b
        if b < a:
            a, b = b, a
    d[0] = a
    d[1] = b
    d[2] = c
    return d


@inner   # kernels call it only
def _argsort_stable(values):
    """Stable ascending order of ``values`` (insertion sort: images are small; the same order as
    ``np.argsort(kind="mergesort")`` without compiling a mergesort)."""
    n = values.shape[0]
    order = np.empty(n, dtype=np.int64)   # np.arange(n), a loop: one numpy overload less to compile
    for i in range(n):
        order[i] = i
    for i in range(1, n):
        j = i
        while j > 0 and values[order[j]] < values[order[j - 1]]:
            t = order[j]
            order[j] = order[j - 1]
            order[j - 1] = t
            j -= 1
    return order


@inner   # kernels call it only
def _search_left(a, v):
    """``np.searchsorted(a, v)`` of an ascending ``a`` in numpy's order (NaN after every number), written
    out: numba's searchsorted costs ~0.3 CPU s per side to compile, in every kernel that inlines it."""
    lo = 0
    hi = a.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        x = a[mid]
        if x < v or (v != v and x == x):
            lo = mid + 1
        else:
            hi = mid
    return lo


@inner   # kernels call it only
def _search_right(a, v):
    """``np.searchsorted(a, v, side="right")``, as :func:`_search_left`."""
    lo = 0
    hi = a.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        x = a[mid]
        if v < x or (x != x and v == v):
            hi = mid
        else:
            lo = mid + 1
    return lo


@inner   # kernels call it only
def match_extras(oc, by_c0, c0_sorted, tri_obs, cat_rows, unit, eps, c_band, out_row):
    """Identify the non-triangle observed stars by their chords to the three triangle stars.

    ``oc[i, j]`` is the chord from observed star ``i`` to observed vertex ``tri_obs[j]``, whose
    catalog row is ``cat_rows[j]``. A guide star G within chord ``c_band`` of ``cat_rows[0]``
    matches observed star i when all three chords agree within ``eps``. Only one-to-one matches
    count (a guide star matching two observed stars, or an observed star matched by two guide
    stars, is left out). Fills ``out_row`` (-1 elsewhere) and returns the number of matches.

    ``by_c0`` orders the observed stars by ``oc[:, 0]`` and ``c0_sorted`` holds those chords in that
    order: a guide star examines only the observed stars whose first chord can agree (a binary search,
    slightly widened so that the exact test below decides), instead of every observed star.
    """
    n = oc.shape[0]
    n_match = np.zeros(n, dtype=np.int64)
    for i in range(n):
        out_row[i] = -1
    r0 = cat_rows[0]
    r1 = cat_rows[1]
    r2 = cat_rows[2]
    g, g_stop = z_band_rows(unit, np.float64(unit[r0, 2]), c_band)   # float64, the signature the core kernels use
    while g < g_stop:
        if g != r0 and g != r1 and g != r2:
            c0 = chord_rows(unit, g, unit, r0)
            if c0 <= c_band:
                c1 = chord_rows(unit, g, unit, r1)
                c2 = chord_rows(unit, g, unit, r2)
                lo = _search_left(c0_sorted, c0 - 2.0 * eps)
                hi = _search_right(c0_sorted, c0 + 2.0 * eps)
                found = -1
                n_found = 0
                for k in range(lo, hi):
                    i = by_c0[k]
                    if i == tri_obs[0] or i == tri_obs[1] or i == tri_obs[2]:
                        continue
                    if abs(oc[i, 0] - c0) <= eps and abs(oc[i, 1] - c1) <= eps and abs(oc[i, 2] - c2) <= eps:
                        n_found += 1
                        found = i
                if n_found == 1:
                    n_match[found] += 1
                    out_row[found] = g
                elif n_found > 1:  # one guide star fits several observed stars: none of them counts
                    for k in range(lo, hi):
                        i = by_c0[k]
                        if i == tri_obs[0] or i == tri_obs[1] or i == tri_obs[2]:
                            continue
                        if abs(oc[i, 0] - c0) <= eps and abs(oc[i, 1] - c1) <= eps and abs(oc[i, 2] - c2) <= eps:
                            n_match[i] += 2
        g += 1
    return keep_unique(n_match, out_row)


@kernel
def chance_k_min(n_obs, n_guide, eps, tail):
    """Smallest k with P(X >= k) <= ``tail`` for X ~ Poisson(lam), the number of chance distance
    matches a WRONG correspondence collects in :func:`match_extras` (0 when ``tail`` <= 0).

    A guide star that a wrong correspondence tests matches an observed star by chance when the
    detection lies in the region where its three chords agree within eps, about (2 eps)^2 = 4 eps^2
    sr; the guide stars tested cover the image with the sky density n_guide / (4 pi), so
    lam = n_obs * n_guide / (4 pi) * 4 eps^2 = n_obs * n_guide * eps^2 / pi. On the Table 4 camera
    at 1 px (eps = 3 sqrt(2) px = 150 arcsec, 5,000 guide stars) lam <= 0.09 even for 100 detections
    and the rule gives k <= 2 (k_min unchanged); on a 20 deg, 1024 px camera at 2 px (eps = 600
    arcsec) with 86 detections lam = 1.2, and a fixed k_min = 2 is reached by chance.
    """
    if tail <= 0.0:
        return 0
    lam = n_obs * n_guide * eps * eps / math.pi
    term = math.exp(-lam)     # P(X = 0)
    below = 0.0               # P(X < k)
    k = 0
    while 1.0 - below > tail and k < 1000:
        below += term
        k += 1
        term *= lam / k
    return k


#: Slots of the work counters :func:`identify_rows` returns (``Identification.counters``).
WORK_NAMES = ("searches", "window_triangles", "candidates", "correspondences", "hypotheses")


@kernel
def identify_rows(x_in, y_in, mag_in, frame_t, db_t, tol_t):
    """``(hip, attitude, ok, triangle, work)``: catalog id per observed star (-1 = unidentified, input
    order), the ICRS -> camera attitude, whether the image was identified, the input indices of
    the accepted triangle (main star, N1, N2; -1 when none) and the work counters (:data:`WORK_NAMES`:
    k-vector searches, database triangles in their windows, those passing the three-side check, vertex
    correspondences confirmed against the other stars, whole-image hypotheses tried).
    ``tol.assign_all`` is left to the caller (``PVector._run``), so the default never compiles it.
    ``frame_t``, ``db_t``, ``tol_t``: a :class:`starid.kernels.Frame`, :class:`Tables` and :class:`Tolerances`
    as plain tuples, nested the same way (:func:`plain`).

    Steps (the docstring of :class:`starid_algorithms.pvector.PVector` maps them to the paper):
    canonical star order; main stars in preference order; per main star its triangle, the
    k-vector window on P, the per-side check, the vertex correspondences (side + chirality
    check) and the confirmations of each; the first main star with exactly one confirmed
    correspondence is verified (mutual consistency, attitude, re-identification from the
    attitude) and reported.
    """
    # plain tuples in, named tuples here: numba's dispatch types a plain tuple in C, a named one in Python
    # (about 4 us of every image for these three arguments)
    frame = Frame(*frame_t)
    db = Tables(db_t[0], KVector(*db_t[1]), db_t[2], db_t[3], db_t[4], db_t[5], db_t[6], DeepSky(*db_t[7]),
                db_t[8])
    tol = Tolerances(*tol_t)
    # writable copies: the harness's arrays are read-only, a different numba type, and _sort_by would be
    # compiled for both (0.3 s of a cold compile)
    x_px = np.empty(x_in.shape[0])
    y_px = np.empty(x_in.shape[0])
    mag = np.empty(x_in.shape[0])
    for i in range(x_in.shape[0]):
        x_px[i] = x_in[i]
        y_px[i] = y_in[i]
        mag[i] = mag_in[i]
    f_px, cx_px, cy_px, width_px, height_px = frame.f_px, frame.cx_px, frame.cy_px, frame.width_px, frame.height_px
    p_axis, tri_sides, tri_rows, unit, hip = db.p_axis, db.tri_sides, db.tri_rows, db.unit, db.hip
    step = db.side_step
    out = np.full(x_px.shape[0], -1, dtype=np.int64)
    tri_found = np.full(3, -1, dtype=np.int64)
    work = np.zeros(len(WORK_NAMES), dtype=np.int64)
    if x_px.shape[0] < 3:
        return out, identity3(), False, tri_found, work
    # only the max_stars brightest detections take part (ties by position)
    sel = _sort_by(mag, x_px, y_px)[:min(x_px.shape[0], tol.max_stars)]
    n = sel.shape[0]
    # canonical order: the answer cannot depend on the input order
    canon = sel[_sort_by(x_px[sel], x_px[sel], y_px[sel])]
    xs = x_px[canon]
    ys = y_px[canon]
    ms = mag[canon]
    v = backproject_px(xs, ys, f_px, cx_px, cy_px)

    mag_limit = tol.mag_limit
    c_rmin = tol.c_rmin
    c_r = tol.c_r
    # per-side tolerance: angle noise sqrt(2) sigma; key tolerance ||p||_1 eps_d
    eps = tol.beta * math.sqrt(2.0) * tol.sigma_px / f_px
    eps_key = (abs(p_axis[0]) + abs(p_axis[1]) + abs(p_axis[2])) * eps
    # the candidate cap counts side matches in a window of volume ~ eps^3: scaled to the same density
    # excess as on the reference camera at 1 px (unchanged there and for any smaller window), at most
    # max_candidates_wide (a time bound)
    max_candidates = tol.max_candidates
    if eps > tol.eps_ref > 0.0:
        scaled = min(tol.max_candidates * (eps / tol.eps_ref) ** 3, float(tol.max_candidates_wide))
        max_candidates = max(max_candidates, int(scaled))
    k_min = max(tol.k_min, chance_k_min(n, unit.shape[0], eps, tol.chance_tail))
    sorted_sides = tol.sorted_sides
    brightest = tol.brightest
    centre_first = tol.centre_first
    inside_only = tol.inside_only
    r_px = f_px * math.tan(tol.r_rad)
    c_fov = field_chord(frame) + eps   # chord from the boresight to the farthest image corner, plus the tolerance

    eligible = ms <= mag_limit + tol.mag_margin   # stars that can be in the database (flight precaution)
    # main-star preference: largest distance to the image edge first (R-disc inside), or brightest
    pref = np.empty(n)
    for i in range(n):
        edge = min(min(xs[i], width_px - xs[i]), min(ys[i], height_px - ys[i]))
        pref[i] = -edge if centre_first else ms[i]
    order = _sort_by(pref, xs, ys)

    oc = np.empty((n, 3))
    tri_obs = np.empty(3, dtype=np.int64)
    cat_rows = np.empty(3, dtype=np.int64)
    rows_try = np.empty(n, dtype=np.int64)
    rows_best = np.empty(n, dtype=np.int64)
    w_idx = np.empty(n, dtype=np.int64)   # Wahba's rows and float64 guide vectors (guide_rows_f64)
    w_cat = np.empty((n, 3))
    best_map = np.empty(3, dtype=np.int64)
    nbs = np.empty(max(2, max(tol.triangles_per_star, tol.image_neighbours)), dtype=np.int64)
    n_perm = 6 if sorted_sides else 1
    need = max(tol.check_min_stars, int(math.ceil(tol.check_fraction * n)))
    hyp_cap = tol.hypotheses if n >= need else 0
    hyp_obs = np.empty((hyp_cap, 3), dtype=np.int64)
    hyp_cat = np.empty((hyp_cap, 3), dtype=np.int64)
    n_hyp = 0

    for oi in range(n):
        s = order[oi]
        if not eligible[s]:
            continue
        if inside_only:
            edge = min(min(xs[s], width_px - xs[s]), min(ys[s], height_px - ys[s]))
            if edge < r_px:
                continue
        n_nb = select_top(v, ms, eligible, s, c_rmin, c_r, brightest, xs, ys, nbs)
        # the triangles of the K brightest neighbours, brightest pair first: (0,1), (0,2), (1,2), (0,3), ...
        for b_i in range(1, n_nb):
            for a_i in range(b_i):
                n1 = nbs[a_i]
                n2 = nbs[b_i]
                tri_obs[0] = s
                tri_obs[1] = n1
                tri_obs[2] = n2
                c01 = chord_rows(v, s, v, n1)
                c02 = chord_rows(v, s, v, n2)
                c12 = chord_rows(v, n1, v, n2)
                d_obs = triangle_feature(chord_to_rad(c01), chord_to_rad(c02), chord_to_rad(c12), sorted_sides)
                p_obs = p_axis[0] * d_obs[0] + p_axis[1] * d_obs[1] + p_axis[2] * d_obs[2]
                if tol.linear_search and db.kv.values.shape[0] == tri_sides.shape[0]:
                    start, stop = linear_range(db.kv.values, p_obs - eps_key, p_obs + eps_key)
                elif tol.linear_search:    # a database built for the k-vector search: scan every triangle
                    start, stop = 0, tri_sides.shape[0]
                else:
                    # the untrimmed slice: every candidate's three sides are checked below anyway
                    start, stop = kvector_slice(db.kv.k, db.kv.m, db.kv.q, tri_sides.shape[0], p_obs - eps_key,
                                                p_obs + eps_key)
                work[0] += 1
                if stop <= start:
                    continue
                n_side = 0
                for t in range(start, stop):
                    if (abs(step * tri_sides[t, 0] - d_obs[0]) <= eps and abs(step * tri_sides[t, 1] - d_obs[1]) <= eps
                            and abs(step * tri_sides[t, 2] - d_obs[2]) <= eps):
                        n_side += 1
                work[1] += stop - start
                work[2] += n_side
                if n_side > max_candidates:
                    continue    # an uninformative triangle: its window is far wider than the catalog's spacing
                if n_side == 0:
                    continue
                trip_obs = triple_product(v[s], v[n1], v[n2])
                chir_significant = abs(trip_obs) > eps * max(c01, max(c02, c12))
                for i in range(n):
                    for j in range(3):
                        oc[i, j] = chord_rows(v, i, v, tri_obs[j])
                c_band = 0.0
                for i in range(n):
                    c_band = max(c_band, oc[i, 0])
                c_band += eps
                by_c0 = _argsort_stable(oc[:, 0])
                c0_sorted = np.empty(by_c0.shape[0], dtype=oc.dtype)   # oc[by_c0, 0], a loop (no fancy indexing)
                for k in range(by_c0.shape[0]):
                    c0_sorted[k] = oc[by_c0[k], 0]
                n_found = 0
                ambiguous = False
                for t in range(start, stop):
                    if (abs(step * tri_sides[t, 0] - d_obs[0]) > eps or abs(step * tri_sides[t, 1] - d_obs[1]) > eps
                            or abs(step * tri_sides[t, 2] - d_obs[2]) > eps):
                        continue
                    for p in range(n_perm):
                        for j in range(3):
                            cat_rows[j] = tri_rows[t, PERMS[p, j]]
                        if sorted_sides:
                            if (abs(chord_rows(unit, cat_rows[0], unit, cat_rows[1]) - c01) > eps
                                    or abs(chord_rows(unit, cat_rows[0], unit, cat_rows[2]) - c02) > eps
                                    or abs(chord_rows(unit, cat_rows[1], unit, cat_rows[2]) - c12) > eps):
                                continue
                        if chir_significant:
                            trip_cat = triple_product(unit[cat_rows[0]], unit[cat_rows[1]], unit[cat_rows[2]])
                            if (trip_cat > 0) != (trip_obs > 0):
                                continue
                        if n_found > 0 and cat_rows[0] == best_map[0] and cat_rows[1] == best_map[1] \
                                and cat_rows[2] == best_map[2]:
                            continue  # the same correspondence reached through another database entry
                        if n_hyp < hyp_cap:    # kept for the whole-image pass (extension)
                            for j in range(3):
                                hyp_obs[n_hyp, j] = tri_obs[j]
                                hyp_cat[n_hyp, j] = cat_rows[j]
                            n_hyp += 1
                        work[3] += 1
                        confirmed = match_extras(oc, by_c0, c0_sorted, tri_obs, cat_rows, unit, eps, c_band, rows_try)
                        if confirmed < k_min:
                            continue
                        if n_found == 0:
                            n_found = 1
                            for j in range(3):
                                best_map[j] = cat_rows[j]
                            for i in range(n):
                                rows_best[i] = rows_try[i]
                        else:
                            ambiguous = True
                if n_found == 0 or ambiguous:
                    continue
                for j in range(3):
                    rows_best[tri_obs[j]] = best_map[j]
                keep = verify_pairwise(v, rows_best, unit, eps, np.int64(0), 1.0)   # every pair must agree
                n_keep = 0
                for i in range(n):
                    if keep[i]:
                        n_keep += 1
                    else:
                        rows_best[i] = -1
                if n_keep < 3 + k_min:
                    continue
                # attitude from the consistent stars, then every star re-identified from it (twice, the
                # second attitude using the larger, better spread set)
                n_assigned = 0
                n_predicted = 0
                for _ in range(2):
                    guide_rows_f64(rows_best, unit, w_idx, w_cat)
                    attitude = wahba_rows(v, w_idx, w_cat)
                    n_assigned, n_predicted = reproject_assign(attitude, v, unit, c_fov, eps, rows_try, f_px, cx_px,
                                                               cy_px,
                                                               width_px, height_px)
                    for i in range(n):
                        rows_best[i] = rows_try[i]
                if n_assigned < 3 + k_min or n_assigned < tol.confirm_fraction * n_predicted:
                    continue
                for i in range(n):
                    if rows_best[i] >= 0:
                        out[canon[i]] = hip[rows_best[i]]
                guide_rows_f64(rows_best, unit, w_idx, w_cat)
                attitude = wahba_rows(v, w_idx, w_cat)
                for j in range(3):
                    tri_found[j] = canon[tri_obs[j]]
                return out, attitude, True, tri_found, work
    if n_hyp > 0:
        # Extension (``hypotheses``), the whole-image pass: when no triangle was confirmed, each correspondence
        # that passed the side and handedness checks (in the order they were met: main-star preference,
        # brightest pair first) is a hypothesis. Its attitude (Wahba on the three stars) must explain its own
        # three stars and ``need`` detections (:func:`starid.kernels.explained`); the attitude is then refined
        # twice on every explained detection and must still explain ``need`` detections, at least 3 of them
        # guide stars, and ``confirm_fraction`` of the guide stars it predicts. ``h``: the first hypothesis
        # that passes (its guide rows in ``rows_best``), or -1. (Here, not a kernel of its own: one level
        # less of the call tree for numba to re-optimise explained, refine_explained and Wahba in.)
        h = -1
        rows_x = np.empty(n, dtype=np.int64)
        for hh in range(n_hyp):
            rows_try[:] = -1
            for j in range(3):
                rows_try[hyp_obs[hh, j]] = hyp_cat[hh, j]
            guide_rows_f64(rows_try, unit, w_idx, w_cat)
            attitude = wahba_rows(v, w_idx, w_cat)
            count, _, _ = explained(attitude, v, unit, db.extra_unit, frame, c_fov, eps, rows_best, rows_x)
            own = True
            for j in range(3):
                if rows_best[hyp_obs[hh, j]] != hyp_cat[hh, j]:
                    own = False
            if not own or count < need:
                continue
            n_seen = 0
            n_predicted = 0
            for _ in range(2):
                attitude, count, n_seen, n_predicted = refine_explained(v, unit, db.extra_unit, frame, c_fov, eps,
                                                                        rows_best, rows_x)
            if count >= need and n_seen >= 3 and n_seen >= tol.confirm_fraction * n_predicted:
                h = hh
                break
        work[4] += n_hyp if h < 0 else h + 1
        if h >= 0:
            for i in range(n):
                if rows_best[i] >= 0:
                    out[canon[i]] = hip[rows_best[i]]
            guide_rows_f64(rows_best, unit, w_idx, w_cat)
            attitude = wahba_rows(v, w_idx, w_cat)
            for j in range(3):
                tri_found[j] = canon[hyp_obs[h, j]]
            return out, attitude, True, tri_found, work
    return out, identity3(), False, tri_found, work
