"""numba kernels of the Tetra plugin: four-star patterns, their hash table, identification.

A pattern is four stars. Its six edges are chords of unit vectors; sorted ascending and divided
by the largest they give five ratios in [0, 1] (the scale-free shape, Brown 2017), each
quantised into ``bins`` bins; the five bin numbers, read as digits in base ``bins``, are the
pattern's key. Catalogue patterns sit in an open-addressing hash table (linear probing),
each slot holding a key and four guide-star rows in canonical order (ascending
distance from the pattern's centroid).
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

import numpy as np

from starid.kernels import backproject_px, chord_rows, order_by, reproject_assign, wahba_rows
from starid.kernels.jit import inner, kernel

#: An empty slot (no slot word reaches it: keys are < bins^5 <= 84^5 < 2^32 - 1).
EMPTY = np.uint64(0xFFFFFFFFFFFFFFFF)
#: A slot word is ``key << EDGE_BITS | edge``: the pattern key and its largest edge, quantised.
EDGE_BITS = np.uint64(16)
EDGE_MASK = np.uint64(0xFFFF)
#: Fibonacci hashing multiplier (2^64 / golden ratio, odd).
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
#: Pair order of the six edges of a pattern in canonical order 0..3.
PAIRS = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], dtype=np.int64)
#: The 24 permutations of four stars (identity first).
PERMS = np.array([[a, b, c, d] for a in range(4) for b in range(4) for c in range(4) for d in range(4)
                  if len({a, b, c, d}) == 4], dtype=np.int64)


class Tables(NamedTuple):
    """The database as one bundle: the pattern hash table and the guide stars.

    word : uint64 (S,) per slot ``key << 16 | edge``, ``EMPTY`` where free (at least one slot is
        free); ``edge`` is the pattern's largest edge in units of ``edge_scale`` / 65535, an
        absolute-scale filter read from the same cache line as the key.
    pattern : uint16/int32 (S, 4) guide rows of the slot's pattern, canonical order.
    bins : number of bins per edge ratio; edge_scale : the chord an ``edge`` of 65535 stands for.
    unit : float32 (g, 3) ICRS unit vectors of the guide stars, sorted by z (for reprojection).
    reportable : bool (g,) False for guide stars with a catalog companion (never reported).
    hip : int32/int64 (g,) catalog id of each guide star.
    v_mag : float32 (g,) catalog magnitude of each guide star.
    """

    word: np.ndarray
    pattern: np.ndarray
    bins: int
    edge_scale: float
    unit: np.ndarray
    reportable: np.ndarray
    hip: np.ndarray
    v_mag: np.ndarray


class Settings(NamedTuple):
    """Everything identify needs besides the database and the stars (angles as chords).

    sigma : per-axis centroid noise the windows assume (rad); beta : window width in sigmas.
    min_edge, max_edge : the pattern's largest edge must lie between them.
    max_keys : a pattern whose ratio windows span more keys than this is skipped.
    eps : verification radius (chord); c_fov : boresight-to-corner chord of the camera.
    report_eps : radius (chord) of the final assignment on the refined attitude; 0 = report the
        verification's assignment.
    mag_window : a star is reported only if its measured magnitude is within this of the
        catalog's (<= 0: no magnitude check).
    min_extra : guide stars beyond the pattern's four that verification must see.
    max_mismatch : largest accepted chance probability of the verification matches.
    n_image : how many of the brightest image stars form patterns.
    f_px, cx_px, cy_px, width_px, height_px : the camera (focal length, principal point, size).
    """

    sigma: float
    beta: float
    min_edge: float
    max_edge: float
    max_keys: int
    eps: float
    report_eps: float
    mag_window: float
    c_fov: float
    min_extra: int
    max_mismatch: float
    n_image: int
    f_px: float
    cx_px: float
    cy_px: float
    width_px: int
    height_px: int


# --------------------------------------------------------------------------- hash table


@inner   # kernels call it only
def hash_slot(key, size):
    """Home slot of ``key`` in a table of ``size`` slots: Fibonacci hashing, then the high 32
    bits scaled to ``[0, size)`` by a multiply-shift (any size up to 2^32, no power of two needed)."""
    h = (np.uint64(key) * _GOLDEN) >> np.uint64(32)
    return np.int64((h * np.uint64(size)) >> np.uint64(32))


@kernel
def table_insert(table_word, table_pattern, keys, edges, patterns):
    """Insert ``patterns[i]`` under ``keys[i]`` (with its quantised largest edge ``edges[i]``) by
    linear probing; returns the longest probe run."""
    size = table_word.shape[0]
    longest = 0
    for i in range(keys.shape[0]):
        s = hash_slot(np.int64(keys[i]), size)   # int64 keys everywhere: one signature
        run = 0
        while table_word[s] != EMPTY:
            s += 1
            if s == size:
                s = 0
            run += 1
        table_word[s] = (np.uint64(keys[i]) << EDGE_BITS) | (np.uint64(edges[i]) & EDGE_MASK)
        for a in range(4):
            table_pattern[s, a] = patterns[i, a]
        longest = max(longest, run)
    return longest


@kernel
def table_lookup(table_word, key, out, n_out):
    """Append to ``out[n_out:]`` the slots holding ``key`` (probe until a free slot); returns the new count."""
    size = table_word.shape[0]
    s = hash_slot(key, size)
    k = np.uint64(key)
    while table_word[s] != EMPTY:
        if (table_word[s] >> EDGE_BITS) == k and n_out < out.shape[0]:
            out[n_out] = s
            n_out += 1
        s += 1
        if s == size:
            s = 0
    return n_out


# --------------------------------------------------------------------------- patterns


@kernel
def canonical_order(unit, rows, out, dist):
    """Rows of a 4-star pattern in ascending distance from its centroid (ties: smaller row first).

    ``rows`` are 4 rows of ``unit``; writes them reordered to ``out`` and their distances (chords
    to the mean of the four vectors) to ``dist``, ascending. No allocation (hot in the build).
    """
    c0 = 0.0
    c1 = 0.0
    c2 = 0.0
    for k in range(4):
        c0 += 0.25 * float(unit[rows[k], 0])
        c1 += 0.25 * float(unit[rows[k], 1])
        c2 += 0.25 * float(unit[rows[k], 2])
    for k in range(4):
        t0 = float(unit[rows[k], 0]) - c0
        t1 = float(unit[rows[k], 1]) - c1
        t2 = float(unit[rows[k], 2]) - c2
        dist[k] = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        out[k] = rows[k]
    for i in range(1, 4):   # insertion sort of 4, carrying the rows along
        j = i
        while j > 0 and (dist[j] < dist[j - 1] or (dist[j] == dist[j - 1] and out[j] < out[j - 1])):
            td = dist[j]
            dist[j] = dist[j - 1]
            dist[j - 1] = td
            tr = out[j]
            out[j] = out[j - 1]
            out[j - 1] = tr
            j -= 1


@inner   # kernels call it only
def sorted_edges(unit, rows, edges):
    """The six chords among ``unit[rows[0..3]]``, sorted ascending into ``edges``; returns the largest."""
    for p in range(6):
        e = chord_rows(unit, rows[PAIRS[p, 0]], unit, rows[PAIRS[p, 1]])
        j = p
        while j > 0 and edges[j - 1] > e:   # insertion sort of 6
            edges[j] = edges[j - 1]
            j -= 1
        edges[j] = e
    return edges[5]


@kernel
def ratio_bin(r, bins):
    """Bin of an edge ratio ``r`` in [0, 1] (``r = 1`` falls into the last bin)."""
    b = int(math.floor(r * bins))
    return min(max(b, 0), bins - 1)


@kernel
def pattern_keys(unit, patterns, bins, largest):
    """Canonical order (in place) and hash key of each catalogue pattern ``(p, 4)``; writes each pattern's
    largest edge (chord) to ``largest`` (the table's edge check; here rather than with numpy in the build:
    six fancy-indexed copies of every pattern's vectors cost ~0.4 s per build)."""
    n = patterns.shape[0]
    keys = np.empty(n, dtype=np.uint32)
    edges = np.empty(6)
    rows = np.empty(4, dtype=np.int64)
    out = np.empty(4, dtype=np.int64)
    dist = np.empty(4)
    for i in range(n):
        for k in range(4):
            rows[k] = patterns[i, k]
        emax = sorted_edges(unit, rows, edges)
        largest[i] = emax
        key = 0
        for p in range(5):
            key = key * bins + ratio_bin(edges[4 - p] / emax, bins)
        keys[i] = key
        canonical_order(unit, rows, out, dist)
        for k in range(4):
            patterns[i, k] = out[k]
    return keys


def field_patterns(unit, field_rows, field_offsets, min_edge, max_edge, chunk=1 << 18):
    """Every 4-subset of each field's stars whose largest edge lies in ``[min_edge, max_edge]``.

    Field ``f`` holds guide rows ``field_rows[field_offsets[f]:field_offsets[f + 1]]``, ascending.
    Each pattern is returned as one int64 packing its four rows in ascending order (16 bits
    each), so the caller can drop the patterns that several fields share (sort, keep the first
    of equals); the order of the patterns is not defined (the caller sorts them).

    Once per database, in numpy (issue #25: a kernel of its own compiled ~0.45 CPU s on a cold
    cache; this takes ~0.09 s on Table 6's 6,601 fields): the fields of each size ``m`` together,
    ``chunk`` candidate patterns at a time, each edge the chord ``chord_rows`` computes (the same
    float operations in the same order, so the same bits) and the pattern kept on its largest edge.
    """
    unit = np.asarray(unit, dtype=np.float64)
    field_rows = np.asarray(field_rows, dtype=np.int64)
    offsets = np.asarray(field_offsets, dtype=np.int64)
    sizes = np.diff(offsets)
    out = [np.zeros(0, dtype=np.int64)]
    for m in np.unique(sizes[sizes >= 4]).tolist():
        combos = np.array(list(itertools.combinations(range(m), 4)), dtype=np.int64)   # (C, 4), a < b < c < d
        ia, ib = np.triu_indices(m, 1)
        pair = np.full((m, m), -1, dtype=np.int64)
        pair[ia, ib] = np.arange(ia.size)
        six = pair[combos[:, [0, 0, 0, 1, 1, 2]], combos[:, [1, 2, 3, 2, 3, 3]]]      # (C, 6) each edge's pair
        fields = np.flatnonzero(sizes == m)
        step = max(1, chunk // combos.shape[0])
        for f0 in range(0, fields.size, step):
            rows = field_rows[offsets[fields[f0:f0 + step], None] + np.arange(m)]     # (F, m)
            u = unit[rows]
            d = u[:, ia] - u[:, ib]                                                   # (F, pairs, 3)
            e = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2])
            emax = e[:, six[:, 0]]
            for k in range(1, 6):
                np.maximum(emax, e[:, six[:, k]], out=emax)
            f, c = np.nonzero((emax >= min_edge) & (emax <= max_edge))
            packed = rows[f, combos[c, 0]]
            for k in range(1, 4):
                packed = packed * 65536 + rows[f, combos[c, k]]
            out.append(packed)
    return np.concatenate(out)


# --------------------------------------------------------------------------- identification


@kernel
def binom_sf(k, m, q):
    """P(X >= k) for X ~ Binomial(m, q) (terms by recurrence from the k-th)."""
    if k <= 0:
        return 1.0
    if k > m:
        return 0.0
    if q <= 0.0:
        return 0.0
    if q >= 1.0:
        return 1.0
    term = math.exp(math.lgamma(m + 1) - math.lgamma(k + 1) - math.lgamma(m - k + 1) + k * math.log(q)
                    + (m - k) * math.log1p(-q))
    total = 0.0
    odds = q / (1.0 - q)
    for j in range(k, m + 1):
        total += term
        term *= (m - j) / (j + 1.0) * odds
    return min(total, 1.0)


@inner   # kernels call it only
def _match_order(img_edge, img_dist, cat_unit, cat_rows, tol, perm_out, cat_edge):
    """Star-to-star correspondence of an image pattern and a catalogue candidate, or False.

    Both are in canonical order. A permutation ``p`` (image star ``p[k]`` <-> catalogue star
    ``k``) is admissible when it only swaps image stars whose centroid distances agree within
    ``tol`` (canonical order up to noise ties; the identity always is); it matches when all six
    edges agree within ``tol``. The admissible match with the smallest largest edge residual
    wins. ``cat_edge`` is (4, 4) scratch.
    """
    for p in range(6):
        a = PAIRS[p, 0]
        b = PAIRS[p, 1]
        e = chord_rows(cat_unit, cat_rows[a], cat_unit, cat_rows[b])
        cat_edge[a, b] = e
        cat_edge[b, a] = e
    best = 1e300
    for t in range(PERMS.shape[0]):
        ok = True
        for k in range(4):
            if abs(img_dist[PERMS[t, k]] - img_dist[k]) > tol:
                ok = False
                break
        if not ok:
            continue
        worst = 0.0
        for p in range(6):
            a = PAIRS[p, 0]
            b = PAIRS[p, 1]
            worst = max(worst, abs(img_edge[PERMS[t, a], PERMS[t, b]] - cat_edge[a, b]))
        if worst <= tol and worst < best:
            best = worst
            for k in range(4):
                perm_out[k] = PERMS[t, k]
    return best <= tol


@inner   # kernels call it only
def _verify(unit, rows, guide_unit, tol, n_stars, out_row):
    """Attitude from the stars with ``rows >= 0`` (Wahba), then every star by reprojection.

    Returns ``(accepted, n_seen)``; ``out_row`` receives the reprojection's guide row per star.
    The chance probability of seeing ``n_seen - 4`` or more of the other predicted guide stars,
    each landing within ``eps`` of one of ``n_stars`` detections spread over the sensor, must
    not exceed ``max_mismatch``, and at least ``min_extra`` must be seen.
    """
    A = wahba_rows(unit, rows, guide_unit)
    # the sensor size as floats: the signature ptp, angle, lpt_improved and geometric voting compile
    # (an int64 pair compiled reproject_assign once more, ~1 CPU s, in a process running them too)
    n_seen, n_predicted = reproject_assign(A, unit, guide_unit, tol.c_fov + tol.eps, tol.eps, out_row,
                                           tol.f_px, tol.cx_px, tol.cy_px, float(tol.width_px),
                                           float(tol.height_px))
    for i in range(rows.shape[0]):   # the pattern's own stars must be confirmed as such
        if rows[i] >= 0 and out_row[i] != rows[i]:
            return False, n_seen
    extra = n_seen - 4
    if extra < tol.min_extra:
        return False, n_seen
    r_px = tol.eps * tol.f_px
    q = min(1.0, n_stars * math.pi * r_px * r_px / (tol.width_px * tol.height_px))
    return binom_sf(extra, max(n_predicted - 4, extra), q) <= tol.max_mismatch, n_seen


@kernel
def identify_kernel(x_px, y_px, mag, table, tol, record):
    """Tetra identification of one image: ``(hip, row)`` per star (catalog id and guide row, -1 = none).

    1. The ``n_image`` brightest detections (``starid.kernels.order_by``) form every 4-star pattern,
       in breadth-first brightness order (all patterns of the 4 brightest, then those adding the
       5th, ...), skipping patterns whose largest edge is outside ``[min_edge, max_edge]``.
    2. Each pattern's sorted edge ratios, with a window of ``beta`` propagated sigmas around
       each, select every key in the product of the bins they touch (tetra3's tolerance); the
       slots holding those keys whose stored largest edge agrees within the edge tolerance are
       the candidates.
    3. A candidate matches when, in canonical order (ties within the tolerance tried both
       ways), all six edges agree within ``beta sqrt(2) sigma``.
    4. Its attitude (Wahba on the four pairs) must be confirmed by the other stars
       (``_verify``); the first confirmed pattern wins. With ``report_eps`` > 0 the attitude is
       refined on every confirmed star and the stars are assigned again within that radius;
       otherwise the verification's assignment stands. Guide stars with a catalog companion,
       and stars whose measured magnitude is more than ``mag_window`` from the catalog's, are
       not reported.

    ``record`` (int64 (9,)) receives the winning pattern: 4 image stars, 4 guide rows in
    matching order, and the number of patterns tried; a 12-slot ``record`` also counts the work
    (slots 9-11: hash-table lookups, catalog patterns whose edges were compared, verifications).
    """
    n = x_px.shape[0]
    result = np.full(n, -1, dtype=np.int64)
    hip = np.full(n, -1, dtype=np.int64)
    for k in range(record.shape[0]):
        record[k] = -1 if k < 9 else 0
    counting = record.shape[0] >= 12
    if n < 4:
        return hip, result
    unit = backproject_px(x_px, y_px, tol.f_px, tol.cx_px, tol.cy_px)
    order = order_by(mag, x_px, y_px)
    m = min(n, tol.n_image)
    edge_tol = tol.beta * math.sqrt(2.0) * tol.sigma
    bins = table.bins
    slots = np.empty(4096, dtype=np.int64)
    rows4 = np.empty(4, dtype=np.int64)
    img4 = np.empty(4, dtype=np.int64)
    edges = np.empty(6)
    img_edge = np.empty((4, 4))
    lo = np.empty(5, dtype=np.int64)
    hi = np.empty(5, dtype=np.int64)
    digit = np.empty(5, dtype=np.int64)
    perm = np.empty(4, dtype=np.int64)
    cat4 = np.empty(4, dtype=np.int64)
    img_dist = np.empty(4)
    cat_edge = np.empty((4, 4))
    edge_unit = table.edge_scale / 65535.0
    edge_window = edge_tol + edge_unit
    trial_rows = np.full(n, -1, dtype=np.int64)
    out_row = np.empty(n, dtype=np.int64)
    tried = 0
    for li in range(3, m):               # breadth-first: the faintest member advances slowest
        for kk in range(2, li):
            for j in range(1, kk):
                for i in range(0, j):
                    rows4[0] = order[i]
                    rows4[1] = order[j]
                    rows4[2] = order[kk]
                    rows4[3] = order[li]
                    emax = sorted_edges(unit, rows4, edges)
                    if emax < tol.min_edge - edge_tol or emax > tol.max_edge + edge_tol or emax <= 0.0:
                        continue
                    tried += 1
                    n_keys = 1
                    for p in range(5):
                        r = edges[4 - p] / emax
                        t = tol.beta * math.sqrt(2.0) * tol.sigma * math.sqrt(1.0 + r * r) / emax
                        lo[p] = ratio_bin(r - t, bins)
                        hi[p] = ratio_bin(r + t, bins)
                        n_keys *= hi[p] - lo[p] + 1
                    if n_keys > tol.max_keys:
                        continue
                    canonical_order(unit, rows4, img4, img_dist)
                    for a in range(4):
                        for b in range(4):
                            img_edge[a, b] = chord_rows(unit, img4[a], unit, img4[b])
                    for p in range(5):
                        digit[p] = lo[p]
                    n_slot = np.int64(0)   # not a literal: one signature of table_lookup
                    while True:             # every key of the window (odometer over the digits)
                        key = np.int64(0)
                        for p in range(5):
                            key = key * bins + digit[p]
                        first = n_slot
                        n_slot = table_lookup(table.word, key, slots, n_slot)
                        if counting:
                            record[9] += 1
                        kept = first
                        for s in range(first, n_slot):   # absolute scale: the largest edge
                            if abs(float(table.word[slots[s]] & EDGE_MASK) * edge_unit - emax) <= edge_window:
                                slots[kept] = slots[s]
                                kept += 1
                        n_slot = kept
                        p = 4
                        while p >= 0 and digit[p] == hi[p]:
                            digit[p] = lo[p]
                            p -= 1
                        if p < 0:
                            break
                        digit[p] += 1
                    for s in range(n_slot):
                        for a in range(4):
                            cat4[a] = table.pattern[slots[s], a]
                        if counting:
                            record[10] += 1
                        if not _match_order(img_edge, img_dist, table.unit, cat4, edge_tol, perm, cat_edge):
                            continue
                        if counting:
                            record[11] += 1
                        for a in range(n):
                            trial_rows[a] = -1
                        for a in range(4):
                            trial_rows[img4[perm[a]]] = cat4[a]
                        ok, n_seen = _verify(unit, trial_rows, table.unit, tol, n, out_row)
                        if not ok:
                            continue
                        if tol.report_eps > 0:   # refine on every confirmed star, assign again
                            A = wahba_rows(unit, out_row, table.unit)
                            reproject_assign(A, unit, table.unit, tol.c_fov + tol.report_eps, tol.report_eps, result,
                                             tol.f_px, tol.cx_px, tol.cy_px, float(tol.width_px),
                                             float(tol.height_px))
                        else:                    # the verification's reprojection is the identification
                            for a in range(n):
                                result[a] = out_row[a]
                        for a in range(n):
                            if result[a] >= 0 and not table.reportable[result[a]]:
                                result[a] = -1
                            if (result[a] >= 0 and tol.mag_window > 0
                                    and abs(mag[a] - float(table.v_mag[result[a]])) > tol.mag_window):
                                result[a] = -1
                            if result[a] >= 0:
                                hip[a] = table.hip[result[a]]
                        for a in range(4):
                            record[a] = img4[perm[a]]
                            record[4 + a] = cat4[a]
                        record[8] = tried
                        return hip, result
    record[8] = tried
    return hip, result
