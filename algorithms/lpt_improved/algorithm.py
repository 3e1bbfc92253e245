"""Improved log-polar star identification (Luo, Xu, Zhang & Sun 2015)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from starid.camera import Camera
from starid.catalog import Catalog
from starid.kernels import camera_frame
from starid.observation import Observation
from starid.params import check_flag, check_number, check_whole, param
from starid.plugin import Database, Explanation

from .kernels import FeatureTable, Search, build_features, chord_order, feature_vector, identify_kernel
from .planar import (
    PlanarAlgorithm,
    acceptance,
    effective_double_px,
    explain_pattern,
    image_neighbours,
    neighbour_lists,
    new_trace,
    pack_params,
    plane_polar,
    prepare_image,
    select_guides,
    z_index,
)


@dataclass(frozen=True, eq=False)
class ImprovedLPTDatabase(Database):
    """The feature database (Luo et al., their eq. 11: one record per navigation star).

    columns : uint8 (m, k) the feature vectors stored by entry: ``columns[i, r]`` is entry i of
        feature row r (:attr:`feature` is its (k, m) transpose); rows sorted by their number of
        non-zero entries. The search reads one entry of every row in a window at a time, so this
        layout makes each read contiguous.
    total : int32 (k,) sum of each row (for the sparse difference).
    count_start : int32 (m + 2,) first row with 0, 1, ..., m + 1 non-zero entries.
    guide, align : int16/int32 (k,) guide rows of each row's reference and alignment star.
    align_chord : float32 (k,) the chord between the two (what ``pair_filter`` compares).
    guide_unit : float32 (g, 3) ICRS unit vectors of the guide stars, sorted by z.
    guide_hip : int64 (g,) their catalog ids.
    radius_deg : the neighbourhood radius R; f_px : focal length (px) the plane distances use;
    double_px : the double-star separation applied (``double_px``, at most R / 10).
    """

    columns: np.ndarray
    total: np.ndarray
    count_start: np.ndarray
    guide: np.ndarray
    align: np.ndarray
    align_chord: np.ndarray
    guide_unit: np.ndarray
    guide_hip: np.ndarray
    radius_deg: float
    f_px: float
    double_px: float

    @property
    def feature(self) -> np.ndarray:
        """The feature vectors, (k, m), one row per record (a view of :attr:`columns`)."""
        return self.columns.T

    @property
    def table(self) -> FeatureTable:
        return FeatureTable(self.columns, self.total, self.count_start, self.guide, self.align, self.align_chord)


def _row_dtype(n: int):
    return np.int16 if n <= np.iinfo(np.int16).max else np.int32


@dataclass(frozen=True)
class ImprovedLPT(PlanarAlgorithm):
    """Improved log-polar (Luo et al., Chin. Phys. B 2015): alignment star, log distance per sector.

    The feature is the log plane distance per angle sector, with no circular shift.

    Luo L.-Y., Xu L.-P., Zhang H., Sun J.-R., "Improved autonomous star identification
    algorithm", Chinese Physics B 24(6), 064202 (2015). Equation numbers below follow the order
    of the paper's section 3 (eq. 3 rotation onto the alignment star, eq. 7 alignment star,
    eq. 8 feature entry, eq. 9 similarity, eq. 10 search window, eq. 11 database record).

    Method, as implemented (``docs/algorithms/lpt_improved.md`` has the details and numbers):

    1. Guide (navigation) stars: V <= ``mag_limit``; stars closer than ``double_px`` to another
       are binaries and dropped (paper: 20 px = 0.39 deg, 6.5 mag). Paper; starid caps the
       separation at R / 10 so that very wide cameras keep guide stars.
    2. Every pattern is built in the plane tangent at its reference star, in pixels
       (``f tan(angle)``), the same way for catalog and image vectors. Reconstruction: the paper
       works on raw image coordinates; the tangent plane makes database and image agree exactly
       (algorithm notes 1.4).
    3. Neighbours: stars within ``radius_deg`` R of the reference star (paper: 6 deg; default
       0.3 x the smaller field of view, at most 20 deg: 6 deg at 20 deg, 3 deg on the 10 deg
       Table 4 camera). The nearest is the alignment star (eq. 7), and angles are measured
       counter-clockwise from it (eq. 3). Paper.
    4. Feature (eq. 8): ``n_sectors`` m = 100 angle intervals; entry i = ceil(``log_scale`` ln r)
       of the farthest neighbour (largest r) in interval i, r the plane distance in px; 0 when
       the interval is empty. Paper, with ``log_scale`` = 1 (the paper's plain ln);
    5. Search (eqs. 9-10): the sum of absolute differences to every database row whose count of
       non-zero entries L_c lies in [L_s - ``count_tol``, L_s + ``count_tol_above``]; the
       smallest wins. Paper, with epsilon1 = 1; the paper's epsilon2 = 1 is
       ``count_tol_above=None`` (= ``count_tol``). starid's default epsilon2 = 3 (reconstruction):
       guide stars lost to magnitude noise or the image edge leave the image with fewer
       non-zero entries than its database row far more often than with more. starid evaluates the same
       sum over the image's non-zero entries only (an exact identity, see :func:`kernels.sad_search`),
       on a table stored entry by entry so that the window's rows are read contiguously.
    6. Reference stars near the image centre first (paper), at most ``max_refs``.

    starid's additions (reconstructions; the paper stops at step 5 and, with a single
    reference star, cannot reject a wrong best match):

    * the ``n_candidates`` best rows, not only the best, are tried, and each is accepted only
      when the attitude it implies (reference and alignment star, Wahba) is confirmed by
      reprojection: at least ``min_matches`` observed stars, and ``confirm_fraction`` of the
      guide stars it puts on the sensor, found within ``beta`` sqrt(2) sigma, sigma =
      max(``sigma_px``, 1 px) (the 1 px floor gives a noise-free world a window); otherwise
      the next candidate, alignment star or reference star is tried. Random fields give no
      result;
    * ``image_alignments`` (default 2): the k-th nearest image neighbour is also tried as the
      alignment star (nearer ones left out of the pattern), which survives a false or
      non-guide star nearer than the true alignment star; 1 is the paper;
    * ``db_alignments`` (default 1 = paper): database rows for the k nearest catalog neighbours
      as alignment stars, against a missing alignment star (k times the memory);
    * ``pair_filter`` (default on; off in the paper): only database rows whose reference and
      alignment stars are as far apart as the image pair (within two first windows of the
      acceptance, a rotation keeps separations) are ranked, so the ``n_candidates`` are the
      best plausible rows rather than the best rows;
    * ``sigma_px`` follows the simulator's centroid noise (``None`` = follow).
    """

    name: ClassVar[str] = "lpt_improved"
    #: work counters its kernel does not count (the SAD search's comparisons are not counted)
    _uncounted: ClassVar[tuple] = ("comparisons",)
    #: the paper's procedure: one reference star (nearest the centre), its best match only, one
    #: alignment, the count window Ls-1..Ls+1, ranked on the feature alone (``lpt_improved:paper``)
    published: ClassVar[dict] = {"max_refs": 1, "n_candidates": 1, "image_alignments": 1, "count_tol_above": 1,
                                 "pair_filter": False}

    n_sectors: int = param(100, help="angle intervals m of the feature vector (eq. 8; paper: 100)")
    log_scale: float = param(
        1.0, help="entry = ceil(log_scale ln r) of the farthest neighbour in an interval (eq. 8; paper: 1)")
    count_tol: int = param(
        1, help="rows searched have at least L_s - count_tol non-zero entries (eq. 10, epsilon1; paper)")
    count_tol_above: int | None = param(
        3, help="rows searched have at most L_s + this entries (epsilon2); None = count_tol (paper: 1; starid's: 3)")
    image_alignments: int = param(
        2, help="nearest image neighbours tried as the alignment star (1 = paper; starid's extension)")
    db_alignments: int = param(
        1, help="nearest catalog neighbours stored as alignment stars (1 = paper; starid's extension)")
    pair_filter: bool = param(
        True, help="rank only rows whose reference-alignment separation fits the image pair (starid's extension)")

    def __post_init__(self):
        super().__post_init__()
        check_whole("n_sectors", self.n_sectors, 4, 4096)
        check_number("log_scale", self.log_scale, lo=0, hi=1000, lo_open=True)
        check_whole("count_tol", self.count_tol, 0)
        if self.count_tol_above is not None:
            check_whole("count_tol_above", self.count_tol_above, 0)
        check_whole("image_alignments", self.image_alignments, 1)
        check_whole("db_alignments", self.db_alignments, 1)
        check_flag("pair_filter", self.pair_filter)

    def build(self, catalog: Catalog, camera: Camera) -> ImprovedLPTDatabase:
        settled = self.derived(catalog, camera)
        radius = settled.radius_deg
        double_px = effective_double_px(self.double_px, radius, camera)
        guides = select_guides(catalog, settled.mag_limit, double_px, camera, self.name)
        nbr, off = neighbour_lists(guides.unit, math.radians(radius))
        max_value = 255 if self.log_scale * math.log(camera.f_px * math.tan(math.radians(radius))) < 255 else 65535
        feature, count, guide, align = build_features(guides.unit.astype(np.float64), nbr, off, float(camera.f_px),
                                                      self.n_sectors, float(self.log_scale),
                                                      self.db_alignments, max_value)
        order = np.argsort(count, kind="stable")
        feature, count, guide, align = feature[order], count[order], guide[order], align[order]
        count_start = np.searchsorted(count, np.arange(self.n_sectors + 2)).astype(np.int32)
        rd = _row_dtype(len(guides.hip))
        align_chord = np.linalg.norm(guides.unit[guide].astype(np.float64) - guides.unit[align], axis=1)
        return ImprovedLPTDatabase(
            columns=np.ascontiguousarray(feature.T, dtype=np.uint8 if max_value == 255 else np.uint16),
            total=feature.sum(axis=1).astype(np.int32), count_start=count_start, guide=guide.astype(rd),
            align=align.astype(rd), align_chord=align_chord.astype(np.float32), guide_unit=guides.unit,
            guide_hip=guides.hip, radius_deg=radius, f_px=float(camera.f_px), double_px=double_px)

    def _search(self, db: ImprovedLPTDatabase) -> Search:
        return Search(self.n_sectors, float(self.log_scale), math.cos(math.radians(db.radius_deg)), self.count_tol,
                      self.count_tol if self.count_tol_above is None else self.count_tol_above,
                      self.max_refs, self.image_alignments, self.n_candidates, float(db.double_px),
                      bool(self.pair_filter))

    def _make_kernel_args(self, db: ImprovedLPTDatabase, cam: Camera) -> tuple:
        sensor = camera_frame(cam)._replace(f_px=float(cam.f_px))
        acc = acceptance(cam, self.sigma_px, self.beta, self.min_matches, self.confirm_fraction)
        return (pack_params(sensor, acc, self._search(db)), *db.table, db.guide_unit, z_index(db.guide_unit),
                *chord_order(db.align_chord, db.count_start))

    def _run(self, db: ImprovedLPTDatabase, observation: Observation):
        trace = new_trace()
        rows, attitude, ok = identify_kernel(observation.x_px, observation.y_px,
                                             *self._kernel_args(db, observation.camera), trace)
        return rows, attitude, ok, trace

    def explain(self, database: ImprovedLPTDatabase, observation: Observation) -> Explanation:
        """The accepted reference star, its alignment star, its neighbours within R and its non-empty sectors."""
        rows, _, ok, trace = self._run(database, observation)
        ref, align = int(trace[0]), int(trace[1])
        x, y = observation.x_px, observation.y_px
        sensor = camera_frame(observation.camera)
        unit, usable, order = prepare_image(x, y, sensor, database.double_px)
        cos_r = math.cos(math.radians(database.radius_deg))
        if ref < 0:   # nothing accepted: show the first reference star's pattern
            nbrs = np.empty(len(x), dtype=np.int64)
            for s in order:
                k = image_neighbours(unit, usable, x, y, int(s), cos_r, nbrs)
                if k:
                    ref, align = int(s), int(nbrs[0])
                    break
        rays = np.zeros(0)
        if ref >= 0:
            nbrs = np.empty(len(x), dtype=np.int64)
            k = image_neighbours(unit, usable, x, y, ref, cos_r, nbrs)
            a = int(np.flatnonzero(nbrs[:k] == align)[0])
            r_px, phi = np.empty(k), np.empty(k)
            plane_polar(unit, ref, nbrs, k, database.f_px, r_px, phi)
            vec = np.zeros(self.n_sectors, dtype=np.int64)
            feature_vector(r_px, phi, k, a, self.n_sectors, float(self.log_scale), vec)
            width = 2 * math.pi / self.n_sectors
            occupied = np.flatnonzero(vec)
            rays = np.unique(np.concatenate([occupied * width, (occupied + 1) * width]))
        radius_px = observation.camera.f_px * math.tan(math.radians(database.radius_deg))
        if ok:
            caption = (f"Improved LPT: reference star matched with difference {int(trace[3])} (feature row "
                       f"{int(trace[2])}); {int((rows >= 0).sum())} stars confirmed by reprojection. Rays bound the "
                       f"non-empty {360 / self.n_sectors:g} deg sectors, measured from the alignment star.")
        else:
            caption = "Improved LPT: no match was confirmed; the first reference star's pattern is shown."
        return explain_pattern(observation, rows, database.guide_hip, ref, align, radius_px, database.double_px,
                               rays, caption)
