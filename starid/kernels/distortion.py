"""Lens distortion in OpenCV's model, order and convention (Brown-Conrady, 5 coefficients).

A camera-frame vector ``(X, Y, Z)`` (``Z > 0``) has normalized (pinhole) coordinates
``x = X / Z``, ``y = Y / Z``; with ``r^2 = x^2 + y^2`` the lens moves them to (OpenCV,
``cv2.projectPoints``; Brown 1966)::

    x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
    y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y

and the pixel is ``u = cx + f x_d``, ``v = cy + f y_d`` (square pixels, ``fx = fy = f``). The
coefficients are given as OpenCV orders them, ``dist = (k1, k2, p1, p2, k3)``, so the output of
``cv2.calibrateCamera`` drops in unchanged.

The inverse has no closed form: :func:`undistort_norm` solves ``D(x, y) = (x_d, y_d)`` by Newton's
iteration with the analytic 2x2 Jacobian, started at ``(x_d, y_d)`` (tested against the forward
model to < 1e-3 px over the whole sensor in ``tests/test_distortion.py``).
"""

from __future__ import annotations

import math

import numpy as np

from .jit import kernel

#: Newton iterations at most, and the step (normalized units) at which they stop.
MAX_ITER = 50
TOL = 1e-14


@kernel
def distort_norm(x, y, k1, k2, p1, p2, k3):
    """OpenCV's forward model on one normalized point: ``(x_d, y_d)`` (module equations)."""
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return xd, yd


@kernel
def undistort_norm(xd, yd, k1, k2, p1, p2, k3):
    """Normalized pinhole coordinates ``(x, y)`` whose distorted image is ``(xd, yd)`` (Newton)."""
    x = xd
    y = yd
    for _ in range(MAX_ITER):
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        g = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)          # d radial / d r^2
        fx = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - xd
        fy = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y - yd
        a = radial + 2.0 * x * x * g + 2.0 * p1 * y + 6.0 * p2 * x
        b = 2.0 * x * y * g + 2.0 * p1 * x + 2.0 * p2 * y
        d = radial + 2.0 * y * y * g + 6.0 * p1 * y + 2.0 * p2 * x
        det = a * d - b * b
        if det == 0.0 or not math.isfinite(det):
            break
        dx = (d * fx - b * fy) / det
        dy = (a * fy - b * fx) / det
        x -= dx
        y -= dy
        if abs(dx) < TOL and abs(dy) < TOL:
            break
    return x, y


@kernel
def project_distorted(v_cam, f_px, cx_px, cy_px, dist):
    """Pixels ``(x_px, y_px)`` of camera-frame vectors ``(n, 3)`` (``vz > 0``) through the lens ``dist``."""
    n = v_cam.shape[0]
    x_px = np.empty(n)
    y_px = np.empty(n)
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    for i in range(n):
        xd, yd = distort_norm(v_cam[i, 0] / v_cam[i, 2], v_cam[i, 1] / v_cam[i, 2], k1, k2, p1, p2, k3)
        x_px[i] = cx_px + f_px * xd
        y_px[i] = cy_px + f_px * yd
    return x_px, y_px


@kernel
def undistort_px(x_px, y_px, f_px, cx_px, cy_px, dist, cx_out_px, cy_out_px):
    """Distorted pixels to the pinhole pixels of the same focal length with principal point
    ``(cx_out_px, cy_out_px)`` (``u' = cx_out + f x``; the frame a plugin works in)."""
    n = x_px.shape[0]
    xo = np.empty(n)
    yo = np.empty(n)
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    for i in range(n):
        x, y = undistort_norm((x_px[i] - cx_px) / f_px, (y_px[i] - cy_px) / f_px, k1, k2, p1, p2, k3)
        xo[i] = cx_out_px + f_px * x
        yo[i] = cy_out_px + f_px * y
    return xo, yo


@kernel
def backproject_distorted(x_px, y_px, f_px, cx_px, cy_px, dist):
    """Camera-frame unit vectors ``(n, 3)`` of distorted pixels (inverse of :func:`project_distorted`)."""
    n = x_px.shape[0]
    v = np.empty((n, 3))
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    for i in range(n):
        x, y = undistort_norm((x_px[i] - cx_px) / f_px, (y_px[i] - cy_px) / f_px, k1, k2, p1, p2, k3)
        norm = math.sqrt(x * x + y * y + 1.0)
        v[i, 0] = x / norm
        v[i, 1] = y / norm
        v[i, 2] = 1.0 / norm
    return v
