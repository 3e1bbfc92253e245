"""numba kernels of the PTP algorithm (Zhou & Ye 2015). Equation numbers refer to that paper."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from llvmlite import ir
from numba import carray, njit, types
from numba.extending import intrinsic

from starid.kernels import (
    Frame,
    KVector,
    backproject_px,
    chord_rows,
    explained,
    guide_rows_f64,
    kvector_query,
    refine_explained,
    reproject_assign,
    verify_pairwise,
    wahba_rows,
)
from starid.kernels.kvector import kvector_ends, kvector_rows, kvector_trim
from starid.kernels.order import stable_sort_by_key
from starid.kernels.params import exact_float64
from starid.kernels.prefetch import prefetch, prefetch_at

#: ptp's two flag sets: :data:`starid.kernels.jit.kernel` and :data:`~starid.kernels.jit.inner` with numba's numpy
#: error model (no zero-divisor test and raise path; every divisor here is guarded: docs/algorithms/ptp.md)
_kernel = njit(cache=True, error_model="numpy", no_cfunc_wrapper=True)
_inner = njit(cache=True, error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)   # kernels call it only


class View(NamedTuple):
    """The camera as identify needs it: the core :class:`starid.kernels.Frame` (focal length, principal
    point, sensor size, px) and ``c_fov``, the chord from the boresight to the farthest image corner
    (from ``Camera.half_diagonal_rad``, computed once per camera)."""

    frame: Frame
    c_fov: float


class SideIndex(NamedTuple):
    """The second index of the database rows (issue #25): by side a, within blocks of the projection order.

    rows : (t,) the database rows (projection order) ordered by (bin of side a, row); the bin of a row is
        ``floor(a / width)`` of its float32 side a.
    sides : float32 (t, 3) the scaled sides a, b, c (eq. 1) of ``rows[e]`` at entry ``e``: the entries a
        window reads lie together in memory. (The only copy of the sides: ``PTPDatabase.sides`` rebuilds
        the projection-ordered (3, t) table from it.)
    offsets : (n_blocks + 1, n_bins) positions in ``rows``: ``offsets[j, i]`` is the first entry of bin ``i``
        whose row is at least ``j << shift`` (``offsets[n_blocks, i]`` is the end of bin ``i``). The rows of
        bin ``i`` inside a k-vector window ``[start, stop)`` are therefore among the entries
        ``offsets[start >> shift, i]`` to ``offsets[((stop - 1) >> shift) + 1, i]``, in ascending row order
        (block-major: a window's neighbouring bins are neighbours in memory).
    width : the bin width (scaled chord); shift : log2 of the block size (rows).
    """

    rows: np.ndarray
    sides: np.ndarray
    offsets: np.ndarray
    width: float
    shift: int


class Tables(NamedTuple):
    """What identify reads from :class:`~starid_algorithms.ptp.PTPDatabase`, as one kernel argument.

    kv : :class:`starid.kernels.KVector` over the projections p_r (eq. 3), ascending.
    ids : (t, 3) guide rows of (r1, r2, r3).
    mean : (3,) mean side vector; axis : (3,) projection axis u_max.
    guide_unit : float32 (g, 3) guide unit vectors (ICRS, z-sorted); guide_hip : int64 (g,) their ids.
    (Not the database's ``deep`` stars: ``assign_all`` runs in ``PTP.identify``, and every array passed
    costs numba's dispatch time on every image.)
    extra_unit : float32 (e, 3) ICRS unit vectors, z-sorted, of the catalog stars that are not guide
        stars, to V <= ``check_mag_limit`` (the whole-image check; may be empty).
    index : :class:`SideIndex`, the rows by side a within blocks of the projection order, with their
        sides a, b, c (eq. 1).
    """

    kv: KVector
    ids: np.ndarray
    mean: np.ndarray
    axis: np.ndarray
    guide_unit: np.ndarray
    guide_hip: np.ndarray
    extra_unit: np.ndarray
    index: SideIndex


#: int64 slots at the start of :func:`pack_tables`' byte buffer: the sizes, then the segments' byte offsets.
PACK_HEADER = 32


def pack_tables(tables: Tables, index_dtype) -> tuple[np.ndarray, np.ndarray]:
    """``tables`` as two arrays, ``(narrow, wide)``: numba unboxes every array of a call's arguments, and for
    the 10 arrays and 5 numbers of a :class:`Tables` that costs some 15 us of every image when the call finds
    Python's and numba's objects out of the cache (interleaved with other plugins). ``narrow`` (``index_dtype``)
    holds the k-vector's k, the guide rows and the index's offsets; ``wide`` (bytes) a header of
    :data:`PACK_HEADER` int64, then the float32, float64 and int64 arrays and the numbers, each segment at a
    multiple of 64 bytes. The index's entries are one float32 (t, 4) segment, each entry's sides a, b, c and
    its row (exact: fewer than 2**24 rows) in one 16-byte record, so a window's bins read one array.
    :func:`tables_of` rebuilds the :class:`Tables` (views, no copy) in the kernel; its ``index.rows`` is the
    entries' fourth column (float32)."""
    kv, index = tables.kv, tables.index
    t, g, e = kv.values.shape[0], tables.guide_unit.shape[0], tables.extra_unit.shape[0]
    nb1, nbins = index.offsets.shape
    header = np.zeros(PACK_HEADER, dtype=np.int64)
    header[:6] = t, g, e, nb1, nbins, index.shift
    if t >= 1 << 24:
        raise ValueError("pack_tables: more rows than a float32 holds exactly")
    entries = np.empty((t, 4), dtype=np.float32)   # an entry's sides and its row in one 16-byte record
    entries[:, :3] = index.sides
    entries[:, 3] = np.asarray(index.rows).astype(np.float32)
    wide_parts = [np.ascontiguousarray(kv.values, dtype=np.float32),
                  np.ascontiguousarray(tables.guide_unit, dtype=np.float32),
                  np.ascontiguousarray(tables.extra_unit, dtype=np.float32),
                  entries,
                  np.ascontiguousarray(tables.mean, dtype=np.float64),
                  np.ascontiguousarray(tables.axis, dtype=np.float64),
                  np.ascontiguousarray(tables.guide_hip, dtype=np.int64),
                  np.array([kv.m, kv.q, index.width], dtype=np.float64)]
    pos = PACK_HEADER * 8
    chunks = []
    for slot, part in enumerate(wide_parts):
        header[6 + slot] = pos
        raw = part.reshape(-1).view(np.uint8)
        pad = -raw.shape[0] % 64
        chunks += [raw, np.zeros(pad, dtype=np.uint8)]
        pos += raw.shape[0] + pad
    narrow_parts = [kv.k, tables.ids, index.offsets]
    npos = 0
    nchunks = []
    per_line = 64 // np.dtype(index_dtype).itemsize
    for slot, part in enumerate(narrow_parts):
        header[14 + slot] = npos
        flat = np.ascontiguousarray(part, dtype=index_dtype).reshape(-1)
        if not np.array_equal(flat.astype(np.int64), np.asarray(part).reshape(-1).astype(np.int64)):
            raise ValueError("pack_tables: a table does not fit index_dtype")
        pad = -flat.shape[0] % per_line
        nchunks += [flat, np.zeros(pad, dtype=index_dtype)]
        npos += flat.shape[0] + pad
    wide = np.concatenate([header.view(np.uint8)] + chunks)
    narrow = np.concatenate(nchunks) if nchunks else np.zeros(0, dtype=index_dtype)
    return np.ascontiguousarray(narrow, dtype=index_dtype), np.ascontiguousarray(wide)


@intrinsic
def _address(typingctx, arr, offset):
    """The address of byte ``offset`` of the 1-D array ``arr``'s data, as a ``void *`` (for ``numba.carray``)."""
    if not isinstance(arr, types.Array) or arr.ndim != 1 or not isinstance(offset, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        ary = context.make_array(sig.args[0])(context, builder, args[0])
        at = context.cast(builder, args[1], sig.args[1], types.intp)
        return builder.gep(builder.bitcast(ary.data, ir.IntType(8).as_pointer()), [at])
    return types.voidptr(arr, offset), codegen


@_inner
def tables_of(narrow, wide):
    """The :class:`Tables` of :func:`pack_tables`' two arrays: arrays over their memory (``numba.carray`` of an
    address: no copy, no reference of their own, so they live as long as the caller holds ``narrow`` and
    ``wide``, i.e. the kernel call), the same dtypes, shapes and layouts as the original arrays (``ids`` in the
    narrow dtype). (``wide[a:b].view(dtype).reshape(shape)`` gives the same arrays through numba's checked
    view and reshape: some 1,900 instructions of machine code, 5 us of a call that finds them out of the
    cache.)"""
    h = carray(_address(wide, 0), PACK_HEADER, np.int64)
    t, g, e, nb1, nbins, shift = h[0], h[1], h[2], h[3], h[4], h[5]
    values = carray(_address(wide, h[6]), t, np.float32)
    guide_unit = carray(_address(wide, h[7]), (g, 3), np.float32)
    extra_unit = carray(_address(wide, h[8]), (e, 3), np.float32)
    entries = carray(_address(wide, h[9]), (t, 4), np.float32)
    mean = carray(_address(wide, h[10]), 3, np.float64)
    axis = carray(_address(wide, h[11]), 3, np.float64)
    guide_hip = carray(_address(wide, h[12]), g, np.int64)
    sc = carray(_address(wide, h[13]), 3, np.float64)
    size = narrow.itemsize
    k = carray(_address(narrow, h[14] * size), t, narrow.dtype)
    ids = carray(_address(narrow, h[15] * size), (t, 3), narrow.dtype)
    offsets = carray(_address(narrow, h[16] * size), (nb1, nbins), narrow.dtype)
    return Tables(KVector(values, k, sc[0], sc[1]), ids, mean, axis, guide_unit, guide_hip, extra_unit,
                  SideIndex(entries[:, 3], entries, offsets, sc[2], shift))


class Tolerances(NamedTuple):
    """The parameters identify uses (see :class:`~starid_algorithms.ptp.PTP`); chords scaled by ``scale``.

    sigma_px : assumed centroid noise (px); the angular sigma is ``sigma_px / f_px``.
    """

    sigma_px: float
    scale: float
    d_min: float
    d_max: float
    n_slaves: int
    beta: float
    side_beta: float
    exclude_doubles: bool
    swap_slaves: bool
    min_shared: int
    majority: bool
    verify: bool
    verify_min_fraction: float
    confirm_fraction: float
    max_stars: int
    max_candidates: int
    image_slaves: int
    star_mag_max: float
    assign_all: bool
    hypotheses: int
    check_min_stars: int
    check_fraction: float
    nearest_check: bool
    unique_only: bool
    conflict_fails: bool
    stop_first: bool
    lone_triangles: bool


#: Slots of :func:`params_of`' array: the :class:`View` (the frame's 5 numbers and ``c_fov``), then the
#: :class:`Tolerances` in field order.
N_VIEW = 6
#: Largest ``max_candidates`` the array holds (exact in float64); a window never holds more rows.
MAX_CANDIDATES_CAP = 1 << 52


def params_of(view: View, tol: Tolerances) -> np.ndarray:
    """``view`` and ``tol`` as one float64 array, :func:`identify_kernel`'s argument: numba unboxes a tuple
    element by element (33 of them), an array at once, some 5 us of a call that finds its objects out of the
    cache (interleaved with other plugins). Every value is exact in float64 (:func:`params_view` and
    :func:`params_tol` rebuild the same numbers, ints and bools)."""
    values = [*view.frame, view.c_fov, *tol._replace(max_candidates=min(int(tol.max_candidates),
                                                                         MAX_CANDIDATES_CAP))]
    return exact_float64(values, "ptp's kernel parameters")


@_inner
def params_view(p):
    """The :class:`View` of :func:`params_of`' array."""
    return View(Frame(p[0], p[1], p[2], p[3], p[4]), p[5])


@_inner
def params_tol(p):
    """The :class:`Tolerances` of :func:`params_of`' array (the same types as the named tuple from Python:
    float64, int64, bool)."""
    q = p[N_VIEW:]
    return Tolerances(q[0], q[1], q[2], q[3], np.int64(q[4]), q[5], q[6], q[7] != 0.0, q[8] != 0.0,
                      np.int64(q[9]), q[10] != 0.0, q[11] != 0.0, q[12], q[13], np.int64(q[14]), np.int64(q[15]),
                      np.int64(q[16]), q[17], q[18] != 0.0, np.int64(q[19]), np.int64(q[20]), q[21],
                      q[22] != 0.0, q[23] != 0.0, q[24] != 0.0, q[25] != 0.0, q[26] != 0.0)


@_inner
def _before(dist, unit, i, j):
    """Strict order of candidate slaves: by distance, exact ties by the unit vector (input-order free)."""
    if dist[i] != dist[j]:
        return dist[i] < dist[j]
    if unit[i, 0] != unit[j, 0]:
        return unit[i, 0] < unit[j, 0]
    return unit[i, 1] < unit[j, 1]


@_kernel
def nearest_slaves(dist_row, unit, usable, master, d_min, d_max, n_slaves, out):
    """The ``n_slaves`` usable stars nearest ``master`` with ``d_min <= D_ms <= d_max`` (eq. 2), nearest first.

    A star at distance 0 (a coincident detection) is never a slave, whatever ``d_min``.

    ``dist_row[j]`` is the scaled chord ``D_ms`` from the master to star ``j``. Writes them to
    ``out`` and returns how many there are. One pass with a stable insertion (equal stars keep index
    order): the same list as selecting the nearest ``n_slaves`` times over, in O(n) instead of O(n k^2).
    """
    n = dist_row.shape[0]
    m = 0
    for j in range(n):      # one pass, an insertion into the sorted list of the best so far
        if j == master or not usable[j] or not (d_min <= dist_row[j] <= d_max) or dist_row[j] <= 0.0:
            continue
        pos = m
        while pos > 0 and _before(dist_row, unit, j, out[pos - 1]):
            pos -= 1
        if pos >= n_slaves:
            continue
        for t in range(min(m, n_slaves - 1), pos, -1):
            out[t] = out[t - 1]
        out[pos] = j
        m = min(m + 1, n_slaves)
    return m


@_kernel
def build_triangles(unit, neighbours, neighbour_offsets, d_min, d_max, n_slaves, scale):
    """Feature triangles of every master star (section 2.1, step 1).

    ``neighbours[neighbour_offsets[i]:neighbour_offsets[i+1]]`` are the candidate slaves of
    master ``i``, already sorted by distance and cut to ``d_min <= D_ms <= d_max``. Each master
    keeps its ``n_slaves`` nearest slaves s1..s4 and forms the triangles (m, s_i, s_j), i < j, with
    r1 = m, r2 = s_i (nearer), r3 = s_j; sides from eq. 1: a = |r1-r2|, b = |r2-r3|, c = |r1-r3|.
    Returns ``(ids (t, 3), sides (t, 3))``.
    """
    n = unit.shape[0]
    count = 0
    for i in range(n):
        k = min(n_slaves, neighbour_offsets[i + 1] - neighbour_offsets[i])
        count += k * (k - 1) // 2
    ids = np.empty((count, 3), dtype=np.int64)
    sides = np.empty((count, 3))
    t = 0
    for i in range(n):
        start = neighbour_offsets[i]
        k = min(n_slaves, neighbour_offsets[i + 1] - start)
        for a in range(k):
            for b in range(a + 1, k):
                s1 = neighbours[start + a]
                s2 = neighbours[start + b]
                ids[t, 0] = i
                ids[t, 1] = s1
                ids[t, 2] = s2
                sides[t, 0] = scale * chord_rows(unit, i, unit, s1)
                sides[t, 1] = scale * chord_rows(unit, s1, unit, s2)
                sides[t, 2] = scale * chord_rows(unit, i, unit, s2)
                t += 1
    return ids, sides


@_inner
def _grad_var(g0, g1, g2, t, i):
    """``g (I - t_i t_i^T) g^T`` for a gradient row ``g`` and unit vector ``t[i]`` (eqs. 11-12 without sigma^2)."""
    gt = g0 * t[i, 0] + g1 * t[i, 1] + g2 * t[i, 2]
    return g0 * g0 + g1 * g1 + g2 * g2 - gt * gt


@_kernel
def projection_sigma(t, i1, i2, i3, a, b, c, w, sigma, scale):
    """Analytic standard deviation of the projection, eqs. 6-14.

    ``t1, t2, t3`` are rows ``i1, i2, i3`` of the unit vectors ``t``; ``a, b, c`` the scaled
    sides; ``w`` the projection axis ``u_max``; ``sigma`` the per-axis angular noise in radians.
    ``T1 = w1 da/dt1 + w3 dc/dt1``, ``T2 = -w1 da/dt1 + w2 db/dt2``, ``T3 = -w2 db/dt2 - w3 dc/dt1``
    (eqs. 7-9, with da/dt1 = (t1 - t2)/a etc. of the unscaled chords) and
    ``sigma_p^2 = sum_i T_i R_i T_i^T`` with ``R_i = sigma^2 (I - t_i t_i^T)`` (eqs. 12-14).
    """
    da0 = scale * (t[i1, 0] - t[i2, 0]) / a
    da1 = scale * (t[i1, 1] - t[i2, 1]) / a
    da2 = scale * (t[i1, 2] - t[i2, 2]) / a
    db0 = scale * (t[i2, 0] - t[i3, 0]) / b
    db1 = scale * (t[i2, 1] - t[i3, 1]) / b
    db2 = scale * (t[i2, 2] - t[i3, 2]) / b
    dc0 = scale * (t[i1, 0] - t[i3, 0]) / c
    dc1 = scale * (t[i1, 1] - t[i3, 1]) / c
    dc2 = scale * (t[i1, 2] - t[i3, 2]) / c
    var = (_grad_var(w[0] * da0 + w[2] * dc0, w[0] * da1 + w[2] * dc1, w[0] * da2 + w[2] * dc2, t, i1)
           + _grad_var(-w[0] * da0 + w[1] * db0, -w[0] * da1 + w[1] * db1, -w[0] * da2 + w[1] * db2, t, i2)
           + _grad_var(-w[1] * db0 - w[2] * dc0, -w[1] * db1 - w[2] * dc1, -w[1] * db2 - w[2] * dc2, t, i3))
    return scale * sigma * math.sqrt(max(var, 0.0))


@_inner
def side_sigma(side, sigma):
    """Standard deviation of one unscaled chord side under eq. 11: ``sigma sqrt(2 - side^2/2)``."""
    return sigma * math.sqrt(max(2.0 - 0.5 * side * side, 0.0))


@_kernel
def _window(t, i1, i2, i3, sides, kv, mean, w, sigma, scale, beta):
    """Sides (eq. 4), projection (eq. 5) and k-vector window [p - xi, p + xi] (eqs. 13-19) of a triangle."""
    lo, hi = _window_bounds(t, i1, i2, i3, sides, mean, w, sigma, scale, beta)
    return kvector_query(kv, lo, hi)


@_inner
def _window_bounds(t, i1, i2, i3, sides, mean, w, sigma, scale, beta):
    """Sides (eq. 4, written to ``sides``) and the projection window ``(p - xi, p + xi)`` (eqs. 5-14)."""
    a = scale * chord_rows(t, i1, t, i2)
    b = scale * chord_rows(t, i2, t, i3)
    c = scale * chord_rows(t, i1, t, i3)
    sides[0] = a
    sides[1] = b
    sides[2] = c
    p = w[0] * (a - mean[0]) + w[1] * (b - mean[1]) + w[2] * (c - mean[2])
    xi = beta * projection_sigma(t, i1, i2, i3, a, b, c, w, sigma, scale)
    return p - xi, p + xi


@_inner
def _projection_window(t, i1, i2, i3, a, b, c, mean, w, sigma, scale, beta):
    """:func:`_window_bounds` of a triangle whose scaled sides ``a, b, c`` are known (the kernel's distance
    matrix holds them: the same bits as ``scale * chord_rows``, whichever vertex comes first)."""
    p = w[0] * (a - mean[0]) + w[1] * (b - mean[1]) + w[2] * (c - mean[2])
    xi = beta * projection_sigma(t, i1, i2, i3, a, b, c, w, sigma, scale)
    return p - xi, p + xi


@_inner
def _side_excess(sa, sb, sc, k, a, b, c, ta, tb, tc):
    """Largest amount by which one of the three sides misses its tolerance (<= 0: all agree)."""
    x = max(abs(sa[k] - a) - ta, abs(sb[k] - b) - tb)
    return max(x, abs(sc[k] - c) - tc)


@_inner
def _side_window(sides, sigma, scale, side_beta):
    """The image triangle's three scaled sides and their tolerances, float32 as the database's sides."""
    a = np.float32(sides[0])
    b = np.float32(sides[1])
    c = np.float32(sides[2])
    ta = np.float32(side_beta * scale * side_sigma(sides[0] / scale, sigma))
    tb = np.float32(side_beta * scale * side_sigma(sides[1] / scale, sigma))
    tc = np.float32(side_beta * scale * side_sigma(sides[2] / scale, sigma))
    return a, b, c, ta, tb, tc


@_kernel
def _side_check(sides, start, stop, db_sides, sigma, scale, side_beta, out_cand):
    """Database rows in ``[start, stop)`` whose three sides all agree with ``sides``; returns the count.

    ``db_sides`` is (3, t) float32, one contiguous row per side. The comparison runs in float32;
    a first pass (min/max reductions, a loop that vectorises) finds the first and last agreeing
    rows, and only the rows between them are then collected. ``out_cand`` must hold
    ``stop - start`` entries.
    """
    a, b, c, ta, tb, tc = _side_window(sides, sigma, scale, side_beta)
    sa = db_sides[0, start:stop]
    sb = db_sides[1, start:stop]
    sc = db_sides[2, start:stop]
    m = sa.shape[0]
    first = m
    last = -1
    for k in range(m):
        ok = _side_excess(sa, sb, sc, k, a, b, c, ta, tb, tc) <= 0
        first = min(first, k if ok else m)
        last = max(last, k if ok else -1)
    n_out = 0
    for k in range(first, last + 1):
        if _side_excess(sa, sb, sc, k, a, b, c, ta, tb, tc) <= 0:
            out_cand[n_out] = start + k
            n_out += 1
    return n_out


#: Margin (scaled chord) by which the bins an indexed check reads extend beyond side a's tolerance: more
#: than the float32 rounding of the sides (1.2e-4 below 2048), so every row the float32 check accepts is read.
INDEX_MARGIN = 0.01


@_inner
def _index_bins(a, ta, index):
    """The bins of side a (:class:`SideIndex`) within ``a +- (ta + INDEX_MARGIN)``: ``(first, last)``."""
    i0 = max(int(math.floor((float(a) - float(ta) - INDEX_MARGIN) / index.width)), 0)
    i1 = min(int(math.floor((float(a) + float(ta) + INDEX_MARGIN) / index.width)), index.offsets.shape[1] - 1)
    return i0, i1


@_kernel
def _side_check_indexed(sides, start, stop, index, sigma, scale, side_beta, out_cand):
    """The rows of :func:`_side_check` (the same rows, ascending), read through the :class:`SideIndex`: only
    the entries of the window ``[start, stop)`` whose side a lies in a bin within the tolerance of
    ``sides[0]`` (about 20 of some 400 rows, 2-3 bins) are compared, by the same float32 test on the same
    float32 sides. ``out_cand`` must hold ``stop - start + 1`` entries.
    """
    a, b, c, ta, tb, tc = _side_window(sides, sigma, scale, side_beta)
    i0, i1 = _index_bins(a, ta, index)
    return _side_check_entries(a, b, c, ta, tb, tc, i0, i1, start, stop, index, out_cand)


@_inner
def _side_check_entries(a, b, c, ta, tb, tc, i0, i1, start, stop, index, out_cand):
    """:func:`_side_check_indexed` with the float32 sides and tolerances of :func:`_side_window` and the bins
    ``i0 .. i1`` of :func:`_index_bins` given (the kernel computes them once per window)."""
    if stop <= start:
        return 0
    offsets = index.offsets
    rows = index.rows
    s = index.sides
    j0 = start >> index.shift
    j1 = ((stop - 1) >> index.shift) + 1
    n_out = 0
    for i in range(i0, i1 + 1):
        for e in range(offsets[j0, i], offsets[j1, i]):
            r = np.int64(rows[e])
            # the test of _side_excess (each excess <= 0) and the window, without a branch: the row is
            # written in any case and kept by counting it (a quarter faster than branching)
            ok = ((abs(s[e, 0] - a) - ta <= 0) & (abs(s[e, 1] - b) - tb <= 0) & (abs(s[e, 2] - c) - tc <= 0)
                  & (r >= start) & (r < stop))
            out_cand[n_out] = r
            n_out += ok
    if i1 > i0 and n_out > 1:       # rows of several bins: ascending, as the scan of the window gives them
        if n_out <= 32:
            for k in range(1, n_out):
                r = out_cand[k]
                m = k
                while m > 0 and out_cand[m - 1] > r:
                    out_cand[m] = out_cand[m - 1]
                    m -= 1
                out_cand[m] = r
        else:
            found = np.empty(n_out, dtype=np.int64)     # (a new array: argsort_int's one signature)
            for k in range(n_out):
                found[k] = out_cand[k]
            order = argsort_int(found)
            for k in range(n_out):
                out_cand[k] = found[order[k]]
    return n_out


@_inner
def _prefetch_entries(start, stop, i0, i1, index):
    """Ask for the entries (rows and sides) :func:`_side_check_indexed` reads for ``[start, stop)``
    (``stop > start``) in the bins ``i0 .. i1``."""
    j0 = start >> index.shift
    j1 = ((stop - 1) >> index.shift) + 1
    for i in range(i0, i1 + 1):
        e0 = np.int64(index.offsets[j0, i])
        e1 = np.int64(index.offsets[j1, i])
        if e1 <= e0:
            continue
        for e in range(e0, e1, 4):      # 4 entries of 16 bytes (sides and row): no 64-byte line skipped
            prefetch_at(index.sides, e, 0)
        prefetch_at(index.sides, e1 - 1, 3)


@_inner
def _triple_key(i, j, k, n):
    """Order-free key of a set of three image stars."""
    a, b, c = min(i, j, k), max(min(i, j), min(max(i, j), k)), max(i, j, k)
    return (a * n + b) * n + c


@_kernel
def argsort_int(keys):
    """Ascending, stable order of int64 ``keys``: the shared merge sort
    (:func:`starid.kernels.order.stable_sort_by_key`, which compiles in a fraction of the time of
    ``np.argsort``'s quicksort) on ``0 .. n-1``; both callers need only a correct order, :func:`validate`
    groups equal keys and :func:`try_hypotheses` sorts unique ones."""
    order = np.arange(keys.shape[0])
    stable_sort_by_key(order, np.int64(order.shape[0]), keys)
    return order


@_kernel
def select_stars(x_px, y_px, mag, max_stars):
    """Indices of the ``max_stars`` brightest detections (ties: by x, then y), brightest first."""
    n = x_px.shape[0]
    order = np.arange(n)
    for i in range(1, n):      # insertion sort on (mag, x, y): images are small, and it is input-order free
        j = i
        while j > 0:
            a = order[j]
            b = order[j - 1]
            if mag[a] < mag[b] or (mag[a] == mag[b] and (x_px[a] < x_px[b] or (x_px[a] == x_px[b]
                                                                                  and y_px[a] < y_px[b]))):
                order[j] = b
                order[j - 1] = a
                j -= 1
            else:
                break
    return order[:min(n, max_stars)].copy()


#: Slots of the work counters :func:`identify_kernel` returns (``Identification.counters``).
WORK_NAMES = ("searches", "window_triangles", "candidates", "hypotheses")


@_kernel
def identify_kernel(x_px, y_px, mag, params, narrow, wide):
    """``(hip, counters, tail)``: the catalog id of each detection (int64, -1 = none), the work counters as a
    tuple of ints (:data:`WORK_NAMES`: k-vector searches, database triangles in their windows, candidates that
    passed the three-side check, single-triangle hypotheses tried), and one int64 array of the detections that
    took part (brightest first; their camera-frame unit vectors are ``backproject_px`` of them) then their guide
    rows (-1 = none) (:func:`unpack_tail`). Two arrays and a tuple: ``PTP.identify`` hands ``hip`` and the
    counters to the ``Identification`` as they are, with no numpy slicing or ``tolist`` in Python (some 3 us of
    a call that finds numpy's code out of the cache).

    ``params`` is a :class:`View` and :class:`Tolerances` as one float64 array (:func:`params_of`), rebuilt
    into the named tuples here: numba's dispatch types a named tuple in Python (about 4 us of every image) and
    unboxes a plain tuple element by element (5 us more when the call's objects are out of the cache).
    ``narrow`` and ``wide`` are the :class:`Tables` packed by
    :func:`pack_tables` (two arrays to unbox instead of ten and five numbers: some 15 us of a call that finds
    them out of the cache).

    The identification runs on the ``tol.max_stars`` brightest detections whose measured magnitude
    is at most ``tol.star_mag_max`` (the flight precaution: a star that cannot be in the database
    makes no pattern). ``tol.assign_all`` (the attitude of ``rows`` assigning every detection to the
    deep catalog) is left to the caller (``PTP.identify``), so the default command never compiles it.

    PTP identification (sections 2.2-2.3), on the detections' camera-frame unit vectors ``unit``:

    1. Every star is a master; its slaves are the ``n_slaves`` nearest stars in
       ``[d_min, d_max]`` (same rule as the database); triangles (m, s_i, s_j), i < j. With
       ``exclude_doubles``, stars closer than ``d_min`` to another detection are neither masters
       nor slaves and stay unidentified (the database drops such guide pairs likewise).
    2. Each triangle's projection (eq. 5) and its 3-sigma window (eqs. 6-14) select database
       triangles through the k-vector (eqs. 15-19); the three sides must each agree within
       ``side_beta`` standard deviations. When the two slaves are at distances closer than the
       side tolerance, the swapped vertex order is tried too (``swap_slaves``).
    3. Sharing-star validation (section 2.3, Table 3): a matched triangle is validated when at
       least ``min_shared`` of its (image star -> catalog star) pairings also come from another
       observed triangle, i.e. another *set* of three image stars (the same three stars reached
       from two masters are one triangle, not independent evidence). The pairings of validated
       triangles are accepted. An image star offered two catalog stars keeps the one proposed by
       more observed triangles (``majority``; a tie drops it), and so does a catalog star offered
       to two image stars; with ``majority=False`` every such conflict is dropped (the paper's
       "otherwise it will be determined as a failure").
    4. (``verify``, starid's extension) the surviving pairings must agree pairwise in angular
       distance (``verify_pairwise`` with a ``side_beta`` sqrt(2) sigma chord tolerance, each
       agreeing with at least two others and ``verify_min_fraction`` of them).
    5. (``confirm_fraction``, starid's extension) the attitude of the surviving pairings
       (Wahba) must put guide stars in the image of which at least that fraction is observed
       within the same tolerance (``reproject_assign``); otherwise nothing is reported.
    6. (``hypotheses``, starid's extension) if fewer than three stars remain, each matched triangle alone
       is a hypothesis checked against the whole image (:func:`try_hypotheses`).

    One function, not a wrapper around a ``match_rows`` kernel: numba re-optimises every callee inside
    each caller it is linked into, so a level less in the call tree is a cold compile about 2 s shorter.
    """
    view = params_view(params)
    db = tables_of(narrow, wide)
    tol = params_tol(params)
    n = x_px.shape[0]
    hip = np.full(n, -1, dtype=np.int64)
    work = np.zeros(len(WORK_NAMES), dtype=np.int64)
    if n < 3:
        return _out(hip, work, work[:0], work[:0])
    sel = select_stars(x_px, y_px, mag, tol.max_stars)
    k = 0
    while k < sel.shape[0] and mag[sel[k]] <= tol.star_mag_max:
        k += 1
    sel = sel[:k]
    if k < 3:
        return _out(hip, work, sel[:0], work[:0])
    frame = view.frame
    unit = backproject_px(x_px[sel], y_px[sel], frame.f_px, frame.cx_px, frame.cy_px)
    f_px, cx_px, cy_px = frame.f_px, frame.cx_px, frame.cy_px
    guide_unit = db.guide_unit
    sigma = tol.sigma_px / f_px
    scale, d_min, d_max, n_slaves = tol.scale, tol.d_min, tol.d_max, tol.n_slaves
    side_beta, exclude_doubles = tol.side_beta, tol.exclude_doubles
    n_guide = guide_unit.shape[0]
    n = unit.shape[0]
    result = np.full(n, -1, dtype=np.int64)
    dist = np.empty((n, n))
    usable = np.ones(n, dtype=np.bool_)
    for i in range(n):
        dist[i, i] = 0.0
        for j in range(i + 1, n):
            d = scale * chord_rows(unit, i, unit, j)
            dist[i, j] = d
            dist[j, i] = d
            if d < d_min and exclude_doubles:
                usable[i] = False
                usable[j] = False
    cand = np.empty(1024, dtype=np.int64)
    n_img_slaves = max(n_slaves, tol.image_slaves)
    # every usable master's slaves (nearest first), then its triangles' windows
    slave_of = np.empty((n, n_img_slaves), dtype=np.int64)
    n_slave = np.zeros(n, dtype=np.int64)
    cap_w = 1
    for master in range(n):
        if usable[master]:
            n_slave[master] = nearest_slaves(dist[master], unit, usable, master, d_min, d_max, n_img_slaves,
                                             slave_of[master])
            cap_w += n_slave[master] * (n_slave[master] - 1)     # both vertex orders of every pair
    # match records: image triangle id, image stars (3), guide stars (3)
    m_cap = 256
    m_tri = np.empty(m_cap, dtype=np.int64)
    m_img = np.empty((m_cap, 3), dtype=np.int64)
    m_cat = np.empty((m_cap, 3), dtype=np.int64)
    n_match = np.int64(0)   # not a literal: one signature of try_hypotheses
    kv = db.kv
    index = db.index
    n_rows = kv.values.shape[0]
    # the windows of a batch of masters: image stars (3), triple key, rows [start, stop), bins of side a
    # [i0, i1]; lo, hi; the float32 sides a, b, c and their tolerances (_side_window)
    w_int = np.empty((cap_w, 8), dtype=np.int64)
    w_flt = np.empty((cap_w, 2))
    w_side = np.empty((cap_w, 6), dtype=np.float32)
    # The search runs in passes over all the windows of a batch (every master; one master with stop_first),
    # each pass asking for the cache lines the next one reads (starid.kernels.prefetch): a window's reads form a chain
    # (k-vector -> its values -> the index's offsets -> the entries -> the guide rows), which the passes turn
    # into independent loads across windows. The same windows, rows, records and order as one pass.
    first = 0
    while first < n:
        last = first + 1 if tol.stop_first else n
        if not usable[first] and tol.stop_first:
            first = last
            continue
        nw = 0
        for master in range(first, last):    # the triangles, in the order of the slave lists
            if not usable[master]:
                continue
            k = n_slave[master]
            for ia in range(k):
                for ib in range(ia + 1, k):
                    s1 = slave_of[master, ia]
                    s2 = slave_of[master, ib]
                    d1 = dist[master, s1]
                    d2 = dist[master, s2]
                    if dist[s1, s2] <= 0.0:
                        continue    # coincident slaves make no triangle
                    d12 = dist[s1, s2]
                    # each side's tolerance once (_side_window's, and the swap test's of the longer slave)
                    t1 = side_beta * scale * side_sigma(d1 / scale, sigma)
                    t2 = side_beta * scale * side_sigma(d2 / scale, sigma)
                    t12 = side_beta * scale * side_sigma(d12 / scale, sigma)
                    tol_swap = t1 if d1 >= d2 else t2
                    n_orders = 2 if (tol.swap_slaves and abs(d2 - d1) <= tol_swap) else 1
                    key = _triple_key(master, s1, s2, n)
                    for o in range(n_orders):
                        sa, sc, ta, tc = (d1, d2, t1, t2) if o == 0 else (d2, d1, t2, t1)
                        w_int[nw, 0] = master
                        w_int[nw, 1] = s1 if o == 0 else s2
                        w_int[nw, 2] = s2 if o == 0 else s1
                        w_int[nw, 3] = key
                        lo, hi = _projection_window(unit, master, w_int[nw, 1], w_int[nw, 2], sa, d12, sc, db.mean,
                                                    db.axis, sigma, scale, tol.beta)
                        w_flt[nw, 0] = lo
                        w_flt[nw, 1] = hi
                        w_side[nw, 0] = np.float32(sa)
                        w_side[nw, 1] = np.float32(d12)
                        w_side[nw, 2] = np.float32(sc)
                        w_side[nw, 3] = np.float32(ta)
                        w_side[nw, 4] = np.float32(t12)
                        w_side[nw, 5] = np.float32(tc)
                        jb, jt = kvector_ends(kv.m, kv.q, lo, hi)
                        w_int[nw, 4] = jb
                        w_int[nw, 5] = jt
                        prefetch(kv.k, min(max(jb - 1, 0), n_rows - 1))
                        prefetch(kv.k, min(max(jt - 1, 0), n_rows - 1))
                        nw += 1
        for w in range(nw):     # the k-vector's slice (its entries asked for above); ask for its ends' values
            start, stop = kvector_rows(kv.k, n_rows, w_int[w, 4], w_int[w, 5])
            w_int[w, 4] = start
            w_int[w, 5] = stop
            prefetch(kv.values, min(max(start - 1, 0), n_rows - 1))
            prefetch(kv.values, min(start, n_rows - 1))
            prefetch(kv.values, min(max(stop - 1, 0), n_rows - 1))
            prefetch(kv.values, min(stop, n_rows - 1))
        for w in range(nw):     # the exact windows (kvector_query's rows); ask for the index's offsets they read
            lo = w_flt[w, 0]
            hi = w_flt[w, 1]
            if n_rows == 0 or hi < lo:
                start, stop = 0, 0
            else:
                start, stop = kvector_trim(kv.values, n_rows, w_int[w, 4], w_int[w, 5], lo, hi)
            w_int[w, 4] = start
            w_int[w, 5] = stop
            if stop > start:
                i0, i1 = _index_bins(w_side[w, 0], w_side[w, 3], index)
                w_int[w, 6] = i0
                w_int[w, 7] = i1
                j0 = start >> index.shift
                j1 = ((stop - 1) >> index.shift) + 1
                prefetch_at(index.offsets, j0, i0)
                prefetch_at(index.offsets, j0, i1)
                prefetch_at(index.offsets, j1, i0)
                prefetch_at(index.offsets, j1, i1)
        for w in range(nw):     # ask for the entries the checks read
            start = w_int[w, 4]
            stop = w_int[w, 5]
            if stop > start:
                _prefetch_entries(start, stop, w_int[w, 6], w_int[w, 7], index)
        n_new = n_match
        for w in range(nw):     # the three-side checks; the records hold the database row until the pass below
            start = w_int[w, 4]
            stop = w_int[w, 5]
            if stop - start >= cand.shape[0]:
                cand = np.empty(2 * (stop - start) + 1, dtype=np.int64)
            nc = _side_check_entries(w_side[w, 0], w_side[w, 1], w_side[w, 2], w_side[w, 3], w_side[w, 4],
                                     w_side[w, 5], w_int[w, 6], w_int[w, 7], start, stop, index, cand)
            work[0] += 1
            work[1] += stop - start
            work[2] += nc
            if nc > tol.max_candidates:
                continue    # an uninformative triangle (a window far wider than the catalog's spacing)
            if tol.unique_only and nc > 1:
                continue    # reading: only a triangle with one catalog match votes
            for c in range(nc):
                if n_match == m_cap:
                    m_cap *= 2
                    new_tri = np.empty(m_cap, dtype=np.int64)
                    new_img = np.empty((m_cap, 3), dtype=np.int64)
                    new_cat = np.empty((m_cap, 3), dtype=np.int64)
                    for r in range(n_match):   # loops, not slice copies: no shape-error code to compile
                        new_tri[r] = m_tri[r]
                        for v in range(3):
                            new_img[r, v] = m_img[r, v]
                            new_cat[r, v] = m_cat[r, v]
                    m_tri, m_img, m_cat = new_tri, new_img, new_cat
                m_tri[n_match] = w_int[w, 3]
                for v in range(3):
                    m_img[n_match, v] = w_int[w, v]
                m_cat[n_match, 0] = cand[c]
                prefetch_at(db.ids, cand[c], 0)
                n_match += 1
        for r in range(n_new, n_match):     # database rows -> their guide rows
            row = m_cat[r, 0]
            for v in range(3):
                m_cat[r, v] = db.ids[row, v]
        if tol.stop_first and n_match > 0:
            # reading: the search stops at the first master after which validation identifies >= 3 stars
            validate(n, n_guide, n_match, m_tri, m_img, m_cat, tol, tol.min_shared, tol.conflict_fails, result)
            found = 0
            for s in range(n):
                if result[s] >= 0:
                    found += 1
            if found >= 3:
                break
            result[:] = -1
        first = last
    if n_match > 0:
        support = validate(n, n_guide, n_match, m_tri, m_img, m_cat, tol, tol.min_shared, tol.conflict_fails, result)
        if tol.lone_triangles:
            n_found = 0
            for s in range(n):
                if result[s] >= 0:
                    n_found += 1
            if n_found < 3:
                # reading: nothing to validate against, so unvalidated matches stand if none conflicts with another
                validate(n, n_guide, n_match, m_tri, m_img, m_cat, tol, np.int64(0), np.bool_(True), result)
        tol_chord = side_beta * math.sqrt(2.0) * sigma
        w_idx = np.empty(n, dtype=np.int64)   # Wahba's rows and float64 guide vectors (guide_rows_f64)
        w_cat = np.empty((n, 3))
        if tol.verify:
            keep = verify_pairwise(unit, result, guide_unit, tol_chord, np.int64(2), tol.verify_min_fraction)
            for s in range(n):
                if not keep[s]:
                    result[s] = -1
        n_found = 0
        for s in range(n):
            if result[s] >= 0:
                n_found += 1
        attitude = np.empty((3, 3))
        have_attitude = False     # the attitude of ``result`` as it stands, for nearest_check
        if tol.confirm_fraction > 0 and n_found >= 2:
            guide_rows_f64(result, guide_unit, w_idx, w_cat)
            attitude = wahba_rows(unit, w_idx, w_cat)
            have_attitude = True
            seen = np.empty(n, dtype=np.int64)
            n_seen, n_predicted = reproject_assign(attitude, unit, guide_unit, view.c_fov + tol_chord, tol_chord, seen,
                                                   f_px, cx_px, cy_px, frame.width_px, frame.height_px)
            if n_seen < tol.confirm_fraction * n_predicted:
                result[:] = -1
                n_found = 0
        if tol.nearest_check and n_found >= 3:
            if not have_attitude:     # (confirmation's attitude is of the same pairings: the same bits)
                guide_rows_f64(result, guide_unit, w_idx, w_cat)
                attitude = wahba_rows(unit, w_idx, w_cat)
            n_found = drop_displaced(unit, result, guide_unit, tol_chord, attitude)
        if n_found < 3 and tol.hypotheses > 0:
            if not try_hypotheses(unit, view, db, tol, n_match, m_img, m_cat, support, tol_chord, result, work):
                result[:] = -1
    for s in range(n):
        if result[s] >= 0:
            hip[sel[s]] = db.guide_hip[result[s]]
    return _out(hip, work, sel, result)


@_inner
def _out(hip, work, sel, rows):
    """:func:`identify_kernel`'s result: ``hip`` (n), the work counters (:data:`WORK_NAMES`) as a tuple of ints,
    and one array of the k detections that took part (``sel``) then their guide rows (:func:`unpack_tail`)."""
    k = sel.shape[0]
    tail = np.empty(2 * k, dtype=np.int64)
    for i in range(k):
        tail[i] = sel[i]
        tail[k + i] = rows[i]
    return hip, (work[0], work[1], work[2], work[3]), tail


def unpack_tail(tail: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(sel, rows)`` of :func:`identify_kernel`'s third value (views)."""
    k = tail.shape[0] // 2
    return tail[:k], tail[k:]


#: Fibonacci hashing's multiplier (2**64 / golden ratio, as a wrapping int64) for :func:`_pair_support`.
HASH_MULTIPLIER = -7046029254386353131


@_inner
def _hash_slot(table, base, mask, bits, value):
    """The slot of ``value`` (>= 0) in the open-addressing table ``table[base:base + mask + 1]`` (-1 = empty,
    linear probing): its own slot if present, else the empty slot it goes to."""
    h = ((value * HASH_MULTIPLIER) >> (64 - bits)) & mask
    while table[base + h] != -1 and table[base + h] != value:
        h = (h + 1) & mask
    return base + h


@_inner
def _pair_support(n, n_guide, n_match, m_tri, m_img, m_cat, support):
    """``support[3 mi + v]``: the number of distinct observed triangles (``m_tri``) among the records that
    propose the pairing (image star ``m_img[mi, v]``, guide row ``m_cat[mi, v]``), for every record ``mi`` of
    the first ``n_match``. Two hash tables, of the pairings and of the (pairing, triangle) pairs: each new
    (pairing, triangle) adds one to its pairing's count. The same counts as grouping a sort of the
    (pairing, triangle) keys, in time linear in the records (the sort's insertions were a third of
    :func:`validate`'s time on the real sky)."""
    n_pair = 3 * n_match
    bits = 6
    while (1 << bits) < 2 * n_pair:
        bits += 1
    cap = np.int64(1) << bits
    mask = cap - 1
    # [0, cap): pairing keys; [cap, 2 cap): (pairing, triangle) keys; [2 cap, 3 cap): each pairing's count
    table = np.empty(3 * cap, dtype=np.int64)
    for h in range(2 * cap):
        table[h] = -1
    for h in range(2 * cap, 3 * cap):
        table[h] = 0
    n_tri = n * n * n
    for mi in range(n_match):
        for v in range(3):
            key = m_img[mi, v] * n_guide + m_cat[mi, v]
            at = _hash_slot(table, np.int64(0), mask, bits, key)
            table[at] = key
            support[3 * mi + v] = at
            pair = key * n_tri + m_tri[mi]
            at_pair = _hash_slot(table, cap, mask, bits, pair)
            if table[at_pair] == -1:
                table[at_pair] = pair
                table[2 * cap + at] += 1
    for t in range(n_pair):
        support[t] = table[2 * cap + support[t]]


@_inner
def validate(n, n_guide, n_match, m_tri, m_img, m_cat, tol, min_shared, conflict_fails, result):
    """Sharing-star validation (section 2.3, Table 3) of the first ``n_match`` match records: writes the
    accepted guide row of each of the ``n`` image stars into ``result`` (-1 = none) and returns the support
    of every pairing (``3 * n_match``: distinct observed triangles proposing it).

    A record is validated when at least ``min_shared`` of its pairings have support >= 2. Conflicts
    (an image star offered two catalog stars, a catalog star offered to two image stars) go to the better
    supported pairing (``tol.majority``; a tie drops it) or are dropped; with ``conflict_fails`` any
    conflict among validated records makes the whole image a failure (``result`` all -1).
    """
    majority = tol.majority
    result[:] = -1
    # Support of each pairing = number of distinct observed triangles that propose it.
    n_pair = 3 * n_match
    support = np.empty(n_pair, dtype=np.int64)
    _pair_support(n, n_guide, n_match, m_tri, m_img, m_cat, support)
    # Validated matches contribute their pairings; conflicts are settled by support.
    best = np.full(n, -1, dtype=np.int64)
    best_support = np.zeros(n, dtype=np.int64)
    tie = np.zeros(n, dtype=np.bool_)
    for mi in range(n_match):
        shared = 0
        for v in range(3):
            if support[3 * mi + v] >= 2:
                shared += 1
        if shared < min_shared:
            continue
        for v in range(3):
            s = m_img[mi, v]
            g = m_cat[mi, v]
            sup = support[3 * mi + v]
            if not majority:
                sup = 1
            if best[s] == -1 or sup > best_support[s]:
                best[s] = g
                best_support[s] = sup
                tie[s] = False
            elif sup == best_support[s] and g != best[s]:
                tie[s] = True
    n_conflict = 0
    for s in range(n):
        if tie[s]:
            best[s] = -1
            n_conflict += 1
    # A catalog star proposed for several image stars goes to the best supported one, if unique.
    for s in range(n):
        if best[s] < 0:
            continue
        win = True
        for t in range(n):
            if t != s and best[t] == best[s] and (best_support[t] >= best_support[s] or not majority):
                win = False
        if win:
            result[s] = best[s]
        else:
            n_conflict += 1
    if conflict_fails and n_conflict > 0:
        result[:] = -1
    return support


@_inner
def drop_displaced(unit, result, guide_unit, eps_chord, attitude):
    """Extension (``nearest_check``): ``attitude``, of all pairings in ``result`` (Wahba), predicts each
    paired guide star; a pairing is dropped when its detection lies farther than ``eps_chord`` (the pair
    tolerance) from that prediction and another detection lies nearer it. Returns the number of pairings
    left."""
    n = unit.shape[0]
    pred = np.empty((1, 3))
    drop = np.zeros(n, dtype=np.bool_)
    for s in range(n):
        g = result[s]
        if g < 0:
            continue
        for a in range(3):
            pred[0, a] = (attitude[a, 0] * guide_unit[g, 0] + attitude[a, 1] * guide_unit[g, 1]
                          + attitude[a, 2] * guide_unit[g, 2])
        own = chord_rows(unit, s, pred, np.int64(0))
        if own <= eps_chord:
            continue
        for t in range(n):
            if t != s and chord_rows(unit, t, pred, np.int64(0)) < own:
                drop[s] = True
                break
    n_found = 0
    for s in range(n):
        if drop[s]:
            result[s] = -1
        elif result[s] >= 0:
            n_found += 1
    return n_found


@_inner
def try_hypotheses(unit, view, db, tol, n_match, m_img, m_cat, support, eps_chord, result, work):
    """Extension (``hypotheses``): when sharing-star validation gives no identification, each matched
    triangle alone is a hypothesis, best supported first (then brightest stars: ``unit`` is in brightness
    order), at most ``tol.hypotheses`` distinct ones. Its attitude (Wahba on the three pairings) must
    explain its own three stars and at least ``max(check_min_stars, check_fraction * n)`` of the ``n``
    detections (:func:`starid.kernels.explained`); the attitude is then refined on every explained detection and the
    check repeated. The first hypothesis that passes gives the guide-star ids in ``result``; ``work[3]``
    counts the hypotheses tried."""
    n = unit.shape[0]
    need = max(tol.check_min_stars, int(math.ceil(tol.check_fraction * n)))
    if n < need or n_match == 0:
        return False
    # order by (-support * 3n + the stars' brightness ranks, record index): a unique integer key, so
    # argsort_int (validate's sort) gives the order of a stable sort of the score
    score = np.empty(n_match, dtype=np.int64)
    for mi in range(n_match):
        sup = support[3 * mi] + support[3 * mi + 1] + support[3 * mi + 2]
        score[mi] = (-sup * 3 * n + m_img[mi, 0] + m_img[mi, 1] + m_img[mi, 2]) * n_match + mi
    order = argsort_int(score)
    rows = np.empty(n, dtype=np.int64)
    rows_g = np.empty(n, dtype=np.int64)
    rows_x = np.empty(n, dtype=np.int64)
    w_idx = np.empty(n, dtype=np.int64)
    w_cat = np.empty((n, 3))
    c_fov = view.c_fov + eps_chord
    tried_img = np.empty((tol.hypotheses, 3), dtype=np.int64)
    tried_cat = np.empty((tol.hypotheses, 3), dtype=np.int64)
    n_tried = 0
    for oi in range(n_match):
        if n_tried >= tol.hypotheses:
            break
        mi = order[oi]
        seen = False
        for t in range(n_tried):
            same = True
            for v in range(3):
                if tried_img[t, v] != m_img[mi, v] or tried_cat[t, v] != m_cat[mi, v]:
                    same = False
            if same:
                seen = True
                break
        if seen:
            continue
        for v in range(3):
            tried_img[n_tried, v] = m_img[mi, v]
            tried_cat[n_tried, v] = m_cat[mi, v]
        n_tried += 1
        work[3] += 1
        rows[:] = -1
        for v in range(3):
            rows[m_img[mi, v]] = m_cat[mi, v]
        guide_rows_f64(rows, db.guide_unit, w_idx, w_cat)
        attitude = wahba_rows(unit, w_idx, w_cat)
        count, _, _ = explained(attitude, unit, db.guide_unit, db.extra_unit, view.frame, c_fov, eps_chord, rows_g,
                                rows_x)
        own = True
        for v in range(3):
            if rows_g[m_img[mi, v]] != m_cat[mi, v]:
                own = False
        if not own or count < need:
            continue
        # refine on every explained detection, then check again
        _, count, _, _ = refine_explained(unit, db.guide_unit, db.extra_unit, view.frame, c_fov, eps_chord, rows_g,
                                          rows_x)
        n_guide = 0
        for i in range(n):
            if rows_g[i] >= 0:
                n_guide += 1
        if count < need or n_guide < 3:
            continue
        for i in range(n):
            result[i] = rows_g[i]
        return True
    return False
