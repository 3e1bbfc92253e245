"""Star-triangle catalogs indexed by (area, polar moment), for Cole & Crassidis' triangle features.

Shared by the ``spherical_triangle`` and ``composite_pyramid`` plugins (``docs/algorithms/``).

* Features (:func:`tri_features`): ``kind = PLANAR`` -- the planar triangle of the three unit vectors
  (Heron area ``A`` and polar moment ``J = A (a^2 + b^2 + c^2) / 36``, Cole & Crassidis 2006 eq. 16);
  ``kind = SPHERICAL`` -- the spherical triangle: its area is the solid angle (spherical excess, the
  Van Oosterom-Strackee form of L'Huilier's theorem) and its polar moment ``J = sum dA theta^2`` over
  the 4^depth sub-triangles of a midpoint subdivision, ``theta`` the angle from the triangle's centroid
  to the sub-triangle's (Cole & Crassidis 2004's recursive moment).
* Windows (:func:`tri_windows`): half-widths ``beta sigma_f`` from the linearised noise model
  (isotropic centroid noise ``sigma_rad`` per axis on each star; the gradients by finite differences).
* Index (:class:`TriangleIndex`): the triangles sorted by area and searched with the shared k-vector;
  consecutive runs of ``BLOCK`` triangles (in area order) are sorted by moment, so a query visits
  ``hits / BLOCK`` blocks with a bisection each instead of every area hit (:func:`tri_query`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .attitude import wahba_rows
from .jit import inner, kernel
from .kvector import KVector, kvector_query
from .verify import reproject_assign

PLANAR = 0
SPHERICAL = 1
#: triangles per moment-sorted block of the index
BLOCK = 128
#: finite-difference step of the window gradients (radians)
FD_STEP_RAD = 1e-6


class TriangleIndex(NamedTuple):
    """The catalog triangles: ``kv`` over the ascending areas (float64 keys); ``BLOCK``-runs of
    the same order re-sorted by moment: ``moment`` (float64), ``area`` (float64) and ``stars``
    (uint16 (N, 3) guide rows, ascending within a row) in that block order."""

    kv: KVector
    moment: np.ndarray
    area: np.ndarray
    stars: np.ndarray


@inner   # kernels call it only
def _solid_angle(ax, ay, az, bx, by, bz, cx, cy, cz):
    """Solid angle of the spherical triangle of three (not necessarily unit) direction vectors."""
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    lc = math.sqrt(cx * cx + cy * cy + cz * cz)
    trip = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    den = la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (ax * cx + ay * cy + az * cz) * lb \
        + (bx * cx + by * cy + bz * cz) * la
    return 2.0 * math.atan2(abs(trip), den)


@inner   # kernels call it only
def _angle(ux, uy, uz, wx, wy, wz):
    """Angle between two (not necessarily unit) vectors (atan2 form, accurate at small angles)."""
    cx = uy * wz - uz * wy
    cy = uz * wx - ux * wz
    cz = ux * wy - uy * wx
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ux * wx + uy * wy + uz * wz)


@kernel
def tri_features(r1, r2, r3, kind, depth):
    """``(area, moment)`` of the triangle of unit vectors ``r1, r2, r3`` (see the module docstring)."""
    e1 = np.empty(3)  # r2 - r1, r3 - r1 as loops (array expressions compile a ufunc kernel each)
    e2 = np.empty(3)
    for x in range(3):
        e1[x] = r2[x] - r1[x]
        e2[x] = r3[x] - r1[x]
    if kind == PLANAR:
        cx = e1[1] * e2[2] - e1[2] * e2[1]
        cy = e1[2] * e2[0] - e1[0] * e2[2]
        cz = e1[0] * e2[1] - e1[1] * e2[0]
        area = 0.5 * math.sqrt(cx * cx + cy * cy + cz * cz)
        d = np.empty(3)
        for x in range(3):
            d[x] = r3[x] - r2[x]
        s2 = e1 @ e1 + e2 @ e2 + d @ d  # the dot products stay (BLAS sums: the same bits as before)
        return area, area * s2 / 36.0
    area = _solid_angle(r1[0], r1[1], r1[2], r2[0], r2[1], r2[2], r3[0], r3[1], r3[2])
    n = 1 << depth
    inv = 1.0 / n
    # grid points r1 + (a e1 + b e2) / n of the flat triangle (a + b <= n): flat and unit
    npt = (n + 1) * (n + 2) // 2
    flat = np.empty((npt, 3))
    unit = np.empty((npt, 3))
    q = 0
    for a in range(n + 1):
        for b in range(n + 1 - a):
            for x in range(3):
                flat[q, x] = r1[x] + (a * inv) * e1[x] + (b * inv) * e2[x]
            ln = math.sqrt(flat[q, 0] ** 2 + flat[q, 1] ** 2 + flat[q, 2] ** 2)
            for x in range(3):
                unit[q, x] = flat[q, x] / ln
            q += 1
    g0 = (r1[0] + r2[0] + r3[0]) / 3.0
    g1 = (r1[1] + r2[1] + r3[1]) / 3.0
    g2 = (r1[2] + r2[2] + r3[2]) / 3.0
    moment = 0.0
    # the 4^depth sub-triangles of the midpoint grid, seen from the centre (a partition of the spherical
    # triangle): "up" (a, b), (a+1, b), (a, b+1) and "down" (a+1, b), (a, b+1), (a+1, b+1); point (a, b) is
    # row a * (n + 1) - a (a - 1) / 2 + b of the grid
    for a in range(n):
        for b in range(n - a):
            for up in range(2):
                if up == 1 and a + b > n - 2:
                    continue
                if up == 0:
                    i0 = a * (n + 1) - a * (a - 1) // 2 + b
                    i1 = (a + 1) * (n + 1) - (a + 1) * a // 2 + b
                    i2 = i0 + 1
                else:
                    i0 = (a + 1) * (n + 1) - (a + 1) * a // 2 + b
                    i1 = a * (n + 1) - a * (a - 1) // 2 + b + 1
                    i2 = i0 + 1
                ax, ay, az = unit[i0, 0], unit[i0, 1], unit[i0, 2]
                bx, by, bz = unit[i1, 0], unit[i1, 1], unit[i1, 2]
                cx, cy, cz = unit[i2, 0], unit[i2, 1], unit[i2, 2]
                trip = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
                den = 1.0 + ax * bx + ay * by + az * bz + ax * cx + ay * cy + az * cz + bx * cx + by * cy + bz * cz
                da = 2.0 * math.atan2(abs(trip), den)
                th = _angle(g0, g1, g2, flat[i0, 0] + flat[i1, 0] + flat[i2, 0],
                            flat[i0, 1] + flat[i1, 1] + flat[i2, 1], flat[i0, 2] + flat[i1, 2] + flat[i2, 2])
                moment += da * th * th
    return area, moment


@kernel
def tri_windows(r1, r2, r3, kind, depth, sigma_rad, beta):
    """``(area, moment, half_area, half_moment)``: features and their ``beta``-sigma half-widths.

    Each star moves by isotropic noise ``sigma_rad`` along two tangent axes; the feature variances
    are ``sigma^2`` times the summed squared derivatives (forward differences of ``FD_STEP_RAD``).
    """
    area, moment = tri_features(r1, r2, r3, kind, depth)
    va = 0.0
    vm = 0.0
    # element writes, not np.array([...]), a tuple of arrays or array expressions: the same arithmetic,
    # fewer numpy overloads to compile
    t1 = np.empty(3)
    t2 = np.empty(3)
    w = np.empty(3)
    for s in range(3):
        if s == 0:
            v = r1
        elif s == 1:
            v = r2
        else:
            v = r3
        # tangent basis at v
        if abs(v[2]) < 0.9:
            t1[0] = -v[1]
            t1[1] = v[0]
            t1[2] = 0.0
        else:
            t1[0] = 0.0
            t1[1] = -v[2]
            t1[2] = v[1]
        t1 /= math.sqrt(t1 @ t1)
        t2[0] = v[1] * t1[2] - v[2] * t1[1]
        t2[1] = v[2] * t1[0] - v[0] * t1[2]
        t2[2] = v[0] * t1[1] - v[1] * t1[0]
        for ti in range(2):
            for x in range(3):
                w[x] = v[x] + FD_STEP_RAD * (t1[x] if ti == 0 else t2[x])
            w /= math.sqrt(w @ w)
            if s == 0:
                a2, m2 = tri_features(w, r2, r3, kind, depth)
            elif s == 1:
                a2, m2 = tri_features(r1, w, r3, kind, depth)
            else:
                a2, m2 = tri_features(r1, r2, w, kind, depth)
            va += ((a2 - area) / FD_STEP_RAD) ** 2
            vm += ((m2 - moment) / FD_STEP_RAD) ** 2
    return area, moment, beta * sigma_rad * math.sqrt(va), beta * sigma_rad * math.sqrt(vm)


@inner   # kernels call it only
def _chord(u, i, w, j):
    d0 = u[i, 0] - w[j, 0]
    d1 = u[i, 1] - w[j, 1]
    d2 = u[i, 2] - w[j, 2]
    return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@kernel
def scan_catalog(unit, nbr_ptr, nbr_idx, chord_max, kind, depth, min_area, fill, stars, area, moment):
    """Every guide-star triple (i < j < k) with all three chords <= ``chord_max`` and area >= ``min_area``.

    ``nbr_ptr``/``nbr_idx``: CSR lists of each star's neighbours j > i within ``chord_max``. With
    ``fill`` False only counts; else writes ``stars``/``area``/``moment``. Returns the count.
    """
    m = 0
    n = unit.shape[0]
    for i in range(n):
        lo = nbr_ptr[i]
        hi = nbr_ptr[i + 1]
        for a in range(lo, hi):
            j = nbr_idx[a]
            for b in range(a + 1, hi):
                k = nbr_idx[b]
                if _chord(unit, j, unit, k) > chord_max:
                    continue
                if not fill:
                    m += 1
                    continue
                ar, mo = tri_features(unit[i], unit[j], unit[k], kind, depth)
                stars[m, 0] = i
                stars[m, 1] = min(j, k)
                stars[m, 2] = max(j, k)
                area[m] = ar
                moment[m] = mo
                m += 1
    return m


def block_order(area: np.ndarray, moment: np.ndarray) -> np.ndarray:
    """Permutation: ascending area, then each run of ``BLOCK`` re-sorted by moment."""
    by_area = np.argsort(area, kind="stable")
    n = by_area.shape[0]
    nb = -(-n // BLOCK)
    mom = np.full(nb * BLOCK, np.inf)
    mom[:n] = moment[by_area]
    within = np.argsort(mom.reshape(nb, BLOCK), axis=1, kind="stable") + (np.arange(nb) * BLOCK)[:, None]
    within = within.ravel()
    return by_area[within[within < n]]


@inner   # kernels call it only
def _sorted3(x, y, z):
    if x > y:
        x, y = y, x
    if y > z:
        y, z = z, y
    if x > y:
        x, y = y, x
    return x, y, z


@inner   # kernels call it only
def _sides_agree(unit, g0, g1, g2, sides, eps):
    """True when the ascending chords of catalog triangle (g0, g1, g2) are within ``eps`` of ``sides``.

    The ids (the index's uint16/int32 rows) are cast to int64, so ``_chord`` keeps the one signature
    the database build gives it."""
    g0 = np.int64(g0)
    g1 = np.int64(g1)
    g2 = np.int64(g2)
    x, y, z = _sorted3(_chord(unit, g0, unit, g1), _chord(unit, g0, unit, g2), _chord(unit, g1, unit, g2))
    return abs(x - sides[0]) <= eps and abs(y - sides[1]) <= eps and abs(z - sides[2]) <= eps


@kernel
def tri_query(index, a_lo, a_hi, m_lo, m_hi, max_hits, truncate, unit, sides, eps_side, out):
    """Triangles with area in ``[a_lo, a_hi]`` and moment in ``[m_lo, m_hi]``, written into ``out``
    (int64 positions in the block order); with ``eps_side > 0`` also with sorted chords (stars = rows of
    ``unit``) within ``eps_side`` of the ascending ``sides`` (necessary for some vertex bijection to agree
    side by side within ``eps_side``). Returns their count; ``-1`` when the area window holds more
    than ``max_hits`` triangles (a work bound: the query is not made; with ``truncate`` only the
    ``max_hits`` smallest areas are searched, as an SQL ``LIMIT`` does) or ``out`` is too small."""
    start, stop = kvector_query(index.kv, a_lo, a_hi)
    if stop - start > max_hits:
        if not truncate:
            return -1
        stop = start + max_hits
        a_hi = index.kv.values[stop - 1]
    if stop <= start:
        return 0
    mom = index.moment
    area = index.area
    count = 0
    b0 = start // BLOCK
    b1 = (stop - 1) // BLOCK
    n = mom.shape[0]
    for b in range(b0, b1 + 1):
        x = b * BLOCK
        y = min(x + BLOCK, n)
        edge = b == b0 or b == b1
        # first entry with moment >= m_lo
        lo, hi = x, y
        while lo < hi:
            mid = (lo + hi) // 2
            if mom[mid] < m_lo:
                lo = mid + 1
            else:
                hi = mid
        p = lo
        while p < y and mom[p] <= m_hi:
            if (not edge or (a_lo <= area[p] <= a_hi)) and (eps_side <= 0.0 or _sides_agree(
                    unit, index.stars[p, 0], index.stars[p, 1], index.stars[p, 2], sides, eps_side)):
                if count == out.shape[0]:
                    return -1
                out[count] = p
                count += 1
            p += 1
    return count


PERMS = np.array([[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]], dtype=np.int64)


@inner   # kernels call it only
def _triple(u, i, j, k):
    return (u[i, 0] * (u[j, 1] * u[k, 2] - u[j, 2] * u[k, 1]) + u[i, 1] * (u[j, 2] * u[k, 0] - u[j, 0] * u[k, 2])
            + u[i, 2] * (u[j, 0] * u[k, 1] - u[j, 1] * u[k, 0]))


@inner   # kernels call it only
def trio_confirm(v_cam, trio, cat, guide_unit, eps, match_sides, c_fov, min_extra, confirm_fraction, cam, rows,
                 trial):
    """The direct-match test of image stars ``trio`` (3 rows of ``v_cam``) against catalog triangle ``cat``.

    Each of the six vertex bijections (with ``match_sides``: only those whose three chords agree within
    ``eps`` and whose triple products have the same sign) gives an attitude (Wahba on the three stars) and
    the detections it explains (``reproject_assign``, match radius ``eps``). The bijection explaining the
    most detections wins; its attitude is re-solved from all of them once. It stands when the three trio
    stars keep their rows, at least ``min_extra`` others are explained, and at least ``confirm_fraction``
    of the guide stars the attitude puts on the sensor are seen. Returns the number of detections explained
    (rows in ``rows``), or -1 (``trial`` is scratch).
    """
    n = v_cam.shape[0]
    best = -1
    best_p = -1
    t_img = _triple(v_cam, trio[0], trio[1], trio[2])
    for p in range(6):
        g0 = np.int64(cat[PERMS[p, 0]])
        g1 = np.int64(cat[PERMS[p, 1]])
        g2 = np.int64(cat[PERMS[p, 2]])
        if match_sides:
            if abs(_chord(v_cam, trio[0], v_cam, trio[1]) - _chord(guide_unit, g0, guide_unit, g1)) > eps:
                continue
            if abs(_chord(v_cam, trio[0], v_cam, trio[2]) - _chord(guide_unit, g0, guide_unit, g2)) > eps:
                continue
            if abs(_chord(v_cam, trio[1], v_cam, trio[2]) - _chord(guide_unit, g1, guide_unit, g2)) > eps:
                continue
            if t_img * _triple(guide_unit, g0, g1, g2) <= 0.0:
                continue
        for i in range(n):
            trial[i] = -1
        trial[trio[0]] = g0
        trial[trio[1]] = g1
        trial[trio[2]] = g2
        att = wahba_rows(v_cam, trial, guide_unit)
        seen, _ = reproject_assign(att, v_cam, guide_unit, c_fov + eps, eps, trial, cam.f_px, cam.cx_px,
                                   cam.cy_px, cam.width_px, cam.height_px)
        if trial[trio[0]] != g0 or trial[trio[1]] != g1 or trial[trio[2]] != g2:
            continue
        if seen > best:
            best = seen
            best_p = p
    if best_p < 0:
        return -1
    for i in range(n):
        rows[i] = -1
    for a in range(3):
        rows[trio[a]] = np.int64(cat[PERMS[best_p, a]])
    att = wahba_rows(v_cam, rows, guide_unit)
    for _ in range(2):
        seen, predicted = reproject_assign(att, v_cam, guide_unit, c_fov + eps, eps, rows, cam.f_px, cam.cx_px,
                                           cam.cy_px, cam.width_px, cam.height_px)
        for a in range(3):
            if rows[trio[a]] != np.int64(cat[PERMS[best_p, a]]):
                return -1
        if seen - 3 < min_extra or seen < confirm_fraction * predicted:
            return -1
        att = wahba_rows(v_cam, rows, guide_unit)
    return seen


def build_triangle_index(unit: np.ndarray, chord_max: float, kind: int, depth: int,
                         min_area: float) -> TriangleIndex:
    """The :class:`TriangleIndex` of every triple of rows of ``unit`` (float64 (n, 3), n < 65536) whose
    three chords are <= ``chord_max`` and whose area is >= ``min_area``."""
    from scipy.spatial import cKDTree

    from .kvector import kvector_make

    n = unit.shape[0]
    if n >= 65536:
        raise ValueError("triangle index: star rows are stored as uint16 (< 65536 stars)")
    pairs = cKDTree(unit).query_pairs(chord_max, output_type="ndarray").astype(np.int64)
    pairs.sort(axis=1)
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(ptr, pairs[:, 0] + 1, 1)
    ptr = np.cumsum(ptr)
    idx = np.ascontiguousarray(pairs[:, 1])
    unit = np.ascontiguousarray(unit, dtype=np.float64)
    dummy_s = np.zeros((0, 3), dtype=np.uint16)
    dummy_f = np.zeros(0)
    m = scan_catalog(unit, ptr, idx, chord_max, kind, depth, min_area, False, dummy_s, dummy_f, dummy_f)
    stars = np.empty((m, 3), dtype=np.uint16)
    area = np.empty(m)
    moment = np.empty(m)
    scan_catalog(unit, ptr, idx, chord_max, kind, depth, min_area, True, stars, area, moment)
    keep = area >= min_area
    stars, area, moment = stars[keep], area[keep], moment[keep]
    order = block_order(area, moment)
    return TriangleIndex(kv=kvector_make(np.sort(area), np.float64, np.int32),
                         moment=np.ascontiguousarray(moment[order]), area=np.ascontiguousarray(area[order]),
                         stars=np.ascontiguousarray(stars[order]))


@kernel   # spherical_triangle's testing.py calls it from Python
def trio_query(v_cam, a, b, c, index, kind, depth, sigma_rad, beta, fixed_area, fixed_moment, chord_max,
               max_hits, truncate, unit, eps_side, out):
    """:func:`tri_query` for the image triangle of rows ``a, b, c`` of ``v_cam``: 0 when a side is longer
    than ``chord_max``; windows ``fixed_area`` / ``fixed_moment`` when > 0, else :func:`tri_windows`;
    ``eps_side > 0``: the catalog triangle's sides must agree too (``unit``: the guide stars)."""
    c_ab = _chord(v_cam, a, v_cam, b)
    c_ac = _chord(v_cam, a, v_cam, c)
    c_bc = _chord(v_cam, b, v_cam, c)
    if c_ab > chord_max or c_ac > chord_max or c_bc > chord_max:
        return 0
    x, y, z = _sorted3(c_ab, c_ac, c_bc)
    sides = np.array([x, y, z])
    if fixed_area > 0.0:
        area, moment = tri_features(v_cam[a], v_cam[b], v_cam[c], kind, depth)
        ha = fixed_area
        hm = fixed_moment
    else:
        area, moment, ha, hm = tri_windows(v_cam[a], v_cam[b], v_cam[c], kind, depth, sigma_rad, beta)
    return tri_query(index, area - ha, area + ha, moment - hm, moment + hm, max_hits, truncate, unit, sides,
                     eps_side, out)


def guide_triangles(catalog, mag_limit: float, fov_db_deg: float, kind: int, depth: int, min_area: float,
                    who: str):
    """Guide stars (V <= ``mag_limit``, unit vectors sorted by z as ``reproject_assign`` needs) and the
    :class:`TriangleIndex` of their triangles whose three sides are <= ``fov_db_deg``.

    Returns ``(index, guide_unit float64 (g, 3), guide_hip int64 (g,))``; raises ``ConfigError`` when
    fewer than three guide stars or none of their triangles fit.
    """
    from starid.errors import ConfigError

    guide = catalog.brighter_than(mag_limit)
    if len(guide) < 3:
        raise ConfigError(f"{who}: only {len(guide)} catalog stars have V <= {mag_limit}")
    if len(guide) >= 65536:
        raise ConfigError(f"{who}: {len(guide)} guide stars (V <= {mag_limit}); at most 65,535 are supported")
    by_z = np.lexsort((guide.hip, guide.unit_icrs[:, 2]))
    unit = np.ascontiguousarray(guide.unit_icrs[by_z], dtype=np.float64)
    chord_max = 2.0 * math.sin(math.radians(fov_db_deg) / 2.0)
    index = build_triangle_index(unit, chord_max, kind, depth, min_area)
    if index.moment.shape[0] < 2:
        raise ConfigError(f"{who}: fewer than two guide-star triangles fit in {fov_db_deg} deg")
    return index, unit, guide.hip[by_z].astype(np.int64)
