"""The triangle-voting plugin class: parameters, database build, identify."""

from __future__ import annotations

import math
import threading
import weakref
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.spatial import cKDTree
from starid_algorithms.planar_triangle.kernels import Finish, deep_v_mag

from starid.camera import Camera
from starid.catalog import Catalog
from starid.errors import ConfigError
from starid.kernels import DeepSky, backproject_px, camera_frame, deep_sky, rad_to_chord
from starid.observation import Observation
from starid.params import check_flag, check_number, check_whole, param
from starid.plugin import Algorithm, Database, Explanation, Identification

from .final import band_order, deep_index
from .kernels import (
    FEAT_BASE,
    FEAT_HEIGHT,
    WORK_COUNTERS,
    Tables,
    Tolerance,
    build_triangles,
    compact_records,
    feature_columns,
    flat_params,
    identify_flat,
    new_scratch,
    record_sides,
    row_columns,
    sky_cell_of,
    vote,
)

MAX_GUIDE_STARS = np.iinfo(np.uint16).max
SKY_AXIS = 20  # sky grid cells per axis of [-1, 1]^3 (cell 0.1 ~ 5.7 deg), for reprojection


SIGMA_FLOOR_PX = 1.0  # smallest centroid noise the windows assume (px)


@dataclass(frozen=True, eq=False)
class TriangleVotingDatabase(Database):
    """Triangle records indexed on a 2-D (base, height) grid, plus the guide stars.

    Record ``r`` (sorted by grid cell, ``cell = cell_b_index * n_cells_h + cell_h_index``, then height):
    ``features[r]`` = (base, height) (float32, chord units ~ radians; the columns are also the properties
    ``base``, ``height``), ``records[r]`` the same two and the record's two main-to-neighbour chords (the
    properties ``side_i``, ``side_j``) as uint16 multiples of ``rec_scale_b``, ``rec_scale_h``, ``rec_scale_s``
    (``kernels.compact_records``), ``main[r]``, ``n_i[r]``,
    ``n_j[r]`` (uint16 rows of the guide arrays). The records of cell ``c`` are
    ``cell_start[c]:cell_start[c + 1]``. ``unit_icrs`` (float32) and ``hip`` (int64) are the
    guide stars, sorted by cell of a uniform ``sky_axis``^3 grid over [-1, 1]^3 (ties by HIP);
    the stars of sky cell ``c`` are rows ``sky_start[c]:sky_start[c + 1]``. ``deep``
    (``starid.kernels.DeepSky``) and ``deep_v_mag`` (float32 V) are every catalog star, for the
    final assignment and the coverage check.
    """

    #: float32 (m, 2) per record base, height: ``vote`` reads them only near a window's edge
    features: np.ndarray
    #: uint16 (m, 4) per record base, height, side_i, side_j rounded: one 8-byte row per record, what ``vote``'s
    #: scan reads (the former 16-byte float32 rows: twice the cache lines, from memory other plugins evicted)
    records: np.ndarray
    #: uint16 (m, 3) per record the guide rows of its main star and two neighbours (the properties ``main``,
    #: ``n_i``, ``n_j``): one row, so a record the vote lists costs one cache line, not three
    rows: np.ndarray
    cell_start: np.ndarray
    unit_icrs: np.ndarray
    hip: np.ndarray
    sky_start: np.ndarray
    sky_axis: int
    cell_b: float
    cell_h: float
    n_cells_b: int
    n_cells_h: int
    pattern_radius_chord: float
    d_min_chord: float
    deep: DeepSky
    deep_v_mag: np.ndarray
    #: int32 (DEEP_BANDS * KEY_BUCKETS + 1,) first row of ``deep`` of each (z band, right-ascension bucket) cell
    #: (``final.deep_index``): where the final step's cone searches start
    deep_index: np.ndarray
    rec_scale_b: float  # the scales of ``records``: base, height, sides (chord units per unit)
    rec_scale_h: float
    rec_scale_s: float

    base, height, side_i, side_j = feature_columns("unit_icrs")   # the columns of ``features``, the sides
    main, n_i, n_j = row_columns()   # the columns of ``rows``

    def tables(self) -> Tables:
        """The arrays the kernels read, as one bundle (made once per database, see ``_tables``)."""
        return _tables(self)


_TABLES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _tables(db: TriangleVotingDatabase) -> Tables:
    """The kernels' bundle of ``db``, made once per database."""
    return _bundles(db)[0]


def _kernel_tables(db: TriangleVotingDatabase) -> tuple:
    """``_tables(db)`` as the plain tuple the kernels are called with (cheaper to dispatch)."""
    return _bundles(db)[1]


def _bundles(db: TriangleVotingDatabase) -> tuple[Tables, tuple]:
    held = _TABLES.get(db)
    if held is None:
        tables = Tables(db.features, db.records, db.rows, db.cell_start, db.n_cells_b,
                        db.n_cells_h, db.cell_b, db.cell_h, db.unit_icrs, db.sky_start, db.sky_axis,
                        db.pattern_radius_chord, db.d_min_chord, _unit_f64(db), db.rec_scale_b, db.rec_scale_h,
                        db.rec_scale_s)
        held = _TABLES[db] = (tables, tuple(tables))
    return held


_SCRATCH = threading.local()


def _scratch(db: TriangleVotingDatabase, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The vote kernel's zeroed scratch counters for images of ``n`` stars on ``db``, kept per
    database and thread (the kernel leaves them zero; allocating and zeroing ``n x n_guide``
    counters per image was a large part of an identification)."""
    held = getattr(_SCRATCH, "held", None)
    if held is None:
        held = _SCRATCH.held = weakref.WeakKeyDictionary()
    votes, mark = held.get(db, (None, None))
    if votes is None or votes.shape[0] < n:
        votes, mark = new_scratch(max(n, 64), db.unit_icrs.shape[0])
        held[db] = (votes, mark)
    return votes, mark


_UNIT_F64: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_FINISH_TABLES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _finish_tables(db: TriangleVotingDatabase) -> tuple:
    """``identify_image``'s ``fin_db``: the guide unit vectors as float64 (``_unit_f64``), the guide HIP,
    the deep sky's unit vectors and HIP and its V, as one plain tuple made once per database."""
    held = _FINISH_TABLES.get(db)
    if held is None:
        held = _FINISH_TABLES[db] = (_unit_f64(db), db.hip, db.deep.unit, db.deep_index, db.deep.hip, db.deep_v_mag)
    return held


def _unit_f64(db: TriangleVotingDatabase) -> np.ndarray:
    """The guide unit vectors as float64, made once per database: ``finish`` (shared with planar_triangle)
    is then compiled for planar_triangle's float64 catalogue only, not again for float32 (1.3 CPU s on a
    cold cache). The same numbers: the attitude solver reads each component as a float64 anyway."""
    unit = _UNIT_F64.get(db)
    if unit is None:
        unit = _UNIT_F64[db] = np.ascontiguousarray(db.unit_icrs, dtype=np.float64)
    return unit


@dataclass(frozen=True)
class TriangleVoting(Algorithm):
    """Triangle voting with double (base, height) feature constraints (Fan & Zhong, Adv. Space Res. 2018).

    Fan Q., Zhong X., Adv. Space Res. 61(4):1132-1142, 2018.

    From the paper (abstract and section 2.1.1, the only parts at hand): every star ``S`` builds
    triangles with its ``n_neighbours`` (the paper's lambda) brightest neighbours lying between
    ``d_min_deg`` (D_min) and ``pattern_radius_deg`` (PR) from it (the separations of its
    eq. 1); each triangle is reduced to two features, base and height; a catalog star may vote
    for a sensor star only when one of its triangles satisfies both features (the double
    feature constraint); the candidates with the most votes go on to verification.

    Reconstructed (see docs/algorithms/triangle_voting.md; the paper's values of PR, lambda and D_min were
    not at hand, so the defaults are this library's choices):

    * features: base = chord between the two neighbours, height = distance of ``S`` from the
      line through them (2 x area / base of the planar triangle of unit vectors), so ``S`` is
      the apex and the features do not depend on the neighbours' order ('opposite_main'
      reading); computed in 3-D on both sides, so no tangent-plane step;
    * ``d_min_deg`` also bounds the base, in the database and in the image;
      guide stars closer than ``double_star_deg`` to a brighter one are dropped;
    * database: C(lambda, 2) records (base, height, main, n_i, n_j) per guide star
      (V <= ``mag_limit``), float32 features and uint16 rows, on a uniform 2-D grid of cell
      ``grid_cell_tol`` x eps_base (measured 2.7x faster than a k-vector on base plus a
      height filter, and smaller);
    * ``sigma_px = None`` follows the simulator's centroid noise (``follows``); the windows assume
      ``max(sigma_px, 1)`` px (``SIGMA_FLOOR_PX``: a noise-free world still needs a window, and at
      <= 1 px the results are those of the former fixed 1 px);
    * tolerances from the centroid noise, sigma = ``sigma_px`` / f_px per axis:
      eps_base = ``k_sigma`` sqrt(2) sigma (also for any separation), eps_height =
      ``k_sigma`` sigma sqrt(1 + t^2 + (1-t)^2) with ``t`` the foot of the height on the base;
    * image side: each star uses its ``n_neighbours + lambda_extra`` brightest image neighbours,
      against magnitude noise, stars fainter than the guide limit pushed into
      the image by it, and pattern neighbours outside the image;
    * voting: a record within both tolerances votes once per observed triangle for its main
      star. With ``side_check`` it votes only if the main-to-neighbour sides match too (a third
      test on the triangle's third degree of freedom; False = the paper's double constraint
      alone); with ``vote_neighbours`` a record whose sides match also votes for its two
      neighbour stars (optional extension). The ``n_candidates`` rows with the most
      votes (at least ``v_min``) are each star's candidates;
    * verification: per star the candidate agreeing in separation
      with the most other stars' candidates is proposed, then pairwise angular consistency
      (``starid.kernels.verify_pairwise``, ``min_support`` partners); the survivors are reduced
      to a set whose every pair agrees, the attitude is solved from it (SVD) and every other
      star takes the only guide star within ``k_sigma`` sigma sqrt(1 + 1/set size) of its
      reprojected direction; the image is reported only with at least
      ``min_stars`` stars (3 mutually consistent stars are too often a chance match);
    * fallback when that yields nothing: the ``max_hypotheses`` best-voted side-matched
      triangles are each extended by reprojection; the largest result is reported if it has at
      least ``min_stars + 1`` stars (one more, as many hypotheses are tried) and beats every
      differing result.

    * coverage check (this library's, against chance matches; ``max_missed_fraction = 1`` turns
      it off; shared with planar_triangle, ``finish`` in ``starid_algorithms.planar_triangle.kernels``): the
      attitude of the final set must explain the bright stars of its field -- of the catalog
      stars with V <= min(``mag_limit``, faintest image star) - ``coverage_mag_margin`` it puts on
      the sensor, at most max(1, ``max_missed_fraction`` x their number) may lack an identified
      star. Without it 4 of 40 fields of 30 uniform random points got a 4-star
      "identification", and a noise-free image (seed 7, trial 222) a wrong one.
    * photometry of a minimal result (this library's, issue 26): a result of at most ``min_stars``
      ids is dropped when its catalog stars are on average more than ``mag_margin`` fainter than
      measured (``_photometry_agrees``); 2 of 200 fields of 10 to 40 random points were named without it.
    * ``mag_limit = 6.5`` (reconstructed; was 6.0): the guide stars. In the V <= 8 sky a field
      with <= 6 guide stars to V 6 fails often (3 of them: always); to V 6.5 the rate goes from
      92.8 % to 97.8 % (seed 7, 500 images, 1 px / 0.5 Mv) for 1.6 MB instead of 0.9 MB.
    * ``max_stars = None``, ``mag_margin = 1.0``: only image stars with measured magnitude <=
      ``mag_limit + mag_margin`` vote, at most the ``max_stars`` brightest; a cap does not help
      here (8: 80.6 %, 12: 89.8 %, none: 92.8 % at V <= 6, seed 7), the neighbour choice is
      already brightest first.
    * ``assign_all`` (default on): once the attitude is known every other image star gets the
      catalog star (any V) projecting within eps_base of it (``starid.kernels.reproject_assign``),
      unless that star is more than ``mag_margin`` fainter than measured (false stars otherwise
      land on faint catalog stars: misid 0.7 % -> 2.3 % with 3 false stars).

    Without ``assign_all`` only stars of the final consistent set get an id; the rest get -1.
    Method step by step, parameters, paper vs reconstructed and measurements:
    ``docs/algorithms/triangle_voting.md``.
    """

    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}
    name: ClassVar[str] = "triangle_voting"

    mag_limit: float = param(6.5, help="guide stars have V <= this (starid's reconstruction)", unit="mag")
    sigma_px: float | None = param(None, unit="px",
                                   help="centroid noise the windows assume; None follows the simulator (floor 1 px)")
    pattern_radius_deg: float = param(
        5.0, help="PR: neighbours lie within this of the main star (paper's parameter, starid's value)", unit="deg")
    d_min_deg: float = param(
        0.3, help="D_min: least main-neighbour distance and least base (paper's parameter, starid's value)", unit="deg")
    n_neighbours: int = param(
        5, help="lambda: brightest neighbours a star's triangles use (paper's parameter, starid's value)")
    lambda_extra: int = param(
        2, help="extra brightest neighbours on the image side, against noise and edges (starid's reconstruction)")
    k_sigma: float = param(3.0, help="tolerances in units of the propagated centroid sigma (starid's reconstruction)")
    double_star_deg: float = param(
        0.05, help="guide stars closer than this to a brighter one are dropped (starid's reconstruction)", unit="deg")
    grid_cell_tol: float = param(1.0, help="database grid cell side in units of eps_base (starid's reconstruction)")
    side_check: bool = param(
        True,
        help="a record votes only if its main-to-neighbour sides match too; False = paper (starid's reconstruction)")
    vote_neighbours: bool = param(
        True, help="a side-matched record also votes for its two neighbour stars (starid's extension)")
    v_min: int = param(2, help="least votes a candidate needs (starid's reconstruction)")
    min_support: int = param(
        2, help="partners a proposed star must agree with in the pairwise check (starid's reconstruction)")
    n_candidates: int = param(3,
                              help="most-voted catalog stars kept as each star's candidates (starid's reconstruction)")
    min_stars: int = param(4, help="least stars an identification must report (starid's reconstruction)")
    max_hypotheses: int = param(
        32,
        help="best-voted side-matched triangles extended when verification yields nothing (starid's reconstruction)")
    coverage_mag_margin: float = param(
        0.75, unit="mag",
        help="coverage check: catalog stars this much brighter than the limit must be seen (starid's reconstruction)")
    max_missed_fraction: float = param(
        1.0 / 3.0,
        help="coverage check: largest fraction of those bright stars missed; 1 = off (starid's reconstruction)")
    max_stars: int | None = param(None, help="brightest image stars that vote; None = all (starid's reconstruction)")
    mag_margin: float = param(1.0, unit="mag",
                              help="image stars fainter than mag_limit + this do not vote (starid's reconstruction)")
    assign_all: bool = param(
        True, help="assign every other image star the catalog star the attitude projects on it (starid's extension)")

    @property
    def sigma_window_px(self) -> float:
        """The centroid noise the windows assume: ``sigma_px`` (the simulator's when None), at least
        ``SIGMA_FLOOR_PX`` so that a noise-free world still gets a window."""
        return max(self.sigma_px or 0.0, SIGMA_FLOOR_PX)

    def __post_init__(self):
        check_number("mag_limit", self.mag_limit)
        if self.sigma_px is not None:
            check_number("sigma_px (or None: follow the simulator)", self.sigma_px, lo=0)
        check_number("pattern_radius_deg", self.pattern_radius_deg, lo=0, hi=90, lo_open=True)
        check_number("d_min_deg", self.d_min_deg, lo=0)
        if self.d_min_deg >= self.pattern_radius_deg:
            raise ConfigError(f"d_min_deg ({self.d_min_deg}) must be smaller than pattern_radius_deg "
                              f"({self.pattern_radius_deg})")
        check_whole("n_neighbours", self.n_neighbours, 2)
        check_whole("lambda_extra", self.lambda_extra, 0)
        check_number("k_sigma", self.k_sigma, lo=0, lo_open=True)
        check_number("double_star_deg", self.double_star_deg, lo=0)
        check_number("grid_cell_tol", self.grid_cell_tol, lo=0, lo_open=True)
        for name in ("side_check", "vote_neighbours"):
            check_flag(name, getattr(self, name))
        check_whole("v_min", self.v_min, 1)
        check_whole("min_support", self.min_support, 1)
        check_whole("n_candidates", self.n_candidates, 2)
        check_whole("min_stars", self.min_stars, 2)
        check_whole("max_hypotheses", self.max_hypotheses, 0)
        check_number("coverage_mag_margin", self.coverage_mag_margin)
        check_number("max_missed_fraction", self.max_missed_fraction, lo=0, hi=1)
        if self.max_stars is not None:
            check_whole("max_stars (or None: every star)", self.max_stars, 3)
        check_number("mag_margin", self.mag_margin, lo=0)
        check_flag("assign_all", self.assign_all)

    def _tolerance_chord(self, f_px: float) -> float:
        """eps_base = k_sigma sqrt(2) sigma: base, side and pairwise-distance tolerance ."""
        return self.k_sigma * math.sqrt(2.0) * self.sigma_window_px / f_px

    # -- database ---------------------------------------------------------------------------
    def build(self, catalog: Catalog, camera: Camera) -> TriangleVotingDatabase:
        guide = catalog.brighter_than(self.mag_limit)
        if self.double_star_deg > 0 and len(guide) > 1:
            # the fainter member of a pair closer than double_star_deg is dropped
            pairs = cKDTree(guide.unit_icrs).query_pairs(rad_to_chord(math.radians(self.double_star_deg)),
                                                        output_type="ndarray")
            if pairs.size:
                i, j = pairs[:, 0], pairs[:, 1]
                i_fainter = (guide.v_mag[i] > guide.v_mag[j]) | ((guide.v_mag[i] == guide.v_mag[j])
                                                                  & (guide.hip[i] > guide.hip[j]))
                drop = np.unique(np.where(i_fainter, i, j))
                guide = guide.subset(np.setdiff1d(np.arange(len(guide)), drop))
        n = len(guide)
        if n >= MAX_GUIDE_STARS:
            raise ConfigError(f"{n} guide stars at mag_limit={self.mag_limit} exceed the uint16 rows "
                              f"({MAX_GUIDE_STARS}); lower mag_limit")
        # guide rows sorted by sky cell (then HIP), so a sky cell is one slice of rows
        sky = np.array([sky_cell_of(u, SKY_AXIS) for u in guide.unit_icrs], dtype=np.int64)
        by_sky = np.lexsort((guide.hip, sky))
        sky_start = np.searchsorted(sky[by_sky], np.arange(SKY_AXIS ** 3 + 1)).astype(np.int32)
        unit = np.ascontiguousarray(guide.unit_icrs[by_sky])
        hip = guide.hip[by_sky]
        v_mag = guide.v_mag[by_sky]
        pr_chord = rad_to_chord(math.radians(self.pattern_radius_deg))
        dmin_chord = rad_to_chord(math.radians(self.d_min_deg))
        lists = cKDTree(unit).query_ball_point(unit, pr_chord)
        counts = np.fromiter((len(x) for x in lists), dtype=np.int64, count=n)
        nbr_ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        nbr_idx = np.fromiter((j for x in lists for j in x), dtype=np.int64, count=int(nbr_ptr[-1]))
        # brightness rank, ties broken by HIP so the patterns do not depend on catalog order
        rank = np.empty(n, dtype=np.int64)
        rank[np.lexsort((hip, v_mag))] = np.arange(n)
        base, height, main, n_i, n_j = build_triangles(unit, rank, nbr_ptr, nbr_idx,
                                                              int(self.n_neighbours), dmin_chord)
        cell = self.grid_cell_tol * self._tolerance_chord(camera.f_px)
        base32 = base.astype(np.float32)
        height32 = height.astype(np.float32)
        cb = np.floor(base32 / cell).astype(np.int64)
        ch = np.floor(height32 / cell).astype(np.int64)
        n_cells_b = int(cb.max()) + 1 if cb.size else 1
        n_cells_h = int(ch.max()) + 1 if ch.size else 1
        cell_id = cb * n_cells_h + ch
        # by cell, then height (then base, main): a grid column's cells are one run of rising height, so
        # vote skips the records below and above its height window
        order = np.lexsort((main, base32, height32, cell_id))
        cell_start = np.searchsorted(cell_id[order], np.arange(n_cells_b * n_cells_h + 1)).astype(np.int32)
        deep = deep_sky(catalog)
        by_cone = band_order(deep.unit, deep.hip)  # the final step's cone searches (final.py), not by z alone
        deep = DeepSky(np.ascontiguousarray(deep.unit[by_cone]), np.ascontiguousarray(deep.hip[by_cone]))
        main_rows, i_rows = main[order].astype(np.uint16), n_i[order].astype(np.uint16)
        j_rows = n_j[order].astype(np.uint16)
        unit32 = unit.astype(np.float32)
        side_i, side_j = record_sides(unit32, main_rows, i_rows, j_rows)
        features = np.empty((order.size, 2), dtype=np.float32)
        features[:, FEAT_BASE] = base32[order]
        features[:, FEAT_HEIGHT] = height32[order]
        records, s_b, s_h, s_s = compact_records(features[:, FEAT_BASE], features[:, FEAT_HEIGHT], side_i, side_j)
        return TriangleVotingDatabase(
            features=features, records=records, rec_scale_b=s_b, rec_scale_h=s_h, rec_scale_s=s_s,
            rows=np.ascontiguousarray(np.c_[main_rows, i_rows, j_rows]),
            cell_start=cell_start, unit_icrs=unit32, hip=hip.astype(np.int64),
            sky_start=sky_start, sky_axis=SKY_AXIS,
            cell_b=cell, cell_h=cell, n_cells_b=n_cells_b, n_cells_h=n_cells_h,
            pattern_radius_chord=pr_chord, d_min_chord=dmin_chord,
            deep=deep, deep_v_mag=deep_v_mag(catalog, deep), deep_index=deep_index(deep.unit))

    # -- identification ---------------------------------------------------------------------
    def identify(self, database: TriangleVotingDatabase, observation: Observation) -> Identification:
        n = observation.x_px.size
        if n < 3:
            return Identification(np.full(n, -1, dtype=np.int64))
        cam = observation.camera
        x, y, mag = observation.x_px, observation.y_px, observation.mag
        db = database
        # one kernel call: brightest first (ties on position, so the result does not depend on input
        # order), only stars bright enough to be guide stars (with a margin), at most max_stars of them;
        # voting, verification (identify_rows) and the final step (finish)
        status, hip, attitude, accepted, w0, w1, w2, w3, n_named = identify_flat(x, y, mag, *self._flat_args(db, cam))
        if status == 0:
            return Identification(hip)
        counters = dict(zip(WORK_COUNTERS, (w0, w1, w2, w3), strict=True))
        if status == 1:
            return Identification(hip, counters=counters)
        # the photometry check passes any result of no id or more than min_stars ids: not called for those
        if accepted and 0 < n_named <= self.min_stars and not self._photometry_agrees(db, hip, mag):
            return Identification(np.full(n, -1, dtype=np.int64), counters=counters)
        return Identification(hip, attitude if accepted else None, counters=counters)

    def _photometry_agrees(self, db: TriangleVotingDatabase, hip: np.ndarray, mag: np.ndarray) -> bool:
        """False for a minimal identification (at most ``min_stars`` ids) whose catalog stars are on
        average more than ``mag_margin`` fainter than measured: mean(V_catalog - mag) > mag_margin.

        Against chance matches in fields of noise: such a set has the least geometric evidence, and
        of 200 fields of 10 to 40 uniform random points two got a 4-star identification whose stars
        were measured 1.45 and 2.45 V brighter (on average) than their catalog stars; correct
        4- and 5-star identifications measured at most 0.41 V (1,000 images each of Table 6's two
        skies, 5 false stars, and 1 Mv of magnitude noise; docs/algorithms/triangle_voting.md).
        """
        named = np.flatnonzero(hip >= 0)
        if named.size == 0 or named.size > self.min_stars:
            return True
        v_mag = np.array([db.deep_v_mag[np.flatnonzero(db.deep.hip == h)[0]] for h in hip[named]])
        return float(np.mean(v_mag - mag[named])) <= self.mag_margin

    def _kernel_args(self, db: TriangleVotingDatabase, cam: Camera) -> tuple[tuple, tuple, tuple, tuple]:
        """``identify_image``'s ``db``, ``tol``, ``fin_db`` and ``fin_cam`` for this database and camera, kept for the
        last pair (one identity check per image instead of three look-ups)."""
        def make():
            _, kernel_tol, fin_cam = self._tolerances(cam)
            return _kernel_tables(db), kernel_tol, _finish_tables(db), fin_cam
        return self.kept("kernel_args", (db, cam), make)

    def _flat_args(self, db: TriangleVotingDatabase, cam: Camera) -> tuple:
        """``identify_flat``'s arguments after the stars: the arrays of ``_kernel_args``' four bundles and their
        scalars as one float64 array (``kernels.flat_params``), kept for the last (database, camera)."""
        def make():
            kdb, ktol, fin_db, fin_cam = self._kernel_args(db, cam)
            unit64, guide_hip, deep_unit, deep_index, deep_hip, deep_mag = fin_db
            return (db.features, db.records, db.rows, db.cell_start, db.unit_icrs, db.sky_start, unit64, guide_hip,
                    deep_unit, deep_index, deep_hip, deep_mag, flat_params(kdb, ktol, fin_cam))
        return self.kept("flat_args", (db, cam), make)

    def _tolerances(self, cam: Camera) -> tuple[Tolerance, tuple, tuple]:
        """``_tolerance(cam)``, the same as the plain tuple the kernels take, and ``identify_image``'s
        ``fin_cam`` (the camera's frame, the final step's rules, the magnitude cut and ``max_stars``), kept
        for the last camera (an identification's images share one; building the bundle was ~1.6 us of
        each image)."""
        return self.kept("tolerances", (cam,), lambda: self._make_tolerances(cam))

    def _make_tolerances(self, cam: Camera) -> tuple[Tolerance, tuple, tuple]:
        tol = self._tolerance(cam)
        rules = Finish(tol.eps_chord, float(self.mag_margin), float(self.mag_limit),
                       float(self.coverage_mag_margin), float(self.max_missed_fraction), bool(self.assign_all))
        fin_cam = (*camera_frame(cam), *rules, float(self.mag_limit + self.mag_margin),
                   -1 if self.max_stars is None else int(self.max_stars))
        return tol, tuple(tol), fin_cam

    def _tolerance(self, cam: Camera) -> Tolerance:
        sigma_chord = self.sigma_window_px / cam.f_px
        return Tolerance(
            sigma_chord=sigma_chord, k_sigma=float(self.k_sigma), eps_chord=self._tolerance_chord(cam.f_px),
            radius_chord=self.k_sigma * sigma_chord, n_nbr=int(self.n_neighbours + self.lambda_extra),
            side_check=bool(self.side_check), vote_neighbours=bool(self.vote_neighbours), v_min=int(self.v_min),
            n_cand=int(self.n_candidates), min_support=int(self.min_support), min_stars=int(self.min_stars),
            max_hypotheses=int(self.max_hypotheses))

    def explain(self, database: TriangleVotingDatabase, observation: Observation) -> Explanation:
        """The image triangles whose catalog match voted (bold: those agreeing with the final answer),
        and each star's largest vote count as its label."""
        n = len(observation)
        x, y, mag = observation.x_px, observation.y_px, observation.mag
        order = np.lexsort((y, x, mag))
        order = order[mag[order] <= self.mag_limit + self.mag_margin][:self.max_stars]
        if order.size < 3:
            return Explanation(caption="fewer than 3 usable stars: no triangle, no vote.")
        cam = observation.camera
        v_cam = backproject_px(x[order], y[order], cam.f_px, cam.cx_px, cam.cy_px)
        db = database
        _, cand_votes, hyp, _, _ = vote(v_cam, _kernel_tables(db), self._tolerances(cam)[1],
                                        *_scratch(db, v_cam.shape[0]))
        hip = self.identify(database, observation).hip
        segments, highlight, seen = [], [], set()
        for i, ri, a, ra, b, rb in hyp:
            tri = tuple(sorted((int(order[i]), int(order[a]), int(order[b]))))
            agrees = all(hip[order[s]] == db.hip[r] for s, r in ((i, ri), (a, ra), (b, rb)))
            if tri in seen and not agrees:
                continue
            seen.add(tri)
            for p, q in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[0], tri[2])):
                if agrees:
                    highlight.append(len(segments))
                segments.append([[x[p], y[p]], [x[q], y[q]]])
        votes = np.zeros(n, dtype=np.int64)
        votes[order] = cand_votes[:, 0]
        labels = tuple(f"{votes[s]} votes" + (f", HIP {hip[s]}" if hip[s] >= 0 else "") for s in range(n))
        caption = (f"{len(seen)} image triangles matched a catalog triangle in base, height and sides and voted; "
                   f"{int(np.sum(hip >= 0))} stars identified.")
        return Explanation(segments=np.array(segments).reshape(-1, 2, 2), points=np.c_[x, y], labels=labels,
                           caption=caption, highlight=np.array(highlight, dtype=np.int64))

