"""numba kernels of the improved log-polar algorithm (Luo, Xu, Zhang & Sun 2015).

The shared geometry (tangent plane, image preparation, acceptance by reprojection) is in
:mod:`.planar`; this module holds the feature vector and its search.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from starid.kernels import chord_rows
from starid.kernels.jit import inner, kernel

from .planar import (
    SEPARATION_TOL,
    acceptance_at,
    begin_identify,
    confirm_pair_near,
    count_work,
    frame_at,
    keep_best,
    no_match,
    pair_work,
    plane_polar,
    reference_pattern,
    relative_angle,
)


class FeatureTable(NamedTuple):
    """The feature database as a kernel bundle (see ``ImprovedLPTDatabase``)."""

    columns: np.ndarray       # uint8/uint16 (m, k): column r is feature row r; rows sorted by non-zero count
    total: np.ndarray         # int32 (k,) sum of each row
    count_start: np.ndarray   # int32 (m + 2,) first row with that many non-zero entries
    guide: np.ndarray         # int32 (k,) guide row of the reference star of each feature row
    align: np.ndarray         # int32 (k,) guide row of its alignment star
    align_chord: np.ndarray   # float32 (k,) chord between the two


class Search(NamedTuple):
    """Search parameters as a kernel bundle."""

    n_sectors: int
    log_scale: float
    cos_radius: float
    count_tol: int
    count_tol_above: int
    max_refs: int
    image_alignments: int
    n_candidates: int
    double_px: float
    pair_filter: bool       # rank only rows whose alignment pair has the image pair's separation


@inner   # kernels call it only
def log_level(r_px, log_scale):
    """Entry of a feature vector for plane distance ``r_px``: ``ceil(log_scale ln r_px)``, at least 1."""
    v = math.ceil(log_scale * math.log(max(r_px, 1.0)))
    return max(int(v), 1)


@kernel
def feature_vector(r_px, phi, n, align, n_sectors, log_scale, out):
    """Luo et al.'s feature (their eqs. 7-8) of the neighbours ``align..n-1`` relative to ``phi[align]``.

    Entry ``i`` is the largest ``ceil(log_scale ln r)`` of the neighbours whose angle from the
    alignment star (counter-clockwise) falls in ``[i, i + 1) 360 / m`` degrees, 0 if none.
    Neighbours nearer than the alignment star (``0..align-1``) are left out. Returns the number
    of non-zero entries.
    """
    for i in range(n_sectors):
        out[i] = 0
    width = 2.0 * math.pi / n_sectors
    nz = 0
    for k in range(align, n):
        b = int(relative_angle(phi[k], phi[align]) / width)
        if b >= n_sectors:
            b = n_sectors - 1
        v = log_level(r_px[k], log_scale)
        if out[b] == 0:
            nz += 1
        if v > out[b]:
            out[b] = v
    return nz


def build_features(unit, nbr, nbr_off, f_px, n_sectors, log_scale, db_alignments, max_value):
    """Feature rows of every guide star, one per alignment choice (``db_alignments``; paper: 1).

    ``nbr[nbr_off[g]:nbr_off[g+1]]`` are the guide rows within R of guide ``g``, nearest
    first; alignment choice ``a`` is the ``a``-th nearest. Returns
    ``(feature (k, m) int64, count (k,), guide (k,), align (k,))`` in guide order.

    Once per database, so plain Python over the guide stars calling the two kernels identify
    compiles anyway (:func:`plane_polar`, :func:`feature_vector`), with the same argument types: a
    build kernel of its own compiled ~0.5 CPU s on a cold cache (issue #25).
    """
    unit = np.ascontiguousarray(unit, dtype=np.float64)
    rows = np.asarray(nbr, dtype=np.int64)   # int64 rows: plane_polar's one (the image's) signature
    off = np.asarray(nbr_off, dtype=np.int64)
    per_guide = np.minimum(db_alignments, np.diff(off))
    k_max = int(per_guide.sum())
    feature = np.zeros((k_max, n_sectors), dtype=np.int64)
    count = np.zeros(k_max, dtype=np.int64)
    guide = np.repeat(np.arange(unit.shape[0], dtype=np.int64), per_guide)
    align = np.zeros(k_max, dtype=np.int64)
    longest = max(1, int(np.diff(off).max())) if off.size > 1 else 1
    r_px, phi = np.empty(longest), np.empty(longest)
    f_px, log_scale, n_sectors = float(f_px), float(log_scale), int(n_sectors)
    row = 0
    for g in np.flatnonzero(per_guide).tolist():
        lo, hi = int(off[g]), int(off[g + 1])
        n = hi - lo
        plane_polar(unit, g, rows[lo:hi], n, f_px, r_px, phi)
        for a in range(int(per_guide[g])):
            count[row] = feature_vector(r_px, phi, n, a, n_sectors, log_scale, feature[row])
            align[row] = rows[lo + a]
            row += 1
    np.minimum(feature, max_value, out=feature)
    return feature, count, guide, align


@kernel
def sad_search(table, vec, nz_idx, nz, count_tol, n_best, best_row, best_sad, count_tol_above, acc, chord,
               chord_tol):
    """The ``n_best`` rows of smallest sum of absolute differences to ``vec`` (Luo et al. eq. 9).

    Only rows whose number of non-zero entries ``L_c`` satisfies
    ``L_s - count_tol <= L_c <= L_s + count_tol_above`` are compared (their eq. 10, epsilon1 =
    ``count_tol``, epsilon2 = ``count_tol_above``; a negative value means ``count_tol``). The sum is evaluated on the
    image's ``nz`` non-zero entries ``nz_idx`` only, by the exact identity
    ``sum_i |a_i - c_i| = sum_i c_i + sum_{a_i != 0} (|a_i - c_i| - c_i)``, one feature entry at
    a time over the whole window of rows (the table is stored by entry, so each pass reads
    contiguous bytes; ``acc``, int32 with at least as many entries as the table has rows, holds the
    running sums). With ``chord_tol >= 0`` only rows whose alignment pair is ``chord`` apart
    within ``chord_tol`` are ranked (``pair_filter``). Writes the best rows (ascending
    difference, ties by row) to ``best_row``/``best_sad`` and returns how many.
    """
    m = table.columns.shape[0]
    lo = max(nz - count_tol, 0)
    hi = min(nz + (count_tol if count_tol_above < 0 else count_tol_above), m)
    # unsigned row indices: no negative-index wraparound test, so the inner loops vectorise
    r0 = np.uint64(table.count_start[lo])
    r1 = np.uint64(table.count_start[hi + 1])
    total = table.total
    for r in range(r0, r1):
        acc[r] = total[r]
    for t in range(nz):
        i = nz_idx[t]
        a = np.int32(vec[i])
        col = table.columns[i]
        for r in range(r0, r1):
            c = np.int32(col[r])
            d = a - c
            acc[r] += max(d, -d) - c
    found = np.int64(0)   # not a literal: one signature of keep_best
    for r in range(r0, r1):
        if found == n_best and -acc[r] <= best_sad[found - 1]:
            continue   # keep_best would drop it
        if chord_tol >= 0 and abs(table.align_chord[r] - chord) > chord_tol:
            continue   # a rotation keeps separations: this row cannot be the image's pattern
        found = keep_best(best_sad, best_row, found, n_best, -acc[r], np.int64(r))   # negated: smallest first
    for c in range(found):
        best_sad[c] = -best_sad[c]
    return found


def chord_order(align_chord: np.ndarray, count_start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The feature rows of each non-zero count, ordered by ``align_chord`` (stable): ``(rows int64, chords
    float32)``, ``rows[count_start[c]:count_start[c + 1]]`` the rows of count ``c`` by chord and
    ``chords`` their chords (for :func:`sad_search_pairs`; derived from the table, kept with the kernel
    arguments, not stored in the database)."""
    rows = np.empty(align_chord.shape[0], dtype=np.int64)
    for c in range(count_start.shape[0] - 1):
        a, b = int(count_start[c]), int(count_start[c + 1])
        rows[a:b] = a + np.argsort(align_chord[a:b], kind="stable")
    return rows, np.ascontiguousarray(align_chord[rows], dtype=np.float32)


@inner   # kernels call it only
def chord_first(chords, lo, hi, chord, limit, upper):
    """First position in ``chords[lo:hi]`` (ascending) whose ``chords[k] - chord`` is >= ``limit``
    (``upper``: > ``limit``); the difference is monotone in ``chords[k]``, so bisection finds it."""
    while lo < hi:
        mid = (lo + hi) // 2
        d = chords[mid] - chord
        if d < limit or (upper and d == limit):
            lo = mid + 1
        else:
            hi = mid
    return lo


@kernel
def sad_search_pairs(table, vec, nz_idx, nz, count_tol, n_best, best_row, best_sad, count_tol_above, chord, chord_tol,
                     by_chord, chords):
    """:func:`sad_search` with ``pair_filter`` (``chord_tol >= 0``), the same rows in the same order.

    :func:`sad_search` sums the difference over every row of the count window and ranks those whose
    alignment chord is within ``chord_tol`` of ``chord``: ``abs(align_chord[r] - chord) <= chord_tol``.
    That difference is monotone in ``align_chord[r]``, so within each count the rows that pass are one
    run of :func:`chord_order`'s ``by_chord``/``chords`` (found by :func:`chord_first`, the same
    expression), about 1 row in 15. Only they are summed (the same int32 sums), and the best are
    kept by (difference, row): the order :func:`sad_search`'s scan of ascending rows gives, ties
    to the earlier row. Writes ``best_row``/``best_sad`` and returns how many, as :func:`sad_search`.
    """
    m = table.columns.shape[0]
    lo = max(nz - count_tol, 0)
    hi = min(nz + (count_tol if count_tol_above < 0 else count_tol_above), m)
    found = np.int64(0)
    for c in range(lo, hi + 1):
        a = chord_first(chords, np.int64(table.count_start[c]), np.int64(table.count_start[c + 1]), chord, -chord_tol,
                        np.bool_(False))
        b = chord_first(chords, a, np.int64(table.count_start[c + 1]), chord, chord_tol, np.bool_(True))
        for k in range(a, b):
            r = by_chord[k]
            sad = np.int32(table.total[r])
            for t in range(nz):
                i = nz_idx[t]
                av = np.int32(vec[i])
                cv = np.int32(table.columns[i, r])
                d = av - cv
                sad += max(d, -d) - cv
            sad64 = np.int64(sad)
            if found == n_best and (sad64 > best_sad[found - 1] or sad64 == best_sad[found - 1]
                                    and r > best_row[found - 1]):
                continue
            p = found if found < n_best else n_best - 1
            while p > 0 and (best_sad[p - 1] > sad64 or best_sad[p - 1] == sad64 and best_row[p - 1] > r):
                best_sad[p] = best_sad[p - 1]
                best_row[p] = best_row[p - 1]
                p -= 1
            best_sad[p] = sad64
            best_row[p] = r
            if found < n_best:
                found += 1
    return found


@kernel
def search_at(p, i):
    """The :class:`Search` packed at ``p[i:i+10]`` by ``planar.pack_params``."""
    return Search(int(p[i]), p[i + 1], p[i + 2], int(p[i + 3]), int(p[i + 4]), int(p[i + 5]), int(p[i + 6]),
                  int(p[i + 7]), p[i + 8], p[i + 9] != 0.0)


@kernel
def identify_kernel(x_px, y_px, params, columns, total, count_start, guide, align, align_chord, guides_unit, z_start,
                    by_chord, chords, trace):
    """Improved-LPT identification of one image; returns ``(rows, attitude, accepted)``.

    ``params``: the sensor :class:`Frame`, the :class:`Acceptance` and the :class:`Search`, packed
    by ``planar.pack_params``; the next six arrays are the :class:`FeatureTable`'s fields (separate
    arguments: numba types arrays at a call in C, NamedTuples field by field in Python); ``z_start`` is
    ``planar.z_index`` of ``guides_unit``, ``by_chord, chords`` are :func:`chord_order` of the table
    (with ``pair_filter`` the search is :func:`sad_search_pairs`, the same rows as :func:`sad_search`).

    For reference stars taken from the image centre outwards (at most ``search.max_refs``):
    the neighbours within R, nearest first; for each of the ``search.image_alignments`` nearest
    as alignment star (the paper: the nearest), the feature vector relative to it, the best
    ``search.n_candidates`` database rows by :func:`sad_search`; each candidate seeds an
    attitude (reference star and alignment star to their guide stars, Wahba) that
    :func:`confirm` must accept (``planar.confirm_pair_near``: the same answers as
    ``planar.confirm_pair``, most rejections proved without the seed's SVD or a catalog walk).
    The first accepted candidate is the answer.
    ``trace`` (int64, 4) receives the reference star, its alignment star, the feature row and the
    difference of the accepted match (-1 when none), for ``explain``.
    """
    sensor = frame_at(params, np.int64(0))
    acc = acceptance_at(params, np.int64(5))
    search = search_at(params, np.int64(10))
    table = FeatureTable(columns, total, count_start, guide, align, align_chord)
    n = x_px.shape[0]
    rows, unit, usable, order = begin_identify(x_px, y_px, sensor, search.double_px, trace)
    m = search.n_sectors
    nbrs = np.empty(n, dtype=np.int64)
    r_px = np.empty(n)
    phi = np.empty(n)
    vec = np.zeros(m, dtype=np.int64)
    nz_idx = np.empty(m, dtype=np.int64)
    best_row = np.empty(search.n_candidates, dtype=np.int64)
    best_sad = np.empty(search.n_candidates, dtype=np.int64)
    seed = np.full(n, -1, dtype=np.int64)
    work, A0 = pair_work(n)
    sums = np.empty(table.total.shape[0], dtype=np.int32)
    chord_tol = SEPARATION_TOL * acc.eps0 if search.pair_filter else -1.0
    for t in range(min(search.max_refs, order.shape[0])):
        s = order[t]
        k = reference_pattern(unit, usable, x_px, y_px, s, search.cos_radius, sensor.f_px, nbrs, r_px, phi)
        for a in range(min(search.image_alignments, k)):
            nz = feature_vector(r_px, phi, k, a, m, search.log_scale, vec)
            count_work(trace, 0, 1)
            q = 0
            for i in range(m):
                if vec[i] != 0:
                    nz_idx[q] = i
                    q += 1
            if chord_tol >= 0:
                found = sad_search_pairs(table, vec, nz_idx, nz, search.count_tol, search.n_candidates, best_row,
                                         best_sad, search.count_tol_above, chord_rows(unit, s, unit, nbrs[a]),
                                         chord_tol, by_chord, chords)
            else:
                found = sad_search(table, vec, nz_idx, nz, search.count_tol, search.n_candidates, best_row, best_sad,
                                   search.count_tol_above, sums, chord_rows(unit, s, unit, nbrs[a]), chord_tol)
            for c in range(found):
                r = best_row[c]
                ok, A = confirm_pair_near(unit, rows, seed, s, nbrs[a], table.guide[r], table.align[r],
                                          guides_unit, z_start, sensor, acc, work, A0)
                count_work(trace, 2, 1)
                if ok:
                    trace[0] = s
                    trace[1] = nbrs[a]
                    trace[2] = r
                    trace[3] = best_sad[c]
                    return rows, A, True
    return no_match(rows)
