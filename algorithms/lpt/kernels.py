"""numba kernels of the log-polar-transform algorithm (Wei, Zhang & Jiang 2009).

Geometry shared with the improved LPT and the grid (tangent plane, image preparation,
acceptance by reprojection) comes from :mod:`starid_algorithms.lpt_improved.planar`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..lpt_improved.planar import (begin_identify, confirm, guide_pattern, keep_best, no_match, polar_buffers,
                                   reference_pattern, seed_attitude_roll)


class StringSearch(NamedTuple):
    """Pattern and search parameters as a kernel bundle."""

    n_sectors: int
    n_levels: int
    ln_r_min: float      # ln of the smallest plane distance coded (px)
    ln_r_max: float      # ln of R as a plane distance (px)
    cos_radius: float
    level_tol: int
    sector_tol: int
    min_score: int
    max_refs: int
    n_candidates: int
    double_px: float


@njit(cache=True)
def lpt_string(r_px, phi, n, search, out, owner):
    """The LPT string of a pattern: character k = the log-radius row of the nearest star in sector k.

    The log-polar plane is ``(ln r, phi)``; its ``phi`` axis is cut into ``n_sectors`` columns
    (measured from the tangent basis, so a rotation of the sensor is a circular shift), its
    ``ln r`` axis over ``[ln r_min, ln R]`` into ``n_levels`` rows, 1 = innermost. A sector
    holding several stars keeps the nearest; 0 = empty. Stars nearer than ``r_min`` are not
    coded. ``owner[k]`` receives the neighbour that set character k (-1 if none). Returns the
    number of non-zero characters.
    """
    m = search.n_sectors
    for k in range(m):
        out[k] = 0
        owner[k] = -1
    width = 2.0 * math.pi / m
    span = search.ln_r_max - search.ln_r_min
    nz = 0
    for i in range(n):
        lr = math.log(max(r_px[i], 1e-9))
        if lr < search.ln_r_min:
            continue
        level = 1 + int(search.n_levels * (lr - search.ln_r_min) / span)
        level = min(max(level, 1), search.n_levels)
        k = int(phi[i] / width)
        if k >= m:
            k = m - 1
        if out[k] == 0:
            nz += 1
        if owner[k] < 0 or r_px[i] < r_px[owner[k]]:
            out[k] = level
            owner[k] = i
    return nz


@njit(cache=True)
def build_strings(unit, nbr, nbr_off, f_px, search):
    """LPT string of every guide star (rows of ``unit``), uint8 ``(g, n_sectors)``."""
    n_guide = unit.shape[0]
    strings = np.zeros((n_guide, search.n_sectors), dtype=np.uint8)
    r_px, phi = polar_buffers(nbr_off)
    out = np.zeros(search.n_sectors, dtype=np.int64)
    owner = np.zeros(search.n_sectors, dtype=np.int64)
    for g in range(n_guide):
        n = guide_pattern(unit, nbr, nbr_off, g, f_px, r_px, phi)
        if n == 0:
            continue
        lpt_string(r_px, phi, n, search, out, owner)
        for k in range(search.n_sectors):
            strings[g, k] = out[k]
    return strings


@njit(cache=True)
def shift_scores(row, img_sector, img_level, nz, search, mark, stamp, score):
    """Score of every circular shift of one database string against the image string.

    ``score[s]`` = the number of image characters (sector ``k``, level ``L``) for which the
    database string has a non-zero character within ``level_tol`` of ``L`` in sector
    ``k + s + d`` (mod m), ``|d| <= sector_tol``: the circular string match of the LPT
    algorithm, all shifts at once. Each image character counts at most once per shift
    (``mark``/``stamp`` bookkeeping). Returns ``(best_score, best_shift, n_chars)``, the
    smallest shift among equals, and the database string's number of non-zero characters.
    """
    m = search.n_sectors
    for s in range(m):
        score[s] = 0
    n_chars = 0
    for j in range(m):
        c = int(row[j])
        if c == 0:
            continue
        n_chars += 1
        for t in range(nz):
            if abs(c - img_level[t]) > search.level_tol:
                continue
            for d in range(-search.sector_tol, search.sector_tol + 1):
                s = (j - img_sector[t] - d) % m
                if mark[t, s] != stamp:
                    mark[t, s] = stamp
                    score[s] += 1
    best = 0
    best_s = 0
    for s in range(m):
        if score[s] > best:
            best = score[s]
            best_s = s
    return best, best_s, n_chars


@njit(cache=True)
def refined_roll(row, img_sector, img_level, img_phi, nz, shift, search):
    """Roll (``phi_catalog - phi_image``) of a match: the shift refined by the matched characters.

    The database keeps only sectors, so each matched pair gives the roll to within a sector;
    their circular mean, around ``shift`` sectors, is the estimate.
    """
    m = search.n_sectors
    width = 2.0 * math.pi / m
    base = shift * width
    total = 0.0
    count = 0
    for t in range(nz):
        for d in range(-search.sector_tol, search.sector_tol + 1):
            j = (img_sector[t] + shift + d) % m
            c = int(row[j])
            if c != 0 and abs(c - img_level[t]) <= search.level_tol:
                r = (j + 0.5) * width - img_phi[t] - base
                while r > math.pi:
                    r -= 2.0 * math.pi
                while r < -math.pi:
                    r += 2.0 * math.pi
                total += r
                count += 1
                break
    return base + (total / count if count else 0.5 * width)


@njit(cache=True)
def identify_kernel(x_px, y_px, sensor, strings, guides_unit, search, acc, trace):
    """LPT identification of one image; returns ``(rows, attitude, accepted)``.

    For reference stars from the image centre outwards (at most ``max_refs``): its LPT string;
    every database string is compared under every circular shift (:func:`shift_scores`, the
    whole database, as in the paper); the ``n_candidates`` best guide stars scoring at least
    ``min_score`` (ties: the string with fewer unmatched characters first) seed an attitude (reference star to guide star, roll from the shift) that
    :func:`confirm` must accept. ``trace`` (int64, 4): reference star, -1, guide row, score.
    """
    n = x_px.shape[0]
    rows, unit, usable, order = begin_identify(x_px, y_px, sensor, search.double_px, trace)
    m = search.n_sectors
    n_guide = strings.shape[0]
    nbrs = np.empty(n, dtype=np.int64)
    r_px = np.empty(n)
    phi = np.empty(n)
    img = np.zeros(m, dtype=np.int64)
    img_sector = np.empty(m, dtype=np.int64)
    img_level = np.empty(m, dtype=np.int64)
    img_phi = np.empty(m)
    owner = np.empty(m, dtype=np.int64)
    mark = np.zeros((m, m), dtype=np.int64)
    score = np.zeros(m, dtype=np.int64)
    stamp = 0
    n_best = search.n_candidates
    best_item = np.empty(n_best, dtype=np.int64)   # guide row * m + shift
    best_sc = np.empty(n_best, dtype=np.int64)
    for t in range(min(search.max_refs, order.shape[0])):
        s = order[t]
        k = reference_pattern(unit, usable, x_px, y_px, s, search.cos_radius, sensor.f_px, nbrs, r_px, phi)
        if k < 1:
            continue
        nz = lpt_string(r_px, phi, k, search, img, owner)
        if nz < 1:
            continue
        q = 0
        for j in range(m):
            if img[j] != 0:
                img_sector[q] = j
                img_level[q] = img[j]
                img_phi[q] = phi[owner[j]]
                q += 1
        found = 0
        for g in range(n_guide):
            stamp += 1
            matched, sh, n_chars = shift_scores(strings[g], img_sector, img_level, nz, search, mark, stamp, score)
            if matched < search.min_score:
                continue
            # more matched characters first; among equals, fewer unmatched database characters
            sc = 1024 * matched - min(n_chars - matched, 1023)
            found = keep_best(best_sc, best_item, found, n_best, sc, g * m + sh)
        for c in range(found):
            g = best_item[c] // m
            roll = refined_roll(strings[g], img_sector, img_level, img_phi, nz, best_item[c] % m, search)
            A = seed_attitude_roll(unit, s, guides_unit, g, roll)
            ok, A = confirm(unit, rows, A, guides_unit, sensor, acc)
            if ok:
                trace[0] = s
                trace[2] = g
                trace[3] = (best_sc[c] + 1023) // 1024
                return rows, A, True
    return no_match(rows)
