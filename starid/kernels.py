"""Shared numba kernels: projection, angular distance, triangle sides and the k-vector.

These live once in the core and every algorithm reuses them. All are ``@njit(cache=True)``
and take/return plain numpy arrays, so they can be called from Python or from other kernels.

Units: angles in radians; unit vectors are 3-vectors in whatever frame the caller says
(camera frame for observed stars, ICRS for catalog stars); "chord" is the Euclidean distance
between two unit vectors, ``2 sin(theta / 2)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def project_cam(v_cam, f_px, cx_px, cy_px):
    """Pinhole projection of camera-frame vectors ``(n, 3)``: ``x = cx + f vx/vz``, ``y = cy + f vy/vz``."""
    n = v_cam.shape[0]
    x_px = np.empty(n)
    y_px = np.empty(n)
    for i in range(n):
        x_px[i] = cx_px + f_px * v_cam[i, 0] / v_cam[i, 2]
        y_px[i] = cy_px + f_px * v_cam[i, 1] / v_cam[i, 2]
    return x_px, y_px


@njit(cache=True)
def backproject_px(x_px, y_px, f_px, cx_px, cy_px):
    """Camera-frame unit vectors ``(n, 3)`` of pixel positions; the exact inverse of ``project_cam``."""
    n = x_px.shape[0]
    v_cam = np.empty((n, 3))
    for i in range(n):
        vx = x_px[i] - cx_px
        vy = y_px[i] - cy_px
        norm = math.sqrt(vx * vx + vy * vy + f_px * f_px)
        v_cam[i, 0] = vx / norm
        v_cam[i, 1] = vy / norm
        v_cam[i, 2] = f_px / norm
    return v_cam


@njit(cache=True)
def chord(u, v):
    """Euclidean distance between two unit 3-vectors (``2 sin(theta/2)``)."""
    dx = u[0] - v[0]
    dy = u[1] - v[1]
    dz = u[2] - v[2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True)
def chord_rows(a, i, b, j):
    """Chord between row ``i`` of ``a`` and row ``j`` of ``b`` (unit vectors, float64 result).

    The same value as ``chord(a[i], b[j])``, without creating array views: inside hot numba
    loops the views' reference counting costs several times the arithmetic.
    """
    dx = float(a[i, 0]) - float(b[j, 0])
    dy = float(a[i, 1]) - float(b[j, 1])
    dz = float(a[i, 2]) - float(b[j, 2])
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True)
def angular_distance_rad(u, v):
    """Angle between two unit 3-vectors in radians, accurate at small angles (via the chord)."""
    c = chord(u, v)
    if c >= 2.0:
        return math.pi
    return 2.0 * math.asin(0.5 * c)


@njit(cache=True)
def chord_to_rad(c):
    """Convert a chord of unit vectors to the angle it subtends, in radians."""
    if c >= 2.0:
        return math.pi
    return 2.0 * math.asin(0.5 * c)


@njit(cache=True)
def rad_to_chord(theta_rad):
    """Chord of unit vectors separated by ``theta_rad``."""
    return 2.0 * math.sin(0.5 * theta_rad)


@njit(cache=True)
def triangle_sides(r1, r2, r3):
    """Chord sides of the planar triangle of three unit vectors (Zhou & Ye 2015, eq. 1).

    Returns ``(a, b, c)`` with ``a = |r1 - r2|``, ``b = |r2 - r3|``, ``c = |r1 - r3|``.
    """
    return chord(r1, r2), chord(r2, r3), chord(r1, r3)


@njit(cache=True)
def pairwise_chords(vectors):
    """Symmetric ``(n, n)`` matrix of chords between unit vectors ``(n, 3)``."""
    n = vectors.shape[0]
    out = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            d = chord(vectors[i], vectors[j])
            out[i, j] = d
            out[j, i] = d
    return out


def kvector_build(sorted_values: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Build Mortari's k-vector over ascending ``sorted_values`` (Mortari & Neta 2000).

    The line ``z(i) = m i + q`` (i = 1..n) is slightly steeper than the data and passes just
    outside both extremes (Zhou & Ye 2015, eqs. 15-16); ``k[i-1] = #{s_j <= z(i)}``.
    Returns ``(k, m, q)``; query with :func:`kvector_range`.
    """
    s = np.ascontiguousarray(sorted_values, dtype=np.float64)
    n = s.shape[0]
    if n >= 2 and np.any(np.diff(s) < 0):
        raise ValueError("kvector_build needs ascending values")
    if n < 2 or s[-1] == s[0]:
        lo = s[0] if n else 0.0
        m, q = 1.0, lo - 1.0
    else:
        xi = np.finfo(np.float64).eps * max(abs(s[0]), abs(s[-1]))
        m = (s[-1] - s[0] + 2.0 * xi) / (n - 1)
        q = s[0] - m - xi
    z = m * np.arange(1, n + 1, dtype=np.float64) + q
    k = np.searchsorted(s, z, side="right").astype(np.int64)
    return k, float(m), float(q)


@njit(cache=True)
def kvector_range(sorted_values, k, m, q, lo, hi):
    """Index range ``[start, stop)`` of ``sorted_values`` lying in ``[lo, hi]``.

    The k-vector gives a slightly wide slice in O(1) (Zhou & Ye 2015, eqs. 17-19); its ends
    are then trimmed exactly, so the result equals
    ``searchsorted(s, lo, 'left'), searchsorted(s, hi, 'right')``.
    """
    n = sorted_values.shape[0]
    if n == 0 or hi < lo:
        return 0, 0
    jb = int(math.floor((lo - q) / m)) - 1
    jt = int(math.ceil((hi - q) / m)) + 1
    if jb < 1:
        start = 0
    elif jb > n:
        start = n
    else:
        start = k[jb - 1]
    if jt < 1:
        stop = 0
    elif jt > n:
        stop = n
    else:
        stop = k[jt - 1]
    # Trim (or widen, when float rounding put the line on the wrong side) to the exact range.
    while start > 0 and sorted_values[start - 1] >= lo:
        start -= 1
    while start < n and sorted_values[start] < lo:
        start += 1
    while stop < n and sorted_values[stop] <= hi:
        stop += 1
    while stop > start and sorted_values[stop - 1] > hi:
        stop -= 1
    if stop < start:
        stop = start
    return start, stop


@njit(cache=True)
def verify_pairwise(v_cam, cand_row, cat_unit, tol_chord, min_support, min_fraction=0.0):
    """Pairwise angular-consistency verification (algorithm notes 1.5, geometric-voting style).

    ``cand_row[i]`` is the catalog row proposed for observed star ``i`` (-1 = none). Two
    proposals agree when their observed chord and catalog chord differ by at most
    ``tol_chord``. The proposal with the least agreement is dropped, repeatedly, until every
    remaining one agrees with at least ``max(min_support, ceil(min_fraction * (k - 1)))`` of
    the ``k - 1`` others (``min_fraction = 0.5``: a majority, so a small self-consistent cluster
    of wrong proposals loses to a larger true one; ``1.0``: every pair must agree). Among equally
    supported proposals the one with the larger sum of chord residuals goes first. Stars left
    sharing a catalog row are dropped too. Returns a boolean mask of the accepted proposals.
    """
    n = v_cam.shape[0]
    active = cand_row >= 0
    while True:
        worst = -1
        worst_support = 1 << 30
        worst_residual = 0.0
        n_active = 0
        for i in range(n):
            if not active[i]:
                continue
            n_active += 1
            support = 0
            residual = 0.0
            for j in range(n):
                if j == i or not active[j] or cand_row[i] == cand_row[j]:
                    continue
                r = abs(chord_rows(v_cam, i, v_cam, j) - chord_rows(cat_unit, cand_row[i], cat_unit, cand_row[j]))
                residual += r
                if r <= tol_chord:
                    support += 1
            # the least supported goes first; among equals, the one with the larger residual sum
            if support < worst_support or (support == worst_support and residual > worst_residual):
                worst_support = support
                worst_residual = residual
                worst = i
        need = max(min_support, int(math.ceil(min_fraction * (n_active - 1))))
        if worst < 0 or worst_support >= need:
            break
        active[worst] = False
    for i in range(n):
        if not active[i]:
            continue
        for j in range(i + 1, n):
            if active[j] and cand_row[i] == cand_row[j]:
                active[i] = False
                active[j] = False
    return active


@njit(cache=True)
def _det3(M):
    """Determinant of a 3x3 matrix."""
    return (M[0, 0] * (M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1])
            - M[0, 1] * (M[1, 0] * M[2, 2] - M[1, 2] * M[2, 0])
            + M[0, 2] * (M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0]))


@njit(cache=True)
def wahba_rows(v, rows, unit):
    """ICRS -> camera rotation from the stars with ``rows >= 0`` (Wahba's problem, equal weights).

    ``v[i]`` is the camera-frame unit vector of star ``i`` and ``unit[rows[i]]`` its catalog
    (ICRS) unit vector; the numba twin of :func:`starid.attitude.solve_wahba`.

    The optimum is the orthogonal polar factor of ``B = sum b r^T`` when ``det B > 0`` (the SVD
    solution of Markley 1988 without the sign flip); it is found by Newton's iteration
    ``X <- (X + X^-T) / 2`` (quadratic convergence, a few 3x3 steps, much cheaper than a LAPACK
    SVD call). When ``det B <= 0`` (degenerate or mirrored data) the SVD solution is used.
    """
    B = np.zeros((3, 3))
    for i in range(v.shape[0]):
        if rows[i] < 0:
            continue
        for a in range(3):
            for b in range(3):
                B[a, b] += v[i, a] * float(unit[rows[i], b])
    det = _det3(B)
    if not det > 1e-12 * (np.abs(B).max() ** 3 + 1e-300):
        U, _, Vt = np.linalg.svd(B)
        d = np.linalg.det(U) * np.linalg.det(Vt)
        for a in range(3):
            U[a, 2] *= d
        return U @ Vt
    X = B / abs(det) ** (1.0 / 3.0)
    for _ in range(50):
        d = _det3(X)
        # inverse transpose = cofactor matrix / det
        C = np.empty((3, 3))
        C[0, 0] = X[1, 1] * X[2, 2] - X[1, 2] * X[2, 1]
        C[0, 1] = X[1, 2] * X[2, 0] - X[1, 0] * X[2, 2]
        C[0, 2] = X[1, 0] * X[2, 1] - X[1, 1] * X[2, 0]
        C[1, 0] = X[0, 2] * X[2, 1] - X[0, 1] * X[2, 2]
        C[1, 1] = X[0, 0] * X[2, 2] - X[0, 2] * X[2, 0]
        C[1, 2] = X[0, 1] * X[2, 0] - X[0, 0] * X[2, 1]
        C[2, 0] = X[0, 1] * X[1, 2] - X[0, 2] * X[1, 1]
        C[2, 1] = X[0, 2] * X[1, 0] - X[0, 0] * X[1, 2]
        C[2, 2] = X[0, 0] * X[1, 1] - X[0, 1] * X[1, 0]
        change = 0.0
        for a in range(3):
            for b in range(3):
                new = 0.5 * (X[a, b] + C[a, b] / d)
                change = max(change, abs(new - X[a, b]))
                X[a, b] = new
        if change < 1e-14:
            break
    return X


@njit(cache=True)
def z_bound(unit, z, upper):
    """First row of z-sorted unit vectors whose z is >= ``z`` (``upper``: > ``z``), by bisection."""
    lo = 0
    hi = unit.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if unit[mid, 2] < z or (upper and unit[mid, 2] == z):
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True)
def z_band_rows(unit, z_centre, c_radius):
    """Rows ``[start, stop)`` of z-sorted unit vectors in the declination band that holds every
    vector within chord ``c_radius`` of a direction whose z component is ``z_centre``."""
    half = 2.0 * math.asin(min(1.0, 0.5 * c_radius))
    dec0 = math.asin(max(-1.0, min(1.0, float(z_centre))))
    z_lo = math.sin(max(-0.5 * math.pi, dec0 - half))
    z_hi = math.sin(min(0.5 * math.pi, dec0 + half))
    return z_bound(unit, z_lo, False), z_bound(unit, z_hi, True)


@njit(cache=True)
def keep_unique(n_match, out_row):
    """Keep the rows of stars matched exactly once (the others become -1); returns how many."""
    count = 0
    for i in range(n_match.shape[0]):
        if n_match[i] == 1:
            count += 1
        else:
            out_row[i] = -1
    return count


@njit(cache=True)
def reproject_assign(A, v_cam, unit, c_fov, eps, out_row, f_px, cx_px, cy_px, width_px, height_px):
    """Identify observed stars from an attitude: each catalog star predicted at ``A r`` (notes 1.5).

    ``unit`` holds the catalog's unit vectors sorted by z; those within chord ``c_fov`` of the
    boresight are predicted, and an observed star within chord ``eps`` of exactly one prediction
    (which is within ``eps`` of no other observed star) gets its row in ``out_row`` (-1
    elsewhere). Returns ``(n_assigned, n_predicted)``, ``n_predicted`` counting the predictions
    that land on the ``width_px`` x ``height_px`` sensor, so a caller can ask what fraction of
    the stars an attitude puts in the image are actually seen.
    """
    n = v_cam.shape[0]
    n_match = np.zeros(n, dtype=np.int64)
    for i in range(n):
        out_row[i] = -1
    bore = np.empty((1, 3))  # boresight in ICRS: A^T (0, 0, 1)
    for a in range(3):
        bore[0, a] = A[2, a]
    b = np.empty((1, 3))
    n_predicted = 0
    g_start, g_stop = z_band_rows(unit, bore[0, 2], c_fov)
    for g in range(g_start, g_stop):
        if chord_rows(unit, g, bore, 0) > c_fov:
            continue
        for a in range(3):
            b[0, a] = A[a, 0] * unit[g, 0] + A[a, 1] * unit[g, 1] + A[a, 2] * unit[g, 2]
        if b[0, 2] > 0:
            x = cx_px + f_px * b[0, 0] / b[0, 2]
            y = cy_px + f_px * b[0, 1] / b[0, 2]
            if 0 <= x < width_px and 0 <= y < height_px:
                n_predicted += 1
        found = -1
        n_found = 0
        for i in range(n):
            if chord_rows(v_cam, i, b, 0) <= eps:
                n_found += 1
                found = i
        if n_found == 1:
            n_match[found] += 1
            out_row[found] = g
        elif n_found > 1:
            for i in range(n):
                if chord_rows(v_cam, i, b, 0) <= eps:
                    n_match[i] += 2
    return keep_unique(n_match, out_row), n_predicted
