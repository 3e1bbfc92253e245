"""numba kernels of the grid algorithm (Padgett & Kreutz-Delgado 1997) and its modified-grid options.

Geometry shared with the log-polar plugins (tangent plane, image preparation, acceptance by
reprojection) comes from :mod:`starid_algorithms.lpt_improved.planar`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from starid.kernels.jit import inner, kernel
from starid.kernels.order import sort_int_prefix

from ..lpt_improved.planar import (
    acceptance_at,
    begin_identify,
    confirm_pair,
    count_work,
    frame_at,
    keep_best,
    no_match,
    plane_polar,
    reference_pattern,
)


class GridSpec(NamedTuple):
    """Pattern and search parameters as a kernel bundle."""

    g: int                 # cells per side
    half_px: float         # half side of the pattern square (px in the tangent plane)
    buffer_px: float       # orientation star: nearest neighbour at least this far (px)
    cos_radius: float      # neighbours considered: within this angle (covers the square's corners)
    soft_edge: float       # credit of an image star one cell away (edge-adjacent); 0 = Padgett
    soft_diag: float       # credit of an image star diagonally adjacent
    normalise: bool        # score / sqrt(n_image n_pattern) instead of the matched count
    min_score: float       # least (unnormalised) matched cells to be a candidate
    max_refs: int
    image_orientations: int
    n_candidates: int
    double_px: float


class GridTable(NamedTuple):
    """Database patterns as a kernel bundle, indexed by cell.

    The patterns with cell c set are ``patterns[cell_start[c]:cell_start[c+1]]``, ascending;
    pattern p has ``start[p+1] - start[p]`` cells.
    """

    patterns: np.ndarray   # uint16 (int32 beyond 65535 patterns) pattern indices, grouped by cell
    cell_start: np.ndarray # int32 (g * g + 1,)
    start: np.ndarray      # int32 (k + 1,) offsets of each pattern's cells (their count)
    guide: np.ndarray      # guide row of each pattern's reference star
    orient: np.ndarray     # guide row of its orientation star


def by_cell(cells: np.ndarray, start: np.ndarray, n_cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Invert the pattern -> cells lists: ``(patterns, cell_start)``, each cell's patterns ascending."""
    owner = np.repeat(np.arange(start.size - 1), np.diff(start))
    order = np.argsort(cells, kind="stable")          # stable: patterns stay ascending within a cell
    cell_start = np.zeros(n_cells + 1, dtype=np.int32)
    np.cumsum(np.bincount(cells, minlength=n_cells), out=cell_start[1:])
    dtype = np.uint16 if start.size - 1 <= np.iinfo(np.uint16).max + 1 else np.int32
    return owner[order].astype(dtype), cell_start


def by_pattern(patterns: np.ndarray, cell_start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pattern -> cells lists back from :func:`by_cell`'s index: ``(cells, start)``, cells ascending."""
    cell = np.repeat(np.arange(cell_start.size - 1), np.diff(cell_start))
    order = np.lexsort((cell, patterns))
    n_pat = int(patterns.max()) + 1 if patterns.size else 0
    start = np.zeros(n_pat + 1, dtype=np.int64)
    np.cumsum(np.bincount(patterns.astype(np.int64), minlength=n_pat), out=start[1:])
    return cell[order], start


@inner   # kernels call it only
def orientation_candidates(r_px, n, buffer_px, half_px, out):
    """Indices (into the nearest-first neighbour list) of neighbours ``buffer_px`` to ``half_px`` away."""
    k = 0
    for i in range(n):
        if buffer_px <= r_px[i] < half_px:
            out[k] = i
            k += 1
    return k


@kernel
def grid_cells(r_px, phi, n, o, spec, out):
    """Occupied cells of the pattern oriented on neighbour ``o`` (Padgett's grid).

    The pattern plane is rotated so that the orientation star lies on +x; a ``g`` x ``g`` grid
    covers ``[-half, half]^2``; every neighbour inside sets its cell. Writes the sorted distinct
    cells to ``out`` and returns how many.
    """
    w = 2.0 * spec.half_px / spec.g
    k = 0
    for i in range(n):
        a = phi[i] - phi[o]
        x = r_px[i] * math.cos(a)
        y = r_px[i] * math.sin(a)
        if abs(x) >= spec.half_px or abs(y) >= spec.half_px:
            continue
        col = min(int((x + spec.half_px) / w), spec.g - 1)
        row = min(int((y + spec.half_px) / w), spec.g - 1)
        out[k] = row * spec.g + col
        k += 1
    sort_int_prefix(out, np.int64(k))   # not np.sort (~1 CPU s to compile); np.int64: one signature
    m = 0
    for i in range(k):
        if m == 0 or out[i] != out[m - 1]:
            out[m] = out[i]
            m += 1
    return m


def build_patterns(unit, nbr, nbr_off, f_px, spec, db_orientations):
    """Grid patterns of every guide star, one per orientation choice (``db_orientations``; Padgett: 1).

    Returns ``(cells int64, start int64, guide int64, orient int32)`` (see :class:`GridTable`).

    Once per database, so plain Python over the guide stars calling the two kernels identify
    compiles anyway (:func:`plane_polar` for the reference star's neighbours, :func:`grid_cells`),
    with the same argument types: a build kernel of its own compiled ~0.9 CPU s on a cold cache
    to save ~0.1 s of Python (issue #25). The orientation choice is :func:`orientation_candidates`
    in numpy (two comparisons per neighbour).
    """
    unit = np.ascontiguousarray(unit, dtype=np.float64)
    rows = np.asarray(nbr, dtype=np.int64)   # int64 rows: plane_polar's one (the image's) signature
    off = np.asarray(nbr_off, dtype=np.int64)
    longest = max(1, int(np.diff(off).max())) if off.size > 1 else 1
    r_px, phi = np.empty(longest), np.empty(longest)
    buf = np.empty(longest, dtype=np.int64)
    f_px = float(f_px)
    cells, start, guide, orient = [], [0], [], []
    total = 0
    for g in range(unit.shape[0]):
        lo, hi = int(off[g]), int(off[g + 1])
        n = hi - lo
        if n == 0:
            continue
        plane_polar(unit, g, rows[lo:hi], n, f_px, r_px, phi)
        r = r_px[:n]
        cand = np.flatnonzero((spec.buffer_px <= r) & (r < spec.half_px))
        for a in range(min(db_orientations, cand.size)):
            k = grid_cells(r_px, phi, n, int(cand[a]), spec, buf)
            cells.append(buf[:k].copy())
            total += k
            start.append(total)
            guide.append(g)
            orient.append(nbr[lo + cand[a]])
    return (np.concatenate(cells) if cells else np.zeros(0, dtype=np.int64), np.array(start, dtype=np.int64),
            np.array(guide, dtype=np.int64), np.array(orient, dtype=np.int32))


@inner   # kernels call it only
def _mark(weight, touched, nt, cell, value):
    if weight[cell] == 0.0:
        touched[nt] = cell
        nt += 1
    if value > weight[cell]:
        weight[cell] = value
    return nt


@kernel
def image_weights(cells, nc, spec, weight, touched):
    """Credit of every grid cell for one image pattern (modified grid: soft neighbour credit).

    An image star's own cell gets 1; with ``soft_edge``/``soft_diag`` > 0 its 4 edge-adjacent
    and 4 diagonal cells get that credit (the largest credit wins). Returns the touched cells'
    count (``touched`` lists them, for a cheap reset).
    """
    g = spec.g
    nt = np.int64(0)   # not a literal: one signature of _mark
    for i in range(nc):
        c = cells[i]
        row = c // g
        col = c % g
        nt = _mark(weight, touched, nt, c, 1.0)
        for dr in range(-1, 2):
            for dc in range(-1, 2):
                if dr == 0 and dc == 0:
                    continue
                v = spec.soft_diag if (dr != 0 and dc != 0) else spec.soft_edge
                if v <= 0.0:
                    continue
                r2 = row + dr
                c2 = col + dc
                if 0 <= r2 < g and 0 <= c2 < g:
                    nt = _mark(weight, touched, nt, r2 * g + c2, v)
    return nt


@inner   # kernels call it only
def spec_at(p, i):
    """The :class:`GridSpec` packed at ``p[i:i+12]`` by ``planar.pack_params``."""
    return GridSpec(int(p[i]), p[i + 1], p[i + 2], p[i + 3], p[i + 4], p[i + 5], p[i + 6] != 0.0, p[i + 7],
                    int(p[i + 8]), int(p[i + 9]), int(p[i + 10]), p[i + 11])


@kernel
def identify_kernel(x_px, y_px, params, patterns, cell_start, start, guide, orient, guides_unit, trace):
    """Grid identification of one image; returns ``(rows, attitude, accepted)``.

    ``params``: the sensor :class:`Frame`, the :class:`Acceptance` and the :class:`GridSpec`,
    packed by ``planar.pack_params``; the next five arrays are the :class:`GridTable`'s fields
    (separate arguments: numba types arrays at a call in C, NamedTuples field by field in Python).

    For reference stars from the image centre outwards (at most ``max_refs``) and each of its
    ``image_orientations`` nearest neighbours beyond the buffer as orientation star: the image
    pattern's cell credits; every database pattern is scored by the credit of its cells (the
    bitwise AND of Padgett's binary grids when there is no soft credit), the whole database
    as in the paper (through the cell index: only the patterns holding a credited cell are
    touched); the ``n_candidates`` best with at least ``min_score`` seed an attitude
    (reference and orientation star to their guide stars, Wahba) that :func:`confirm` must
    accept. ``trace`` (int64, 4): reference star, orientation star, pattern, 1000 x score.
    """
    sensor = frame_at(params, np.int64(0))
    acc = acceptance_at(params, np.int64(5))
    spec = spec_at(params, np.int64(10))
    table = GridTable(patterns, cell_start, start, guide, orient)
    n = x_px.shape[0]
    rows, unit, usable, order = begin_identify(x_px, y_px, sensor, spec.double_px, trace)
    nbrs = np.empty(n, dtype=np.int64)
    r_px = np.empty(n)
    phi = np.empty(n)
    cand = np.empty(n, dtype=np.int64)
    cells = np.empty(n, dtype=np.int64)
    weight = np.zeros(spec.g * spec.g)
    touched = np.empty(spec.g * spec.g, dtype=np.int64)
    n_pat = table.guide.shape[0]
    raw = np.zeros(n_pat)
    hot = np.empty(n_pat, dtype=np.int64)
    n_best = spec.n_candidates
    best_p = np.empty(n_best, dtype=np.int64)
    best_sc = np.empty(n_best)
    seed = np.full(n, -1, dtype=np.int64)
    for t in range(min(spec.max_refs, order.shape[0])):
        s = order[t]
        k = reference_pattern(unit, usable, x_px, y_px, s, spec.cos_radius, sensor.f_px, nbrs, r_px, phi)
        if k < 1:
            continue
        n_or = orientation_candidates(r_px, k, spec.buffer_px, spec.half_px, cand)
        for a in range(min(spec.image_orientations, n_or)):
            o = cand[a]
            nc = grid_cells(r_px, phi, k, o, spec, cells)
            nt = image_weights(cells, nc, spec, weight, touched)
            count_work(trace, 0, 1)
            # credit of every pattern: each credited cell adds its weight to the patterns holding it,
            # cells in ascending order (each pattern's sum is then added up in the same order as
            # over its own sorted cells, so it is the same float)
            # (every credit is positive, so a pattern's sum reaches min_score at most once: the patterns
            # that reach it are listed as they do, ``hot``, and only they are ranked, in pattern order)
            sort_int_prefix(touched, np.int64(nt))
            nh = 0
            for i in range(nt):
                c = touched[i]
                w = weight[c]
                for q in range(np.uint64(table.cell_start[c]), np.uint64(table.cell_start[c + 1])):
                    p = table.patterns[q]
                    before = raw[p]
                    raw[p] = before + w
                    if before < spec.min_score <= raw[p]:
                        hot[nh] = p
                        nh += 1
                count_work(trace, 1, table.cell_start[c + 1] - table.cell_start[c])
            found = np.int64(0)   # not a literal: one signature of keep_best
            if spec.min_score > 0.0:
                sort_int_prefix(hot, np.int64(nh))
                for i in range(nh):
                    p = hot[i]
                    score = raw[p]
                    sc = score / math.sqrt(nc * (table.start[p + 1] - table.start[p])) if spec.normalise else score
                    if found == n_best and sc <= best_sc[n_best - 1]:
                        continue   # keep_best would drop it
                    found = keep_best(best_sc, best_p, found, n_best, sc, p)
                raw[:] = 0.0
            else:   # every pattern is a candidate, the untouched ones too
                for p in range(n_pat):
                    score = raw[p]
                    raw[p] = 0.0
                    sc = score / math.sqrt(nc * (table.start[p + 1] - table.start[p])) if spec.normalise else score
                    if found == n_best and sc <= best_sc[n_best - 1]:
                        continue   # keep_best would drop it
                    found = keep_best(best_sc, best_p, found, n_best, sc, p)
            for i in range(nt):
                weight[touched[i]] = 0.0
            for c in range(found):
                p = best_p[c]
                ok, A = confirm_pair(unit, rows, seed, s, nbrs[o], table.guide[p], table.orient[p], guides_unit,
                                     sensor, acc)
                count_work(trace, 2, 1)
                if ok:
                    trace[0] = s
                    trace[1] = nbrs[o]
                    trace[2] = p
                    trace[3] = int(1000 * best_sc[c])
                    return rows, A, True
    return no_match(rows)
