"""Motion smear: where each star lies on the sensor during an exposure while the camera turns.

The camera turns at a constant rate about a fixed axis (camera frame) during an exposure of
``T`` seconds; the attitude at mid-exposure is the trial's attitude. A star whose camera-frame
direction at mid-exposure is ``v`` is at ``v(t) = Rot(axis, -rate t) v`` (Rodrigues) for
``t`` in ``[-T/2, T/2]``: it sweeps a streak on the sensor. This is the motion model of LOST's
image generator (UWCubeSat/lost, ``src/io.cpp``, ``GeneratedPipelineInput``: the star's
position at mid-exposure plus a constant pixel velocity ``delta`` from a fixed "motion blur"
rotation; the PSF integrated along the streak, ``motionBlurredPixelBrightness``).

The kernels return pixel **offsets relative to the mid-exposure position** (pinhole projection),
so the caller adds them to its own projected positions; through a distorted lens the caller
rotates the directions with :func:`rotate_all` and projects them with the true camera
(:func:`starid.sky.streak_offsets_px`).
"""

from __future__ import annotations

import math

import numpy as np

from .jit import kernel


@kernel
def _rotate(v, axis, angle_rad):
    """Rodrigues: ``v`` rotated by ``angle_rad`` about the unit ``axis`` (right-handed)."""
    c = math.cos(angle_rad)
    s = math.sin(angle_rad)
    kx, ky, kz = axis[0], axis[1], axis[2]
    vx, vy, vz = v[0], v[1], v[2]
    dot = kx * vx + ky * vy + kz * vz
    out = np.empty(3)
    out[0] = vx * c + (ky * vz - kz * vy) * s + kx * dot * (1.0 - c)
    out[1] = vy * c + (kz * vx - kx * vz) * s + ky * dot * (1.0 - c)
    out[2] = vz * c + (kx * vy - ky * vx) * s + kz * dot * (1.0 - c)
    return out


@kernel
def rotate_all(v_cam, axis, angle_rad):
    """Every row of ``v_cam`` (n, 3) rotated by ``angle_rad`` about the unit ``axis`` (Rodrigues):
    the directions at one instant of the exposure, for projection through a distorted camera."""
    n = v_cam.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        out[i] = _rotate(v_cam[i], axis, angle_rad)
    return out


@kernel
def streak_samples_px(v_cam, axis, sweep_rad, n_samples, f_px, cx_px, cy_px):
    """Offsets ``(n, n_samples)`` in x and y of each star at ``n_samples`` equally spaced times.

    Sample ``k`` is at ``t_k = ((k + 0.5) / n_samples - 0.5) T`` (midpoint rule over the
    exposure), i.e. the star turned by ``-sweep_rad t_k / T`` about ``axis``, with
    ``sweep_rad = rate T`` the angle turned during the exposure. Offsets are relative to the
    mid-exposure pinhole position.
    """
    n = v_cam.shape[0]
    dx = np.empty((n, n_samples))
    dy = np.empty((n, n_samples))
    for i in range(n):
        x0 = cx_px + f_px * v_cam[i, 0] / v_cam[i, 2]
        y0 = cy_px + f_px * v_cam[i, 1] / v_cam[i, 2]
        for k in range(n_samples):
            frac = (k + 0.5) / n_samples - 0.5
            w = _rotate(v_cam[i], axis, -sweep_rad * frac)
            dx[i, k] = cx_px + f_px * w[0] / w[2] - x0
            dy[i, k] = cy_px + f_px * w[1] / w[2] - y0
    return dx, dy


@kernel
def streak_px(v_cam, axis, sweep_rad, f_px, cx_px, cy_px):
    """Each star's streak: ``(centre_dx, centre_dy, length_dx, length_dy)`` in px.

    ``centre``: the light-weighted centre of the streak (the time average of the position,
    Simpson's rule on start, middle and end: exact to fourth order in ``sweep_rad``) relative
    to the mid-exposure position; ``length``: end minus start (``t = T/2`` minus ``t = -T/2``).
    """
    n = v_cam.shape[0]
    cdx = np.empty(n)
    cdy = np.empty(n)
    ldx = np.empty(n)
    ldy = np.empty(n)
    for i in range(n):
        x0 = cx_px + f_px * v_cam[i, 0] / v_cam[i, 2]
        y0 = cy_px + f_px * v_cam[i, 1] / v_cam[i, 2]
        a = _rotate(v_cam[i], axis, 0.5 * sweep_rad)     # t = -T/2
        b = _rotate(v_cam[i], axis, -0.5 * sweep_rad)    # t = +T/2
        xa = cx_px + f_px * a[0] / a[2]
        ya = cy_px + f_px * a[1] / a[2]
        xb = cx_px + f_px * b[0] / b[2]
        yb = cy_px + f_px * b[1] / b[2]
        cdx[i] = (xa + xb - 2.0 * x0) / 6.0
        cdy[i] = (ya + yb - 2.0 * y0) / 6.0
        ldx[i] = xb - xa
        ldy[i] = yb - ya
    return cdx, cdy, ldx, ldy


@kernel
def smear_noise(z_x, z_y, length_dx, length_dy, psf_sigma_px):
    """Unit centroid-noise draws ``(z_x, z_y)`` stretched along each star's streak.

    A photon-limited centroid's error scales with the rms width of the light distribution.
    A Gaussian PSF of sigma ``s`` swept uniformly over a streak of length ``L`` has the
    second moment ``s^2 + L^2 / 12`` along the streak (a uniform distribution's variance
    ``L^2 / 12`` added to the Gaussian's) and ``s^2`` across it, so the along-streak component
    of the noise is multiplied by ``k = sqrt(1 + L^2 / (12 s^2))``; the cross-streak one is
    unchanged. Returns the new ``(z_x, z_y)`` (unchanged where ``L = 0``).
    """
    n = z_x.shape[0]
    out_x = z_x.copy()
    out_y = z_y.copy()
    s2 = psf_sigma_px * psf_sigma_px
    for i in range(n):
        l2 = length_dx[i] * length_dx[i] + length_dy[i] * length_dy[i]
        if l2 <= 0.0:
            continue
        length = math.sqrt(l2)
        ux = length_dx[i] / length
        uy = length_dy[i] / length
        k = math.sqrt(1.0 + l2 / (12.0 * s2))
        along = z_x[i] * ux + z_y[i] * uy
        out_x[i] += (k - 1.0) * along * ux
        out_y[i] += (k - 1.0) * along * uy
    return out_x, out_y
