"""Projection and angular-distance kernels (pinhole camera, chords of unit vectors).

Units: angles in radians; a "chord" is the Euclidean distance between two unit vectors,
``2 sin(theta / 2)``.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import inner, kernel


@kernel
def project_cam(v_cam, f_px, cx_px, cy_px):
    """Pinhole projection of camera-frame vectors ``(n, 3)``: ``x = cx + f vx/vz``, ``y = cy + f vy/vz``."""
    n = v_cam.shape[0]
    x_px = np.empty(n)
    y_px = np.empty(n)
    for i in range(n):
        x_px[i] = cx_px + f_px * v_cam[i, 0] / v_cam[i, 2]
        y_px[i] = cy_px + f_px * v_cam[i, 1] / v_cam[i, 2]
    return x_px, y_px


@kernel
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


@kernel
def chord(u, v):
    """Euclidean distance between two unit 3-vectors (``2 sin(theta/2)``)."""
    dx = u[0] - v[0]
    dy = u[1] - v[1]
    dz = u[2] - v[2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@kernel
def chord_rows(a, i, b, j):
    """Chord between row ``i`` of ``a`` and row ``j`` of ``b`` (unit vectors, float64 result).

    The same value as ``chord(a[i], b[j])``, without creating array views: inside hot numba
    loops the views' reference counting costs several times the arithmetic.
    """
    dx = float(a[i, 0]) - float(b[j, 0])
    dy = float(a[i, 1]) - float(b[j, 1])
    dz = float(a[i, 2]) - float(b[j, 2])
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@kernel
def triple_product(u, v, w):
    """``u . (v x w)`` of three 3-vectors; for unit vectors its sign is the triangle's handedness (chirality)."""
    return (u[0] * (v[1] * w[2] - v[2] * w[1]) + u[1] * (v[2] * w[0] - v[0] * w[2])
            + u[2] * (v[0] * w[1] - v[1] * w[0]))


@kernel
def angular_distance_rad(u, v):
    """Angle between two unit 3-vectors in radians, accurate at small angles (via the chord)."""
    c = chord(u, v)
    if c >= 2.0:
        return math.pi
    return 2.0 * math.asin(0.5 * c)


@inner   # kernels call it only
def chord_to_rad(c):
    """Convert a chord of unit vectors to the angle it subtends, in radians."""
    if c >= 2.0:
        return math.pi
    return 2.0 * math.asin(0.5 * c)


def rad_to_chord(theta_rad):
    """Chord of unit vectors separated by ``theta_rad``.

    Plain Python: only Python calls it (tolerances and database builds), and a kernel compiled
    ~0.04 CPU s in every process on a cold cache for one multiplication and a sine (numba's
    ``math.sin`` is the same C library call, so the same float)."""
    return 2.0 * math.sin(0.5 * theta_rad)


@kernel
def triangle_sides(r1, r2, r3):
    """Chord sides of the planar triangle of three unit vectors (Zhou & Ye 2015, eq. 1).

    Returns ``(a, b, c)`` with ``a = |r1 - r2|``, ``b = |r2 - r3|``, ``c = |r1 - r3|``.
    """
    return chord(r1, r2), chord(r2, r3), chord(r1, r3)


@kernel
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
