"""hoku's query step for the six methods of Galvizo & Lim (2018), searched on starid's catalog.

The paper's query table (``doc/include/floats/query-table.tex`` in ``glennga/hoku`` at 0cb340ec: f = the
share of 2,000 query steps whose candidate set R holds the right catalog set, S = the number with
|R| = 1, no noise) comes from hoku's separate query experiment, not from its identifications:
``Experiment::Query::trial`` (``include/experiment/experiment.h`` at 2a2c1ca156b4) calls
``Query::generate_n_stars`` (``lib/experiment/experiment.cpp`` at e6f6c8afb4e7: every catalog star with
m < 6 within 10 deg of a random centre, shuffled, the first N kept), runs the method's ``query`` on those
N stars and logs ``r.size()`` and whether a row of R is the query's set. This module does that step for
each method with its own features, table and windows, as read in the stored hoku sources
(``lib/identification/{angle,dot-angle,pyramid,spherical-triangle,planar-triangle,base-triangle}.cpp``
at b7d2ff1b9dd1, ``composite-pyramid.cpp`` in its stored version with sigma_1 / sigma_2, the features
of ``lib/math/trio.cpp``); no hoku code is used:

* ANG (``Angle::query``): two stars; every row of K2 (each unordered pair within 20 deg once) whose
  angle is within the window.
* INT (``Dot::query``): three stars, the third the central one c; every ordered row (i, j, c) of K3-bar
  (each trio within 20 deg, once per central star, theta(c, i) < theta(c, j)) with theta_1, theta_2
  (deg) and phi (the angle between the chords i - c and j - c, deg) within the window.
* SPH (``Sphere::query`` -> ``BaseTriangle::e_query``): three stars; spherical area (L'Huilier, sr)
  and spherical polar moment (``Trio::spherical_moment``, depth 3: the triangle cut into 64 by
  great-arc midpoints, each piece's area times the squared angle (rad) from the root's planar
  centroid to its own); every row of K3 (each trio with all sides within 20 deg once, area > 0)
  within the window on both, moment > 0.
* PLN (``Plane::query``): planar area (Heron on the chords) and planar polar moment
  (area x (sum of squared chords) / 36); K3 rows with both > 0.
* COM (``Composite::query``): PLN's features, windows and table (hoku builds it with
  ``Plane::generate_table``), R the raw rows.
* PYR (``Pyramid::query``): three stars i, j, k; the pair windows ij, ik, jk of K2 each flattened
  into a multiset of star labels; T_i = ij & ik, T_j = (ij & jk) - T_i, T_k = (ik & jk) - T_i - T_j
  (multiset intersections; "-" drops every copy); an empty T_j or T_k is the one-label
  ``NO_COMMON_FOUND`` list, R every combination T_i x T_j x T_k (none when T_i is empty, at most
  sql_limit = 5,000 rows): |R| = |T_i| max(|T_j|, 1) max(|T_k|, 1).

The windows are the paper's (Section V-B, "Determining Query sigma"), 3 sigma each:
sigma_theta = 1e-4 deg for ANG / PYR, sigma_theta = sigma_phi = 1e-2 deg for INT, sigma_a =
sigma_tau = 1e-9 for SPH / PLN / COM. The fields are hoku's generator: a uniformly random centre,
every catalog star with V < 6 within 10 deg, at least N (2 for ANG, 3 otherwise), N of them at
random in a random order; no rotation and no noise (the features do not depend on the attitude).
Each method draws from its own stream, ``numpy.random.default_rng([seed, 6, STREAM[method]])``.

|R| is counted as rows (hoku's ``r.size()``) and as distinct catalog sets (they differ only for
INT's K3-bar rows and PYR's combinations). SPH and PLN's ``e_query`` logs an empty R as one row; the
empty count is kept apart (``n_empty``). K3 (12 million trios on 4,560 stars) is not stored: one
pass of a numba kernel enumerates it and matches every query's windows at once.

``benchmarks/tools/galvizo6_query_step.py`` prints the per-seed detail; docs/experiments.md ("The
query table") gives the measurements.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from starid.kernels.jit import kernel

#: hoku's field of view: pairs and trios of the tables are within this of each other (deg).
FOV_DEG = 20.0
#: The query fields: every catalog star within this of a random centre (deg; the paper's psi / 2).
CONE_RADIUS_DEG = FOV_DEG / 2
#: The catalog's magnitude limit (the paper's m < 6) and size (4,560 stars in the paper).
V_MAX = 6.0
N_STARS = 4560
#: The paper's windows (Section V-B), 3 sigma each.
WINDOW_PAIR_DEG = 3 * 1e-4      # ANG, PYR: sigma_theta = 1e-4 deg
WINDOW_INT_DEG = 3 * 1e-2       # INT: sigma_theta = sigma_phi = 1e-2 deg
WINDOW_TRIANGLE = 3 * 1e-9      # SPH (sr, sr rad^2), PLN / COM (unit-sphere chord units): sigma_a = sigma_tau
#: hoku's CONFIG.ini ``sl`` (the most rows a query returns) and ``Sphere::DEFAULT_TD_H``.
SQL_LIMIT = 5000
MOMENT_DEPTH = 3
#: ``NO_COMMON_FOUND``'s label in PYR's combinations.
SENTINEL = -1
METHODS = ("ANG", "INT", "SPH", "PLN", "PYR", "COM")
#: Each method's random stream (the third word of its seed sequence).
STREAM = {"ANG": 0, "INT": 1, "SPH": 2, "PLN": 3, "COM": 4, "PYR": 5}
#: Stars per query.
N_QUERY_STARS = {"ANG": 2, "INT": 3, "SPH": 3, "PLN": 3, "COM": 3, "PYR": 3}
#: The paper's runs per method (S is scaled to this many).
PAPER_RUNS = 2000


# ---------------------------------------------------------------- geometry (numpy, rows of unit vectors)

def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between rows of unit vectors (deg), atan2 form."""
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), (a * b).sum(-1)))


def chord_angle_deg(c: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """hoku's phi (``Trio::dot_angle``): the angle between the normalised chords i - c and j - c (deg)."""
    u = i - c
    w = j - c
    u = u / np.linalg.norm(u, axis=-1, keepdims=True)
    w = w / np.linalg.norm(w, axis=-1, keepdims=True)
    return angle_deg(u, w)


def bright_stars(catalog, n_stars: int | None = N_STARS, v_max: float = V_MAX) -> tuple[np.ndarray, np.ndarray]:
    """Catalog rows of the stars with V < ``v_max`` (the brightest ``n_stars`` of them, all when None),
    in catalog order, and their unit vectors (ICRS, renormalised)."""
    rows = np.nonzero(catalog.v_mag < v_max)[0]
    if n_stars is not None:
        rows = np.sort(rows[np.argsort(catalog.v_mag[rows], kind="stable")[:n_stars]])
    u = np.asarray(catalog.unit_icrs, dtype=np.float64)[rows]
    return rows, u / np.linalg.norm(u, axis=1, keepdims=True)


def _close_pairs(u: np.ndarray, ordered: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs of rows within FOV_DEG (a < b, or both orders), sorted by their angle (deg)."""
    cmin = np.cos(np.radians(FOV_DEG))
    a_all, b_all = [], []
    for lo in range(0, len(u), 512):
        d = u[lo:lo + 512] @ u.T
        a, b = np.nonzero(d >= cmin - 1e-12)
        keep = (a + lo) != b if ordered else (a + lo) < b
        a_all.append(a[keep] + lo)
        b_all.append(b[keep])
    a, b = np.concatenate(a_all), np.concatenate(b_all)
    t = angle_deg(u[a], u[b])
    keep = t <= FOV_DEG if ordered else t < FOV_DEG
    o = np.argsort(t[keep], kind="stable")
    return a[keep][o], b[keep][o], t[keep][o]


class PairTable:
    """K2: every unordered pair (a < b) within FOV_DEG once, sorted by its angle ``t`` (deg)."""

    def __init__(self, u: np.ndarray):
        self.u = u
        self.a, self.b, self.t = _close_pairs(u, ordered=False)
        n = len(u)
        key = self.a.astype(np.int64) * n + self.b
        self._key_order = np.argsort(key, kind="stable")
        self._keys = key[self._key_order]

    def window(self, theta_deg: float) -> slice:
        lo = np.searchsorted(self.t, theta_deg - WINDOW_PAIR_DEG, side="left")
        hi = np.searchsorted(self.t, theta_deg + WINDOW_PAIR_DEG, side="right")
        return slice(lo, hi)

    def windows(self, theta_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Start and stop of each angle's window in the sorted table."""
        return (np.searchsorted(self.t, theta_deg - WINDOW_PAIR_DEG, side="left"),
                np.searchsorted(self.t, theta_deg + WINDOW_PAIR_DEG, side="right"))

    def position(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Each pair's row in the sorted table (-1 when not in K2)."""
        key = np.minimum(a, b).astype(np.int64) * len(self.u) + np.maximum(a, b)
        if self._keys.size == 0:
            return np.full(key.shape, -1, dtype=np.int64)
        k = np.minimum(np.searchsorted(self._keys, key), self._keys.size - 1)
        return np.where(self._keys[k] == key, self._key_order[k], -1)

    def labels(self, theta_deg: float) -> tuple[np.ndarray, np.ndarray]:
        """The window's pairs flattened into a multiset of star labels: sorted labels and their counts."""
        w = self.window(theta_deg)
        return np.unique(np.concatenate([self.a[w], self.b[w]]), return_counts=True)

    def upper_neighbours(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR lists of each row's partners b > a (sorted)."""
        o = np.lexsort((self.b, self.a))
        indptr = np.zeros(len(self.u) + 1, dtype=np.int64)
        np.cumsum(np.bincount(self.a, minlength=len(self.u)), out=indptr[1:])
        return indptr, self.b[o].astype(np.int64)


class TrioTable:
    """K3-bar for INT on unit vectors ``u`` (n, 3), searched through the sorted ordered-pair list."""

    def __init__(self, u: np.ndarray):
        self.u = u
        self.a, self.b, self.t = _close_pairs(u, ordered=True)

    def window(self, theta_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        lo = np.searchsorted(self.t, theta_deg - WINDOW_INT_DEG, side="left")
        hi = np.searchsorted(self.t, theta_deg + WINDOW_INT_DEG, side="right")
        return self.a[lo:hi], self.b[lo:hi], self.t[lo:hi]

    def query(self, t1_deg: float, t2_deg: float, phi_deg: float) -> np.ndarray:
        """Rows (i, j, c) of K3-bar within the windows, as hoku's ``Dot::query`` returns them."""
        if t1_deg > t2_deg:
            t1_deg, t2_deg = t2_deg, t1_deg
        c1, i1, th1 = self.window(t1_deg)
        c2, j2, th2 = self.window(t2_deg)
        none = np.empty((0, 3), dtype=np.int64)
        if c1.size == 0 or c2.size == 0:
            return none
        o = np.argsort(c2, kind="stable")
        c2, j2, th2 = c2[o], j2[o], th2[o]
        lo = np.searchsorted(c2, c1, side="left")
        k = np.searchsorted(c2, c1, side="right") - lo
        rep = np.repeat(np.arange(c1.size), k)
        if rep.size == 0:
            return none
        pos = np.repeat(lo, k) + np.arange(rep.size) - np.repeat(np.cumsum(k) - k, k)
        c, i, j = c1[rep], i1[rep], j2[pos]
        u = self.u
        keep = (i != j) & (th1[rep] < th2[pos]) & (angle_deg(u[i], u[j]) <= FOV_DEG)
        c, i, j = c[keep], i[keep], j[keep]
        keep = np.abs(chord_angle_deg(u[c], u[i], u[j]) - phi_deg) <= WINDOW_INT_DEG
        return np.stack([i[keep], j[keep], c[keep]], axis=1)


def int_features(u: np.ndarray, c: int, i: int, j: int) -> tuple[float, float, float]:
    """theta(c, i), theta(c, j) and phi (deg) of a trio with central star c."""
    return (float(angle_deg(u[c], u[i])), float(angle_deg(u[c], u[j])), float(chord_angle_deg(u[c], u[i], u[j])))


def int_query(table: TrioTable, c: int, i: int, j: int) -> tuple[int, int, int, float]:
    """INT's step: |R| as rows, |R| as distinct sets, whether R holds the set, the longer side (deg)."""
    t1, t2, phi = int_features(table.u, c, i, j)
    rows = table.query(t1, t2, phi)
    sets = np.unique(np.sort(rows, axis=1), axis=0) if rows.size else rows
    has = bool(np.any(np.all(sets == np.sort([c, i, j]), axis=1))) if sets.size else False
    return len(rows), len(sets), int(has), max(t1, t2)


# ---------------------------------------------------------------- triangle features (numba, hoku's formulas)

@kernel
def _norm3(x0, x1, x2):
    return math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)


@kernel
def _arc_rad(x, y):
    """Angle between two (not necessarily unit) vectors (rad), arccos form; NaN past +-1."""
    d = (x[0] * y[0] + x[1] * y[1] + x[2] * y[2]) / (_norm3(x[0], x[1], x[2]) * _norm3(y[0], y[1], y[2]))
    return np.arccos(d)


@kernel
def _planar(b1, b2, b3):
    """Planar area (Heron on the chords) and planar polar moment."""
    a = _norm3(b1[0] - b2[0], b1[1] - b2[1], b1[2] - b2[2])
    b = _norm3(b2[0] - b3[0], b2[1] - b3[1], b2[2] - b3[2])
    c = _norm3(b3[0] - b1[0], b3[1] - b1[1], b3[2] - b1[2])
    s = 0.5 * (a + b + c)
    p = s * (s - a) * (s - b) * (s - c)
    area = math.sqrt(p) if p >= 0 else np.nan
    return area, area * (a * a + b * b + c * c) / 36.0


@kernel
def _spherical_area(b1, b2, b3):
    """L'Huilier's spherical excess (sr); NaN where hoku returns its invalid marker."""
    a, b, c = _arc_rad(b1, b2), _arc_rad(b2, b3), _arc_rad(b3, b1)
    s = 0.5 * (a + b + c)
    f = math.tan(0.5 * s) * math.tan(0.5 * (s - a)) * math.tan(0.5 * (s - b)) * math.tan(0.5 * (s - c))
    if not f >= 0:
        return np.nan
    return 4.0 * math.atan(math.sqrt(f))


@kernel
def _mid(x, y):
    m = x + y
    return m / _norm3(m[0], m[1], m[2])


@kernel
def _spherical_moment(b1, b2, b3, depth):
    """hoku's recursive spherical polar moment: 4**depth pieces (in hoku's order), each piece's area
    times the squared angle (rad) from the root's planar centroid to its planar centroid; NaN unless >= 0."""
    root = (b1 + b2 + b3) / 3.0
    total = 0.0
    for leaf in range(4 ** depth):
        c1, c2, c3 = b1, b2, b3
        for level in range(depth):
            child = (leaf // 4 ** (depth - 1 - level)) % 4
            m12, m13, m23 = _mid(c1, c2), _mid(c1, c3), _mid(c2, c3)
            if child == 0:
                c2, c3 = m12, m13
            elif child == 1:
                c1, c3 = m12, m23
            elif child == 2:
                c1, c2 = m13, m23
            else:
                c1, c2, c3 = m12, m13, m23
        theta = _arc_rad(root, (c1 + c2 + c3) / 3.0)
        total = total + _spherical_area(c1, c2, c3) * theta * theta
    return total if total >= 0 else np.nan


@kernel
def _features(u, stars, spherical, depth):
    """Each query trio's (area, moment): spherical or planar, stars in the query's order."""
    out = np.empty((stars.shape[0], 2))
    for q in range(stars.shape[0]):
        b1, b2, b3 = u[stars[q, 0]], u[stars[q, 1]], u[stars[q, 2]]
        if spherical:
            out[q, 0] = _spherical_area(b1, b2, b3)
            out[q, 1] = _spherical_moment(b1, b2, b3, depth)
        else:
            out[q, 0], out[q, 1] = _planar(b1, b2, b3)
    return out


@kernel
def _match(area, mom, lo, hi, q_mom, truth, i, j, k, eps, rows, has):
    """Count the trio (i, j, k) against every query window holding ``area`` (windows sorted)."""
    first = np.searchsorted(hi, area, side="left")
    last = np.searchsorted(lo, area, side="right")
    for q in range(first, last):
        if abs(mom - q_mom[q]) <= eps:
            rows[q] += 1
            if truth[q, 0] == i and truth[q, 1] == j and truth[q, 2] == k:
                has[q] = 1


@kernel
def _triangle_search(u, indptr, nbr, p_lo, p_hi, p_mom, p_truth, s_lo, s_hi, s_mom, s_truth,
                     do_planar, do_spherical, eps, depth):
    """One pass over K3 (every trio i < j < k whose three pairs are in K2): the planar and spherical
    rows matching each query's windows. ``*_lo`` / ``*_hi`` are the queries' area windows sorted
    ascending, ``*_mom`` their moments, ``*_truth`` their sorted star rows. Returns the rows and
    whether R held the query's set per query, and the numbers of trios, planar and spherical rows."""
    n = u.shape[0]
    mark = np.zeros(n, dtype=np.bool_)
    p_rows = np.zeros(p_lo.size, dtype=np.int64)
    p_has = np.zeros(p_lo.size, dtype=np.int64)
    s_rows = np.zeros(s_lo.size, dtype=np.int64)
    s_has = np.zeros(s_lo.size, dtype=np.int64)
    counts = np.zeros(3, dtype=np.int64)
    for i in range(n):
        for t in range(indptr[i], indptr[i + 1]):
            mark[nbr[t]] = True
        for t in range(indptr[i], indptr[i + 1]):
            j = nbr[t]
            for v in range(indptr[j], indptr[j + 1]):
                k = nbr[v]
                if not mark[k]:
                    continue
                counts[0] += 1
                if do_planar:
                    area, mom = _planar(u[i], u[j], u[k])
                    if area > 0 and mom > 0:
                        counts[1] += 1
                        _match(area, mom, p_lo, p_hi, p_mom, p_truth, i, j, k, eps, p_rows, p_has)
                if do_spherical:
                    area = _spherical_area(u[i], u[j], u[k])
                    if area > 0:
                        counts[2] += 1
                        first = np.searchsorted(s_hi, area, side="left")
                        if first < np.searchsorted(s_lo, area, side="right"):   # a window holds it
                            mom = _spherical_moment(u[i], u[j], u[k], depth)
                            if mom > 0:
                                _match(area, mom, s_lo, s_hi, s_mom, s_truth, i, j, k, eps, s_rows, s_has)
        for t in range(indptr[i], indptr[i + 1]):
            mark[nbr[t]] = False
    return p_rows, p_has, s_rows, s_has, counts


class HokuTables:
    """hoku's tables on the unit vectors ``u``: K2 (:class:`PairTable`), K3-bar (:class:`TrioTable`, built
    when first needed) and K3 (enumerated per search, not stored)."""

    def __init__(self, u: np.ndarray):
        self.u = np.ascontiguousarray(u, dtype=np.float64)
        self.pairs = PairTable(self.u)
        self._trios: TrioTable | None = None
        #: K3's numbers of trios, planar rows and spherical rows, once a search has counted them.
        self.k3_counts: dict[str, int] = {}

    @property
    def trios(self) -> TrioTable:
        if self._trios is None:
            self._trios = TrioTable(self.u)
        return self._trios

    def triangle_search(self, planar: np.ndarray | None = None,
                        spherical: np.ndarray | None = None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """|R| (rows) and whether R holds the set (0 / 1) for query trios (rows of star indices in the
        query's order): ``planar`` on PLN / COM's table, ``spherical`` on SPH's, in one pass over K3.
        Returns ``{"planar": (rows, in_R), "spherical": (rows, in_R)}`` for the kinds given."""
        given = {"planar": planar, "spherical": spherical}
        order, args = {}, []
        for kind, stars in given.items():
            stars = np.ascontiguousarray(np.empty((0, 3)) if stars is None else stars, dtype=np.int64)
            f = _features(self.u, stars, kind == "spherical", MOMENT_DEPTH)
            idx = np.nonzero(np.isfinite(f[:, 0]))[0]       # a query with no area matches nothing
            idx = idx[np.argsort(f[idx, 0], kind="stable")]
            area = f[idx, 0]
            args += [area - WINDOW_TRIANGLE, area + WINDOW_TRIANGLE, np.ascontiguousarray(f[idx, 1]),
                     np.ascontiguousarray(np.sort(stars[idx], axis=1))]
            order[kind] = (len(stars), idx)
        indptr, nbr = self.pairs.upper_neighbours()
        p_rows, p_has, s_rows, s_has, counts = _triangle_search(
            self.u, indptr, nbr, *args, planar is not None, spherical is not None, WINDOW_TRIANGLE, MOMENT_DEPTH)
        self.k3_counts["trios"] = int(counts[0])
        found = {"planar": (p_rows, p_has, counts[1]), "spherical": (s_rows, s_has, counts[2])}
        result = {}
        for kind, stars in given.items():
            if stars is None:
                continue
            n_q, idx = order[kind]
            rows_sorted, has_sorted, n_rows = found[kind]
            self.k3_counts[kind] = int(n_rows)
            rows, has = np.zeros(n_q, dtype=np.int64), np.zeros(n_q, dtype=np.int64)
            rows[idx], has[idx] = rows_sorted, has_sorted
            result[kind] = (rows, has)
        return result


# ---------------------------------------------------------------- the query step

def draw_queries(u: np.ndarray, method: str, n_queries: int, seed: int) -> np.ndarray:
    """hoku's query stars for ``method``: ``n_queries`` rows of 2 (ANG) or 3 star indices of ``u``, each
    from a cone field (every star within CONE_RADIUS_DEG of a uniformly random centre, redrawn while it
    holds fewer), in random order; all draws from ``default_rng([seed, 6, STREAM[method]])``."""
    rng = np.random.default_rng([seed, 6, STREAM[method]])
    need = N_QUERY_STARS[method]
    cmin = math.cos(math.radians(CONE_RADIUS_DEG))
    out = np.empty((n_queries, need), dtype=np.int64)
    n = 0
    while n < n_queries:    # one query per pass: each draw depends on the field the last one gave
        centre = rng.normal(size=3)
        centre /= np.linalg.norm(centre)
        field = np.nonzero(u @ centre > cmin)[0]
        if field.size < need:
            continue
        out[n] = rng.permutation(field)[:need]
        n += 1
    return out


def longest_side_deg(u: np.ndarray, stars: np.ndarray) -> np.ndarray:
    """Each query's longest side (deg)."""
    sides = [angle_deg(u[stars[:, p]], u[stars[:, (p + 1) % stars.shape[1]]]) for p in range(stars.shape[1])]
    return np.max(sides, axis=0)


def _pyramid_one(pairs: PairTable, u: np.ndarray, s: np.ndarray) -> tuple[int, int, int, int]:
    """hoku's ``Pyramid::query`` on stars s = (i, j, k): rows, distinct sets (-1 past SQL_LIMIT), whether
    R holds the set, and whether a set difference removed a true star (1: J in T_i; 2: K in T_i or T_j)."""
    th = angle_deg(u[s[[0, 0, 1]]], u[s[[1, 2, 2]]])
    (ij, n_ij), (ik, n_ik), (jk, n_jk) = (pairs.labels(float(t)) for t in th)

    def inter(x, nx, y, ny):
        keep_x, keep_y = np.isin(x, y), np.isin(y, x)
        return x[keep_x], np.minimum(nx[keep_x], ny[keep_y])

    t_i, n_i = inter(ij, n_ij, ik, n_ik)
    t_j, n_j = inter(ij, n_ij, jk, n_jk)
    keep = ~np.isin(t_j, t_i)
    t_j, n_j = t_j[keep], n_j[keep]
    t_k, n_k = inter(ik, n_ik, jk, n_jk)
    keep = ~np.isin(t_k, t_i) & ~np.isin(t_k, t_j)
    t_k, n_k = t_k[keep], n_k[keep]
    sum_i, sum_j, sum_k = int(n_i.sum()), int(n_j.sum()), int(n_k.sum())
    removed = 1 if s[1] in t_i else 2 if (s[2] in t_i or s[2] in t_j) else 0
    if sum_i == 0:
        return 0, 0, 0, removed
    rows = min(sum_i * max(sum_j, 1) * max(sum_k, 1), SQL_LIMIT)
    t_j = t_j if sum_j else np.array([SENTINEL])
    t_k = t_k if sum_k else np.array([SENTINEL])
    has = any(s[a] in t_i and s[b] in t_j and s[c] in t_k
              for a, b, c in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)))
    sets = -1
    if rows < SQL_LIMIT:
        combos = np.stack(np.meshgrid(t_i, t_j, t_k, indexing="ij"), axis=-1).reshape(-1, 3)
        sets = len(np.unique(np.sort(combos, axis=1), axis=0))
    return rows, sets, int(has), removed


def query_results(tables: HokuTables, method: str, stars: np.ndarray) -> pd.DataFrame:
    """One row per query of ``method`` on the query stars ``stars`` (from :func:`draw_queries`): ``rows``
    (|R| as hoku's ``r.size()``, 0 when empty), ``sets`` (distinct catalog sets), ``in_R`` (1 when R
    holds the query's set), ``removed`` (PYR: a true star dropped by a set difference, 1 / 2; else 0)
    and ``longest_side_deg``."""
    u, n = tables.u, len(stars)
    removed = np.zeros(n, dtype=np.int64)
    if method == "ANG":
        lo, hi = tables.pairs.windows(angle_deg(u[stars[:, 0]], u[stars[:, 1]]))
        pos = tables.pairs.position(stars[:, 0], stars[:, 1])
        rows = sets = hi - lo
        has = ((pos >= lo) & (pos < hi)).astype(np.int64)
    elif method == "INT":
        r = np.array([int_query(tables.trios, c, i, j)[:3] for i, j, c in stars.tolist()], dtype=np.int64)
        rows, sets, has = r.T if n else np.zeros((3, 0), dtype=np.int64)
    elif method == "PYR":
        r = np.array([_pyramid_one(tables.pairs, u, s) for s in stars], dtype=np.int64).reshape(n, 4)
        rows, sets, has, removed = r.T
    elif method in ("PLN", "COM", "SPH"):
        kind = "spherical" if method == "SPH" else "planar"
        rows, has = tables.triangle_search(**{kind: stars})[kind]
        sets = rows
    else:
        raise ValueError(f"unknown method {method!r}; valid: {', '.join(METHODS)}")
    return pd.DataFrame({"rows": rows, "sets": sets, "in_R": has, "removed": removed,
                         "longest_side_deg": longest_side_deg(u, stars)})


def interval(k: int, n: int, scale: float = 1.0) -> tuple[float, float]:
    """A count k of n as ``scale`` x share, and the half-width of its 95 % interval (normal approximation)."""
    p = k / n
    return scale * p, 1.96 * scale * math.sqrt(max(p * (1 - p), 0.0) / n)


def summary(method: str, r: pd.DataFrame) -> dict:
    """f, S (rows and sets, scaled to the paper's 2,000 runs) and their intervals for one method's queries."""
    n = len(r)
    f, f_ci = interval(int(r["in_R"].sum()), n)
    s, s_ci = interval(int((r["rows"] == 1).sum()), n, PAPER_RUNS)
    return {"method": method, "n_queries": n, "f": f, "f_ci95": f_ci, "S_rows": s, "S_rows_ci95": s_ci,
            "S_sets": PAPER_RUNS * float((r["sets"] == 1).mean()), "n_empty": int((r["rows"] == 0).sum()),
            "mean_R_rows": float(r["rows"].mean())}


def query_step(catalog, n_queries: int = PAPER_RUNS, seed: int = 0, n_stars: int | None = N_STARS,
               methods: tuple[str, ...] = METHODS) -> pd.DataFrame:
    """hoku's query step for each method on the brightest ``n_stars`` stars of ``catalog`` with V < 6:
    one row per method with ``f`` (share of queries whose R holds the set), ``S_rows`` (queries with
    |R| = 1 as rows, scaled to 2,000), ``S_sets`` (as distinct sets), their 95 % intervals, ``n_empty``
    and ``mean_R_rows``, and ``n_queries``. The triangle methods share one pass over K3."""
    _, u = bright_stars(catalog, n_stars)
    tables = HokuTables(u)
    stars = {m: draw_queries(u, m, n_queries, seed) for m in methods}
    tri = {}
    planar = [m for m in methods if m in ("PLN", "COM")]
    if planar or "SPH" in methods:
        found = tables.triangle_search(planar=np.concatenate([stars[m] for m in planar]) if planar else None,
                                       spherical=stars["SPH"] if "SPH" in methods else None)
        for k, m in enumerate(planar):
            part = slice(k * n_queries, (k + 1) * n_queries)
            tri[m] = (found["planar"][0][part], found["planar"][1][part])
        if "SPH" in methods:
            tri["SPH"] = found["spherical"]
    out = []
    for m in methods:
        if m in tri:
            rows, has = tri[m]
            r = pd.DataFrame({"rows": rows, "sets": rows, "in_R": has})
        else:
            r = query_results(tables, m, stars[m])
        out.append(summary(m, r))
    return pd.DataFrame(out)
