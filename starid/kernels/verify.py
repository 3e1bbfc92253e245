"""Verification kernels: pairwise angular consistency and identification by reprojection."""

from __future__ import annotations

import math

import numpy as np

from .geometry import chord_rows
from .jit import inline_inner, inner, kernel


@kernel
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


@inner   # kernels call it only
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


@kernel
def z_band_rows(unit, z_centre, c_radius):
    """Rows ``[start, stop)`` of z-sorted unit vectors in the declination band that holds every
    vector within chord ``c_radius`` of a direction whose z component is ``z_centre``."""
    half = 2.0 * math.asin(min(1.0, 0.5 * c_radius))
    dec0 = math.asin(max(-1.0, min(1.0, float(z_centre))))
    z_lo = math.sin(max(-0.5 * math.pi, dec0 - half))
    z_hi = math.sin(min(0.5 * math.pi, dec0 + half))
    return z_bound(unit, z_lo, np.bool_(False)), z_bound(unit, z_hi, np.bool_(True))   # runtime bools: one signature


@inner   # kernels call it only
def keep_unique(n_match, out_row):
    """Keep the rows of stars matched exactly once (the others become -1); returns how many."""
    count = 0
    for i in range(n_match.shape[0]):
        if n_match[i] == 1:
            count += 1
        else:
            out_row[i] = -1
    return count


@inline_inner   # inlined in numba IR: the same code in reproject_assign's loop as before it was shared
def predict_on_sensor(A, unit, g, b, f_px, cx_px, cy_px, width_px, height_px):
    """Predict guide star ``g``: ``b[0] = A unit[g]``, its direction in the camera frame; whether it lands on
    the ``width_px`` x ``height_px`` sensor (in front of the camera, its pinhole projection inside). The
    prediction step of :func:`reproject_assign` and :func:`predicted_on_sensor`."""
    for a in range(3):
        b[0, a] = A[a, 0] * unit[g, 0] + A[a, 1] * unit[g, 1] + A[a, 2] * unit[g, 2]
    if b[0, 2] > 0:
        x = cx_px + f_px * b[0, 0] / b[0, 2]
        y = cy_px + f_px * b[0, 1] / b[0, 2]
        return 0 <= x < width_px and 0 <= y < height_px
    return False


@inner   # kernels call it only
def predicted_on_sensor(A, unit, c_fov, f_px, cx_px, cy_px, width_px, height_px):
    """:func:`reproject_assign`'s second count alone: the guide rows of ``unit`` (sorted by z) within chord
    ``c_fov`` of the boresight whose prediction lands on the sensor (for a plugin that assigns by its own
    means and needs only the count: lpt_improved)."""
    bore = np.empty((1, 3))  # boresight in ICRS: A^T (0, 0, 1)
    for a in range(3):
        bore[0, a] = A[2, a]
    b = np.empty((1, 3))
    n_predicted = 0
    g_start, g_stop = z_band_rows(unit, bore[0, 2], c_fov)
    for g in range(g_start, g_stop):
        if chord_rows(unit, g, bore, np.int64(0)) > c_fov:
            continue
        if predict_on_sensor(A, unit, g, b, f_px, cx_px, cy_px, width_px, height_px):
            n_predicted += 1
    return n_predicted


@kernel
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
        if chord_rows(unit, g, bore, np.int64(0)) > c_fov:
            continue
        if predict_on_sensor(A, unit, g, b, f_px, cx_px, cy_px, width_px, height_px):
            n_predicted += 1
        found = -1
        n_found = 0
        for i in range(n):
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
    return keep_unique(n_match, out_row), n_predicted
