"""Numba kernels of the planar-triangle algorithm (Cole & Crassidis 2006).

Features of a triangle of unit vectors ``b1, b2, b3`` (chord space):
area ``A`` (Heron's formula; computed here as half the norm of the edge cross product, which
is the same number and stays accurate for skinny triangles), polar moment about the centroid
``J = A (a^2 + b^2 + c^2) / 36`` (paper eq. 16), and the angular diameter of the smallest
enclosing circle (Cole's ``CalcFOV.m``). Variances follow paper eqs. 9-20 in the numerically
stable cross-product form.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from starid.kernels import (
    KVector,
    assign_all,
    backproject_px,
    chord_rows,
    field_chord,
    triple_product,
    verify_pairwise,
    wahba_rows,
    z_band_rows,
)
from starid.kernels.jit import inner, kernel
from starid.kernels.kvector import kvector_ends, kvector_rows, kvector_trim
from starid.kernels.order import search_left, sort_int_prefix
from starid.kernels.prefetch import prefetch

MOMENT_BLOCK = 256  # triangles per block of the moment index (offsets fit uint8)
FENCE_STEP = 16  # moment-index entries per fence post: 16 float32, one 64-byte cache line of the index
FENCE_POSTS = MOMENT_BLOCK // FENCE_STEP  # posts per block: 16 float32, one cache line of the fence
HASH_ROOM = 16  # hash-table slots per cached candidate (3 pairs, table at most 3/8 full, power of two)
EMPTY = np.uint64(0xFFFFFFFFFFFFFFFF)  # an empty hash slot (no star pair lo < hi < 65536 has this key)
SHIFT = np.uint64(32)  # a slot is (star-pair key << 32) | candidate, one 8-byte read per probe
LOW = np.uint64(0xFFFFFFFF)
#: names of the per-image work counters the identify kernels return (``Identification.counters``):
#: star subsets pivoted, pivots made (triangles appended to a chain), catalog candidates examined
#: (start-triangle hits plus star-pair hash hits at each pivot), unique finalists verified, and
#: image triangles kept after the area k-vector search (one k-vector search each); then the first query
#: step's (the start triangle of the first chain: the largest-area image triangle of the first subset
#: tried): |R| = its catalog candidates (area and moment windows), whether the identification names its
#: three stars, and whether R holds the catalog triangle it names them as (``first_R``,
#: ``first_named``, ``first_in_R``: Galvizo & Lim's f and S, docs/experiments.md); start triangles
#: queried, and the queries (start triangles and pivots) made up to the first that left one finalist
#: (``to_r``: hoku's catalog accesses to obtain r; 0 when none did, reported as every query made)
WORK_COUNTERS = ("subsets", "pivots", "candidates", "verifications", "image_triangles", "first_R", "first_named",
                 "first_in_R", "starts", "to_r")
N_WORK = len(WORK_COUNTERS)
CACHE_PER_TRIANGLE = 2048  # room for moment candidates per image triangle (on average) in the cache
CACHE_MAX = 1 << 22  # at most this many cached candidates per image (32 MB, their hash tables 512 MB of address
# space): an image of 20,000 triangles (the paper's reading with false stars) asked 344 MB + 5.5 GB, which a
# worker's --memory-limit-gb (address space) refused; past it candidates are computed again, the same ones
MEMO_DIM = 64  # first pivots (start triangle g0, second g1) with g0, g1 < MEMO_DIM are memoised per image
MEMO_NODES = 1 << 15  # room for the memoised pivots' new finalists per image (full: no more memoising)
#: a pivot of at most this many finalists into a triangle whose hash table is not built matches them
#: against the candidates holding two of their stars only (``_few_hash``; the second such pivot into
#: the same triangle builds the whole table, kept for the other subsets)
FEW_FINALISTS = 256
KEY_BASE = 65536  # star indices are < 65536 (uint16), so a sorted pair packs into lo * 65536 + hi


class Rules(NamedTuple):
    """What a star triple must satisfy to be a database triangle (chord units, radians)."""

    chord_max: float  # every side at most this chord (``fov_db_rad`` as a chord)
    fov_rad: float  # angular diameter of the smallest enclosing circle at most this
    min_area: float  # chord-triangle area at least this


class Tables(NamedTuple):
    """The database as the kernels read it (see ``PlanarTriangleDatabase``)."""

    stars: np.ndarray  # uint16 (N, 3) guide rows of the triangle of each moment-index entry, ascending within a row
    area: KVector  # float32 areas, ascending, with their k-vector
    moment: np.ndarray  # float32 (N,) polar moments, sorted within each block of MOMENT_BLOCK triangles
    fence: np.ndarray  # float32 (blocks, FENCE_POSTS) every FENCE_STEP-th entry of ``moment`` (moment_fence)
    moment_perm: np.ndarray  # uint8 (N,) triangle (offset in its block, area order) of each entry of ``moment``
    unit: np.ndarray  # float64 (n, 3) guide-star unit vectors, ICRS
    nbr_ptr: np.ndarray  # int32 (n + 1,) CSR neighbours within the sensor diagonal
    nbr_idx: np.ndarray  # uint16
    rules: Rules


class Tolerance(NamedTuple):
    """Windows and switches of one identification (see ``PlanarTriangle``)."""

    sigma_rad: float  # centroid noise per axis, radians
    beta: float  # window half-width in standard deviations
    climit: int  # drop image triangles with more area hits than this
    pivot_limit: int  # at most this many pivots (-1: no limit)
    abort_if_grow: bool
    consistent_chain: bool
    restarts: int
    extend: bool
    min_support: int
    min_verified: int


class ImageTriangles(NamedTuple):
    """The image triangles of one identification and their area hits."""

    v: np.ndarray  # (n, 3) camera-frame unit vectors of the stars
    tri: np.ndarray  # int64 (m, 3) star indices of each triangle
    area: np.ndarray  # (m,) chord-triangle area
    start: np.ndarray  # int64 (m,) first area hit in the catalog
    stop: np.ndarray  # int64 (m,) one past the last area hit
    gid: np.ndarray  # int64 (m,) row of each triangle in the candidate cache (``MomentCache``)


class MomentCache(NamedTuple):
    """Moment-filtered area hits of image triangles, computed once per triangle and shared by
    every star subset of an image (a subset's triangles are triangles of the whole image)."""

    done: np.ndarray  # bool (M,) candidates of triangle g computed
    start: np.ndarray  # int64 (M,) they are buf[start[g]:stop[g]]
    stop: np.ndarray
    buf: np.ndarray  # int64 (CACHE_PER_TRIANGLE x M,) storage; full: no more caching
    keys: np.ndarray  # uint64 (HASH_ROOM x len(buf),) hash tables of the candidates' star pairs: slot =
    # key << SHIFT | candidate (EMPTY: empty slot)
    hstart: np.ndarray  # int64 (M,) triangle g's table is keys[hstart[g]:hstart[g] + hsize[g]]
    hsize: np.ndarray  # int64 (M,) a power of two >= 8 x its candidates (3 keys each)
    fill: np.ndarray  # int64 (1,) used length of buf
    hfill: np.ndarray  # int64 (1,) used length of keys
    # the first pivot of a chain (start triangle g0 -> second triangle g1) depends on (g0, g1) alone,
    # and the star subsets of one image repeat it (about 40 % of them on false-star images):
    memo_of: np.ndarray  # int64 (MEMO_DIM^2,) entry of the pivot g0 -> g1 at g0 * MEMO_DIM + g1 (-1: none)
    memo_start: np.ndarray  # int64 (MEMO_DIM^2,) its new finalists are memo_node/memo_parent[start:start + len]
    memo_len: np.ndarray  # int64 (MEMO_DIM^2,)
    memo_work: np.ndarray  # int64 (MEMO_DIM^2,) candidates it examined (added to the counter again)
    memo_grew: np.ndarray  # bool (MEMO_DIM^2,) it abandoned the chain (more finalists than before)
    memo_node: np.ndarray  # int64 (MEMO_NODES,) catalog triangle of each new finalist
    memo_parent: np.ndarray  # int64 (MEMO_NODES,) its parent: index of a start candidate
    memo_fill: np.ndarray  # int64 (2,) entries and memo_node slots used
    # a pivot with few finalists matches them without the next triangle's hash table (``_few_hash``):
    mark: np.ndarray  # uint8 (guide stars,) all zero between pivots; 1 = a star of a finalist's last triangle
    scans: np.ndarray  # int64 (M,) pivots into triangle g matched that way (the second builds its table)


@inner
def _cross(u0, u1, u2, w0, w1, w2):
    return u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0


@inner
def triangle_features(r1, r2, r3):
    """``(area, moment, diameter_rad)`` of the chord triangle of three unit vectors.

    area = Heron's area of the planar triangle with chord sides (paper's ``A``), computed as
    ``|(r2 - r1) x (r3 - r1)| / 2``; moment = ``A (a^2 + b^2 + c^2) / 36`` (paper eq. 16);
    diameter_rad = angular diameter of the smallest circle enclosing the three stars
    (``CalcFOV.m``: circumcircle of an acute triangle, else the longest side as diameter).
    """
    e1x, e1y, e1z = r2[0] - r1[0], r2[1] - r1[1], r2[2] - r1[2]
    e2x, e2y, e2z = r3[0] - r1[0], r3[1] - r1[1], r3[2] - r1[2]
    nx, ny, nz = _cross(e1x, e1y, e1z, e2x, e2y, e2z)
    area = 0.5 * math.sqrt(nx * nx + ny * ny + nz * nz)
    a2 = e1x * e1x + e1y * e1y + e1z * e1z
    c2 = e2x * e2x + e2y * e2y + e2z * e2z
    dx, dy, dz = r3[0] - r2[0], r3[1] - r2[1], r3[2] - r2[2]
    b2 = dx * dx + dy * dy + dz * dz
    s2 = a2 + b2 + c2
    moment = area * s2 / 36.0
    big = max(a2, b2, c2)
    if big < s2 - big and area > 0.0:  # acute: circumradius abc / (4A)
        radius = math.sqrt(a2 * b2 * c2) / (4.0 * area)
    else:
        radius = 0.5 * math.sqrt(big)
    if radius >= 1.0:
        diameter = math.pi
    else:
        diameter = 2.0 * math.asin(radius)
    return area, moment, diameter


@inner
def triangle_variances(r1, r2, r3, sigma_rad):
    """``(var_area, var_moment)`` of the chord triangle under the QUEST noise model.

    Paper eqs. 9-20 (``sigma_A^2 = H R H^T``, ``sigma_J^2 = Hbar R Hbar^T`` with
    ``R_i = sigma^2 (I - b_i b_i^T)``), evaluated with the cross-product gradients:
    ``grad_1 A = (b2 - b3) x n_hat / 2`` (cyclic), ``grad_i J = (S grad_i A + A grad_i S) / 36``
    with ``S = a^2 + b^2 + c^2``.
    """
    # the nine coordinates read once (scalars: every array access is a typed operation to compile)
    x1, y1, z1 = r1[0], r1[1], r1[2]
    x2, y2, z2 = r2[0], r2[1], r2[2]
    x3, y3, z3 = r3[0], r3[1], r3[2]
    e1x, e1y, e1z = x2 - x1, y2 - y1, z2 - z1
    e2x, e2y, e2z = x3 - x1, y3 - y1, z3 - z1
    nx, ny, nz = _cross(e1x, e1y, e1z, e2x, e2y, e2z)
    nn = math.sqrt(nx * nx + ny * ny + nz * nz)
    if nn == 0.0:
        return 0.0, 0.0
    area = 0.5 * nn
    nx, ny, nz = nx / nn, ny / nn, nz / nn
    s2 = 0.0
    s2 += (x1 - x2) ** 2 + (x2 - x3) ** 2 + (x1 - x3) ** 2
    s2 += (y1 - y2) ** 2 + (y2 - y3) ** 2 + (y1 - y3) ** 2
    s2 += (z1 - z2) ** 2 + (z2 - z3) ** 2 + (z1 - z3) ** 2
    var_a = 0.0
    var_j = 0.0
    # vertex p with the other two q, r: (1, 2, 3), (2, 3, 1), (3, 1, 2)
    px, py, pz, qx, qy, qz, rx, ry, rz = x1, y1, z1, x2, y2, z2, x3, y3, z3
    for _ in range(3):
        # grad_p A = (q - r) x n_hat / 2; grad_p S = 2 (p - q) + 2 (p - r)
        gx, gy, gz = _cross(qx - rx, qy - ry, qz - rz, nx, ny, nz)
        gx, gy, gz = 0.5 * gx, 0.5 * gy, 0.5 * gz
        sx = 2.0 * (2.0 * px - qx - rx)
        sy = 2.0 * (2.0 * py - qy - ry)
        sz = 2.0 * (2.0 * pz - qz - rz)
        jx = (s2 * gx + area * sx) / 36.0
        jy = (s2 * gy + area * sy) / 36.0
        jz = (s2 * gz + area * sz) / 36.0
        pg = px * gx + py * gy + pz * gz
        pj = px * jx + py * jy + pz * jz
        var_a += gx * gx + gy * gy + gz * gz - pg * pg
        var_j += jx * jx + jy * jy + jz * jz - pj * pj
        px, py, pz, qx, qy, qz, rx, ry, rz = qx, qy, qz, rx, ry, rz, px, py, pz
    s = sigma_rad * sigma_rad
    return s * var_a, s * var_j


SCAN_CHUNK = 1 << 14  # neighbour pairs per numpy pass of the database scan (small: the temporaries stay in cache)


def scan_triangles(unit, nbr_ptr, nbr_idx, rules):
    """Catalog triangles ``i < j < k`` that pass the database ``rules``, as ``(stars uint16 (N, 3), area,
    moment)`` in the order of the loops ``for i: for a < b in i's neighbours (j = nbr_idx[a], k =
    nbr_idx[b])``.

    numpy, not a kernel: it runs once per database, and a kernel cost more to compile (~0.5 CPU s on
    a cold cache) than this takes to run (about the kernel's own time at Table 6's 2.1 M triangles). The
    arithmetic is :func:`triangle_features`' operation by operation (and ``chord_rows``' for the side
    ``j``-``k``), so the values are the same bits; the smallest enclosing circle's diameter decides
    with libm's ``asin`` (the kernel's) wherever numpy's could differ from it (within 1e-9 of the limit).
    """
    n = unit.shape[0]
    ptr = np.asarray(nbr_ptr, dtype=np.int64)
    m = int(ptr[-1])
    ux, uy, uz = (np.ascontiguousarray(unit[:, q], dtype=np.float64) for q in range(3))
    idx = np.asarray(nbr_idx, dtype=np.int64)
    owner = np.repeat(np.arange(n, dtype=np.int64), np.diff(ptr))  # star i of each neighbour entry a
    n_pairs = ptr[owner + 1] - 1 - np.arange(m, dtype=np.int64)  # entries b > a of the same star
    ends = np.cumsum(n_pairs)
    parts = []
    a_lo = 0
    while a_lo < m:
        done = int(ends[a_lo - 1]) if a_lo else 0
        a_hi = min(max(int(np.searchsorted(ends, done + SCAN_CHUNK, side="right")), a_lo + 1), m)
        cnt = n_pairs[a_lo:a_hi]
        a = np.repeat(np.arange(a_lo, a_hi, dtype=np.int64), cnt)
        b = a + 1 + (np.arange(a.size, dtype=np.int64) - np.repeat(np.cumsum(cnt) - cnt, cnt))
        a_lo = a_hi
        j = idx[a]
        k = idx[b]
        x2, y2, z2, x3, y3, z3 = ux[j], uy[j], uz[j], ux[k], uy[k], uz[k]
        dx, dy, dz = x3 - x2, y3 - y2, z3 - z2
        b2 = dx * dx + dy * dy + dz * dz  # side j-k squared (chord_rows' (x2 - x3)^2: the same bits)
        near = np.flatnonzero(~(np.sqrt(b2) > rules.chord_max))
        i = owner[a[near]]
        j, k, b2 = j[near], k[near], b2[near]
        x1, y1, z1 = ux[i], uy[i], uz[i]
        x2, y2, z2, x3, y3, z3 = x2[near], y2[near], z2[near], x3[near], y3[near], z3[near]
        e1x, e1y, e1z = x2 - x1, y2 - y1, z2 - z1
        e2x, e2y, e2z = x3 - x1, y3 - y1, z3 - z1
        nx = e1y * e2z - e1z * e2y
        ny = e1z * e2x - e1x * e2z
        nz = e1x * e2y - e1y * e2x
        area = 0.5 * np.sqrt(nx * nx + ny * ny + nz * nz)
        a2 = e1x * e1x + e1y * e1y + e1z * e1z
        c2 = e2x * e2x + e2y * e2y + e2z * e2z
        s2 = a2 + b2 + c2
        big = np.maximum(np.maximum(a2, b2), c2)
        acute = (big < s2 - big) & (area > 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            radius = np.where(acute, np.sqrt(a2 * b2 * c2) / (4.0 * area), 0.5 * np.sqrt(big))
        keep = np.flatnonzero(area >= rules.min_area)
        r = radius[keep]
        diameter = np.full(r.shape, math.pi)
        inside = r < 1.0
        diameter[inside] = 2.0 * np.arcsin(r[inside])
        # np.arcsin may differ from libm's asin (the kernel's) in the last bits: near the limit, libm's
        edge = np.flatnonzero(inside & (np.abs(diameter - rules.fov_rad) <= 1e-9 * rules.fov_rad))
        diameter[edge] = [2.0 * math.asin(x) for x in r[edge].tolist()]
        keep = keep[diameter <= rules.fov_rad]
        parts.append((i[keep], j[keep], k[keep], area[keep], area[keep] * s2[keep] / 36.0))
    cols = [np.concatenate([p[q] for p in parts]) if parts else np.zeros(0) for q in range(5)]
    stars = np.empty((cols[0].shape[0], 3), dtype=np.uint16)
    for q in range(3):
        stars[:, q] = cols[q]
    return stars, cols[3].astype(np.float64), cols[4].astype(np.float64)


def moment_blocks(moment):
    """The moment index: ``(moment sorted within each block of MOMENT_BLOCK consecutive triangles
    of the area order, float32; uint8 offset in the block of the triangle of each entry)``."""
    n = moment.shape[0]
    sorted_moment = np.empty(n, dtype=np.float32)
    perm = np.empty(n, dtype=np.uint8)
    for base in range(0, n, MOMENT_BLOCK):
        block = moment[base:base + MOMENT_BLOCK].astype(np.float32)
        order = np.argsort(block, kind="stable")
        sorted_moment[base:base + block.size] = block[order]
        perm[base:base + block.size] = order
    return sorted_moment, perm


def entry_triangles(moment_perm):
    """The area-order triangle of each entry ``p`` of the moment index: ``p - p % MOMENT_BLOCK +
    moment_perm[p]`` (int64)."""
    entry = np.arange(moment_perm.shape[0], dtype=np.int64)
    return entry - entry % MOMENT_BLOCK + moment_perm


def moment_fence(sorted_moment):
    """The moment index's fence: float32 ``(blocks, FENCE_POSTS)``, post ``k`` of block ``b`` the entry
    ``b * MOMENT_BLOCK + k * FENCE_STEP`` of ``sorted_moment`` (+inf where the last block ends first).
    One cache line per block, the blocks' lines consecutive: :func:`_moment_filter` finds the stretch of
    ``FENCE_STEP`` entries where a block's hits begin from it and reads one line of the index there."""
    n = sorted_moment.shape[0]
    blocks = -(-n // MOMENT_BLOCK)
    padded = np.full(blocks * MOMENT_BLOCK, np.inf, dtype=np.float32)
    padded[:n] = sorted_moment
    return np.ascontiguousarray(padded.reshape(blocks, FENCE_POSTS, FENCE_STEP)[:, :, 0])


@inner
def _moment_filter(db, start, stop, lo, hi):
    """The catalog triangles in ``[start, stop)`` (area order) whose polar moment lies in
    ``[lo, hi]``, as their entries (positions) in the moment index, ascending: the triangle of entry
    ``p`` is ``p - p % MOMENT_BLOCK + moment_perm[p]`` in area order, its stars ``Tables.stars[p]``.

    The same set as scanning the area hits, found in each block of the moment index that the area
    range touches (the area window holds ~20x more triangles than the moment window). A first pass
    reads only the blocks' fence lines (:func:`moment_fence`, consecutive): each says which stretch of
    ``FENCE_STEP`` entries holds the block's first entry >= ``lo``, and the lines of the index, of
    ``moment_perm`` and of the stars there are asked for (``prefetch``) at once for every block. The
    second scans each stretch to that entry (the one a binary search of the block finds, which read
    ~5 dependent lines of the index where this reads one, already on its way) and on through the
    block's hits, consecutive entries whose stars (stored in the index's order) the caller reads next.
    """
    moment, fence, moment_perm, stars = db.moment, db.fence, db.moment_perm, db.stars
    out = np.empty(max(stop - start, 0), dtype=np.int64)
    m = 0
    if stop <= start:
        return out
    n = moment.shape[0]
    b0 = start // MOMENT_BLOCK
    seek = np.empty((stop - 1) // MOMENT_BLOCK + 1 - b0, dtype=np.int64)
    for q in range(seek.shape[0]):      # from the fence alone: where each block's scan starts; its lines asked for
        below = 0          # posts < lo (the posts ascend; +inf never is)
        for k in range(FENCE_POSTS):
            below += fence[b0 + q, k] < lo
        # the first entry >= lo is the block's first (no post below lo) or in ((below-1) * STEP, below * STEP]
        seek[q] = (b0 + q) * MOMENT_BLOCK + max(below - 1, 0) * FENCE_STEP + (below > 0)
        prefetch(moment, min(seek[q], n - 1))
        prefetch(moment_perm, min(seek[q], n - 1))
        prefetch(stars, min(seek[q], n - 1))
        prefetch(stars, min(seek[q] + 10, n - 1))
    for q in range(seek.shape[0]):
        base = (b0 + q) * MOMENT_BLOCK
        end = min(base + MOMENT_BLOCK, n)
        pos = seek[q]
        last = min(pos + FENCE_STEP - 1, end)    # a post >= lo (or the block's end) follows the stretch
        while pos < last and moment[pos] < lo:
            pos += 1
        while pos < end and moment[pos] <= hi:
            if moment[pos] >= lo:
                t = base + np.int64(moment_perm[pos])
                if t >= start and t < stop:
                    out[m] = pos
                    m += 1
            pos += 1
    return out[:m]


@inner
def _slot(key, mask):
    """Home slot of a star-pair key in a hash table of ``mask + 1`` slots (Fibonacci hashing)."""
    return np.int64((np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(40)) & mask


@inner
def _moment_list(t, img, db, tol, cache):
    """The candidates of image triangle ``t``: its area hits ``[img.start[t], img.stop[t])`` whose
    polar moment lies within ``beta`` standard deviations of its own (paper eqs. 16-20), ascending.
    From ``cache`` when this triangle was already looked up for another subset (a view: do not
    write into it); stored there while it has room."""
    g = img.gid[t]
    if cache.done[g]:
        return cache.buf[cache.start[g]:cache.stop[g]]
    r1, r2, r3 = img.v[img.tri[t, 0]], img.v[img.tri[t, 1]], img.v[img.tri[t, 2]]
    _, moment, _ = triangle_features(r1, r2, r3)
    _, var_j = triangle_variances(r1, r2, r3, tol.sigma_rad)
    half = tol.beta * math.sqrt(var_j)
    out = _moment_filter(db, img.start[t], img.stop[t], moment - half, moment + half)
    nc = out.shape[0]
    p = cache.fill[0]
    if p + nc <= cache.buf.shape[0]:
        for q in range(nc):  # not a slice assignment: its shape check compiles numba's string formatting
            cache.buf[p + q] = out[q]
        cache.start[g] = p
        cache.stop[g] = p + nc
        cache.fill[0] = p + nc
        cache.done[g] = True
    return out


@inner
def _fill_hash(cand, n, tri_stars, keys):
    """Open-addressing hash table (linear probing; ``keys.shape[0]`` a power of two, EMPTY = empty
    slot) of the three star pairs ``lo * KEY_BASE + hi`` of the catalog triangles ``cand[:n]``, each
    slot ``key << SHIFT | candidate``. Entries of one key are met by a probe in the order of ``cand``."""
    mask = keys.shape[0] - 1
    keys[:] = EMPTY
    for c in range(n):
        s0 = np.int64(tri_stars[cand[c], 0])
        s1 = np.int64(tri_stars[cand[c], 1])
        s2 = np.int64(tri_stars[cand[c], 2])  # stored ascending
        for x in range(3):
            if x == 0:
                key = s0 * KEY_BASE + s1
            elif x == 1:
                key = s0 * KEY_BASE + s2
            else:
                key = s1 * KEY_BASE + s2
            pos = _slot(key, mask)
            while keys[pos] != EMPTY:
                pos = (pos + 1) & mask
            keys[pos] = (np.uint64(key) << SHIFT) | np.uint64(cand[c])


@inner
def _hash_size(n):
    """Slots of a table of ``n`` candidates (3 keys each, at most 3/8 full: short probes): a power of two >= 16."""
    size = 16
    while size < 8 * n:
        size *= 2
    return size


@inner
def _moment_hash(t, img, cand, tri_stars, cache):
    """``keys``: the hash table (:func:`_fill_hash`) of the star pairs of image triangle
    ``t``'s candidates ``cand`` (:func:`_moment_list`), what a pivot matches on. From ``cache`` when
    built before (views: do not write into them); stored there while it has room (only for a
    triangle whose candidates are cached)."""
    g = img.gid[t]
    if cache.done[g] and cache.hsize[g] > 0:
        h0 = cache.hstart[g]
        return cache.keys[h0:h0 + cache.hsize[g]]
    nc = cand.shape[0]
    size = _hash_size(nc)
    q = cache.hfill[0]
    cached = cache.done[g] and q + size <= cache.keys.shape[0]
    if cached:
        keys = cache.keys[q:q + size]
    else:
        keys = np.empty(size, dtype=np.uint64)
    _fill_hash(cand, nc, tri_stars, keys)
    if cached:
        cache.hstart[g] = q
        cache.hsize[g] = size
        cache.hfill[0] = q + size
    return keys


@inner
def _few_hash(cand, tri_stars, node_cat, layer_lo, layer_hi, mark):
    """The hash table of only those candidates ``cand`` that hold two or more stars of the
    finalists' last triangles (``node_cat[layer_lo:layer_hi]``), in the order of ``cand``: a probe
    for a finalist's star pair meets exactly the entries it meets in the whole table (a candidate
    holding that pair holds two marked stars), in the same order, so the pivot is the same; for a
    few finalists it costs a pass over the candidates instead of a table of all of them.
    ``mark`` (uint8 per guide star) is all zero on entry and on return."""
    for f in range(layer_lo, layer_hi):
        for x in range(3):
            mark[tri_stars[node_cat[f], x]] = 1
    nc = cand.shape[0]
    keep = np.empty(nc, dtype=np.int64)
    n = np.int64(0)  # np.int64: _fill_hash and _hash_size not compiled again for a literal
    for c in range(nc):
        r = cand[c]
        if mark[tri_stars[r, 0]] + mark[tri_stars[r, 1]] + mark[tri_stars[r, 2]] >= 2:
            keep[n] = r
            n += 1
    for f in range(layer_lo, layer_hi):
        for x in range(3):
            mark[tri_stars[node_cat[f], x]] = 0
    size = _hash_size(n)
    keys = np.empty(size, dtype=np.uint64)
    _fill_hash(keep, n, tri_stars, keys)
    return keys


@inner
def new_cache(img, n_guide):
    """An empty :class:`MomentCache` for the triangles of ``img`` (``gid`` 0..m-1), room for
    CACHE_PER_TRIANGLE candidates per triangle on average, at most CACHE_MAX; ``n_guide`` guide stars."""
    m = img.tri.shape[0]
    total = min(CACHE_PER_TRIANGLE * m, CACHE_MAX)
    # np.empty and loops, not np.zeros / np.full: each of those (per dtype) compiles np.empty and a fill
    # of its own, ~0.1 CPU s each on a cold cache
    done = np.empty(m, dtype=np.bool_)
    per_triangle = np.empty((5, m), dtype=np.int64)  # start, stop, hstart, hsize, scans
    for g in range(m):
        done[g] = False
        for r in range(5):
            per_triangle[r, g] = 0
    fills = np.empty(4, dtype=np.int64)  # fill, hfill, memo_fill (2)
    for r in range(4):
        fills[r] = 0
    memo_of = np.empty(MEMO_DIM * MEMO_DIM, dtype=np.int64)
    for e in range(MEMO_DIM * MEMO_DIM):
        memo_of[e] = -1
    mark = np.empty(n_guide, dtype=np.uint8)
    for g in range(n_guide):
        mark[g] = 0
    return MomentCache(done, per_triangle[0], per_triangle[1],
                       np.empty(total, dtype=np.int64), np.empty(HASH_ROOM * total, dtype=np.uint64),
                       per_triangle[2], per_triangle[3], fills[0:1], fills[1:2],
                       memo_of, np.empty(MEMO_DIM * MEMO_DIM, dtype=np.int64),
                       np.empty(MEMO_DIM * MEMO_DIM, dtype=np.int64), np.empty(MEMO_DIM * MEMO_DIM, dtype=np.int64),
                       np.empty(MEMO_DIM * MEMO_DIM, dtype=np.bool_), np.empty(MEMO_NODES, dtype=np.int64),
                       np.empty(MEMO_NODES, dtype=np.int64), fills[2:4],
                       mark, per_triangle[4])


@inner
def first_query(img, tri_stars, cand, rows, first, work):
    """``work[5:8]`` (the first-query counters) of the image triangle ``first`` (a row of ``img``, the
    whole image's triangles) and its candidates ``cand`` (``_moment_list``) given the identification's
    ``rows`` (guide row per star of ``img.v``): its number of candidates, whether ``rows`` names its
    three stars, and whether a candidate is the triangle of the rows they are named as. The caller looks
    the candidates up: this kernel does not call ``_moment_list``, so its machine code does not hold
    that kernel's call tree once more."""
    work[5] = cand.shape[0]
    r0 = rows[img.tri[first, 0]]
    r1 = rows[img.tri[first, 1]]
    r2 = rows[img.tri[first, 2]]
    if r0 < 0 or r1 < 0 or r2 < 0:
        return
    work[6] = 1
    for c in range(cand.shape[0]):
        hit = 0
        for a in range(3):
            g = np.int64(tri_stars[cand[c], a])
            if g == r0 or g == r1 or g == r2:
                hit += 1
        if hit == 3:
            work[7] = 1
            return


@inner
def _next_in_chain(prev, used, img_tri, img_area):
    """Cole's linked list: the unused image triangle of largest area sharing exactly two stars
    with ``prev`` (-1 if none)."""
    best = -1
    for t in range(img_tri.shape[0]):
        if used[t]:
            continue
        shared = 0
        for x in range(3):
            for y in range(3):
                if img_tri[t, x] == img_tri[prev, y]:
                    shared += 1
        if shared == 2 and (best < 0 or img_area[t] > img_area[best]):
            best = t
    return best


@inner
def _signatures(members, length):
    """Sorted membership bitmasks of the stars of a chain of ``length`` triangles.

    ``members[l]`` holds the 3 star ids of triangle ``l``; star ``x`` gets bit ``l`` when it
    belongs to triangle ``l``. Two chains share stars the same way exactly when these sorted
    lists are equal.
    """
    ids = np.empty(3 * length, dtype=np.int64)
    masks = np.empty(3 * length, dtype=np.int64)
    n = _fill_masks(members, length, ids, masks)
    sort_int_prefix(masks, n)  # not np.sort: numba's quicksort costs ~0.5 CPU s of a cold compile
    return masks[:n]


@inner
def _fill_masks(members, length, ids, masks):
    """The chain's distinct stars into ``ids[:n]`` and their membership bitmasks (bit ``l`` for
    triangle ``l``) into ``masks[:n]``, in first-seen order; returns ``n``."""
    n = 0
    for li in range(length):
        for x in range(3):
            s = members[li, x]
            p = -1
            for q in range(n):
                if ids[q] == s:
                    p = q
                    break
            if p < 0:
                p = n
                ids[n] = s
                masks[n] = 0
                n += 1
            masks[p] |= np.int64(1) << li
    return n


@inner
def _same_signatures(members, length, want, ids, masks):
    """``_signatures(members, length)`` equals ``want`` (sorted), computed in the scratch arrays
    ``ids`` and ``masks`` (at least ``3 * length`` long) without allocating: the pivot calls this
    once per candidate, where allocating and sorting new arrays was most of its time."""
    n = _fill_masks(members, length, ids, masks)
    if n != want.shape[0]:
        return False
    sort_int_prefix(masks, n)
    for i in range(n):
        if masks[i] != want[i]:
            return False
    return True


@inner
def _grow(arr, size):
    out = np.empty(max(2 * arr.shape[0], size), dtype=np.int64)  # int64 only: np.empty compiled once
    for q in range(arr.shape[0]):  # not a slice assignment (see _moment_list)
        out[q] = arr[q]
    return out


@inner
def _pivot_layer(layer_lo, layer_hi, n_nodes, node_cat, node_parent, hkeys, tri_stars, img_sig, step,
                 abort_if_grow, consistent_chain, work):
    """One pivot of :func:`_pivot`: every finalist ``f`` in ``[layer_lo, layer_hi)`` extended by the
    candidates of the next image triangle (hash table ``hkeys`` of their star pairs) that
    share exactly two catalog stars with its last triangle (and, with ``consistent_chain``, whose
    chain shares its stars as the image chain's signatures ``img_sig``); the new finalists are
    written to ``node_cat``/``node_parent`` from ``n_nodes`` on, in order. Counts the candidates
    examined into ``work[2]``.

    Returns ``(n_new, grew, fits)``: ``grew`` when ``abort_if_grow`` and the finalists would grow;
    ``fits`` False when the node arrays ran out of room (the caller grows them and calls again).
    A function of its own so that the node arrays are not rebound inside the probe loop (numba then
    updated their reference counts on every probe, most of a pivot's time)."""
    n_fin = layer_hi - layer_lo
    room = min(node_cat.shape[0], node_parent.shape[0])
    hmask = hkeys.shape[0] - 1
    cat_members = np.empty((step + 1, 3), dtype=np.int64)
    sig_ids = np.empty(3 * (step + 1), dtype=np.int64)
    sig_masks = np.empty(3 * (step + 1), dtype=np.int64)
    n_new = 0
    for f in range(layer_lo, layer_hi):
        last = node_cat[f]
        a0 = np.int64(tri_stars[last, 0])
        a1 = np.int64(tri_stars[last, 1])
        a2 = np.int64(tri_stars[last, 2])
        for p in range(3):
            if p == 0:
                key = a0 * KEY_BASE + a1
            elif p == 1:
                key = a0 * KEY_BASE + a2
            else:
                key = a1 * KEY_BASE + a2
            pos = _slot(key, hmask)
            ukey = np.uint64(key)
            while hkeys[pos] != EMPTY:
                entry = hkeys[pos]
                pos = (pos + 1) & hmask
                if (entry >> SHIFT) != ukey:
                    continue
                c = np.int64(entry & LOW)
                work[2] += 1
                shared = 0
                for x in range(3):
                    s = tri_stars[c, x]
                    if s == a0 or s == a1 or s == a2:
                        shared += 1
                if shared != 2:
                    continue
                if consistent_chain:
                    node = f
                    for li in range(step - 1, -1, -1):
                        for x in range(3):
                            cat_members[li, x] = tri_stars[node_cat[node], x]
                        node = node_parent[node]
                    for x in range(3):
                        cat_members[step, x] = tri_stars[c, x]
                    if not _same_signatures(cat_members, step + 1, img_sig, sig_ids, sig_masks):
                        continue
                if abort_if_grow and n_new >= n_fin:
                    return n_new, True, True
                if n_nodes + n_new >= room:
                    return n_new, False, False
                node_cat[n_nodes + n_new] = c
                node_parent[n_nodes + n_new] = f
                n_new += 1
    return n_new, False, True


@inner
def _pivot(first, img, db, tol, pivot_limit, cache, work):
    """The chain and pivot procedure of ``MatchStarsWPlanarTris.m``.

    The chain starts at image triangle ``first``; each pivot appends the unused triangle of
    largest area sharing two stars with the previous one (built lazily, only as far as the
    pivots go; at most ``pivot_limit`` pivots). Finalists are chains of catalog triangles:
    first the area hits of the start triangle whose polar moment is within ``beta`` sigma;
    at each pivot a finalist is extended by every moment-filtered candidate of the next image
    triangle that shares exactly two catalog stars with the finalist's last triangle. Stops at
    one or zero finalists; abandons (no finalist) when the count grows and ``abort_if_grow``.
    With ``consistent_chain`` (reconstructed; Cole compares only with the last triangle) a
    finalist chain must also share its stars exactly as the image chain does (same sorted
    membership signatures, :func:`_signatures`), i.e. the two stars a pivot shares are the
    same two stars throughout.

    The first pivot's outcome (the new finalists in order, or the abandonment) depends on the
    start and second image triangles alone, so it is kept in ``cache`` and replayed when another
    star subset of the image makes the same first pivot (most of a failing image's time is spent
    there: ~1,400 start candidates probed each time); the replay adds the candidates the pivot
    examined to ``work`` again, so the counters stay the method's work, whatever is memoised.

    Returns ``(chain, cat_chain, n_finalists)``: the image triangles used and, when exactly one
    finalist survives, its catalog triangles (else an empty array). Adds to ``work`` (see
    :data:`WORK_COUNTERS`) the pivots made and the candidates examined.
    """
    img_tri = img.tri
    img_area = img.area
    tri_stars = db.stars
    abort_if_grow = tol.abort_if_grow
    consistent_chain = tol.consistent_chain
    m = img_tri.shape[0]
    used_tri = np.empty(m, dtype=np.bool_)  # not np.zeros (see new_cache)
    for q in range(m):
        used_tri[q] = False
    chain = np.empty(m, dtype=np.int64)
    chain[0] = first
    used_tri[first] = True
    # finalist tree: node = (catalog triangle, parent node); one layer per chain triangle
    node_cat = _moment_list(first, img, db, tol, cache).copy()
    n_nodes = node_cat.shape[0]
    work[2] += n_nodes
    node_parent = np.empty(max(n_nodes, 1), dtype=np.int64)  # not np.full (see new_cache)
    for q in range(node_parent.shape[0]):
        node_parent[q] = -1
    layer_lo = 0
    n_fin = n_nodes
    length = 1
    while n_fin > 1 and length <= pivot_limit:
        t = _next_in_chain(chain[length - 1], used_tri, img_tri, img_area)
        if t < 0:
            break
        step = length
        chain[step] = t
        used_tri[t] = True
        length += 1
        work[1] += 1
        layer_hi = layer_lo + n_fin
        memo_key = -1
        if step == 1 and img.gid[first] < MEMO_DIM and img.gid[t] < MEMO_DIM:
            memo_key = img.gid[first] * MEMO_DIM + img.gid[t]
            e = cache.memo_of[memo_key]
            if e >= 0:  # this first pivot was made for another subset: the same finalists, in order
                work[2] += cache.memo_work[e]
                if cache.memo_grew[e]:
                    return chain[:length], np.empty(0, dtype=np.int64), 0
                n_new = cache.memo_len[e]
                if n_nodes + n_new > node_cat.shape[0]:
                    node_cat = _grow(node_cat, n_nodes + n_new)
                if n_nodes + n_new > node_parent.shape[0]:
                    node_parent = _grow(node_parent, n_nodes + n_new)
                a = cache.memo_start[e]
                for q in range(n_new):
                    node_cat[n_nodes] = cache.memo_node[a + q]
                    node_parent[n_nodes] = cache.memo_parent[a + q]
                    n_nodes += 1
                layer_lo = layer_hi
                n_fin = n_new
                continue
        work_before = work[2]
        nodes_before = n_nodes
        # the candidates indexed by each of their three star pairs: all of them (kept for the other
        # subsets), or for a few finalists only those that can match (the same probes, see _few_hash)
        cand = _moment_list(t, img, db, tol, cache)
        g = img.gid[t]
        if (cache.done[g] and cache.hsize[g] > 0) or n_fin > FEW_FINALISTS or cache.scans[g] > 0:
            hkeys = _moment_hash(t, img, cand, tri_stars, cache)
        else:
            cache.scans[g] += 1
            hkeys = _few_hash(cand, tri_stars, node_cat, np.int64(layer_lo), np.int64(layer_hi), cache.mark)
        img_members = np.empty((step + 1, 3), dtype=np.int64)
        for li in range(step + 1):
            for x in range(3):
                img_members[li, x] = img_tri[chain[li], x]
        img_sig = _signatures(img_members, step + 1)
        # room for every new finalist the abort rule allows (more only without it: grown and redone)
        if n_nodes + n_fin + 1 > node_cat.shape[0]:
            node_cat = _grow(node_cat, n_nodes + n_fin + 1)
        if node_parent.shape[0] < node_cat.shape[0]:
            node_parent = _grow(node_parent, node_cat.shape[0])
        while True:
            # np.int64: not compiled again for the literal first layer (0) and step (1)
            n_new, grew, fits = _pivot_layer(np.int64(layer_lo), np.int64(layer_hi), np.int64(n_nodes), node_cat,
                                             node_parent, hkeys, tri_stars, img_sig, np.int64(step),
                                             abort_if_grow, consistent_chain, work)
            if fits:
                break
            work[2] = work_before
            node_cat = _grow(node_cat, node_cat.shape[0] + 1)
            node_parent = _grow(node_parent, node_cat.shape[0])
        n_nodes += n_new
        if memo_key >= 0:
            e = cache.memo_fill[0]
            a = cache.memo_fill[1]
            if a + n_new <= MEMO_NODES:
                cache.memo_of[memo_key] = e
                cache.memo_start[e] = a
                cache.memo_len[e] = n_new
                cache.memo_work[e] = work[2] - work_before
                cache.memo_grew[e] = grew
                for q in range(n_new):
                    cache.memo_node[a + q] = node_cat[nodes_before + q]
                    cache.memo_parent[a + q] = node_parent[nodes_before + q]
                cache.memo_fill[0] = e + 1
                cache.memo_fill[1] = a + n_new
        if grew:  # more finalists than before: Cole abandons the match (inconclusive)
            return chain[:length], np.empty(0, dtype=np.int64), 0
        layer_lo = layer_hi
        n_fin = n_new
    cat_chain = np.empty(0, dtype=np.int64)
    if n_fin == 1:
        cat_chain = np.empty(length, dtype=np.int64)
        node = layer_lo
        for li in range(length - 1, -1, -1):
            cat_chain[li] = node_cat[node]
            node = node_parent[node]
    return chain[:length], cat_chain, n_fin


PERMS = np.array([[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]], dtype=np.int64)


@inner
def _triangle_consistent(img_v, cat_unit, i0, i1, i2, g0, g1, g2, tol_chord):
    """Chords agree within ``tol_chord`` and the handedness is the same."""
    if abs(chord_rows(img_v, i0, img_v, i1) - chord_rows(cat_unit, g0, cat_unit, g1)) > tol_chord:
        return False
    if abs(chord_rows(img_v, i1, img_v, i2) - chord_rows(cat_unit, g1, cat_unit, g2)) > tol_chord:
        return False
    if abs(chord_rows(img_v, i0, img_v, i2) - chord_rows(cat_unit, g0, cat_unit, g2)) > tol_chord:
        return False
    ti = triple_product(img_v[i0], img_v[i1], img_v[i2])
    tc = triple_product(cat_unit[g0], cat_unit[g1], cat_unit[g2])
    return (ti > 0.0) == (tc > 0.0)


@inner
def recover_correspondence(img, chain, cat_chain, db, tol_chord):
    """Per-star catalog rows from the single surviving chain, or all -1.

    Every vertex order of the start triangle is tried; the others follow from the stars each
    triangle shares with the ones before it. An assignment survives when every chain triangle
    matches in chords and chirality, no catalog star is used twice, and every pair of assigned
    stars agrees in chord. Exactly one surviving assignment is required.
    """
    img_v = img.v
    img_tri = img.tri
    tri_stars = db.stars
    cat_unit = db.unit
    perms = PERMS
    n = img_v.shape[0]
    best = np.empty(n, dtype=np.int64)  # np.empty and loops, not np.full (see new_cache)
    for i in range(n):
        best[i] = -1
    n_ok = 0
    length = cat_chain.shape[0]
    for p in range(perms.shape[0]):
        rows = np.empty(n, dtype=np.int64)
        for i in range(n):
            rows[i] = -1
        t0 = chain[0]
        c0 = cat_chain[0]
        for s in range(3):
            rows[img_tri[t0, s]] = tri_stars[c0, perms[p, s]]
        ok = True
        for step in range(length):
            t = chain[step]
            c = cat_chain[step]
            cs = tri_stars[c]
            # catalog stars of this triangle not yet claimed by its already assigned stars
            free = -1
            n_free = 0
            for x in range(3):
                claimed = False
                for y in range(3):
                    if rows[img_tri[t, y]] == cs[x]:
                        claimed = True
                if not claimed:
                    free = cs[x]
                    n_free += 1
            n_unassigned = 0
            for y in range(3):
                if rows[img_tri[t, y]] < 0:
                    n_unassigned += 1
            if n_unassigned != n_free or n_free > 1:
                ok = False
                break
            for y in range(3):
                if rows[img_tri[t, y]] < 0:
                    rows[img_tri[t, y]] = free
            i0, i1, i2 = img_tri[t, 0], img_tri[t, 1], img_tri[t, 2]
            if not _triangle_consistent(img_v, cat_unit, i0, i1, i2, rows[i0], rows[i1], rows[i2],
                                        tol_chord):
                ok = False
                break
        if not ok:
            continue
        for i in range(n):
            if rows[i] < 0:
                continue
            for j in range(i + 1, n):
                if rows[j] < 0:
                    continue
                if rows[i] == rows[j]:
                    ok = False
                elif abs(chord_rows(img_v, i, img_v, j) - chord_rows(cat_unit, rows[i], cat_unit, rows[j])) > tol_chord:
                    ok = False
        if ok:
            n_ok += 1
            best = rows
    if n_ok != 1:
        for i in range(n):
            best[i] = -1
    return best


@inner
def extend_by_distance(img_v, rows, db, tol_chord):
    """Extension (not in the paper): identify further stars by angular distance.

    For each unassigned observed star, the guide stars near the first assigned star's catalog
    star whose chords to *every* assigned star agree with the observed chords within
    ``tol_chord``; the star gets it when exactly one qualifies. Two stars given the same guide
    star both lose it. Candidates are judged against the chain's stars only, so the result does
    not depend on the order of the stars.
    """
    cat_unit = db.unit
    nbr_ptr = db.nbr_ptr
    nbr_idx = db.nbr_idx
    n = img_v.shape[0]
    out = rows.copy()
    n_anchors = 0
    for i in range(n):
        if rows[i] >= 0:
            n_anchors += 1
    if n_anchors == 0:
        return out
    anchors = np.empty(n_anchors, dtype=np.int64)  # the assigned stars (not np.flatnonzero: compiles slowly)
    n_anchors = 0
    for i in range(n):
        if rows[i] >= 0:
            anchors[n_anchors] = i
            n_anchors += 1
    a0 = anchors[0]
    g0 = rows[a0]
    for o in range(n):
        if rows[o] >= 0:
            continue
        found = -1
        n_found = 0
        for e in range(nbr_ptr[g0], nbr_ptr[g0 + 1]):
            g = np.int64(nbr_idx[e])
            taken = False
            for a in anchors:
                if rows[a] == g:
                    taken = True
            if taken:
                continue
            ok = True
            for a in anchors:
                if abs(chord_rows(img_v, o, img_v, a) - chord_rows(cat_unit, g, cat_unit, rows[a])) > tol_chord:
                    ok = False
                    break
            if ok:
                found = g
                n_found += 1
        if n_found == 1:
            out[o] = found
    clash = np.empty(n, dtype=np.bool_)  # not np.zeros (see new_cache)
    for i in range(n):
        clash[i] = False
    for i in range(n):
        if rows[i] >= 0 or out[i] < 0:
            continue
        for j in range(n):
            if j != i and rows[j] < 0 and out[j] == out[i]:
                clash[i] = True
    for i in range(n):
        if clash[i]:
            out[i] = -1
    return out


@inner
def _image_triangles(img_v, db, tol):
    """Step 1: every image triangle within ``fov_rad`` and of area >= ``min_area``, looked up in
    the area-sorted catalog with the k-vector, ``[A - beta sA, A + beta sA]``; triangles with
    more than ``climit`` hits are dropped (``MatchStarsWPlanarTris.m``).

    In three passes over the triangles, the result of ``kvector_query`` for each: their windows and
    k-vector positions (the two k entries asked for), then the k-vector's slices (the values at their
    ends asked for), then the slices trimmed; so the ~50 triangles' reads of a database out of cache
    overlap instead of waiting for each other."""
    n = img_v.shape[0]
    rules = db.rules
    kv = db.area
    nv = kv.values.shape[0]
    max_t = n * (n - 1) * (n - 2) // 6
    img_tri = np.empty((max_t, 3), dtype=np.int64)
    img_area = np.empty(max_t)
    img_start = np.empty(max_t, dtype=np.int64)
    img_stop = np.empty(max_t, dtype=np.int64)
    window = np.empty((max_t, 2))
    m = 0
    for i in range(n):
        for j in range(i + 1, n):
            if chord_rows(img_v, i, img_v, j) > rules.chord_max:
                continue
            for k in range(j + 1, n):
                if chord_rows(img_v, j, img_v, k) > rules.chord_max or chord_rows(img_v, i, img_v, k) > rules.chord_max:
                    continue
                area, mo, diam = triangle_features(img_v[i], img_v[j], img_v[k])
                if diam > rules.fov_rad or area < rules.min_area:
                    continue
                var_a, _ = triangle_variances(img_v[i], img_v[j], img_v[k], tol.sigma_rad)
                half = tol.beta * math.sqrt(var_a)
                lo = area - half
                hi = area + half
                img_tri[m, 0] = i
                img_tri[m, 1] = j
                img_tri[m, 2] = k
                img_area[m] = area
                window[m, 0] = lo
                window[m, 1] = hi
                if nv == 0 or hi < lo:      # kvector_query's empty range
                    img_start[m] = 0
                    img_stop[m] = 0
                else:
                    jb, jt = kvector_ends(kv.m, kv.q, lo, hi)
                    img_start[m] = jb
                    img_stop[m] = jt
                    prefetch(kv.k, min(max(jb - 1, 0), nv - 1))
                    prefetch(kv.k, min(max(jt - 1, 0), nv - 1))
                m += 1
    for t in range(m):     # the k-vector's slices
        if nv == 0 or window[t, 1] < window[t, 0]:
            continue
        start, stop = kvector_rows(kv.k, nv, img_start[t], img_stop[t])
        img_start[t] = start
        img_stop[t] = stop
        prefetch(kv.values, min(max(start - 1, 0), nv - 1))
        prefetch(kv.values, min(stop, nv - 1))
    kept = 0
    for t in range(m):     # trimmed to the values in the window; too many hits: dropped
        start, stop = img_start[t], img_stop[t]
        if not (nv == 0 or window[t, 1] < window[t, 0]):
            start, stop = kvector_trim(kv.values, nv, start, stop, window[t, 0], window[t, 1])
        if stop - start > tol.climit:
            continue
        for c in range(3):
            img_tri[kept, c] = img_tri[t, c]
        img_area[kept] = img_area[t]
        img_start[kept] = start
        img_stop[kept] = stop
        kept += 1
    m = kept
    gid = np.empty(m, dtype=np.int64)  # np.arange(m) (a loop: see new_cache)
    for t in range(m):
        gid[t] = t
    return ImageTriangles(img_v, img_tri[:m], img_area[:m], img_start[:m], img_stop[:m], gid)


@kernel
def image_triangles(img_v, db, tol):
    """:func:`_image_triangles` from Python (the profiling tools); the identification calls that one, so
    this entry point is compiled only when a tool calls it."""
    return _image_triangles(img_v, db, tol)


@inner
def argsort_desc(values):
    """``np.argsort(-values, kind="mergesort")``: indices by descending value, ties by ascending index.

    A bottom-up merge sort of a few lines: numba's own merge sort cost ~0.9 s of compile per plugin
    (planar_triangle and triangle_voting each), this one a fraction of it; a stable sort's order is
    unique, so the result is the same."""
    n = values.shape[0]
    idx = np.empty(n, dtype=np.int64)  # np.arange(n) (a loop: its overload compiles per caller's flags)
    for q in range(n):
        idx[q] = q
    tmp = np.empty(n, dtype=np.int64)
    width = 1
    while width < n:
        lo = 0
        while lo < n:
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i = lo
            j = mid
            k = lo
            while i < mid and j < hi:
                if values[idx[j]] > values[idx[i]]:  # the right run first only when strictly larger: stable
                    tmp[k] = idx[j]
                    j += 1
                else:
                    tmp[k] = idx[i]
                    i += 1
                k += 1
            while i < mid:
                tmp[k] = idx[i]
                i += 1
                k += 1
            while j < hi:
                tmp[k] = idx[j]
                j += 1
                k += 1
            lo = hi
        for q in range(n):
            idx[q] = tmp[q]
        width *= 2
    return idx


def identify_rows(img_v, db, tol):
    """The whole identification of one image: guide-star row per observed star, -1 if none.

    1. image triangles and their area hits (:func:`_image_triangles`);
    2. start triangle = the one of largest area; chain of triangles sharing two stars, at
       most ``pivot_limit`` pivots; finalists filtered by the polar moment; pivot procedure;
    3. a unique finalist chain is turned into per-star rows (chords + chirality);
    4. (extension, ``extend``) further stars by angular distance, then pairwise verification;
       at least ``min_verified`` verified stars are needed;
    5. (extension, ``restarts`` > 0) on failure, start again from the next-largest triangle.

    Returns ``(rows, chain, work)``: ``chain`` (L, 3) the stars of the image triangles of the accepted
    pivot sequence (of the last one tried when none is accepted; for ``explain``); ``work`` the
    int64 counters of :data:`WORK_COUNTERS`.

    :func:`identify_subsets` with one stage of one subset, all the stars (the same steps, the same
    counters): not a kernel of its own, so numba compiles the identification once for both.
    """
    n = img_v.shape[0]
    rows, chain, _, work = identify_subsets(img_v, np.arange(n, dtype=np.int64), db, tol,
                                            np.array([[n, n, 1]], dtype=np.int64))
    return rows, chain, work


@inner
def _key_before(a, b, k0, k1, k2):
    """Star ``a`` sorts before star ``b`` by ``(k0, k1, k2)`` (the first key first; finite values)."""
    if k0[a] != k0[b]:
        return k0[a] < k0[b]
    if k1[a] != k1[b]:
        return k1[a] < k1[b]
    return k2[a] < k2[b]


@inner
def _stable_sort(items, n, k0, k1, k2):
    """``items[:n]`` (star indices) sorted in place by ``(k0, k1, k2)``, ties kept in their order:
    ``items[np.lexsort((k2[items], k1[items], k0[items]))]`` (insertion sort: a few dozen stars).
    The order of ``starid.kernels.sort_rows`` (key, then x, then y); not that kernel because it carries
    a merge-sort presort: calling it here cost 1.5-1.7 CPU s more on a cold cache (planar_triangle
    alone, 24.2-25.0 against 22.8-23.4), and 63.1 -> 64.9 s in the two-process benchmark."""
    for i in range(1, n):
        cur = items[i]
        j = i - 1
        while j >= 0 and _key_before(cur, items[j], k0, k1, k2):
            items[j + 1] = items[j]
            j -= 1
        items[j + 1] = cur


@kernel
def choose_stars(x_px, y_px, mag, mag_max, n_chosen, f_px, cx_px, cy_px):
    """The stars the triangles are built from, in one call (what ``PlanarTriangle._run`` did with
    ``np.flatnonzero``, three ``np.lexsort`` and the back-projection): those with ``mag <= mag_max``,
    the ``n_chosen`` brightest of them (ties by x, then y; all when ``n_chosen < 0``).

    Returns ``(order, v_cam, rank)``: ``order`` the chosen stars' indices in the canonical geometric
    order (by x, then y, then mag, so the answer does not depend on the input order), ``v_cam``
    their camera-frame unit vectors (pinhole, ``starid.kernels.backproject_px``) and ``rank`` the
    positions in ``order`` brightest first (ties by x, then y)."""
    n = x_px.shape[0]
    xs = np.empty(n)  # writable copies: the sorts see one array type (observation arrays are read-only)
    ys = np.empty(n)
    ms = np.empty(n)
    for i in range(n):
        xs[i] = x_px[i]
        ys[i] = y_px[i]
        ms[i] = mag[i]
    usable = np.empty(n, dtype=np.int64)
    k = np.int64(0)  # not a literal: _stable_sort compiled once
    for i in range(n):
        if ms[i] <= mag_max:
            usable[k] = i
            k += 1
    if n_chosen >= 0 and k > n_chosen:
        _stable_sort(usable, k, ms, xs, ys)
        k = n_chosen
    order = np.empty(k, dtype=np.int64)
    for a in range(k):
        order[a] = usable[a]
    _stable_sort(order, k, xs, ys, ms)
    xo = np.empty(k)
    yo = np.empty(k)
    mo = np.empty(k)
    for a in range(k):
        xo[a] = xs[order[a]]
        yo[a] = ys[order[a]]
        mo[a] = ms[order[a]]
    rank = np.arange(k)
    _stable_sort(rank, k, mo, xo, yo)
    return order, backproject_px(xo, yo, f_px, cx_px, cy_px), rank


@inner
def _sub_triangles(img, idx, size, sub_v):
    """The triangles of ``img`` whose three stars are all in ``idx[:size]`` (sorted star indices),
    renumbered to positions in ``idx``; ``gid`` keeps the row in ``img`` (the cache key)."""
    n = img.v.shape[0]
    local = np.empty(n, dtype=np.int64)  # not np.full (see new_cache)
    for i in range(n):
        local[i] = -1
    for a in range(size):
        local[idx[a]] = a
    m = img.tri.shape[0]
    keep = np.empty(m, dtype=np.int64)
    k = 0
    for t in range(m):
        if local[img.tri[t, 0]] >= 0 and local[img.tri[t, 1]] >= 0 and local[img.tri[t, 2]] >= 0:
            keep[k] = t
            k += 1
    keep = keep[:k]
    tri = np.empty((k, 3), dtype=np.int64)
    for q in range(k):
        for x in range(3):
            tri[q, x] = local[img.tri[keep[q], x]]
    return ImageTriangles(sub_v, tri, img.area[keep], img.start[keep], img.stop[keep], img.gid[keep])


@kernel
def identify_subsets(img_v, bright, db, tol, stages):
    """Brightest-first star subsets: the pivoting of :func:`identify_rows` on subsets of the stars.

    ``img_v`` holds the candidate stars in a canonical (geometric) order; ``bright`` indexes them
    brightest first. ``stages`` (int64 (S, 3)): rows ``(size, pool, max_subsets)``, tried in
    order: the subsets of ``size`` of the ``pool`` brightest stars, in lexicographic order of
    brightness rank (the brightest combination first), skipping those an earlier stage of the
    same size already tried, at most ``max_subsets`` per stage; the first identification wins.
    A star that is not in the database (a fainter star that magnitude noise made look bright)
    breaks every pivot chain through it; a subset without it does not. The image triangles and
    their moment-filtered area hits are computed once for all subsets.

    Returns ``(rows, chain, stage, work)``: the row per star of ``img_v`` (-1 = none), the pivot
    sequence of the last subset tried (star indices of ``img_v``, see :func:`identify_rows`), the
    stage that identified (-1: none) and the int64 counters of :data:`WORK_COUNTERS`.
    """
    n = img_v.shape[0]
    k = bright.shape[0]
    # np.empty and loops, not np.full / np.zeros: this kernel has a Python entry point, so numba compiles
    # every numpy function it calls once more for its flags (the inner kernels' copies do not serve it)
    out = np.empty(n, dtype=np.int64)
    for i in range(n):
        out[i] = -1
    chain = np.empty((0, 3), dtype=np.int64)
    work = np.empty(N_WORK, dtype=np.int64)
    for i in range(N_WORK):
        work[i] = 0
    if n < 3:
        return out, chain, -1, work
    img = _image_triangles(img_v, db, tol)
    work[4] = img.tri.shape[0]
    cache = new_cache(img, db.unit.shape[0])
    tol_chord = tol.beta * math.sqrt(2.0) * tol.sigma_rad
    first = np.int64(-1)  # the first subset's start triangle (a row of img; np.int64: not a literal)
    stage = -1  # the stage that identified
    for st in range(stages.shape[0]):
        pool = stages[st, 1] if stages[st, 1] < k else k  # min(): see np.empty above
        size = stages[st, 0] if stages[st, 0] < pool else pool
        if size < 3:
            continue
        comb = np.arange(size)
        tried = 0
        while tried < stages[st, 2]:
            # skip a subset an earlier stage of the same size already tried (all within its pool)
            seen = False
            for e in range(st):
                pool_e = stages[e, 1] if stages[e, 1] < k else k
                if (stages[e, 0] if stages[e, 0] < pool_e else pool_e) == size and comb[size - 1] < pool_e:
                    seen = True
            if not seen:
                tried += 1
                work[0] += 1
                idx = np.empty(size, dtype=np.int64)  # bright[comb] sorted (insertion sort: np.sort and
                for a in range(size):                  # fancy indexing cost compile time, not run time)
                    v = bright[comb[a]]
                    j = a - 1
                    while j >= 0 and idx[j] > v:
                        idx[j + 1] = idx[j]
                        j -= 1
                    idx[j + 1] = v
                sub = np.empty((size, 3))
                for a in range(size):
                    for x in range(3):
                        sub[a, x] = img_v[idx[a], x]
                sub_img = _sub_triangles(img, idx, size, sub)
                if first < 0 and sub_img.tri.shape[0] > 0:  # its start triangle, as in identify_rows
                    best = 0  # np.argmax: the first of the largest areas
                    for q in range(1, sub_img.tri.shape[0]):
                        if sub_img.area[q] > sub_img.area[best]:
                            best = q
                    first = sub_img.gid[best]
                # steps 2-5 of identify_rows on the subset (inline: a kernel level less to compile)
                rows = np.empty(size, dtype=np.int64)
                for a in range(size):
                    rows[a] = -1
                found = False
                sub_chain = np.empty((0, 3), dtype=np.int64)
                m_sub = sub_img.tri.shape[0]
                if m_sub > 0:
                    pivot_limit = tol.pivot_limit
                    if pivot_limit < 0:  # no limit: the chain may use every image triangle
                        pivot_limit = m_sub - 1
                    ranked = argsort_desc(sub_img.area)
                    for attempt in range(tol.restarts + 1 if tol.restarts + 1 < m_sub else m_sub):
                        tri_chain, cat_chain, n_fin = _pivot(ranked[attempt], sub_img, db, tol, pivot_limit, cache,
                                                             work)
                        work[8] += 1
                        if n_fin == 1 and work[9] == 0:  # the queries (starts and pivots) to the first finalist
                            work[9] = work[8] + work[1]
                        sub_chain = np.empty((tri_chain.shape[0], 3), dtype=np.int64)  # sub_img.tri[tri_chain]
                        for li in range(tri_chain.shape[0]):
                            for x in range(3):
                                sub_chain[li, x] = sub_img.tri[tri_chain[li], x]
                        if n_fin != 1:
                            continue
                        work[3] += 1
                        got = recover_correspondence(sub_img, tri_chain, cat_chain, db, tol_chord)
                        if tol.extend:
                            got = extend_by_distance(sub, got, db, tol_chord)
                        keep = verify_pairwise(sub, got, db.unit, tol_chord, tol.min_support)
                        n_keep = 0
                        for i in range(size):
                            if not keep[i]:
                                got[i] = -1
                            else:
                                n_keep += 1
                        if n_keep >= tol.min_verified:
                            rows = got
                            found = True
                            break
                chain = np.empty((sub_chain.shape[0], 3), dtype=np.int64)
                for li in range(sub_chain.shape[0]):
                    for x in range(3):
                        chain[li, x] = idx[sub_chain[li, x]]
                if found:
                    for a in range(size):
                        out[idx[a]] = rows[a]
                    stage = st
                    break
            # next combination of ``size`` out of ``pool`` in lexicographic order
            p = size - 1
            while p >= 0 and comb[p] == pool - size + p:
                p -= 1
            if p < 0:
                break
            comb[p] += 1
            for q in range(p + 1, size):
                comb[q] = comb[q - 1] + 1
        if stage >= 0:
            break
    if first >= 0:  # the first query's counters, its candidates from the cache
        first_query(img, db.stars, _moment_list(first, img, db, tol, cache), out, first, work)
    return out, chain, stage, work


# -- the final step (shared with triangle_voting) -------------------------------------------


class Finish(NamedTuple):
    """What the final step (:func:`finish`) assumes besides the image and the database."""

    eps_chord: float  # assignment tolerance (chord)
    mag_margin: float  # an assigned star may be at most this much fainter (V) than measured
    mag_limit: float  # the guide stars' V limit
    coverage_mag_margin: float  # the coverage check looks at stars this much brighter than the limit
    max_missed_fraction: float  # coverage: fraction of predicted bright stars that may be missing (>= 1: off)
    assign_all: bool  # report the assigned ids (else only the guide identification)


def deep_v_mag(catalog, deep) -> np.ndarray:
    """float32 V magnitude of every star of ``deep`` (a ``starid.kernels.DeepSky`` of ``catalog``), row by row."""
    by_hip = np.argsort(catalog.hip, kind="stable")
    return catalog.v_mag[by_hip[np.searchsorted(catalog.hip[by_hip], deep.hip)]].astype(np.float32)


@inner
def _deep_mag_of(deep, deep_mag, r_icrs, eps_chord, hip):
    """V of the deep star ``hip``, which lies within chord ``eps_chord`` of the ICRS direction ``r_icrs``."""
    start, stop = z_band_rows(deep.unit, float(r_icrs[2]), 2.0 * eps_chord)
    for g in range(start, stop):
        if deep.hip[g] == hip:
            return float(deep_mag[g])
    return np.inf


@inner
def _rivals(deep, deep_mag, r_icrs, eps_chord, mag_max):
    """How many deep stars with V <= ``mag_max`` lie within chord ``eps_chord`` of the ICRS direction ``r_icrs``."""
    start, stop = z_band_rows(deep.unit, float(r_icrs[2]), eps_chord)
    count = 0
    for g in range(start, stop):
        if deep_mag[g] <= mag_max:
            d0 = float(deep.unit[g, 0]) - r_icrs[0]
            d1 = float(deep.unit[g, 1]) - r_icrs[1]
            d2 = float(deep.unit[g, 2]) - r_icrs[2]
            if d0 * d0 + d1 * d1 + d2 * d2 <= eps_chord * eps_chord:
                count += 1
    return count


@inner
def coverage(attitude, deep, deep_mag, mag_max, found_hip, frame):
    """``(predicted, missed)``: stars of ``deep`` with V <= ``mag_max`` that ``attitude`` puts on the
    sensor, and how many of them are not among ``found_hip`` (sorted ids of the identified stars).

    A true identification explains the bright stars of its field; a chance match among noise
    points or wrong stars predicts bright stars that are not there.
    """
    start, stop = z_band_rows(deep.unit, attitude[2, 2], field_chord(frame))
    predicted = 0
    missed = 0
    for g in range(start, stop):
        if deep_mag[g] > mag_max:
            continue
        u0, u1, u2 = float(deep.unit[g, 0]), float(deep.unit[g, 1]), float(deep.unit[g, 2])
        pz = attitude[2, 0] * u0 + attitude[2, 1] * u1 + attitude[2, 2] * u2
        if pz <= 0.0:
            continue
        x = frame.cx_px + frame.f_px * (attitude[0, 0] * u0 + attitude[0, 1] * u1 + attitude[0, 2] * u2) / pz
        y = frame.cy_px + frame.f_px * (attitude[1, 0] * u0 + attitude[1, 1] * u1 + attitude[1, 2] * u2) / pz
        if not (0.0 <= x < frame.width_px and 0.0 <= y < frame.height_px):
            continue
        predicted += 1
        h = deep.hip[g]
        lo = search_left(found_hip, h)  # np.searchsorted(found_hip, h): its overload compiles slowly
        if lo >= found_hip.shape[0] or found_hip[lo] != h:
            missed += 1
    return predicted, missed


@kernel
def finish(x_px, y_px, mag, rows, guide_unit, guide_hip, deep, deep_mag, frame, rules):
    """Attitude, the core final assignment and the coverage check, for ``rows`` (guide rows or -1).

    Returns ``(hip int64 (n,), attitude 3x3, accepted)``; not accepted: every id -1.

    1. The attitude is solved from the identified stars (Wahba, ``starid.kernels.wahba_rows``).
    2. ``starid.kernels.assign_all`` gives every image star the deep star predicted within
       ``eps_chord`` of it. The guide identification stands for the stars it names; another star
       takes its assigned id unless a guide star already has that id or the assigned star is more
       than ``mag_margin`` fainter than the star's measured ``mag`` (a false detection near a
       faint catalog star is not it).
    3. Coverage (:func:`coverage`, on the ids of step 2): of the deep stars with
       V <= min(``mag_limit``, faintest image star) - ``coverage_mag_margin`` that the attitude
       puts on the sensor, at most max(1, ``max_missed_fraction`` x their number) may lack an
       identified star; otherwise the identification is dropped.
    4. A guide identification is not reported when two deep stars bright enough to be the detection
       (V <= ``mag`` + ``mag_margin``) are predicted within ``eps_chord`` of it (:func:`_rivals`): a
       close pair that the window cannot separate (on 71" pixels at 2 px of noise triangle voting
       misidentified 11 of 300 images; the five examined were such pairs, see triangle_voting.md).
    The ids of step 2 are reported only with ``assign_all``; otherwise those of ``rows``.
    """
    n = rows.shape[0]
    # np.empty and loops, not np.full / np.zeros (see identify_subsets); ``none``: every id -1
    none = np.empty(n, dtype=np.int64)
    hip = np.empty(n, dtype=np.int64)
    n_found = 0
    for i in range(n):
        none[i] = -1
        hip[i] = -1
        if rows[i] >= 0:
            hip[i] = guide_hip[rows[i]]
            n_found += 1
    if n_found < 2:
        zero = np.empty((3, 3))
        for a in range(3):
            for b in range(3):
                zero[a, b] = 0.0
        return none, zero, False
    v_cam = backproject_px(x_px, y_px, frame.f_px, frame.cx_px, frame.cy_px)
    attitude = wahba_rows(v_cam, rows, guide_unit)
    assigned = hip.copy()
    assign_all(attitude, x_px, y_px, frame, deep, rules.eps_chord, assigned)
    hip_all = hip.copy()
    r_icrs = np.empty(3)
    for i in range(n):
        if rows[i] >= 0 or assigned[i] < 0:
            continue
        taken = False
        for j in range(n):
            if rows[j] >= 0 and hip[j] == assigned[i]:
                taken = True
        if taken:
            continue
        for a in range(3):
            r_icrs[a] = attitude[0, a] * v_cam[i, 0] + attitude[1, a] * v_cam[i, 1] + attitude[2, a] * v_cam[i, 2]
        if _deep_mag_of(deep, deep_mag, r_icrs, rules.eps_chord, assigned[i]) <= mag[i] + rules.mag_margin:
            hip_all[i] = assigned[i]
    if rules.max_missed_fraction < 1.0:
        # np.sort(hip_all[hip_all >= 0]) and mag.max() as loops (their overloads cost compile time)
        found = np.empty(n, dtype=np.int64)
        n_ids = np.int64(0)  # np.int64: sort_int_prefix not compiled again for a literal
        for i in range(n):
            if hip_all[i] >= 0:
                found[n_ids] = hip_all[i]
                n_ids += 1
        sort_int_prefix(found, n_ids)
        mag_top = mag[0]
        for i in range(n):
            if math.isnan(mag[i]):  # np.max propagates NaN
                mag_top = mag[i]
                break
            if mag[i] > mag_top:
                mag_top = mag[i]
        mag_max = min(rules.mag_limit, mag_top) - rules.coverage_mag_margin
        predicted, missed = coverage(attitude, deep, deep_mag, mag_max, found[:n_ids], frame)
        if not (missed <= 1 or missed <= rules.max_missed_fraction * predicted):
            return none, attitude, False
    # a guide identification is not reported when two stars bright enough to be the detection are
    # predicted within the window of it: the triangles could not tell them apart either (close pairs
    # at coarse pixels and 2 px of noise; the attitude and the coverage above still use it)
    for i in range(n):
        if rows[i] < 0:
            continue
        for a in range(3):
            r_icrs[a] = attitude[0, a] * v_cam[i, 0] + attitude[1, a] * v_cam[i, 1] + attitude[2, a] * v_cam[i, 2]
        if _rivals(deep, deep_mag, r_icrs, rules.eps_chord, mag[i] + rules.mag_margin) > 1:
            hip[i] = -1
            hip_all[i] = -1
    if rules.assign_all:
        return hip_all, attitude, True
    return hip, attitude, True
