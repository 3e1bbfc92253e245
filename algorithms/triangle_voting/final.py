"""The final step of triangle voting over a deep sky ordered for cone searches (issue #25, branch tvspeed2).

The same step as planar_triangle's ``finish`` (attitude, ``starid.kernels.assign_all``, the coverage check,
close-pair rivals; see docs/algorithms/triangle_voting.md) with the same answers, but the deep sky (every
catalog star, the database's ``deep``) is stored in another order: by one of :data:`DEEP_BANDS` bands of z,
then by a right-ascension key (:func:`ra_key`), then by HIP, instead of by z alone. The shared kernels scan
the whole declination band of the field (about 5,000 of 41,225 stars for Table 6's camera) and test each
star's distance from the boresight; here only each z band's slice of right ascension that can reach the
cone is read (:func:`cone_ranges`, a few hundred stars). Every star so read is then put to the shared
kernels' own tests, band membership included (the z band ``starid.kernels.z_band_rows`` would have
scanned), so a star counts here exactly when it counts there; a star the cone search skips is farther
than the cone's radius (plus :data:`CONE_MARGIN`), where no test can pass.
"""

from __future__ import annotations

import math

import numpy as np

from starid.kernels import backproject_px, chord_rows, merge_assigned, wahba_rows
from starid.kernels.jit import inline_kernel, inner, kernel
from starid.kernels.prefetch import prefetch


# inline="always": called for arrays of several dtypes and row sizes (literal); inlined, it adds no signature
@inline_kernel
def _prefetch_rows(arr, ranges, count, per_line):
    """:func:`~starid.kernels.prefetch.prefetch` every ``per_line``-th row of ``arr`` in the row ranges
    ``ranges[:count]`` (rows of ``64 / per_line`` bytes or more: one request per cache line), and each
    range's last row."""
    for k in range(count):
        for g in range(ranges[k, 0], ranges[k, 1], per_line):
            prefetch(arr, g)
        if ranges[k, 1] > ranges[k, 0]:
            prefetch(arr, ranges[k, 1] - 1)


#: z bands of the deep sky's order (``z`` in [-1, 1] cut in this many equal bands)
DEEP_BANDS = 64
#: widening of every cone search (chord / radians): covers the float32 rows' departure from unit length
#: (~1e-7) and the rounding of the bounds with a wide margin
CONE_MARGIN = 1e-5
#: right-ascension buckets of each z band in :func:`deep_index` (a key ``k`` in [0, 4) is in bucket
#: ``min(int(k * KEY_BUCKETS / 4), KEY_BUCKETS - 1)``; a power of two, so that product is exact)
KEY_BUCKETS = 64
#: most row ranges one cone search returns (two per band: a right-ascension slice may wrap around)
MAX_RANGES = 2 * DEEP_BANDS


@inner
def deep_band(z):
    """The z band of a row (``DEEP_BANDS`` equal bands of [-1, 1])."""
    return min(max(int((z + 1.0) * 0.5 * DEEP_BANDS), 0), DEEP_BANDS - 1)


@inner
def ra_key(x, y):
    """A key in [0, 4) increasing with the right ascension ``atan2(y, x)`` taken in [0, 2 pi) (no trigonometry:
    the quadrant plus the share of ``|x| + |y|`` along it)."""
    if y >= 0.0:
        if x >= 0.0:
            s = x + y
            return y / s if s > 0.0 else 0.0
        return 1.0 - x / (y - x)
    if x < 0.0:
        return 2.0 - y / (-x - y)
    return 3.0 + x / (x - y)


@kernel
def deep_keys(unit):
    """Per row of ``unit`` (float32 (m, 3)) its :func:`deep_band` and :func:`ra_key` (the sort keys of the order)."""
    m = unit.shape[0]
    band = np.empty(m, dtype=np.int64)
    key = np.empty(m)
    for g in range(m):
        band[g] = deep_band(np.float64(unit[g, 2]))  # np.float64: float() of a float32 stays float32
        key[g] = ra_key(np.float64(unit[g, 0]), np.float64(unit[g, 1]))
    return band, key


def band_order(unit: np.ndarray, hip: np.ndarray) -> np.ndarray:
    """The rows of a deep sky (float32 unit vectors, HIP) in this module's order: band, then key, then HIP."""
    band, key = deep_keys(unit)
    return np.lexsort((hip, key, band))


@inner
def _key_bucket(k):
    """The right-ascension bucket of key ``k`` (:data:`KEY_BUCKETS` equal buckets of [0, 4))."""
    return min(int(k * (KEY_BUCKETS / 4.0)), KEY_BUCKETS - 1)


def deep_index(unit: np.ndarray) -> np.ndarray:
    """int32 ``(DEEP_BANDS * KEY_BUCKETS + 1,)``: of a deep sky in :func:`band_order`, the first row of each (z band,
    right-ascension bucket) cell, ``cell = band * KEY_BUCKETS + bucket`` (the rows of a cell are
    ``index[cell]:index[cell + 1]``). The cone search (:func:`cone_ranges_indexed`) starts its binary searches
    there instead of over the whole deep sky: the same rows found, a few cache lines read instead of ~35 scattered
    ones per band (issue #25: in the benchmark's interleaved timing each was a miss)."""
    band, key = deep_keys(unit)
    cell = band * KEY_BUCKETS + np.minimum((key * (KEY_BUCKETS / 4.0)).astype(np.int64), KEY_BUCKETS - 1)
    return np.searchsorted(cell, np.arange(DEEP_BANDS * KEY_BUCKETS + 1)).astype(np.int32)


@inner
def _first_band(unit, b, lo, hi):
    """First row in ``[lo, hi)`` whose band is ``>= b`` (rows sorted by band)."""
    while lo < hi:
        mid = (lo + hi) // 2
        if deep_band(np.float64(unit[mid, 2])) < b:
            lo = mid + 1
        else:
            hi = mid
    return lo


@inner
def _first_key(unit, k, lo, hi, upper):
    """First row in ``[lo, hi)`` whose key is ``>= k`` (``upper``: ``> k``), rows of one band (sorted by key)."""
    while lo < hi:
        mid = (lo + hi) // 2
        km = ra_key(np.float64(unit[mid, 0]), np.float64(unit[mid, 1]))
        if km < k or (upper and km == k):
            lo = mid + 1
        else:
            hi = mid
    return lo


@inner   # kernels call it only
def _cone_bounds(cx, cy, cz, c_radius):
    """``(b0, b1, full, k0, k1, wrap)`` of a cone search around ``(cx, cy, cz)``: its z bands ``b0..b1``;
    ``full`` when every right ascension is in the cone; else the right-ascension keys ``[k0, k1]``, or
    ``[k0, 4)`` and ``[0, k1]`` when ``wrap``."""
    rho = c_radius + CONE_MARGIN
    b0 = deep_band(cz - rho)
    b1 = deep_band(cz + rho)
    theta = 2.0 * math.asin(min(1.0, 0.5 * rho)) + CONE_MARGIN
    cos_dec = math.sqrt(max(0.0, 1.0 - cz * cz))
    full = cos_dec <= math.sin(theta) or theta >= 0.5 * math.pi
    k0 = 0.0
    k1 = 4.0
    wrap = False
    if not full:
        half = math.asin(min(1.0, math.sin(theta) / cos_dec)) + CONE_MARGIN
        ra = math.atan2(cy, cx)
        a0 = ra - half
        if a0 < 0.0:
            a0 += 2.0 * math.pi
        a1 = a0 + 2.0 * half
        k0 = ra_key(math.cos(a0), math.sin(a0))
        if a1 >= 2.0 * math.pi:
            a1 -= 2.0 * math.pi
            wrap = True
        k1 = ra_key(math.cos(a1), math.sin(a1))
        if not wrap and k1 < k0:  # a1 just below 2 pi whose key rounded to 0
            wrap = True
    return b0, b1, full, k0, k1, wrap


@kernel
def cone_ranges(unit, cx, cy, cz, c_radius, ranges):
    """Row ranges ``ranges[:count]`` (start, stop) of the deep sky that hold every row within chord
    ``c_radius`` of the direction ``(cx, cy, cz)`` (unit length); returns ``count``."""
    b0, b1, full, k0, k1, wrap = _cone_bounds(cx, cy, cz, c_radius)
    m = unit.shape[0]
    count = 0
    start = _first_band(unit, b0, np.int64(0), m)  # runtime values: one signature
    for b in range(b0, b1 + 1):
        stop = _first_band(unit, b + 1, start, m)
        if full:
            ranges[count, 0] = start
            ranges[count, 1] = stop
            count += 1
        elif wrap:  # [k0, 4) and [0, k1]
            ranges[count, 0] = _first_key(unit, k0, start, stop, np.bool_(False))
            ranges[count, 1] = stop
            ranges[count + 1, 0] = start
            ranges[count + 1, 1] = _first_key(unit, k1, start, stop, np.bool_(True))
            count += 2
        else:
            lo = _first_key(unit, k0, start, stop, np.bool_(False))
            ranges[count, 0] = lo
            ranges[count, 1] = _first_key(unit, k1, lo, stop, np.bool_(True))
            count += 1
        start = stop
    return count


@kernel
def cone_ranges_indexed(unit, index, cx, cy, cz, c_radius, ranges):
    """:func:`cone_ranges` (the same ranges) with the cells of :func:`deep_index`: a band's rows from the index, and
    each key's binary search only over its bucket (rows of a lower bucket have a smaller key, of a higher bucket
    a larger one)."""
    b0, b1, full, k0, k1, wrap = _cone_bounds(cx, cy, cz, c_radius)
    q0 = _key_bucket(k0)
    q1 = _key_bucket(k1)
    # the index entries of every band first, then the rows where the binary searches start, so that the
    # bands' cache misses overlap instead of following one another
    for b in range(b0, b1 + 1):
        prefetch(index, b * KEY_BUCKETS + q0)
        prefetch(index, b * KEY_BUCKETS + q1)
        prefetch(index, (b + 1) * KEY_BUCKETS)
    if not full:
        for b in range(b0, b1 + 1):
            prefetch(unit, index[b * KEY_BUCKETS + q0])
            prefetch(unit, index[b * KEY_BUCKETS + q1])
    count = 0
    for b in range(b0, b1 + 1):
        cell = b * KEY_BUCKETS
        start = np.int64(index[cell])
        stop = np.int64(index[cell + KEY_BUCKETS])
        if full:
            ranges[count, 0] = start
            ranges[count, 1] = stop
            count += 1
        elif wrap:  # [k0, 4) and [0, k1]
            ranges[count, 0] = _first_key(unit, k0, np.int64(index[cell + q0]), np.int64(index[cell + q0 + 1]),
                                          np.bool_(False))
            ranges[count, 1] = stop
            ranges[count + 1, 0] = start
            ranges[count + 1, 1] = _first_key(unit, k1, np.int64(index[cell + q1]), np.int64(index[cell + q1 + 1]),
                                              np.bool_(True))
            count += 2
        else:
            lo = _first_key(unit, k0, np.int64(index[cell + q0]), np.int64(index[cell + q0 + 1]), np.bool_(False))
            ranges[count, 0] = lo
            ranges[count, 1] = _first_key(unit, k1, max(lo, np.int64(index[cell + q1])),
                                          np.int64(index[cell + q1 + 1]), np.bool_(True))
            count += 1
    return count


@inner
def z_band(z_centre, c_radius):
    """``(z_lo, z_hi)`` of ``starid.kernels.z_band_rows``: its rows are those with ``z_lo <= z <= z_hi``."""
    half = 2.0 * math.asin(min(1.0, 0.5 * c_radius))
    dec0 = math.asin(max(-1.0, min(1.0, float(z_centre))))
    z_lo = math.sin(max(-0.5 * math.pi, dec0 - half))
    z_hi = math.sin(min(0.5 * math.pi, dec0 + half))
    return z_lo, z_hi


@inner
def field_chord_px(f_px, cx_px, cy_px, width_px, height_px):
    """``starid.kernels.field_chord`` of the frame: chord from the boresight to the farthest sensor corner."""
    corners = backproject_px(np.array([0.0, width_px, 0.0, width_px]), np.array([0.0, 0.0, height_px, height_px]),
                             f_px, cx_px, cy_px)
    c = 0.0
    for i in range(4):
        c = max(c, math.sqrt(corners[i, 0] ** 2 + corners[i, 1] ** 2 + (corners[i, 2] - 1.0) ** 2))
    return c


@inner
def _reproject_assign(A, v_cam, unit, index, c_fov, eps, out_row, ranges, f_px, cx_px, cy_px, width_px, height_px):
    """``starid.kernels.reproject_assign`` (its ``n_assigned``) over the rows of the cone search."""
    n = v_cam.shape[0]
    n_match = np.zeros(n, dtype=np.int64)
    for i in range(n):
        out_row[i] = -1
    bore = np.empty((1, 3))
    for a in range(3):
        bore[0, a] = A[2, a]
    b = np.empty((1, 3))
    z_lo, z_hi = z_band(bore[0, 2], c_fov)
    count = cone_ranges_indexed(unit, index, bore[0, 0], bore[0, 1], bore[0, 2], c_fov, ranges)
    eps_x = eps * (1.0 + 1e-9)
    _prefetch_rows(unit, ranges, count, 5)
    for k in range(count):
        for g in range(ranges[k, 0], ranges[k, 1]):
            z = unit[g, 2]
            if not (z >= z_lo and z <= z_hi):  # the z band the shared kernel scans
                continue
            if chord_rows(unit, g, bore, np.int64(0)) > c_fov:
                continue
            for a in range(3):
                b[0, a] = A[a, 0] * unit[g, 0] + A[a, 1] * unit[g, 1] + A[a, 2] * unit[g, 2]
            found = -1
            n_found = 0
            for i in range(n):
                # a star farther than eps_x along x alone is farther than eps (the chord's float64 rounding is
                # ~3e-16 of it, far inside eps_x's margin): decided without the chord, the same outcome
                if abs(v_cam[i, 0] - b[0, 0]) > eps_x:
                    continue
                if chord_rows(v_cam, i, b, np.int64(0)) <= eps:
                    n_found += 1
                    found = i
            if n_found == 1:
                n_match[found] += 1
                out_row[found] = g
            elif n_found > 1:
                for i in range(n):
                    if chord_rows(v_cam, i, b, np.int64(0)) <= eps:
                        n_match[i] += 2
    for i in range(n):
        if n_match[i] != 1:
            out_row[i] = -1


@inner
def _assign_all(attitude, v_all, deep_unit, deep_index, deep_hip, eps_chord, hip, ranges, f_px, cx_px, cy_px, width_px,
                height_px):
    """``starid.kernels.assign_all`` (``hip`` updated in place) over the cone search; ``v_all`` the stars'
    camera vectors (``backproject_px`` of every star)."""
    n = v_all.shape[0]
    rows = np.empty(n, dtype=np.int64)
    c_fov = field_chord_px(f_px, cx_px, cy_px, width_px, height_px) + eps_chord
    _reproject_assign(attitude, v_all, deep_unit, deep_index, c_fov, eps_chord, rows, ranges, f_px, cx_px, cy_px,
                      width_px, height_px)
    merge_assigned(rows, deep_hip, hip)


@inner
def _deep_mag_of(deep_unit, deep_index, deep_hip, deep_mag, r_icrs, eps_chord, hip, ranges):
    """V of the deep star ``hip``, which lies within chord ``eps_chord`` of the ICRS direction ``r_icrs``
    (planar_triangle's ``_deep_mag_of``: searched in the z band of chord ``2 eps_chord``)."""
    z_lo, z_hi = z_band(float(r_icrs[2]), 2.0 * eps_chord)
    count = cone_ranges_indexed(deep_unit, deep_index, r_icrs[0], r_icrs[1], r_icrs[2], 2.0 * eps_chord, ranges)
    _prefetch_rows(deep_unit, ranges, count, 5)
    _prefetch_rows(deep_hip, ranges, count, 8)
    for k in range(count):
        for g in range(ranges[k, 0], ranges[k, 1]):
            z = deep_unit[g, 2]
            if deep_hip[g] == hip and z >= z_lo and z <= z_hi:
                return float(deep_mag[g])
    return np.inf


@inner
def _rivals(deep_unit, deep_index, deep_mag, r_icrs, eps_chord, mag_max, ranges):
    """How many deep stars with V <= ``mag_max`` lie within chord ``eps_chord`` of ``r_icrs`` (planar_triangle's
    ``_rivals``)."""
    z_lo, z_hi = z_band(float(r_icrs[2]), eps_chord)
    n_ranges = cone_ranges_indexed(deep_unit, deep_index, r_icrs[0], r_icrs[1], r_icrs[2], eps_chord, ranges)
    _prefetch_rows(deep_mag, ranges, n_ranges, 16)
    _prefetch_rows(deep_unit, ranges, n_ranges, 5)
    count = 0
    for k in range(n_ranges):
        for g in range(ranges[k, 0], ranges[k, 1]):
            z = deep_unit[g, 2]
            if deep_mag[g] <= mag_max and z >= z_lo and z <= z_hi:
                d0 = float(deep_unit[g, 0]) - r_icrs[0]
                d1 = float(deep_unit[g, 1]) - r_icrs[1]
                d2 = float(deep_unit[g, 2]) - r_icrs[2]
                if d0 * d0 + d1 * d1 + d2 * d2 <= eps_chord * eps_chord:
                    count += 1
    return count


@inner
def _coverage(attitude, deep_unit, deep_index, deep_hip, deep_mag, mag_max, found_hip, ranges, f_px, cx_px, cy_px,
              width_px, height_px):
    """``(predicted, missed)`` of planar_triangle's ``coverage`` over the cone search of the field; ``found_hip``:
    the identified stars' HIP (-1: none), in any order."""
    c_field = field_chord_px(f_px, cx_px, cy_px, width_px, height_px)
    z_lo, z_hi = z_band(attitude[2, 2], c_field)
    n_ranges = cone_ranges_indexed(deep_unit, deep_index, attitude[2, 0], attitude[2, 1], attitude[2, 2], c_field,
                                   ranges)
    _prefetch_rows(deep_mag, ranges, n_ranges, 16)
    _prefetch_rows(deep_unit, ranges, n_ranges, 5)
    predicted = 0
    missed = 0
    for k in range(n_ranges):
        for g in range(ranges[k, 0], ranges[k, 1]):
            if deep_mag[g] > mag_max:
                continue
            z = deep_unit[g, 2]
            if not (z >= z_lo and z <= z_hi):
                continue
            u0, u1, u2 = float(deep_unit[g, 0]), float(deep_unit[g, 1]), float(deep_unit[g, 2])
            pz = attitude[2, 0] * u0 + attitude[2, 1] * u1 + attitude[2, 2] * u2
            if pz <= 0.0:
                continue
            x = cx_px + f_px * (attitude[0, 0] * u0 + attitude[0, 1] * u1 + attitude[0, 2] * u2) / pz
            y = cy_px + f_px * (attitude[1, 0] * u0 + attitude[1, 1] * u1 + attitude[1, 2] * u2) / pz
            if not (0.0 <= x < width_px and 0.0 <= y < height_px):
                continue
            predicted += 1
            found = False  # a scan of the few ids (-1: none), not np.sort / np.searchsorted (compile time)
            for q in range(found_hip.shape[0]):
                if found_hip[q] == deep_hip[g]:
                    found = True
                    break
            if not found:
                missed += 1
    return predicted, missed


# inline="always": identify_image takes its body in numba IR (one level of compilation less; see identify_rows)
@inline_kernel
def finish_cone(x_px, y_px, mag, rows, guide_unit, guide_hip, deep_unit, deep_index, deep_hip, deep_mag, f_px, cx_px,
                cy_px, width_px, height_px, eps_chord, mag_margin, mag_limit, coverage_mag_margin, max_missed_fraction,
                assign_all):
    """planar_triangle's ``finish`` (same steps, same answers) on a deep sky in :func:`band_order` with its
    :func:`deep_index`, with the camera frame and the rules as plain numbers. Returns ``(hip int64 (n,), attitude
    3x3, accepted)``."""
    n = rows.shape[0]
    hip = np.full(n, -1, dtype=np.int64)
    n_found = 0
    for i in range(n):
        if rows[i] >= 0:
            hip[i] = guide_hip[rows[i]]
            n_found += 1
    if n_found < 2:
        return np.full(n, -1, dtype=np.int64), np.zeros((3, 3)), False
    ranges = np.empty((MAX_RANGES, 2), dtype=np.int64)
    v_cam = backproject_px(x_px, y_px, f_px, cx_px, cy_px)
    attitude = wahba_rows(v_cam, rows, guide_unit)
    assigned = hip.copy()
    _assign_all(attitude, v_cam, deep_unit, deep_index, deep_hip, eps_chord, assigned, ranges, f_px, cx_px, cy_px,
                width_px, height_px)
    hip_all = hip.copy()
    r_icrs = np.empty(3)
    for i in range(n):
        if rows[i] >= 0 or assigned[i] < 0:
            continue
        taken = False
        for j in range(n):
            if rows[j] >= 0 and hip[j] == assigned[i]:
                taken = True
        if taken:
            continue
        for a in range(3):
            r_icrs[a] = attitude[0, a] * v_cam[i, 0] + attitude[1, a] * v_cam[i, 1] + attitude[2, a] * v_cam[i, 2]
        v_assigned = _deep_mag_of(deep_unit, deep_index, deep_hip, deep_mag, r_icrs, eps_chord, assigned[i], ranges)
        if v_assigned <= mag[i] + mag_margin:
            hip_all[i] = assigned[i]
    if max_missed_fraction < 1.0:
        faintest_mag = mag[0]  # mag.max() without numpy's reduction machinery (compile time)
        for i in range(1, n):
            if mag[i] > faintest_mag or math.isnan(mag[i]):
                faintest_mag = mag[i]
        mag_max = min(mag_limit, faintest_mag) - coverage_mag_margin
        predicted, missed = _coverage(attitude, deep_unit, deep_index, deep_hip, deep_mag, mag_max, hip_all, ranges,
                                      f_px, cx_px, cy_px, width_px, height_px)
        if not (missed <= 1 or missed <= max_missed_fraction * predicted):
            return np.full(n, -1, dtype=np.int64), attitude, False
    for i in range(n):
        if rows[i] < 0:
            continue
        for a in range(3):
            r_icrs[a] = attitude[0, a] * v_cam[i, 0] + attitude[1, a] * v_cam[i, 1] + attitude[2, a] * v_cam[i, 2]
        if _rivals(deep_unit, deep_index, deep_mag, r_icrs, eps_chord, mag[i] + mag_margin, ranges) > 1:
            hip[i] = -1
            hip_all[i] = -1
    if assign_all:
        return hip_all, attitude, True
    return hip, attitude, True
