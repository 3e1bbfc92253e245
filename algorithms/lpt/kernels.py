"""numba kernels of the log-polar-transform algorithm (Wei, Zhang & Jiang 2009).

Geometry shared with the improved LPT and the grid (tangent plane, image preparation,
acceptance by reprojection) comes from :mod:`starid_algorithms.lpt_improved.planar`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from starid.kernels.jit import inline_inner, inline_kernel, inner, kernel

from ..lpt_improved.planar import (
    acceptance_at,
    begin_identify,
    confirm_near,
    count_work,
    frame_at,
    keep_best,
    no_match,
    pair_work,
    reference_pattern,
    seed_attitude_roll,
)

#: the largest budget :func:`reaches_budget` takes; a string with more goes to :func:`reaches_tables`
BUDGET_MAX = 4


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


@kernel
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


class Strings(NamedTuple):
    """The database strings as a kernel bundle: their non-zero characters, CSR by guide row.

    Guide ``g``'s characters are ``q`` in ``start[g]:start[g+1]``, sectors ascending:
    ``sector[q]`` (uint8; uint16 beyond 256 sectors) and its row ``level[q]`` (uint8). An empty
    sector (character 0) never matches, so the match reads these alone; :func:`dense_string`
    gives a guide's string back in the layout of :func:`lpt_string`.
    """

    sector: np.ndarray
    level: np.ndarray
    start: np.ndarray


def sparse_strings(strings: np.ndarray) -> Strings:
    """The :class:`Strings` bundle of dense strings ``(g, m)`` (built once, in ``build``)."""
    g_idx, sector = np.nonzero(strings)          # row-major: guide by guide, sectors ascending
    start = np.zeros(strings.shape[0] + 1, dtype=np.int32)
    np.cumsum(np.bincount(g_idx, minlength=strings.shape[0]), out=start[1:])
    sector_dtype = np.uint8 if strings.shape[1] <= 256 else np.uint16
    return Strings(sector.astype(sector_dtype), strings[g_idx, sector].astype(np.uint8), start)


@kernel
def dense_string(chars, g, out):
    """Guide ``g``'s string in the layout of :func:`lpt_string`, written into ``out`` (length m)."""
    for k in range(out.shape[0]):
        out[k] = 0
    for q in range(chars.start[g], chars.start[g + 1]):
        out[chars.sector[q]] = chars.level[q]


class ImageString(NamedTuple):
    """One image string, indexed for the match (:func:`index_image`).

    The image characters ``t < nz`` (sector ``sector[t]``, row ``level[t]``); for each database
    row L, the characters within ``level_tol`` of it: ``by_level[level_start[L]:level_start[L+1]]``,
    and as bits ``mask[L]`` (bit t; used when ``nz <= 62``).
    """

    sector: np.ndarray
    level: np.ndarray
    nz: int
    level_start: np.ndarray
    by_level: np.ndarray
    mask: np.ndarray


@kernel
def index_image(img_sector, img_level, nz, search, level_start, by_level, mask):
    """Fill ``level_start`` (n_levels + 2), ``by_level`` and ``mask`` (n_levels + 1) of an :class:`ImageString`."""
    q = 0
    level_start[0] = 0
    level_start[1] = 0
    mask[0] = 0
    for lv in range(1, search.n_levels + 1):
        bits = 0
        for t in range(nz):
            if abs(lv - img_level[t]) <= search.level_tol:
                by_level[q] = t
                q += 1
                if nz <= 62:
                    bits |= 1 << t
        mask[lv] = bits
        level_start[lv + 1] = q


@inner   # kernels call it only
def _popcount(x):
    """Set bits of a non-negative int64 word (SWAR: no data-dependent branch)."""
    x = x - ((x >> 1) & 0x5555555555555555)
    x = (x & 0x3333333333333333) + ((x >> 2) & 0x3333333333333333)
    x = (x + (x >> 4)) & 0x0F0F0F0F0F0F0F0F
    return (x * 0x0101010101010101) >> 56


@inner   # kernels call it only
def _lowest_bit(x):
    """Index of the lowest set bit of a non-zero int64 word."""
    x = x & -x
    n = 0
    if x & 0xFFFFFFFF == 0:
        n += 32
        x >>= 32
    if x & 0xFFFF == 0:
        n += 16
        x >>= 16
    if x & 0xFF == 0:
        n += 8
        x >>= 8
    if x & 0xF == 0:
        n += 4
        x >>= 4
    if x & 0x3 == 0:
        n += 2
        x >>= 2
    if x & 0x1 == 0:
        n += 1
    return n


@kernel
def rank_key(matched, n_chars):
    """Ranking key of a match: more matched characters first; among equals, fewer unmatched database characters.

    Strictly increasing in ``matched`` for a fixed ``n_chars``, so a bound on ``matched`` bounds it.
    """
    return 1024 * matched - min(n_chars - matched, 1023)


@kernel
def least_needed(threshold, n_chars, min_score):
    """Smallest score ``>= min_score`` whose :func:`rank_key` is above ``threshold`` (the last of a full list)."""
    need = max(min_score, threshold // 1024 - 1)
    while rank_key(need, n_chars) <= threshold:
        need += 1
    return need


@kernel
def match_bound(chars, g, img):
    """Upper bound of guide ``g``'s best score, without trying shifts.

    Under any shift an image character counts only if some database character is within
    ``level_tol`` rows of it: the bound is the number of image characters level-compatible
    with at least one of ``g``'s characters (bit masks when ``nz <= 62``), else the number of
    compatible (database, image) character pairs, and at most ``nz``.
    """
    a = chars.start[g]
    b = chars.start[g + 1]
    if img.nz <= 62:
        bits = np.int64(0)   # not a literal: one signature of _popcount
        for q in range(np.uint64(a), np.uint64(b)):
            bits |= img.mask[chars.level[q]]
        return _popcount(bits)
    n_pairs = 0
    for q in range(a, b):
        lv = chars.level[q]
        n_pairs += img.level_start[lv + 1] - img.level_start[lv]
    return min(n_pairs, img.nz)


@kernel
def shift_scores(chars, g, img, search, sets, planes):
    """Best circular shift of guide ``g``'s string against the image string: ``(best_score, best_shift)``.

    The score of shift ``s`` is the number of image characters (sector ``k``, row ``L``) for
    which the database string has a non-zero character within ``level_tol`` of ``L`` in sector
    ``k + s + d`` (mod m), ``|d| <= sector_tol``: the circular string match of the LPT
    algorithm, every shift at once, and the smallest shift among equals (0 when nothing
    matches). Bit-parallel: each image character's set of matching shifts is a bit set over
    the m shifts (``sets``, int64 (nz + 1, words), the last row a work row; OR makes each
    character count at most once per shift), the sets are summed as bit-sliced counters
    (``planes``, int64 (bits, words)) and the maximum is read from the top bit plane down.
    """
    m = search.n_sectors
    tol = search.sector_tol
    nw = sets.shape[1]
    nz = img.nz
    # unsigned indices throughout: no negative-index wraparound tests
    for t in range(np.uint64(nz)):
        for w in range(np.uint64(nw)):
            sets[t, w] = 0
    for q in range(np.uint64(chars.start[g]), np.uint64(chars.start[g + 1])):
        j = np.int64(chars.sector[q])
        lv = np.int64(chars.level[q])
        for p in range(np.uint64(img.level_start[lv]), np.uint64(img.level_start[lv + 1])):
            t = img.by_level[p]
            base = j - img.sector[t]
            row = sets[np.uint64(t)]
            for d in range(-tol, tol + 1):
                s = base - d
                if s < 0:
                    s += m
                elif s >= m:
                    s -= m
                row[np.uint64(s >> 6)] |= np.int64(1) << (s & 63)
    return best_shift(sets, nz, nw, planes, sets[nz])


@inner   # kernels call it only
def best_shift(sets, nz, nw, planes, cand):
    """``(best_score, best_shift)`` of the shift sets ``sets[:nz, :nw]`` (see :func:`shift_scores`).

    The largest number of rows holding one shift, and the smallest such shift (``(0, 0)`` when
    no row holds any): the rows are summed as bit-sliced counters (``planes``) and the maximum
    read from the top bit plane down; ``cand`` (``nw`` words) is a work row.
    """
    n_bits = planes.shape[0]
    for b in range(np.uint64(n_bits)):
        for w in range(np.uint64(nw)):
            planes[b, w] = 0
    top = 0
    for t in range(np.uint64(nz)):
        for w in range(np.uint64(nw)):
            carry = sets[t, w]
            b = np.uint64(0)
            while carry != 0:
                c = planes[b, w] & carry
                planes[b, w] ^= carry
                carry = c
                b += np.uint64(1)
            if b > top:
                top = np.int64(b)
    for w in range(nw):        # shifts still reaching the best so far; bits >= m are never set in planes
        cand[w] = -1
    best = 0
    for b in range(top - 1, -1, -1):
        hit = False
        for w in range(nw):
            if cand[w] & planes[b, w] != 0:
                hit = True
        if hit:
            best += 1 << b
            for w in range(nw):
                cand[w] &= planes[b, w]
    if best == 0:
        return 0, 0
    first_w = 0
    while cand[first_w] == 0:
        first_w += 1
    return best, first_w * 64 + _lowest_bit(cand[first_w])


@kernel
def window_counts(img, search, most):
    """``most[L]`` (L = 1..n_levels): the most image characters near row L in any few consecutive sectors.

    Near: within ``level_tol`` rows; few: 2 ``sector_tol`` + 1.

    Under any shift a database character of row L matches only image characters within
    ``level_tol`` rows of L in the 2 ``sector_tol`` + 1 sectors it covers: at most ``most[L]``
    of them. The image characters are in ascending sectors (as :func:`index_image` lists them).
    """
    m = search.n_sectors
    span = 2 * search.sector_tol
    most[0] = 0
    for lv in range(1, search.n_levels + 1):
        a = img.level_start[lv]
        b = img.level_start[lv + 1]
        best = 0
        for p in range(a, b):
            k0 = img.sector[img.by_level[p]]
            c = 0
            for r in range(a, b):
                gap = img.sector[img.by_level[r]] - k0
                if gap < 0:
                    gap += m
                if gap <= span:
                    c += 1
            if c > best:
                best = c
        most[lv] = best


@inner   # kernels call it only
def fill_pattern(pattern, m, sector_tol):
    """``pattern[x]`` (int64 rows of two words, zeros on entry) |= the shifts ``(x - d) mod m``,
    ``|d| <= sector_tol``: the shifts under which a database character in sector j matches an image
    character in sector ``j - x``."""
    for x in range(pattern.shape[0]):
        for d in range(-sector_tol, sector_tol + 1):
            s = (x - d) % m
            pattern[x, s >> 6] |= np.int64(1) << (s & 63)


@kernel
def shift_tables(img, search, tables):
    """Per reference star, the shifts under which one database character matches image characters.

    ``tables[r, L, j]`` (int64 (3, n_levels + 1, m, 2)): the shifts s (bit s) under which a
    database character of row L in sector j matches at least r + 1 image characters (those
    within ``level_tol`` rows of L in sectors j - s + d, ``|d| <= sector_tol``). Only for
    ``n_sectors <= 128`` and ``sector_tol <= 1`` (two words, at most 3 characters per window).
    (:func:`shift_tables_of`, the scan's form, on every layer of every row, with its inputs derived here.)
    """
    m = search.n_sectors
    pattern = np.zeros((m, 2), dtype=np.int64)
    fill_pattern(pattern, m, search.sector_tol)
    by_level_x, pattern2 = at_forms(img, pattern)
    most = np.full(search.n_levels + 1, tables.shape[0], dtype=np.int64)   # every layer of every row
    tables[:, 0] = 0                                                         # row 0: no character
    shift_tables_of(img, search, most, by_level_x, pattern2, tables)


@inner   # kernels call it only
def shift_tables_of(img, search, most, by_level_x, pattern2, tables):
    """:func:`shift_tables` with the shifts of a pair read from ``pattern2`` (see :func:`image_groups_at`),
    written only where they can be non-empty: layers r < ``most[L]`` (:func:`window_counts`) of rows
    L with ``most[L] > 0``; the scan reads no other entry (a database character of row L matches at
    most ``most[L]`` image characters)."""
    m = search.n_sectors
    for lv in range(1, search.n_levels + 1):
        a = img.level_start[lv]
        b = img.level_start[lv + 1]
        depth = most[lv]
        if depth == 0:
            continue
        for j in range(m):
            r1a = np.int64(0)
            r1b = np.int64(0)
            r2a = np.int64(0)
            r2b = np.int64(0)
            r3a = np.int64(0)
            r3b = np.int64(0)
            for p in range(a, b):
                x = j + by_level_x[p]
                xa = pattern2[x, 0]
                xb = pattern2[x, 1]
                r3a |= r2a & xa
                r3b |= r2b & xb
                r2a |= r1a & xa
                r2b |= r1b & xb
                r1a |= xa
                r1b |= xb
            tables[0, lv, j, 0] = r1a
            tables[0, lv, j, 1] = r1b
            if depth > 1:
                tables[1, lv, j, 0] = r2a
                tables[1, lv, j, 1] = r2b
            if depth > 2:
                tables[2, lv, j, 0] = r3a
                tables[2, lv, j, 1] = r3b


@inline_kernel
def reaches_tables(chars, g, need, tables, planes):
    """Whether guide ``g``'s best score can reach ``need``: false only when :func:`shift_scores` is below it.

    Under a shift s every matched image character is matched by some database character, and
    database character q matches w_q(s) <= 3 image characters, so score(s) <= sum over q of
    w_q(s), which is the number of :func:`shift_tables` sets (q's row and sector, layers 1..3)
    holding s. Those sums, every shift at once, are added as bit-sliced counters (``planes``,
    int64 (bits, 2)) and compared with ``need``. (:func:`reaches_tables_at` over every layer: the scan
    calls that one with the layers each row can fill.)
    """
    most = np.empty(tables.shape[1], dtype=np.int64)   # every layer of every row (tests, tools)
    for lv in range(most.shape[0]):
        most[lv] = tables.shape[0]
    return reaches_tables_at(chars, g, need, most, tables, planes)


@inner   # kernels call it only
def reaches_tables_at(chars, g, need, most, tables, planes):
    """:func:`reaches_tables` reading only the layers r < ``most[L]`` of a character of row L (the
    others are empty, and :func:`shift_tables_of` does not write them)."""
    a = np.uint64(chars.start[g])
    b = np.uint64(chars.start[g + 1])
    n_bits = planes.shape[0]
    for i in range(n_bits):
        planes[i, 0] = 0
        planes[i, 1] = 0
    for q in range(a, b):
        lv = np.uint64(chars.level[q])
        j = np.uint64(chars.sector[q])
        for r in range(np.uint64(most[lv])):
            xa = tables[r, lv, j, 0]
            xb = tables[r, lv, j, 1]
            if (xa | xb) == 0:
                break
            i = np.uint64(0)
            while (xa | xb) != 0:
                ca = planes[i, 0] & xa
                cb = planes[i, 1] & xb
                planes[i, 0] ^= xa
                planes[i, 1] ^= xb
                xa = ca
                xb = cb
                i += np.uint64(1)
    gta = np.int64(0)
    gtb = np.int64(0)
    eqa = np.int64(-1)
    eqb = np.int64(-1)
    for i in range(n_bits - 1, -1, -1):
        if (need >> i) & 1:
            eqa &= planes[i, 0]
            eqb &= planes[i, 1]
        else:
            gta |= eqa & planes[i, 0]
            gtb |= eqb & planes[i, 1]
    return (gta | eqa | gtb | eqb) != 0


@inline_kernel
def image_groups(chars, g, img, u, pattern, valid, xs, groups):
    """A necessary condition of guide ``g``'s best score reaching ``nz - u`` (``u >= 0``): false only when it does not.

    For every image character t, the set of shifts under which it is matched (``xs[t]``, int64
    (nz, 2), overwritten: ``pattern[(j - k) mod m]`` over the level-compatible pairs of a database
    character in sector j and t in sector k, ``pattern[x]`` the shifts x - d, ``|d| <=
    sector_tol``). A shift reaching ``nz - u`` misses at most u image characters, so one of the
    ``u + 1`` groups the characters are dealt into (``groups``, int64 (u + 1, 2)) has all its
    characters matched under it: when every group's intersection is empty, the score stays below.
    (:func:`image_groups_at` on tables derived here; the scan calls :func:`image_groups_pad`.)
    """
    by_level_x, pattern2 = at_forms(img, pattern)
    return image_groups_at(chars, g, img, by_level_x, u, pattern2, valid, xs, groups)


@kernel   # tests' and tools' form
def image_groups_padded(chars, g, img, u, pattern, valid, xs, groups):
    """:func:`image_groups` through :func:`pad_rows` and :func:`image_groups_pad`, the scan's form (``xs``:
    at least ``2 nz`` rows)."""
    by_level_x, pattern2 = at_forms(img, pattern)
    n_levels = img.level_start.shape[0] - 2
    pad_t = np.empty((n_levels + 1) * max(img.nz, 1), dtype=np.int64)
    pad_x = np.empty(pad_t.shape[0], dtype=np.int64)
    width = pad_rows(img, n_levels, by_level_x, pad_t, pad_x)
    return image_groups_pad(chars, g, img.nz, width, pad_t, pad_x, u, pattern2, valid, xs, groups)


@inner   # tests' and tools' forms only
def at_forms(img, pattern):
    """``(by_level_x, pattern2)``, what :func:`image_groups_at` and :func:`shift_tables_of` read, derived from
    the image and ``pattern`` (int64 (m, 2), the shifts x - d of each x): ``by_level_x[p]`` = m - (sector of
    ``img.by_level[p]``), ``pattern2[y]`` = ``pattern[y mod m]`` (the scan builds both once per image)."""
    m = pattern.shape[0]
    pattern2 = np.empty((2 * m, 2), dtype=np.int64)
    for y in range(2 * m):
        pattern2[y, 0] = pattern[y % m, 0]
        pattern2[y, 1] = pattern[y % m, 1]
    by_level_x = np.empty(img.by_level.shape[0], dtype=np.int64)
    for p in range(by_level_x.shape[0]):
        by_level_x[p] = m - img.sector[img.by_level[p]] if p < img.level_start[img.level_start.shape[0] - 1] else 0
    return by_level_x, pattern2


@inline_inner   # kernels call it only
def any_group(xs, nz, u, valid, groups):
    """Deal the image characters' shift sets ``xs[:nz]`` into ``u + 1`` groups in turn, intersect each
    group's (starting from ``valid``), and tell whether any group's intersection is non-empty: the last
    step of :func:`image_groups_at` and :func:`image_groups_pad`."""
    for i in range(u + 1):
        groups[i, 0] = valid[0]
        groups[i, 1] = valid[1]
    e = 0
    for t in range(nz):
        groups[e, 0] &= xs[t, 0]
        groups[e, 1] &= xs[t, 1]
        e += 1
        if e > u:
            e = 0
    any_a = np.int64(0)
    any_b = np.int64(0)
    for i in range(u + 1):
        any_a |= groups[i, 0]
        any_b |= groups[i, 1]
    return (any_a | any_b) != 0


@inline_kernel   # tests' and tools' form (the scan: image_groups_pad)
def image_groups_at(chars, g, img, by_level_x, u, pattern2, valid, xs, groups):
    """:func:`image_groups` without a branch per pair: ``by_level_x[p]`` = m - (sector of ``img.by_level[p]``),
    and ``pattern2[y]`` (int64 (2 m, 2)) = ``pattern[y mod m]``, read at ``j + by_level_x[p]``."""
    nz = np.uint64(img.nz)
    for t in range(nz):
        xs[t, 0] = 0
        xs[t, 1] = 0
    for q in range(np.uint64(chars.start[g]), np.uint64(chars.start[g + 1])):
        lv = np.uint64(chars.level[q])
        j = np.uint64(chars.sector[q])
        for p in range(np.uint64(img.level_start[lv]), np.uint64(img.level_start[lv + 1])):
            t = np.uint64(img.by_level[p])
            x = j + np.uint64(by_level_x[p])
            xs[t, 0] |= pattern2[x, 0]
            xs[t, 1] |= pattern2[x, 1]
    return any_group(xs, nz, u, valid, groups)


@inline_kernel   # one call site, the scan's most frequent test
def image_groups_pad(chars, g, nz, width, pad_t, pad_x, u, pattern2, valid, xs, groups):
    """:func:`image_groups_at` with every row's list of image characters padded to ``width`` entries.

    ``pad_t[L * width + i]``, ``pad_x[L * width + i]`` (i < ``width``): the i-th image character
    within ``level_tol`` rows of row L and m minus its sector, as ``img.by_level`` and ``by_level_x``
    list them; past the row's own count, the junk row ``nz + i`` of ``xs`` and 0. Every database
    character then reads ``width`` entries, a loop count fixed per reference star instead of one
    that changes with each character's row (a mispredicted branch per character); the rows ``t <
    nz`` of ``xs`` are :func:`image_groups_at`'s, and so is the answer.
    """
    for t in range(np.uint64(nz)):
        xs[t, 0] = 0
        xs[t, 1] = 0
    w = np.uint64(width)
    for q in range(np.uint64(chars.start[g]), np.uint64(chars.start[g + 1])):
        base = np.uint64(chars.level[q]) * w
        j = np.uint64(chars.sector[q])
        for i in range(w):
            t = np.uint64(pad_t[base + i])
            x = j + np.uint64(pad_x[base + i])
            xs[t, 0] |= pattern2[x, 0]
            xs[t, 1] |= pattern2[x, 1]
    return any_group(xs, nz, u, valid, groups)


@inner   # kernels call it only
def pad_rows(img, n_levels, by_level_x, pad_t, pad_x):
    """The padded lists of :func:`image_groups_pad` for one reference star; returns their ``width``
    (the longest row list, at least 1)."""
    width = 1
    for lv in range(1, n_levels + 1):
        width = max(width, img.level_start[lv + 1] - img.level_start[lv])
    for lv in range(n_levels + 1):
        a = img.level_start[lv] if lv > 0 else 0
        c = img.level_start[lv + 1] - a if lv > 0 else 0
        for i in range(width):
            if i < c:
                pad_t[lv * width + i] = img.by_level[a + i]
                pad_x[lv * width + i] = by_level_x[a + i]
            else:
                pad_t[lv * width + i] = img.nz + i
                pad_x[lv * width + i] = 0
    return width


@kernel   # a call, not inlined: the same speed, 0.4 CPU s less compile
def reaches_groups(chars, g, v, most, tables, valid, groups):
    """A necessary condition of :func:`reaches_budget` (same arguments): false only when it is false.

    The sets are dealt in turn into ``v + 1`` groups (``groups``, int64 (v + 1, 2), overwritten)
    and each group's sets are intersected. A shift missing at most ``v`` sets has a group it misses
    none of (pigeonhole), so it is in that group's intersection: when every intersection is empty,
    no shift reaches. Intersections of two or more of these sparse sets are nearly always empty,
    so an unrelated string is turned away by one pass over its characters, without branches.
    """
    for i in range(v + 1):
        groups[i, 0] = valid[0]
        groups[i, 1] = valid[1]
    e = 0
    for q in range(np.uint64(chars.start[g]), np.uint64(chars.start[g + 1])):
        lv = np.uint64(chars.level[q])
        j = np.uint64(chars.sector[q])
        for r in range(np.uint64(most[lv])):
            groups[e, 0] &= tables[r, lv, j, 0]
            groups[e, 1] &= tables[r, lv, j, 1]
            e += 1
            if e > v:
                e = 0
    any_a = np.int64(0)
    any_b = np.int64(0)
    for i in range(v + 1):
        any_a |= groups[i, 0]
        any_b |= groups[i, 1]
    return (any_a | any_b) != 0


@kernel
def reaches_budget(chars, g, v, most, tables, valid, at_most):
    """Whether some shift s has ``sum over g's characters q of w_q(s) >= total - v`` (see :func:`reaches_tables`).

    ``total`` is the sum of ``most[L_q]`` over ``g``'s characters and ``v = total - need >= 0``.
    Character q stands for its ``most[L_q]`` :func:`shift_tables` sets (layers 1..most[L_q]), and
    the sets not holding s are its misses, ``most[L_q] - w_q(s)`` of them: the test holds at s
    exactly when s misses at most ``v`` sets in all. The sets are taken in turn; ``at_most[i]``
    (int64 (v + 1, 2), overwritten) holds the shifts missed by at most i so far:
    ``at_most[i] = at_most[i - 1] | (at_most[i] & x)``, starting from the ``valid`` shifts (2
    words). No as soon as ``at_most[v]`` empties: for an unrelated string after about ``v + 1``
    sets, each holding a few of the m shifts.
    """
    for i in range(v + 1):
        at_most[i, 0] = valid[0]
        at_most[i, 1] = valid[1]
    for q in range(np.uint64(chars.start[g]), np.uint64(chars.start[g + 1])):
        lv = np.uint64(chars.level[q])
        j = np.uint64(chars.sector[q])
        for r in range(np.uint64(most[lv])):
            xa = tables[r, lv, j, 0]
            xb = tables[r, lv, j, 1]
            for i in range(v, 0, -1):
                at_most[i, 0] = at_most[i - 1, 0] | (at_most[i, 0] & xa)
                at_most[i, 1] = at_most[i - 1, 1] | (at_most[i, 1] & xb)
            at_most[0, 0] &= xa
            at_most[0, 1] &= xb
            if at_most[v, 0] | at_most[v, 1] == 0:
                return False
    return True


class ScanOrder(NamedTuple):
    """The database strings in the order of the scan, built once per database (:func:`scan_order`).

    ``strings``: the :class:`Strings` re-laid by character count (counting order, guide order
    within a count), so the scan reads them in memory order; position ``i`` is guide
    ``guide[i]``; strings of ``c`` characters are positions ``count_start[c]:count_start[c+1]``.
    When ``n_levels <= 16`` and no string has more than 15 characters in one row (else both
    empty): ``levels[i]`` (uint16), bit L - 1 set when the string has a character in row L, and
    ``counts[i]`` (uint64), nibble L - 1 the number of its characters in row L: the level bound
    and the window sum read these instead of the characters.
    """

    strings: Strings
    guide: np.ndarray
    count_start: np.ndarray
    levels: np.ndarray
    counts: np.ndarray


def scan_order(chars: Strings, n_sectors: int, n_levels: int) -> ScanOrder:
    """The :class:`ScanOrder` of the database strings ``chars`` (numpy, in the plugin's kernel arguments)."""
    n_chars = np.diff(chars.start).astype(np.int64)
    guide = np.argsort(n_chars, kind="stable").astype(np.int64)
    count_start = np.zeros(n_sectors + 2, dtype=np.int64)
    np.cumsum(np.bincount(n_chars, minlength=n_sectors + 1)[:n_sectors + 1], out=count_start[1:])
    lengths = n_chars[guide]
    start = np.zeros(guide.size + 1, dtype=np.int32)
    np.cumsum(lengths, out=start[1:])
    src = np.arange(int(start[-1]), dtype=np.int64) + np.repeat(chars.start[guide].astype(np.int64) - start[:-1],
                                                                   lengths)
    strings = Strings(chars.sector[src], chars.level[src], start)
    levels = np.zeros(0, dtype=np.uint16)
    counts = np.zeros(0, dtype=np.uint64)
    if n_levels <= 16 and src.size:
        pos = np.repeat(np.arange(guide.size), lengths)
        per = np.zeros((guide.size, 17), dtype=np.int64)
        np.add.at(per, (pos, strings.level.astype(np.int64)), 1)
        if per.max() <= 15:
            weights = np.uint64(1) << (np.arange(16, dtype=np.uint64) * np.uint64(4))
            counts = (per[:, 1:].astype(np.uint64) * weights).sum(axis=1, dtype=np.uint64)
            levels = ((per[:, 1:] > 0) * (1 << np.arange(16))).sum(axis=1).astype(np.uint16)
    return ScanOrder(strings, guide, count_start, levels, counts)


@inner   # kernels call it only
def _nibble_sum(x):
    """Sum of the 16 nibbles of a uint64 word, when it is below 256."""
    lo = np.uint64(0x0F0F0F0F0F0F0F0F)
    y = (x & lo) + ((x >> np.uint64(4)) & lo)
    return np.int64((y * np.uint64(0x0101010101010101)) >> np.uint64(56))


@inner   # kernels call it only
def level_set_masks(img, search, most, set_masks, most_masks):
    """Per reference star, the level bound and window sum of a string from its :class:`ScanOrder` summaries.

    ``set_masks[h, b]`` (int64 (2, 256)): the OR of ``img.mask[L]`` over the rows L whose bit is
    set in byte ``b`` of a levels word (h = 0: rows 1..8, h = 1: rows 9..16), so a string's
    :func:`match_bound` bits are ``set_masks[0, ls & 255] | set_masks[1, ls >> 8]``.
    ``most_masks[r]`` (uint64, 3): nibble L - 1 all ones when ``most[L] > r``, so the sum of
    ``most`` over a string's characters is the sum over r of the nibble sums of ``counts & most_masks[r]``.
    """
    for h in range(2):
        set_masks[h, 0] = 0
        for b in range(1, 256):
            low = b & -b
            lv = 1 + 8 * h + _lowest_bit(np.int64(low))
            set_masks[h, b] = set_masks[h, b ^ low] | (img.mask[lv] if lv <= search.n_levels else 0)
    for r in range(3):
        w = np.uint64(0)
        for lv in range(1, min(search.n_levels, 16) + 1):
            if most[lv] > r:
                w |= np.uint64(15) << np.uint64(4 * (lv - 1))
        most_masks[r] = w


@inner   # kernels call it only
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


@kernel
def search_at(p, i):
    """The :class:`StringSearch` packed at ``p[i:i+11]`` by ``planar.pack_params``."""
    return StringSearch(int(p[i]), int(p[i + 1]), p[i + 2], p[i + 3], p[i + 4], int(p[i + 5]), int(p[i + 6]),
                        int(p[i + 7]), int(p[i + 8]), int(p[i + 9]), p[i + 10])


@kernel
def identify_kernel(x_px, y_px, params, char_sector, char_level, char_start, scan_guide, count_start, scan_levels,
                    scan_counts, guides_unit, z_start, trace):
    """LPT identification of one image; returns ``(rows, attitude, accepted)``.

    ``params``: the sensor :class:`Frame`, the :class:`Acceptance` and the :class:`StringSearch`,
    packed by ``planar.pack_params``; the next seven arrays are the :class:`ScanOrder`'s fields (its
    :class:`Strings` field by field: separate arguments, as numba types arrays at a call in C,
    NamedTuples field by field in Python).

    For reference stars from the image centre outwards (at most ``max_refs``): its LPT string;
    every database string is compared under every circular shift (:func:`shift_scores`, the
    whole database, as in the paper); the ``n_candidates`` best guide stars scoring at least
    ``min_score`` (ties: the string with fewer unmatched characters first, then guide order)
    seed an attitude (reference star to guide star, roll from the shift) that :func:`confirm_near`
    must accept. Strings are visited by length (see the comment in the scan); a string whose
    :func:`match_bound` cannot reach ``min_score``, or, once the candidate list is full, cannot
    rank above its last, is skipped without trying its shifts: the candidates are exactly those
    of the full scan.
    ``trace`` (int64, 4): reference star, -1, guide row, score.
    """
    sensor = frame_at(params, np.int64(0))
    acc = acceptance_at(params, np.int64(5))
    search = search_at(params, np.int64(10))
    chars = Strings(char_sector, char_level, char_start)   # in scan order: position i is guide scan_guide[i]
    n = x_px.shape[0]
    rows, unit, usable, order = begin_identify(x_px, y_px, sensor, search.double_px, trace)
    m = search.n_sectors
    n_guide = chars.start.shape[0] - 1
    nbrs = np.empty(n, dtype=np.int64)
    r_px = np.empty(n)
    phi = np.empty(n)
    unsolved = np.full(n, -2, dtype=np.int64)   # the roll-seeded attitudes come from no assignment
    work4, _ = pair_work(n)
    img = np.zeros(m, dtype=np.int64)
    img_sector = np.empty(m, dtype=np.int64)
    img_level = np.empty(m, dtype=np.int64)
    img_phi = np.empty(m)
    owner = np.empty(m, dtype=np.int64)
    level_start = np.zeros(search.n_levels + 2, dtype=np.int64)
    by_level = np.empty(m * (2 * search.level_tol + 1), dtype=np.int64)
    mask = np.zeros(search.n_levels + 1, dtype=np.int64)
    n_words = (m + 63) // 64
    n_bits = 1
    while (1 << n_bits) <= m:
        n_bits += 1
    sets = np.zeros((m + 1, n_words), dtype=np.int64)
    planes = np.zeros((n_bits + 1, n_words), dtype=np.int64)
    fast = m <= 128 and search.sector_tol <= 1    # the shift tables' layout (two words, 3 layers)
    most = np.zeros(search.n_levels + 1, dtype=np.int64)
    tables = np.empty((3, search.n_levels + 1, m if fast else 0, 2), dtype=np.int64)   # see shift_tables_of
    sum_planes = np.zeros((n_bits + 3, 2), dtype=np.int64)
    at_most = np.zeros((BUDGET_MAX + 1, 2), dtype=np.int64)
    valid = np.zeros(2, dtype=np.int64)
    groups = np.zeros((3 * m + 1, 2), dtype=np.int64)
    xs = np.zeros((2 * m + 1, 2), dtype=np.int64)   # rows nz.. : image_groups_pad's junk rows
    pad_t = np.zeros((search.n_levels + 1) * m if fast else 0, dtype=np.int64)
    pad_x = np.zeros(pad_t.shape[0], dtype=np.int64)
    width = 1
    cand = np.zeros(2, dtype=np.int64)
    pattern = np.zeros((m if fast else 0, 2), dtype=np.int64)
    fill_pattern(pattern, m, search.sector_tol)
    pattern2 = np.zeros((2 * pattern.shape[0], 2), dtype=np.int64)   # pattern2[y] = pattern[y mod m]
    for x_ in range(pattern2.shape[0]):
        pattern2[x_, 0] = pattern[x_ % m, 0]
        pattern2[x_, 1] = pattern[x_ % m, 1]
    by_level_x = np.zeros(by_level.shape[0], dtype=np.int64)
    for s_ in range(min(m, 128)):
        valid[s_ >> 6] |= np.int64(1) << (s_ & 63)
    row = np.zeros(m, dtype=np.uint8)
    n_best = search.n_candidates
    best_item = np.empty(n_best, dtype=np.int64)   # guide row * m + shift
    best_sc = np.empty(n_best, dtype=np.int64)
    summed = fast and scan_levels.shape[0] == n_guide and n_guide > 0   # ScanOrder's row summaries
    set_masks = np.zeros((2, 256 if summed else 0), dtype=np.int64)
    most_masks = np.zeros(3, dtype=np.uint64)
    for t in range(min(search.max_refs, order.shape[0])):
        s = order[t]
        k = reference_pattern(unit, usable, x_px, y_px, s, search.cos_radius, sensor.f_px, nbrs, r_px, phi)
        if k < 1:
            continue
        nz = lpt_string(r_px, phi, k, search, img, owner)
        if nz < 1:
            continue
        count_work(trace, 0, 1)
        q = 0
        for j in range(m):
            if img[j] != 0:
                img_sector[q] = j
                img_level[q] = img[j]
                img_phi[q] = phi[owner[j]]
                q += 1
        index_image(img_sector, img_level, nz, search, level_start, by_level, mask)
        image = ImageString(img_sector, img_level, nz, level_start, by_level, mask)
        if fast:
            window_counts(image, search, most)
            for p_ in range(level_start[search.n_levels + 1]):
                by_level_x[p_] = m - img_sector[by_level[p_]]
            shift_tables_of(image, search, most, by_level_x, pattern2, tables)
            width = pad_rows(image, np.int64(search.n_levels), by_level_x, pad_t, pad_x)
        if summed:
            level_set_masks(image, search, most, set_masks, most_masks)
        # Strings by length (character count), lengths from nz up, then from nz - 1 down: the image's own
        # pattern is most likely among strings of about its length, and finding it first raises the
        # bar for the rest. A database character matches at most 2 sector_tol + 1 image characters
        # (one per sector), so a string of length c scores at most cap(c) = min(nz, (2 sector_tol + 1) c),
        # and a whole length whose cap cannot reach the list is skipped. The order changes no result:
        # equal ranks come only from strings of one length, which are scanned in guide order, so the
        # list is the full scan's, ties included.
        spread = 2 * search.sector_tol + 1
        first = min(nz, m)
        found = np.int64(0)   # not a literal: one signature of keep_best
        for step in range(m):
            length = first + step if first + step <= m else m - step
            lo = count_start[length]
            hi = count_start[length + 1]
            if lo == hi:
                continue
            cap = min(nz, spread * length)
            need = search.min_score
            if found == n_best:
                need = least_needed(best_sc[n_best - 1], length, search.min_score)
            if need > cap:
                continue
            for g in range(lo, hi):   # a position in the scan order (guide scan_guide[g])
                # need changes only when the list does: it is updated after each keep_best below
                scored = False
                if fast:
                    if summed:
                        # the level bound and the window sum from the row summaries
                        ls = np.int64(scan_levels[g])
                        if nz <= 62:
                            bound = _popcount(set_masks[0, ls & 255] | set_masks[1, ls >> 8])
                        else:
                            bound = match_bound(chars, g, image)
                        if bound < need:
                            continue
                        w = scan_counts[g]
                        total = (_nibble_sum(w & most_masks[0]) + _nibble_sum(w & most_masks[1])
                                 + _nibble_sum(w & most_masks[2]))
                    else:
                        # match_bound and the sum of most over the characters, in one pass
                        bits = np.int64(0)   # not a literal: one signature of _popcount
                        total = 0
                        for q in range(np.uint64(chars.start[g]), np.uint64(chars.start[g + 1])):
                            lv = chars.level[q]
                            bits |= mask[lv]
                            total += most[lv]
                        if (_popcount(bits) if nz <= 62 else match_bound(chars, g, image)) < need:
                            continue
                    count_work(trace, 1, 1)
                    if total < need:
                        continue
                    if nz - need < total - need:
                        if not image_groups_pad(chars, g, nz, width, pad_t, pad_x, nz - need, pattern2, valid, xs,
                                                groups):
                            continue
                        # xs holds shift_scores' shift sets: score them at once
                        matched, sh = best_shift(xs, nz, sets.shape[1], planes, cand)
                        scored = True
                    elif not reaches_groups(chars, g, total - need, most, tables, valid, groups):
                        continue
                    elif total - need <= BUDGET_MAX:
                        if not reaches_budget(chars, g, total - need, most, tables, valid, at_most):
                            continue
                    elif not reaches_tables_at(chars, g, need, most, tables, sum_planes):
                        continue
                else:
                    if match_bound(chars, g, image) < need:
                        continue
                    count_work(trace, 1, 1)
                if not scored:
                    matched, sh = shift_scores(chars, g, image, search, sets, planes)
                if matched < need:
                    continue
                found = keep_best(best_sc, best_item, found, n_best, rank_key(matched, length), g * m + sh)
                if found == n_best:
                    need = least_needed(best_sc[n_best - 1], length, search.min_score)
                    if need > cap:
                        break
        for c in range(found):
            g = scan_guide[best_item[c] // m]
            dense_string(chars, best_item[c] // m, row)
            roll = refined_roll(row, img_sector, img_level, img_phi, nz, best_item[c] % m, search)
            A = seed_attitude_roll(unit, s, guides_unit, g, roll)
            ok, A = confirm_near(unit, rows, A, guides_unit, z_start, sensor, acc, unsolved, work4, np.int64(-1))
            count_work(trace, 2, 1)
            if ok:
                trace[0] = s
                trace[2] = g
                trace[3] = (best_sc[c] + 1023) // 1024
                return rows, A, True
    return no_match(rows)
