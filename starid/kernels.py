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
