"""numba kernels of the triangle-voting plugin (Fan & Zhong 2018): features, database, voting.

Feature convention (both sides, rotation invariant, no tangent-plane projection needed): the
triangle of three unit vectors ``S`` (main star, the apex), ``A`` and ``B`` (two neighbours) is
taken as a planar triangle in 3-D; ``base = |B - A|`` (chord) and ``height`` = the distance of
``S`` from the line ``AB``, i.e. ``2 * area / base``. ``t`` is where the foot of that height
falls on the line (``0`` at ``A``, ``1`` at ``B``); it only sets the height tolerance.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from starid_algorithms.planar_triangle.kernels import argsort_desc

from starid.kernels import backproject_px, chord_rows, verify_pairwise, wahba_rows
from starid.kernels.jit import inline_kernel, inner, kernel
from starid.kernels.params import exact_float64
from starid.kernels.prefetch import prefetch

from .final import finish_cone

#: names of the per-image work counters :func:`identify_rows` returns (``Identification.counters``):
#: image triangles looked up in the grid, catalog records in the grid cells scanned, records within
#: both the base and the height window, and of those the records whose sides matched too
WORK_COUNTERS = ("triangles", "records", "matches", "side_matches")


#: columns of ``Tables.features`` (the database's ``features``): the records' base and height (float32, chord
#: units), the exact values the windows test. ``vote`` reads them only for a record within the rounding of
#: the compact record (``records``) from a window's edge.
FEAT_BASE, FEAT_HEIGHT = 0, 1
#: columns of ``Tables.records``: base, height and the main-to-n_i and main-to-n_j chords (``record_sides``)
#: rounded to multiples of ``rec_scale_b``, ``rec_scale_h``, ``rec_scale_s`` (uint16): one 8-byte row per record,
#: the only bytes ``vote``'s scan of a grid column reads for most records (issue #25: in the benchmark's
#: interleaved timing the records come from memory the other plugins evicted)
REC_BASE, REC_HEIGHT, REC_SIDE_I, REC_SIDE_J = 0, 1, 2, 3
#: columns of ``Tables.rows`` (uint16 guide rows of a record: main star, the apex, and its two neighbours): one
#: 6-byte row, so a listed record costs one cache line, not one per column
ROW_MAIN, ROW_I, ROW_J = 0, 1, 2
#: largest value of a compact record's column (of 65,535), so rounding never overflows
REC_MAX = 65000
#: margin of a compact value, in units of its scale: it is within half a unit of the float32 value it rounds
#: (the rest covers the float64 arithmetic of dividing and rounding)
REC_MARGIN = 0.501


def row_columns() -> tuple[property, property, property]:
    """Read-only properties ``main, n_i, n_j``: the columns of ``rows``, for a class holding it (``Tables``
    and the database), as the three arrays they once were."""
    def column(k: int, doc: str) -> property:
        return property(lambda self: self.rows[:, k], doc=doc)
    return (column(ROW_MAIN, "uint16 (m,) the records' main star (guide row)"),
            column(ROW_I, "uint16 (m,) the records' first neighbour (guide row)"),
            column(ROW_J, "uint16 (m,) the records' second neighbour (guide row)"))


def feature_columns(unit_name: str) -> tuple[property, property, property, property]:
    """Read-only properties ``base, height, side_i, side_j`` for a class holding ``features``, ``main``,
    ``n_i``, ``n_j`` and the guide unit vectors as ``unit_name``: the columns of ``features`` and the records'
    float32 side chords (``record_sides``, recomputed on access: the kernels read their compact copies)."""
    def column(k: int, doc: str) -> property:
        return property(lambda self: self.features[:, k], doc=doc)

    def side(k: int, doc: str) -> property:
        return property(lambda self: record_sides(getattr(self, unit_name), *(np.ascontiguousarray(c) for c in (
            self.main, self.n_i, self.n_j)))[k], doc=doc)
    return (column(FEAT_BASE, "float32 (m,) the records' base (chord units)"),
            column(FEAT_HEIGHT, "float32 (m,) the records' height (chord units)"),
            side(0, "float32 (m,) per record the chord main-to-``n_i`` (``record_sides``)"),
            side(1, "float32 (m,) per record the chord main-to-``n_j`` (``record_sides``)"))


def compact_records(base32, height32, side_i32, side_j32):
    """``(records, scale_b, scale_h, scale_s)``: the four float32 columns as uint16 multiples of a scale per
    column (sides share one), ``round(value / scale)``; each within ``REC_MARGIN * scale`` of its value."""
    def scale(*cols):
        top = max((float(c.max()) for c in cols if c.size), default=0.0)
        return top / REC_MAX if top > 0.0 else 1.0

    s_b, s_h, s_s = scale(base32), scale(height32), scale(side_i32, side_j32)
    records = np.empty((base32.size, 4), dtype=np.uint16)
    for k, (col, s) in enumerate(((base32, s_b), (height32, s_h), (side_i32, s_s), (side_j32, s_s))):
        records[:, k] = np.rint(col.astype(np.float64) / s)
    return records, s_b, s_h, s_s


class Tables(NamedTuple):
    """The database as the kernels read it (see ``TriangleVotingDatabase``)."""

    features: np.ndarray  # float32 (m, 2) per record base, height (exact); records sorted by 2-D grid cell, then height
    records: np.ndarray  # uint16 (m, 4) per record base, height, side_i, side_j rounded (see REC_BASE)
    rows: np.ndarray  # uint16 (m, 3) guide rows: main star (apex) and its two neighbours (see ROW_MAIN)
    cell_start: np.ndarray  # int32 records of grid cell c: cell_start[c]:cell_start[c + 1]
    n_cells_b: int
    n_cells_h: int
    cell_b: float  # grid cell size in base and height (chord units)
    cell_h: float
    unit: np.ndarray  # float32 (n, 3) guide-star unit vectors, ICRS, sorted by sky cell
    sky_start: np.ndarray  # int32 guide rows of sky cell c: sky_start[c]:sky_start[c + 1]
    sky_axis: int
    pr_chord: float  # pattern radius as a chord
    dmin_chord: float  # D_min as a chord
    unit64: np.ndarray  # float64 (n, 3) ``unit`` as float64 (the same values), the attitude solver's input: one
    # compilation of ``wahba_rows`` (float64, shared with the final step) instead of two (issue #25)
    rec_scale_b: float  # the scales of ``records``' columns (chord units per unit)
    rec_scale_h: float
    rec_scale_s: float

    base, height, side_i, side_j = feature_columns("unit")
    main, n_i, n_j = row_columns()


class Tolerance(NamedTuple):
    """Windows and switches of one identification (see ``TriangleVoting``)."""

    sigma_chord: float  # centroid noise per axis, chord units
    k_sigma: float
    eps_chord: float  # k_sigma sqrt(2) sigma: base, side and pairwise-separation window
    radius_chord: float  # k_sigma sigma: reprojection radius
    n_nbr: int  # image neighbours per star (lambda + lambda_extra)
    side_check: bool
    vote_neighbours: bool
    v_min: int
    n_cand: int
    min_support: int
    min_stars: int
    max_hypotheses: int


# The kernels take both bundles as plain tuples (``tuple(Tables(...))``; a NamedTuple argument costs
# about 1 us more per call to dispatch) and read them by these field positions (numba constants).
DB_UNIT = Tables._fields.index("unit")
DB_UNIT64 = Tables._fields.index("unit64")
DB_SKY_START = Tables._fields.index("sky_start")
DB_SKY_AXIS = Tables._fields.index("sky_axis")
TOL_EPS_CHORD = Tolerance._fields.index("eps_chord")
TOL_RADIUS_CHORD = Tolerance._fields.index("radius_chord")
TOL_MIN_SUPPORT = Tolerance._fields.index("min_support")
TOL_MIN_STARS = Tolerance._fields.index("min_stars")
TOL_MAX_HYPOTHESES = Tolerance._fields.index("max_hypotheses")


@kernel
def triangle_features(s, a, b):
    """``(base, height, t)`` of the triangle with apex ``s`` over the base ``a``-``b`` (chord units)."""
    abx = b[0] - a[0]
    aby = b[1] - a[1]
    abz = b[2] - a[2]
    sax = s[0] - a[0]
    say = s[1] - a[1]
    saz = s[2] - a[2]
    base2 = abx * abx + aby * aby + abz * abz
    if base2 == 0.0:  # coincident neighbours: no triangle (callers reject base < D_min)
        return 0.0, 0.0, 0.5
    base = math.sqrt(base2)
    cx = say * abz - saz * aby
    cy = saz * abx - sax * abz
    cz = sax * aby - say * abx
    height = math.sqrt(cx * cx + cy * cy + cz * cz) / base
    t = (sax * abx + say * aby + saz * abz) / base2
    return base, height, t


@kernel
def build_triangles(unit, rank, nbr_ptr, nbr_idx, lam, dmin_chord):
    """Triangle records of every star: ``(base, height, main, n_i, n_j)``.

    ``nbr_idx[nbr_ptr[s]:nbr_ptr[s+1]]`` are the stars within the pattern radius of star ``s``;
    those closer than ``dmin_chord`` are skipped, the ``lam`` of lowest ``rank`` (brightest)
    are kept, and every pair of them whose base is at least ``dmin_chord`` makes a triangle.
    """
    n = unit.shape[0]
    cap = n * (lam * (lam - 1) // 2)
    base = np.empty(cap)
    height = np.empty(cap)
    main = np.empty(cap, dtype=np.int64)
    ni = np.empty(cap, dtype=np.int64)
    nj = np.empty(cap, dtype=np.int64)
    m = 0
    for s in range(n):
        cand = nbr_idx[nbr_ptr[s]:nbr_ptr[s + 1]]
        keep = np.empty(cand.size, dtype=np.int64)
        k = 0
        for c in cand:
            if c != s and chord_rows(unit, s, unit, c) >= dmin_chord:
                keep[k] = c
                k += 1
        # the lam kept stars of lowest rank, by rank (ranks are unique: np.argsort's order; a bounded
        # insertion, not np.argsort and fancy indexing, which cost compile time)
        top = np.empty(lam, dtype=np.int64)
        n_top = 0
        for e in range(k):
            c = keep[e]
            if n_top == lam:
                if rank[c] >= rank[top[lam - 1]]:
                    continue
                p = lam - 1  # the last one drops out
            else:
                p = n_top
                n_top += 1
            while p > 0 and rank[top[p - 1]] > rank[c]:
                top[p] = top[p - 1]
                p -= 1
            top[p] = c
        for i in range(n_top):
            for j in range(i + 1, n_top):
                b, h, _ = triangle_features(unit[s], unit[top[i]], unit[top[j]])
                if b < dmin_chord:
                    continue
                base[m] = b
                height[m] = h
                main[m] = s
                ni[m] = top[i]
                nj[m] = top[j]
                m += 1
    return base[:m], height[:m], main[:m], ni[:m], nj[:m]


#: bound of the float32 rounding of a chord (at most 2, so its error is at most 2 * 2^-24 = 1.2e-7),
#: doubled: a record whose float32 sides miss the window by more than this misses it exactly too; and
#: one whose float32 side errors are more than this inside the window (and whose two vertex orders
#: differ by more than twice this) matches exactly too, in the same order
SIDE_ROUNDING = 2.5e-7


@kernel
def record_sides(unit, main, n_i, n_j):
    """Per record the chords main-to-``n_i`` and main-to-``n_j`` (``chord_rows`` of ``unit``) as float32.

    Read sequentially by :func:`vote` in place of two random reads of ``unit`` and two square roots
    per record in both windows. The float32 values are within :data:`SIDE_ROUNDING` of the exact
    chords: they decide the side check only where that rounding cannot change its outcome; a record
    closer than that to the window's edge or to a tie of its two vertex orders is checked from ``unit``.
    """
    m = main.size
    side_i = np.empty(m, dtype=np.float32)
    side_j = np.empty(m, dtype=np.float32)
    for r in range(m):
        side_i[r] = chord_rows(unit, main[r], unit, n_i[r])
        side_j[r] = chord_rows(unit, main[r], unit, n_j[r])
    return side_i, side_j


@inner
def _key_after(q, r, records, features, rows_db):
    """Whether record ``q`` comes after record ``r`` by (base, height, main star), the float32 values: from the
    compact records where they differ (rounding keeps the order: a larger compact value means a larger value),
    so the float32 rows (another cache line) are read only on a tie of the compact ones."""
    if records[q, REC_BASE] != records[r, REC_BASE]:
        return records[q, REC_BASE] > records[r, REC_BASE]
    if features[q, FEAT_BASE] != features[r, FEAT_BASE]:
        return features[q, FEAT_BASE] > features[r, FEAT_BASE]
    if records[q, REC_HEIGHT] != records[r, REC_HEIGHT]:
        return records[q, REC_HEIGHT] > records[r, REC_HEIGHT]
    if features[q, FEAT_HEIGHT] != features[r, FEAT_HEIGHT]:
        return features[q, FEAT_HEIGHT] > features[r, FEAT_HEIGHT]
    return rows_db[q, ROW_MAIN] > rows_db[r, ROW_MAIN]


@inner
def _by_base(listed, n, cell, cell_start, cb0, cb1, ch0, ch1, n_cells_h, records, features, rows_db):
    """Reorder the records ``listed[:n]`` (ascending, from the cells ``cb0..cb1`` x ``ch0..ch1``) by cell,
    then base, height and main star (stable): the order of the records before they were sorted by height
    within a cell, so the side-matched triangles (the fallback's hypotheses, whose ties go by position)
    come in the same order as before. ``cell``: scratch of at least ``n`` entries (``vote``'s, not one
    allocation per triangle)."""
    # each record's cell: the records ascend and so do their cells (the cells in the scan's order, column by
    # column), so one walk over the cells finds them all (not a search of every cell per record)
    cb = cb0
    ch = ch0
    for e in range(n):
        r = listed[e]
        c = cb * n_cells_h + ch
        while cb <= cb1 and r >= cell_start[c + 1]:
            ch += 1
            if ch > ch1:
                ch = ch0
                cb += 1
            c = cb * n_cells_h + ch
        cell[e] = c if cb <= cb1 and cell_start[c] <= r else -1
    for k in range(1, n):
        r = listed[k]
        c = cell[k]
        p = k
        while p > 0:
            q = listed[p - 1]
            cq = cell[p - 1]
            after = cq > c or (cq == c and _key_after(q, r, records, features, rows_db))
            if not after:
                break
            listed[p] = q
            cell[p] = cq
            p -= 1
        listed[p] = r
        cell[p] = c


#: slots of :func:`vote`'s table at the start (a power of 2): room for half as many (observed star, catalog row)
#: pairs before it grows; Table 6's images touch a median 221 (paper sky) and 353 (real sky) of them, 90 % at most
#: 739 and 974
VOTE_SLOTS = 1024
#: Fibonacci hashing of a pair key (2^64 / golden ratio, odd): the slot is taken from the product's bits 40 and up,
#: which depend on every bit of the key (the key's low bits alone are the catalog row)
HASH_MUL = np.uint64(11400714819323198485)


@inner
def _slot(table, key1):
    """The slot of the pair key ``key1`` (``(o << 16) + c + 1``, ``c`` < 2^16: uint16 rows) in :func:`vote`'s table
    (``table[e] = (key, votes)``): the one holding it, or the empty one (key 0) where it goes (linear probing;
    ``table.shape[0]`` a power of 2 of at most 2^24, never full). One load per probe, and the pair's votes on the
    same cache line."""
    mask = np.uint64(table.shape[0] - 1)
    e = ((np.uint64(key1) * HASH_MUL) >> np.uint64(40)) & mask
    while True:
        h = table[e, 0]
        if h == 0 or h == key1:
            return np.int64(e)
        e = (e + np.uint64(1)) & mask


@inner
def _rehash(table, touched, n_touched, size):
    """:func:`vote`'s table rebuilt with ``size`` slots (the same pairs and votes) and its list of used slots
    (``touched[:n_touched]``, room for ``size // 2``)."""
    grown = np.zeros((size, 2), dtype=np.int64)
    listed = np.empty(size // 2, dtype=np.int64)
    for k in range(n_touched):
        e = _slot(grown, table[touched[k], 0])
        grown[e, 0] = table[touched[k], 0]
        grown[e, 1] = table[touched[k], 1]
        listed[k] = e
    return grown, listed


@inner
def _span(lo, hi):
    """``(lo, hi - lo)`` of the integer interval ``[lo, hi]`` for :func:`vote`'s one-comparison test
    ``np.uint64(q - lo) <= hi - lo`` (``lo`` int64, the width uint64); an empty interval (``hi < lo``) as
    ``(2^40, 0)``, which no compact value (0..65535) is in."""
    if hi < lo:
        return np.int64(1 << 40), np.uint64(0)
    return np.int64(lo), np.uint64(hi - lo)


@kernel
def vote(v_cam, db, tol, votes, mark):
    """Triangle voting (Fan & Zhong's double feature constraint) over a 2-D grid index.

    ``v_cam`` (n, 3) must be ordered brightest first (the neighbour ranking reads that order).
    For each observed star, the ``n_nbr`` brightest other stars within ``[dmin, pr]`` (widened
    by the base tolerance) form ``C(n_nbr, 2)`` triangles; every catalog triangle within
    ``eps_b`` in base AND ``eps_h`` in height (and, with ``side_check``, whose two
    main-to-neighbour sides match within ``eps_b``, in the better of the two vertex orders)
    votes for its main star, and with ``vote_neighbours`` and matching sides also for its two
    neighbour stars. ``eps_b = k_sigma sqrt(2) sigma``, ``eps_h = k_sigma sigma
    sqrt(1 + t^2 + (1-t)^2)`` (first-order propagation of the per-axis noise ``sigma_chord``).

    Returns ``cand`` (n, n_cand) / ``cand_votes``: per star the rows with the most votes (at
    least ``v_min``, -1 / 0 pad), most votes first, ties by row; ``hyp`` (m, 6): every matched
    record whose sides matched too, as ``(i, row_i, a, row_a, b, row_b)``; ``score`` (m,):
    the votes of its three assignments summed; ``work``: int64 counters of :data:`WORK_COUNTERS`.

    ``votes``, ``mark``: no longer read (the former per-database scratch counters, (n, n_guide) and
    (3, n_guide); the votes are now tallied in a small table of the pairs touched, which stays in
    the first-level cache); kept so that callers and tools keep their signature, left as they are.
    """
    (features, records, rows_db, cell_start, n_cells_b, n_cells_h, cell_b, cell_h, cat_unit, _, _,
     pr_chord, dmin_chord, _, s_b, s_h, s_s) = db
    sigma_chord, k_sigma, _, _, n_nbr, side_check, vote_neighbours, v_min, n_cand, _, _, _ = tol
    n = v_cam.shape[0]
    eps_b = k_sigma * math.sqrt(2.0) * sigma_chord
    lo_d = dmin_chord - eps_b
    hi_d = pr_chord + eps_b
    # the compact records' values are within m_b, m_h, m_s of the float32 ones (the sides also within
    # SIDE_ROUNDING of the exact chords): a test passed or failed by more than that margin is decided
    m_b = REC_MARGIN * s_b
    m_h = REC_MARGIN * s_h
    m_s = REC_MARGIN * s_s + SIDE_ROUNDING
    eps_b_in = eps_b - m_b
    eps_b_out = eps_b + m_b
    eps_near = eps_b + m_s  # a record whose exact sides match (best error <= eps_b) is within this
    inv_b = 1.0 / s_b  # the windows in units of the compact records' scales
    inv_h = 1.0 / s_h
    inv_s = 1.0 / s_s
    e_b_in = eps_b_in * inv_b
    e_b_out = eps_b_out * inv_b
    e_near = eps_near * inv_s
    # the compact records as one flat uint16 array (a view), read in the scan with unsigned indices
    rec_flat = records.reshape(4 * records.shape[0])
    u4 = np.uint64(4)
    u_base = np.uint64(REC_BASE)
    u_height = np.uint64(REC_HEIGHT)
    u_side_i = np.uint64(REC_SIDE_I)
    u_side_j = np.uint64(REC_SIDE_J)
    # the votes of (observed star o, catalog row c): a small open-addressing table, per slot the pair's key
    # (o << 16) + c + 1 (0 = empty) and its votes, side by side (one cache line per vote). Small enough to stay
    # in the first-level cache, where an (n, n_guide) matrix sent each vote to a random line of 1.3 MB; 16 KB
    # zeroed per image, the keys' own (there were also 16 KB of slot indices and 24 KB of touched-pair lists: in
    # the benchmark's interleaved timing every line of scratch is a cold write). tri_u / tri_c: the (vertex, row)
    # pairs the current triangle has voted (one vote per triangle each)
    tri = 0
    table = np.zeros((VOTE_SLOTS, 2), dtype=np.int64)
    touched = np.empty(VOTE_SLOTS // 2, dtype=np.int64)  # the slots in use, in the order of their first vote
    n_touched = 0
    tri_u = np.empty(64, dtype=np.int64)
    tri_c = np.empty(64, dtype=np.int64)
    nbr = np.empty(n_nbr, dtype=np.int64)
    listed = np.empty(256, dtype=np.int64)  # records of one image triangle left for the exact side check
    hyp = np.empty((256, 6), dtype=np.int64)  # side-matched records: (i, c, a, c_a, b, c_b)
    n_hyp = 0
    n_records = 0
    n_matches = 0
    # the image triangles first (in the order they vote: main star, then neighbour pairs), so that the scan
    # of one can ask the CPU for the grid cells and records of the next ones (``starid.kernels.prefetch``): in the
    # benchmark's interleaved timing these come from memory the other plugins evicted
    cap = n * (n_nbr * (n_nbr - 1) // 2)
    g_obs = np.empty((cap, 3), dtype=np.int32)  # i, a, b (int32: fewer scratch bytes to write per image)
    g_cells = np.empty((cap, 4), dtype=np.int32)  # cb0, cb1, ch0, ch1
    g_feat = np.empty((cap, 5))  # base, height, eps_h, d_ia, d_ib
    for i in range(n):
        k = 0
        for j in range(n):
            if k == n_nbr:
                break
            if j == i:
                continue
            d = chord_rows(v_cam, i, v_cam, j)
            if d >= lo_d and d <= hi_d:
                nbr[k] = j
                k += 1
        for p in range(k):
            a = nbr[p]
            for q in range(p + 1, k):
                b = nbr[q]
                base, height, t = triangle_features(v_cam[i], v_cam[a], v_cam[b])
                if base < lo_d:
                    continue
                eps_h = k_sigma * sigma_chord * math.sqrt(1.0 + (1.0 - t) * (1.0 - t) + t * t)
                g_obs[tri, 0] = i
                g_obs[tri, 1] = a
                g_obs[tri, 2] = b
                g_feat[tri, 0] = base
                g_feat[tri, 1] = height
                g_feat[tri, 2] = eps_h
                g_feat[tri, 3] = chord_rows(v_cam, i, v_cam, a)
                g_feat[tri, 4] = chord_rows(v_cam, i, v_cam, b)
                g_cells[tri, 0] = max(int(math.floor((base - eps_b) / cell_b)), 0)
                g_cells[tri, 1] = min(int(math.floor((base + eps_b) / cell_b)), n_cells_b - 1)
                g_cells[tri, 2] = max(int(math.floor((height - eps_h) / cell_h)), 0)
                g_cells[tri, 3] = min(int(math.floor((height + eps_h) / cell_h)), n_cells_h - 1)
                tri += 1
    # each triangle in two steps, one loop turn apart: step 1 (turn g) scans the triangle's grid cells and lists
    # its records near a match, and asks for their guide rows; step 2 (turn g + 1, after the next triangle's
    # step 1) checks their sides and votes. The guide rows then arrive while the next scan runs, instead of
    # each costing a wait (in the benchmark's interleaved timing they come from memory the other plugins
    # evicted). The triangles' step 2 come in the same order, so the votes and hypotheses are the same.
    listed_prev = np.empty(256, dtype=np.int64)  # the records step 1 listed for the previous triangle
    edge = np.empty(256, dtype=np.int64)  # records near a window's edge, decided one turn later (2 r + near)
    edge_prev = np.empty(256, dtype=np.int64)
    n_edge_prev = 0
    cells_of = np.empty(256, dtype=np.int64)  # _by_base's scratch: the cell of each listed record
    n_prev = 0
    n_near = 0
    n_edge = 0
    for g in range(tri + 1):
        if g < tri:
            # ahead: the grid cells' bounds two triangles on, the records of the next triangle's cells
            if g + 2 < tri:
                for cb in range(g_cells[g + 2, 0], g_cells[g + 2, 1] + 1):
                    prefetch(cell_start, cb * n_cells_h + g_cells[g + 2, 2])
                    prefetch(cell_start, cb * n_cells_h + g_cells[g + 2, 3] + 1)
            if g + 1 < tri:
                for cb in range(g_cells[g + 1, 0], g_cells[g + 1, 1] + 1):
                    r1 = cell_start[cb * n_cells_h + g_cells[g + 1, 3] + 1]
                    for r in range(cell_start[cb * n_cells_h + g_cells[g + 1, 2]], r1, 8):  # 8 records a line
                        prefetch(records, r)
                    if r1 > 0:
                        prefetch(records, r1 - 1)
            base = g_feat[g, 0]
            height = g_feat[g, 1]
            eps_h = g_feat[g, 2]
            d_ia = g_feat[g, 3]
            d_ib = g_feat[g, 4]
            cb0 = g_cells[g, 0]
            cb1 = g_cells[g, 1]
            ch0 = g_cells[g, 2]
            ch1 = g_cells[g, 3]
            n_scan = 0
            for cb in range(cb0, cb1 + 1):
                n_scan += cell_start[cb * n_cells_h + ch1 + 1] - cell_start[cb * n_cells_h + ch0]
            n_records += n_scan
            if n_scan + 1 > listed.size:
                listed = np.empty(2 * (n_scan + 1), dtype=np.int64)
            if n_scan + 1 > edge.size:
                edge = np.empty(2 * (n_scan + 1), dtype=np.int64)
            # first pass, branch-free over every record of the cells (about half of them are in both
            # windows: a branch on that is mispredicted half the time), reading only the 8-byte compact
            # records: the records in both windows (decided from the compact values, or for the rare
            # record within their rounding of a window's edge from the float32 ones) whose compact sides
            # come within their rounding of a side match, listed; the second pass checks those sides
            # and votes
            n_near = 0
            n_edge = 0
            # the tests as integer intervals of the compact values: "surely in" (a value inside passes the float32
            # test too: the margins leave more than the float64 rounding of these bounds), "not surely out"
            # (rounded outward), and for the sides "near" (outward: every record whose exact sides match is inside)
            # (in units of the scales, by multiplying with their reciprocals: no division; the rounding of these
            # products, ~1e-11 units, is far inside the margins' 0.001 units of slack, so the bounds still hold)
            q_base = base * inv_b
            q_height = height * inv_h
            q_ia = d_ia * inv_s
            q_ib = d_ib * inv_s
            e_h_in = (eps_h - m_h) * inv_h
            e_h_out = (eps_h + m_h) * inv_h
            # each interval [lo, hi] as (lo, hi - lo): a value q is inside when the unsigned q - lo is at most
            # hi - lo, one comparison instead of two (the same integers, the same outcome; an empty interval
            # becomes one no q of 0..65535 reaches)
            o_b_in, w_b_in = _span(math.ceil(q_base - e_b_in), math.floor(q_base + e_b_in))
            o_b_out, w_b_out = _span(math.floor(q_base - e_b_out), math.ceil(q_base + e_b_out))
            o_h_in, w_h_in = _span(math.ceil(q_height - e_h_in), math.floor(q_height + e_h_in))
            lh_out = math.floor(q_height - e_h_out)
            hh_out = math.ceil(q_height + e_h_out)
            if side_check:
                o_a, w_a = _span(math.floor(q_ia - e_near), math.ceil(q_ia + e_near))
                o_bb, w_bb = _span(math.floor(q_ib - e_near), math.ceil(q_ib + e_near))
            else:  # every record is "near": intervals holding every compact value (0..65535)
                o_a, w_a = np.int64(0), np.uint64(65535)
                o_bb, w_bb = o_a, w_a
            for cb in range(cb0, cb1 + 1):
                # the cells (cb, ch0..ch1) are contiguous in the record order and sorted by height
                # (cell, then height): the records surely below and above the height window are skipped,
                # so every record scanned is within the "not surely out" height bounds (not tested again)
                r0 = cell_start[cb * n_cells_h + ch0]
                r1 = cell_start[cb * n_cells_h + ch1 + 1]
                while r0 < r1 and np.int64(rec_flat[np.uint64(r0) * u4 + u_height]) < lh_out:
                    r0 += 1
                while r1 > r0 and np.int64(rec_flat[np.uint64(r1 - 1) * u4 + u_height]) > hh_out:
                    r1 -= 1
                for r in range(r0, r1):
                    # unsigned indices into the flat view: no negative-index wrap-around code in the loop
                    k = np.uint64(r) * u4
                    qb = np.int64(rec_flat[k + u_base])
                    qh = np.int64(rec_flat[k + u_height])
                    qi = np.int64(rec_flat[k + u_side_i])
                    qj = np.int64(rec_flat[k + u_side_j])
                    in_windows = (np.uint64(qb - o_b_in) <= w_b_in) & (np.uint64(qh - o_h_in) <= w_h_in)
                    near = (((np.uint64(qi - o_a) <= w_a) & (np.uint64(qj - o_bb) <= w_bb))
                            | ((np.uint64(qj - o_a) <= w_a) & (np.uint64(qi - o_bb) <= w_bb)))
                    n_matches += in_windows
                    listed[np.uint64(n_near)] = r
                    n_near += in_windows & near
                    # a record within the rounding of a window's edge (rare): decided from its float32 values
                    # one turn later, when their line has come (each was a wait on memory here), as 2 r + near
                    edge[np.uint64(n_edge)] = 2 * r + near
                    n_edge += (np.uint64(qb - o_b_out) <= w_b_out) & (not in_windows)
            for e in range(n_near):  # their guide rows, read in the next turn's second pass
                prefetch(rows_db, listed[e])
            for e in range(n_edge):
                prefetch(features, edge[e] >> 1)
                prefetch(rows_db, edge[e] >> 1)
        if g == 0:
            listed_prev, listed = listed, listed_prev
            edge_prev, edge = edge, edge_prev
            n_prev = n_near
            n_edge_prev = n_edge
            continue
        # second pass of the previous triangle gp = g - 1 (its records listed one turn ago)
        gp = g - 1
        i = g_obs[gp, 0]
        a = g_obs[gp, 1]
        b = g_obs[gp, 2]
        d_ia = g_feat[gp, 3]
        d_ib = g_feat[gp, 4]
        cb0 = g_cells[gp, 0]
        cb1 = g_cells[gp, 1]
        ch0 = g_cells[gp, 2]
        ch1 = g_cells[gp, 3]
        # the previous triangle's records near a window's edge: the float32 test of the scan (the same values,
        # the same outcome); those inside and near go into the list in its ascending place
        for e in range(n_edge_prev):
            r = edge_prev[e] >> 1
            inside = ((abs(features[r, FEAT_BASE] - g_feat[gp, 0]) <= eps_b)
                      & (abs(features[r, FEAT_HEIGHT] - g_feat[gp, 1]) <= g_feat[gp, 2]))
            n_matches += inside
            if inside and (edge_prev[e] & 1) == 1:
                p = n_prev
                while p > 0 and listed_prev[p - 1] > r:
                    listed_prev[p] = listed_prev[p - 1]
                    p -= 1
                listed_prev[p] = r
                n_prev += 1
        while 2 * (n_touched + 3 * n_prev) > table.shape[0]:  # at most half full after every possible vote
            table, touched = _rehash(table, touched, np.int64(n_touched), 2 * table.shape[0])
        if 3 * n_prev > tri_u.size:
            tri_u = np.empty(3 * n_prev, dtype=np.int64)
            tri_c = np.empty(3 * n_prev, dtype=np.int64)
        n_tri = 0
        while n_hyp + n_prev > hyp.shape[0]:
            grown = np.empty((2 * hyp.shape[0], 6), dtype=np.int64)
            for q in range(n_hyp):
                for col in range(6):
                    grown[q, col] = hyp[q, col]
            hyp = grown
        if n_prev > 1:  # the records in the order of (cell, base, height, main), as they were stored
            if n_prev > cells_of.size:
                cells_of = np.empty(2 * n_prev, dtype=np.int64)
            _by_base(listed_prev, np.int64(n_prev), cells_of, cell_start, cb0, cb1, ch0, ch1, n_cells_h, records,
                     features, rows_db)
        for e in range(n_prev):
            r = listed_prev[e]
            c = rows_db[r, ROW_MAIN]
            ci = rows_db[r, ROW_I]
            cj = rows_db[r, ROW_J]
            # the side check from the compact sides when their rounding cannot change its outcome (both
            # errors and their difference farther than the rounding from the window and from a tie);
            # else exactly, from the guide vectors (three random reads: cold in the interleaved timing)
            s_i = records[r, REC_SIDE_I] * s_s
            s_j = records[r, REC_SIDE_J] * s_s
            e_straight = max(abs(d_ia - s_i), abs(d_ib - s_j))
            e_swapped = max(abs(d_ia - s_j), abs(d_ib - s_i))
            e_best = min(e_straight, e_swapped)
            if abs(e_straight - e_swapped) > 2.0 * m_s and abs(e_best - eps_b) > m_s:
                if e_swapped < e_straight:
                    ci, cj = cj, ci
                sides_match = e_best < eps_b
            else:
                d_ci = chord_rows(cat_unit, c, cat_unit, ci)
                d_cj = chord_rows(cat_unit, c, cat_unit, cj)
                e_straight = max(abs(d_ia - d_ci), abs(d_ib - d_cj))
                e_swapped = max(abs(d_ia - d_cj), abs(d_ib - d_ci))
                if e_swapped < e_straight:
                    ci, cj = cj, ci
                    e_straight = e_swapped
                sides_match = e_straight <= eps_b
            if side_check and not sides_match:
                continue
            n_votes = 3 if vote_neighbours and sides_match else 1
            if sides_match:
                hyp[n_hyp, 0] = i
                hyp[n_hyp, 1] = c
                hyp[n_hyp, 2] = a
                hyp[n_hyp, 3] = ci
                hyp[n_hyp, 4] = b
                hyp[n_hyp, 5] = cj
                n_hyp += 1
            c_main = c
            for u in range(n_votes):  # the three (observed star, catalog row) pairs as scalars, no arrays
                o = i if u == 0 else (a if u == 1 else b)
                c = c_main if u == 0 else (ci if u == 1 else cj)
                again = False  # at most one vote per observed triangle
                for t in range(n_tri):
                    if tri_u[t] == u and tri_c[t] == c:
                        again = True
                        break
                if again:
                    continue
                tri_u[n_tri] = u
                tri_c[n_tri] = c
                n_tri += 1
                key1 = (np.int64(o) << 16) + c + 1
                e = _slot(table, key1)
                if table[e, 0] == 0:
                    table[e, 0] = key1
                    touched[n_touched] = e
                    n_touched += 1
                table[e, 1] += 1
        listed_prev, listed = listed, listed_prev
        edge_prev, edge = edge, edge_prev
        n_prev = n_near
        n_edge_prev = n_edge
    cand = np.full((n, n_cand), -1, dtype=np.int64)
    cand_votes = np.zeros((n, n_cand), dtype=np.int64)
    for k in range(n_touched):
        e = touched[k]
        o = (table[e, 0] - 1) >> 16
        c = (table[e, 0] - 1) & 0xFFFF
        w = table[e, 1]
        # insertion into the top list of o: more votes first, ties by lower catalog row (a strict order, so the
        # lists do not depend on the order the pairs come in)
        pos = n_cand
        while pos > 0 and (cand[o, pos - 1] < 0 or w > cand_votes[o, pos - 1]
                           or (w == cand_votes[o, pos - 1] and c < cand[o, pos - 1])):
            pos -= 1
        if pos == n_cand:
            continue
        for s in range(n_cand - 1, pos, -1):
            cand[o, s] = cand[o, s - 1]
            cand_votes[o, s] = cand_votes[o, s - 1]
        cand[o, pos] = c
        cand_votes[o, pos] = w
    for o in range(n):
        for s in range(n_cand):
            if cand_votes[o, s] < v_min:
                cand[o, s] = -1
                cand_votes[o, s] = 0
    hyp = hyp[:n_hyp]
    score = np.empty(n_hyp, dtype=np.int64)
    for h in range(n_hyp):
        w = 0
        for u in range(3):
            e = _slot(table, (hyp[h, 2 * u] << 16) + hyp[h, 2 * u + 1] + 1)
            if table[e, 0] != 0:
                w += table[e, 1]
        score[h] = w
    work = np.zeros(len(WORK_COUNTERS), dtype=np.int64)
    work[0] = tri
    work[1] = n_records
    work[2] = n_matches
    work[3] = n_hyp
    return cand, cand_votes, hyp, score, work


def new_scratch(n, n_guide):
    """Zeroed scratch counters ``(votes, mark)`` for :func:`vote` on images of up to ``n`` stars."""
    return np.zeros((n, n_guide), dtype=np.int32), np.zeros((3, n_guide), dtype=np.int32)


@inner
def _agree(v_cam, cat_unit, i, ri, j, rj, tol_chord):
    """Whether observed stars ``i``, ``j`` and catalog rows ``ri``, ``rj`` have the same separation."""
    return ri != rj and abs(chord_rows(v_cam, i, v_cam, j) - chord_rows(cat_unit, ri, cat_unit, rj)) <= tol_chord


@inner
def select_candidates(v_cam, cand, cand_votes, cat_unit, tol_chord):
    """Per observed star, the vote candidate best supported by the other stars' candidates.

    The support of row ``c`` for star ``i`` is the number of other stars ``j`` having some
    candidate ``c'`` with the same separation (``|d_ij - d_cc'| <= tol_chord``). The chosen row
    has the largest support, then the most votes, then the lowest row; -1 when no candidate
    is supported. Returns the chosen rows and their votes.
    """
    n, k = cand.shape
    for i in range(n):  # the candidates' guide vectors, read below in no particular order
        for s in range(k):
            if cand[i, s] >= 0:
                prefetch(cat_unit, cand[i, s])
    chosen = np.full(n, -1, dtype=np.int64)
    chosen_votes = np.zeros(n, dtype=np.int64)
    # the separations, each computed once (the same values as ``_agree``'s: a chord is the same
    # number whichever row comes first): observed pairs, and candidate pairs on first use
    d_obs = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            d_obs[i, j] = chord_rows(v_cam, i, v_cam, j)
    # the candidates' guide vectors as float64 rows of one small array (n k x 3, hot), in place of a cache of
    # their separations (an (n k)^2 float64 matrix and its byte mask: in the benchmark's interleaved timing
    # mostly cache lines written cold); each separation is computed from them with chord_rows' arithmetic
    # (float64 of the float32 components), so the same numbers
    cu = np.empty((n * k, 3))
    for i in range(n):
        for s in range(k):
            c = cand[i, s]
            if c >= 0:
                for ax in range(3):
                    cu[i * k + s, ax] = float(cat_unit[c, ax])
    for i in range(n):
        best_support = 0
        for s in range(k):
            c = cand[i, s]
            if c < 0:
                break
            p = i * k + s
            support = 0
            for j in range(n):
                if j == i:
                    continue
                for s2 in range(k):
                    c2 = cand[j, s2]
                    if c2 < 0:
                        break
                    if c2 == c:
                        continue
                    d = chord_rows(cu, p, cu, j * k + s2)
                    if abs(d_obs[i, j] - d) <= tol_chord:
                        support += 1
                        break
            if support > best_support or (support == best_support and support > 0 and (
                    cand_votes[i, s] > chosen_votes[i]
                    or (cand_votes[i, s] == chosen_votes[i] and c < chosen[i]))):
                best_support = support
                chosen[i] = c
                chosen_votes[i] = cand_votes[i, s]
    return chosen, chosen_votes


@kernel
def sky_cell_of(u, n_axis):
    """Cell of a unit vector in the uniform ``n_axis``^3 grid over the cube [-1, 1]^3."""
    ix = min(int((u[0] + 1.0) * 0.5 * n_axis), n_axis - 1)
    iy = min(int((u[1] + 1.0) * 0.5 * n_axis), n_axis - 1)
    iz = min(int((u[2] + 1.0) * 0.5 * n_axis), n_axis - 1)
    return (ix * n_axis + iy) * n_axis + iz


@inner
def _nearest_row(r, db, tol_chord):
    """The only catalog row within ``tol_chord`` of unit vector ``r`` (-1 if none or several)."""
    cat_unit, sky_start, n_axis = db[DB_UNIT], db[DB_SKY_START], db[DB_SKY_AXIS]
    found = -1
    w = 2.0 / n_axis
    # the cell ranges as scalars (two small arrays per call were a measurable part of the fallback)
    lo_x = max(int((r[0] - tol_chord + 1.0) / w), 0)
    hi_x = min(int((r[0] + tol_chord + 1.0) / w), n_axis - 1)
    lo_y = max(int((r[1] - tol_chord + 1.0) / w), 0)
    hi_y = min(int((r[1] + tol_chord + 1.0) / w), n_axis - 1)
    lo_z = max(int((r[2] - tol_chord + 1.0) / w), 0)
    hi_z = min(int((r[2] + tol_chord + 1.0) / w), n_axis - 1)
    for ix in range(lo_x, hi_x + 1):
        for iy in range(lo_y, hi_y + 1):
            for iz in range(lo_z, hi_z + 1):
                cell = (ix * n_axis + iy) * n_axis + iz
                for c in range(sky_start[cell], sky_start[cell + 1]):
                    dx = r[0] - float(cat_unit[c, 0])  # chord(r, cat_unit[c]) without the row view
                    dy = r[1] - float(cat_unit[c, 1])
                    dz = r[2] - float(cat_unit[c, 2])
                    if math.sqrt(dx * dx + dy * dy + dz * dz) <= tol_chord:
                        if found >= 0:
                            return -1
                        found = c
    return found


@inner
def _extend(v_cam, row, db, tol):
    """Extend the consistent set ``row`` (-1 = not in it) by reprojection, in place; returns its size.

    The attitude is solved from the set (SVD,; every other star takes the only
    catalog star within ``radius_chord * sqrt(1 + 1 / set size)`` of its reprojected direction
    (centroid noise plus the attitude's own error) (``cat_unit`` rows are
    sorted by cell of the ``n_axis``^3 sky grid, ``sky_start`` delimiting the cells) when
    that row also agrees in separation with every star of the set and no other star takes it.
    """
    cat_unit = db[DB_UNIT]
    tol_chord = tol[TOL_EPS_CHORD]
    radius_chord = tol[TOL_RADIUS_CHORD]
    n = v_cam.shape[0]
    n_set = 0
    for i in range(n):
        if row[i] >= 0:
            n_set += 1
    if n_set < 2:
        return n_set
    A = wahba_rows(v_cam, row, db[DB_UNIT64])  # ICRS -> camera (float64 copy: the same values, one compilation)
    radius = radius_chord * math.sqrt(1.0 + 1.0 / n_set)
    new = np.full(n, -1, dtype=np.int64)
    r = np.empty(3)
    # every star's reprojected direction first, and a request for its sky cell's bounds, then for that cell's guide
    # vectors: the searches below then find them in cache instead of waiting for each in turn (in the benchmark's
    # interleaved timing they come from memory the other plugins evicted)
    sky_start, n_axis = db[DB_SKY_START], db[DB_SKY_AXIS]
    w = 2.0 / n_axis
    dirs = np.empty((n, 3))
    home = np.empty(n, dtype=np.int64)
    for i in range(n):
        if row[i] >= 0:
            continue
        for p in range(3):
            dirs[i, p] = A[0, p] * v_cam[i, 0] + A[1, p] * v_cam[i, 1] + A[2, p] * v_cam[i, 2]
        home[i] = ((min(max(int((dirs[i, 0] + 1.0) / w), 0), n_axis - 1) * n_axis
                    + min(max(int((dirs[i, 1] + 1.0) / w), 0), n_axis - 1)) * n_axis
                   + min(max(int((dirs[i, 2] + 1.0) / w), 0), n_axis - 1))
        prefetch(sky_start, home[i])
    for i in range(n):
        if row[i] < 0 and sky_start[home[i] + 1] > sky_start[home[i]]:
            prefetch(cat_unit, sky_start[home[i]])
    for i in range(n):
        if row[i] >= 0:
            continue
        for p in range(3):
            r[p] = dirs[i, p]
        c = _nearest_row(r, db, radius)
        if c < 0:
            continue
        ok = True
        for j in range(n):
            if row[j] >= 0 and not _agree(v_cam, cat_unit, i, c, j, row[j], tol_chord):
                ok = False
                break
        if ok:
            new[i] = c
    for i in range(n):
        if new[i] < 0:
            continue
        dup = False
        for j in range(n):
            if j != i and new[j] == new[i]:
                dup = True
                break
        if not dup:
            row[i] = new[i]
            n_set += 1
    return n_set


@inner
def confirm(v_cam, proposed, weight, db, tol, min_stars):
    """Make the verified proposals one consistent set, extend it by reprojection, keep it if large enough.

    1. ``proposed`` (rows or -1, from:func:`starid.kernels.verify_pairwise`) is reduced to a
       set whose every pair agrees in separation: the proposal disagreeing with the most others
       is dropped (ties: lower ``weight``, i.e. fewer votes, then higher index) until none
       disagrees.
    2. The set is extended by reprojection (:func:`_extend`).
    3. Fewer than ``min_stars`` stars in the end: nothing is reported.
    Returns the catalog row per observed star (-1 = none).
    """
    cat_unit = db[DB_UNIT]
    tol_chord = tol[TOL_EPS_CHORD]
    n = v_cam.shape[0]
    row = proposed.copy()
    while True:
        worst = -1
        worst_bad = 0
        for i in range(n):
            if row[i] < 0:
                continue
            bad = 0
            for j in range(n):
                if j != i and row[j] >= 0 and not _agree(v_cam, cat_unit, i, row[i], j, row[j], tol_chord):
                    bad += 1
            if bad > worst_bad or (bad == worst_bad and bad > 0 and weight[i] <= weight[worst]):
                worst = i
                worst_bad = bad
        if worst < 0:
            break
        row[worst] = -1
    if _extend(v_cam, row, db, tol) < min_stars:
        return np.full(n, -1, dtype=np.int64)
    return row


@inner
def best_hypothesis(v_cam, hyp, score, db, tol, min_stars):
    """Fallback when voting and verification found no set: test single matched triangles.

    The ``max_hypotheses`` matched triangles ``hyp`` with the highest ``score`` (ties: lower
    index, i.e. geometric order) are each extended by reprojection (:func:`_extend`). The
    largest result wins if it has at least ``min_stars`` stars and at least one star more than
    every result that assigns differently; otherwise nothing is reported.
    """
    n = v_cam.shape[0]
    order = argsort_desc(score)
    best = np.full(n, -1, dtype=np.int64)
    best_size = 0
    rival_size = 0
    row = np.empty(n, dtype=np.int64)
    for h in order[:tol[TOL_MAX_HYPOTHESES]]:
        for q in range(n):  # a loop, not row[:] = -1 (slice assignment: compile time)
            row[q] = -1
        row[hyp[h, 0]] = hyp[h, 1]
        row[hyp[h, 2]] = hyp[h, 3]
        row[hyp[h, 4]] = hyp[h, 5]
        size = _extend(v_cam, row, db, tol)
        same = True
        for i in range(n):
            if row[i] != best[i]:
                same = False
                break
        if same:
            continue
        if size > best_size:
            rival_size = best_size
            best_size = size
            for q in range(best.shape[0]):
                best[q] = row[q]
        elif size > rival_size:
            rival_size = size
    if best_size < min_stars or best_size <= rival_size:
        return np.full(n, -1, dtype=np.int64)
    return best


@inner
def _any_row(rows):
    """``rows.max() >= 0`` without numpy's reduction machinery (compile time)."""
    for k in range(rows.shape[0]):
        if rows[k] >= 0:
            return True
    return False


# inline="always": identify_image takes its body in numba IR, so it is not compiled and optimised once more as a
# level of its own between identify_image and vote (numba re-optimises every linked callee at each level); tools
# calling it from Python compile it as usual
@inline_kernel
def identify_rows(v_cam, db, tol, votes, mark):
    """The whole identification of one image (``v_cam`` brightest first): ``(rows, work)``, the guide
    row per star or -1 and :func:`vote`'s work counters.

    Voting (:func:`vote`), the best-supported candidate per star (:func:`select_candidates`),
    pairwise verification (``starid.kernels.verify_pairwise``), one consistent set extended by
    reprojection (:func:`confirm`), and when that yields nothing the single-triangle fallback
    (:func:`best_hypothesis`). ``votes``, ``mark``: :func:`vote`'s zeroed scratch (zero again on return).
    """
    cand, cand_votes, hyp, score, work = vote(v_cam, db, tol, votes, mark)
    cat_unit, eps_chord = db[DB_UNIT], tol[TOL_EPS_CHORD]
    chosen, chosen_votes = select_candidates(v_cam, cand, cand_votes, cat_unit, eps_chord)
    verified = verify_pairwise(v_cam, chosen, cat_unit, eps_chord, tol[TOL_MIN_SUPPORT])
    for i in range(chosen.shape[0]):
        if not verified[i]:
            chosen[i] = -1
    rows = confirm(v_cam, chosen, chosen_votes, db, tol, tol[TOL_MIN_STARS])
    if not _any_row(rows) and tol[TOL_MAX_HYPOTHESES] > 0:
        rows = best_hypothesis(v_cam, hyp, score, db, tol, tol[TOL_MIN_STARS] + 1)
    return rows, work



@inner
def _brightest_first(x_px, y_px, mag):
    """``np.lexsort((y_px, x_px, mag))``: the stars by magnitude, then x, then y (stable insertion sort,
    the same order for the few dozen stars of an image)."""
    n = mag.shape[0]
    order = np.empty(n, dtype=np.int64)
    for k in range(n):
        o = k
        p = k
        while p > 0:
            q = order[p - 1]
            after = mag[q] > mag[o] or (mag[q] == mag[o] and (
                x_px[q] > x_px[o] or (x_px[q] == x_px[o] and y_px[q] > y_px[o])))
            if after:
                order[p] = q
                p -= 1
            else:
                break
        order[p] = o
    return order


#: positions in :func:`identify_flat`'s ``params`` of its three bundles' scalars: ``Tables``' (in their order),
#: ``Tolerance``'s, ``identify_image``'s ``fin_cam``'s
PARAMS_DB = tuple(k for k, f in enumerate(Tables._fields) if f in (
    "n_cells_b", "n_cells_h", "cell_b", "cell_h", "sky_axis", "pr_chord", "dmin_chord", "rec_scale_b", "rec_scale_h",
    "rec_scale_s"))
assert PARAMS_DB == (4, 5, 6, 7, 10, 11, 12, 14, 15, 16)  # the order identify_flat rebuilds
PARAMS_TOL = len(PARAMS_DB)
PARAMS_CAM = PARAMS_TOL + len(Tolerance._fields)
#: length of ``fin_cam`` (the camera's ``Frame`` fields, the ``Finish`` rules' fields, ``mag_cut``, ``max_stars``)
N_FIN_CAM = 13


def flat_params(db: tuple, tol: tuple, fin_cam: tuple) -> np.ndarray:
    """:func:`identify_flat`'s ``params``: the scalars of the plain tuples ``db`` (``Tables``), ``tol``
    (``Tolerance``) and ``fin_cam`` as one float64 array (every value exact: floats, small integers, flags 0 / 1)."""
    if len(fin_cam) != N_FIN_CAM:
        raise ValueError("flat_params: not the fin_cam identify_image takes")
    return exact_float64([db[k] for k in PARAMS_DB] + list(tol) + list(fin_cam), "triangle voting's kernel parameters")


@kernel
def identify_flat(x_px, y_px, mag, features, records, rows, cell_start, unit, sky_start, unit64, guide_hip, deep_unit,
                  deep_index, deep_hip, deep_mag, p):
    """:func:`identify_image` with its bundles' arrays as arguments of their own and their scalars in one float64
    array ``p`` (:func:`flat_params`): the same values, the same tuples rebuilt (the same types: one compilation
    of the kernels below), the same result. What ``identify`` calls: the entry converts 15 arrays and one array of
    35 numbers instead of 4 tuples of 13 arrays and 35 Python numbers (issue #25: in the benchmark's interleaved
    timing, with every object cold, the entry of ``identify_image`` took ~20-30 us against ~4 us warm). Returns
    ``identify_image``'s result with ``work`` as its four counters: ``(status, hip, attitude, accepted, triangles,
    records, matches, side_matches, n_named)``."""
    db = (features, records, rows, cell_start, int(p[0]), int(p[1]), p[2], p[3], unit, sky_start, int(p[4]), p[5],
          p[6], unit64, p[7], p[8], p[9])
    t = PARAMS_TOL
    tol = (p[t], p[t + 1], p[t + 2], p[t + 3], int(p[t + 4]), p[t + 5] != 0.0, p[t + 6] != 0.0, int(p[t + 7]),
           int(p[t + 8]), int(p[t + 9]), int(p[t + 10]), int(p[t + 11]))
    c = PARAMS_CAM
    fin_cam = (p[c], p[c + 1], p[c + 2], p[c + 3], p[c + 4], p[c + 5], p[c + 6], p[c + 7], p[c + 8], p[c + 9],
               p[c + 10] != 0.0, p[c + 11], int(p[c + 12]))
    status, hip, attitude, accepted, work, n_named = _identify_image(
        x_px, y_px, mag, db, tol, (unit64, guide_hip, deep_unit, deep_index, deep_hip, deep_mag), fin_cam)
    # the work counters as four numbers (one array fewer to convert for Python)
    return status, hip, attitude, accepted, work[0], work[1], work[2], work[3], n_named


@kernel
def identify_image(x_px, y_px, mag, db, tol, fin_db, fin_cam):
    """:func:`_identify_image` from Python with the plain tuples (the tools call it; ``identify`` calls
    :func:`identify_flat`)."""
    return _identify_image(x_px, y_px, mag, db, tol, fin_db, fin_cam)


# inline="always": identify_flat (and identify_image) take its body in numba IR, as identify_rows'
@inline_kernel
def _identify_image(x_px, y_px, mag, db, tol, fin_db, fin_cam):
    """``identify`` of one image in one call: ``(status, hip, attitude, accepted, work, n_named)``, ``n_named`` the
    number of stars with an id (``hip >= 0``; the wrapper's photometry check reads only small results).

    The stars brightest first (``np.lexsort((y, x, mag))``) with ``mag <= mag_cut``, at most ``max_stars``
    (-1: all); fewer than 3: ``status`` 0. Then :func:`identify_rows` on their camera vectors (no guide row:
    ``status`` 1, ``work`` its counters) and planar_triangle's ``finish`` on every star (``status`` 2).
    ``db``, ``tol``: the plain tuples of :class:`Tables` and :class:`Tolerance`; ``fin_db`` = (guide unit
    vectors float64, guide HIP, deep unit, deep index (``final.deep_index``), deep HIP, deep V); ``fin_cam`` =
    (the camera's ``Frame`` fields, the ``Finish`` rules' fields, ``mag_cut``, ``max_stars``), plain tuples (a
    NamedTuple argument costs about 1 us more per call to dispatch). One call instead of the wrapper's several
    kernel calls.
    """
    unit64, guide_hip, deep_unit, deep_index, deep_hip, deep_mag = fin_db
    (f_px, cx_px, cy_px, width_px, height_px, eps_chord, mag_margin, mag_limit, coverage_mag_margin,
     max_missed_fraction, assign_all, mag_cut, max_stars) = fin_cam
    n = x_px.shape[0]
    order = _brightest_first(x_px, y_px, mag)
    sel = np.empty(n, dtype=np.int64)
    m = 0
    for k in range(n):
        if mag[order[k]] <= mag_cut:
            sel[m] = order[k]
            m += 1
    if max_stars >= 0 and m > max_stars:
        m = max_stars
    if m < 3:
        no_work = np.zeros(len(WORK_COUNTERS), dtype=np.int64)
        return 0, np.full(n, -1, dtype=np.int64), np.zeros((3, 3)), False, no_work, 0
    xs = np.empty(m)
    ys = np.empty(m)
    for k in range(m):
        xs[k] = x_px[sel[k]]
        ys[k] = y_px[sel[k]]
    v_cam = backproject_px(xs, ys, f_px, cx_px, cy_px)
    no_scratch = np.zeros((0, 0), dtype=np.int32)  # vote's former scratch, no longer read
    rows, work = identify_rows(v_cam, db, tol, no_scratch, no_scratch)
    if not _any_row(rows):
        return 1, np.full(n, -1, dtype=np.int64), np.zeros((3, 3)), False, work, 0
    all_rows = np.full(n, -1, dtype=np.int64)
    for k in range(m):
        all_rows[sel[k]] = rows[k]
    hip, attitude, accepted = finish_cone(x_px, y_px, mag, all_rows, unit64, guide_hip, deep_unit, deep_index, deep_hip,
                                          deep_mag,
                                          f_px, cx_px, cy_px, width_px, height_px, eps_chord, mag_margin, mag_limit,
                                          coverage_mag_margin, max_missed_fraction, assign_all)
    n_named = 0
    for k in range(n):
        if hip[k] >= 0:
            n_named += 1
    return 2, hip, attitude, accepted, work, n_named
