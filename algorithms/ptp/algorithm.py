"""PTP: planar-triangle principal-component star identification (Zhou & Ye 2015)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import ClassVar

import numpy as np
from scipy.spatial import cKDTree

from starid.camera import Camera
from starid.catalog import Catalog
from starid.errors import ConfigError
from starid.kernels import (
    DeepSky,
    KVector,
    assign_all,
    backproject_px,
    camera_frame,
    check_stars,
    deep_sky,
    kvector_make,
    rad_to_chord,
    wahba_rows,
)
from starid.observation import Observation
from starid.params import check_flag, check_number, check_whole, param
from starid.plugin import Algorithm, Database, Explanation, Identification

from .kernels import (
    WORK_NAMES,
    SideIndex,
    Tables,
    Tolerances,
    View,
    build_triangles,
    identify_kernel,
    nearest_slaves,
    pack_tables,
    params_of,
    select_stars,
    unpack_tail,
)

#: Sides and D_ms are chords of unit vectors times this (section 2.1: 5 deg -> 872.8).
CHORD_SCALE = 10000.0
#: Smallest centroid noise (px) the windows assume, whatever ``sigma_px`` says, on the paper's camera.
SIGMA_FLOOR_PX = 1.0
#: Bin width of side a in the second index (scaled chord, about 0.05 deg): near the 3 sigma side tolerance
#: at 1 px on the paper's camera (7.2), so a window reads 2-3 bins. Any width gives the same rows.
INDEX_WIDTH = 8.0
#: log2 of the block of projection-ordered rows the second index points into (64 rows).
INDEX_SHIFT = 6
#: The paper's double-star limit d_min (section 2.1: D_ms >= 8.728, i.e. 0.05 deg), on its camera
#: (Table 4, which is :data:`starid.camera.REFERENCE_CAMERA`).
D_MIN_DEG = 0.05


def camera_rules(camera: Camera, sigma_px: float | None = None) -> tuple[float, float]:
    """``(d_min_deg, sigma_floor_px)`` derived from ``camera`` (and the assumed centroid noise ``sigma_px``,
    None = noise-free) when the parameters are ``None``.

    ``r = camera.pixel_ratio`` is the camera's pixel (IFOV) in the paper camera's pixels (exactly 1.0 on
    the Table 4 camera). The paper's d_min = 0.05 deg is 5.1 px on its camera, 1.2 times the
    3 sqrt(2) x 1 px side tolerance: two stars are confused when their separation is comparable to that
    tolerance, which is set in pixels by the noise. So d_min keeps those 5.1 px on coarser pixels
    (``0.05 r`` deg) and grows with the noise above 1 px (``0.05 r sigma_px`` deg):
    ``d_min = 0.05 max(1, r max(1, sigma_px))`` deg. The noise floor stays 35.2 arcsec (1 px on the
    paper's camera; ``1 / r`` px), because it only has to cover the catalog's and the float32 tables'
    rounding, which are angles. On finer pixels and at up to 1 px both stay the paper's (0.05 deg, 1 px).
    """
    r = camera.pixel_ratio
    noise = max(1.0, sigma_px or 0.0)
    return D_MIN_DEG * max(1.0, r * noise), SIGMA_FLOOR_PX * min(1.0, 1.0 / r)


@dataclass(frozen=True, eq=False)
class PTPDatabase(Database):
    """The pattern database of section 2.1 (Table 1) plus its k-vector (Table 2).

    kv : :class:`starid.kernels.KVector`: ``kv.values`` float32 (t,) the projections p_r (eq. 3),
        ascending; ``kv.k`` uint16/int32 (t,) the k-vector, ``kv.m``, ``kv.q`` its line (eq. 16).
    ids : uint16/int32 (t, 3) guide-star rows of (r1, r2, r3) = (master, nearer slave, farther slave).
    mean : float64 (3,) mean side vector; axis : float64 (3,) the projection axis u_max.
    guide_hip : int64 (g,) catalog id of each guide row; guide rows are sorted by z (declination).
    guide_unit : float32 (g, 3) ICRS unit vectors of the guide stars, for verification and
        confirmation (float32: 0.02 arcsec, far below the tolerances).
    d_min_deg, sigma_floor_px : the values used (``PTP.d_min_deg`` and ``PTP.sigma_floor_px``, or, when
        those are None, derived from the build camera by :func:`camera_rules`); identify uses these.
    deep : :class:`starid.kernels.DeepSky`, the stars to V <= ``deep_mag_limit`` for ``assign_all``
        (empty unless ``assign_all``).
    index : :class:`~starid_algorithms.ptp.kernels.SideIndex`, the second index: the rows by bins of
        side a within blocks of the projection order, with their float32 scaled sides a, b, c of eq. 1
        (:func:`side_index`), so a window reads only the rows whose side a can agree. The sides in
        projection order, (3, t), are :attr:`sides` (derived, not stored).
    """

    kv: KVector
    ids: np.ndarray
    mean: np.ndarray
    axis: np.ndarray
    guide_hip: np.ndarray
    guide_unit: np.ndarray
    deep: DeepSky
    extra_unit: np.ndarray
    explained_variance: float
    index: SideIndex
    d_min_deg: float = D_MIN_DEG
    sigma_floor_px: float = SIGMA_FLOOR_PX

    @property
    def proj(self) -> np.ndarray:
        """The sorted projections p_r (``kv.values``)."""
        return self.kv.values

    @cached_property
    def sides(self) -> np.ndarray:
        """float32 (3, t) the scaled sides a, b, c of eq. 1 in projection order, one row per side, rebuilt
        from the index (identify reads them only through the index)."""
        out = np.empty((3, self.index.rows.shape[0]), dtype=np.float32)
        out[:, self.index.rows.astype(np.int64)] = self.index.sides.T
        return out

    def tables(self) -> Tables:
        """The arrays identify reads, as one kernel argument."""
        return self._tables

    @cached_property
    def packed(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`tables` packed into two arrays (:func:`~starid_algorithms.ptp.kernels.pack_tables`), as
        :func:`~starid_algorithms.ptp.kernels.identify_kernel` takes them: a copy of the same numbers, the
        index's rows beside their sides (not counted again in ``nbytes``)."""
        return pack_tables(self._tables, self.kv.k.dtype)

    @cached_property
    def _tables(self) -> Tables:     # built once: saves about 1 us per image
        return Tables(self.kv, self.ids, self.mean, self.axis, self.guide_unit, self.guide_hip, self.extra_unit,
                      self.index)


@lru_cache(maxsize=16)
def _view(camera: Camera) -> View:
    """The camera as the kernel needs it: the core frame and ``c_fov``, the chord from the boresight to
    the farthest corner. (``identify`` asks once per (database, camera): :meth:`PTP._kernel_call`.)"""
    return View(camera_frame(camera), rad_to_chord(camera.half_diagonal_rad))


def _chord(deg: float) -> float:
    """An angle as a scaled chord (0.05 deg -> 8.728, 5 deg -> 872.8)."""
    return CHORD_SCALE * rad_to_chord(math.radians(deg))


@lru_cache(maxsize=64)
def _tolerances(algorithm: PTP, d_min_deg: float, sigma_floor_px: float) -> Tolerances:
    return algorithm._tol(d_min_deg, sigma_floor_px)


def _index_dtype(n: int):
    return np.uint16 if n <= np.iinfo(np.uint16).max else np.int32


def side_index(sides: np.ndarray, width: float = INDEX_WIDTH, shift: int = INDEX_SHIFT) -> SideIndex:
    """The second index over the database rows (in projection order) by their float32 side a (``sides``:
    float32 (3, t), projection order): the rows sorted by (``floor(a / width)``, row), their sides in that
    order, and for every bin the position of its first row in each block of ``2**shift`` rows
    (:class:`~starid_algorithms.ptp.kernels.SideIndex`)."""
    t = sides.shape[1]
    bins = np.floor(sides[0].astype(np.float64) / width).astype(np.int64)
    n_bins = int(bins.max()) + 1
    n_blocks = (t + (1 << shift) - 1) >> shift
    span = n_blocks << shift
    keys = bins * span + np.arange(t, dtype=np.int64)
    order = np.argsort(keys, kind="stable")
    marks = (np.arange(n_bins, dtype=np.int64)[:, None] * span
             + (np.arange(n_blocks + 1, dtype=np.int64) << shift)[None, :])
    offsets = np.searchsorted(keys[order], marks, side="left")
    return SideIndex(order.astype(_index_dtype(t)), np.ascontiguousarray(sides[:, order].T, dtype=np.float32),
                     np.ascontiguousarray(offsets.T, dtype=_index_dtype(t)), float(width), int(shift))


@dataclass(frozen=True)
class PTP(Algorithm):
    """PTP: planar triangles projected on their first principal axis, k-vector search and sharing-star validation.

    Zhou F., Ye T., "Lost-in-space star identification using planar triangle principal component
    analysis algorithm", Mathematical Problems in Engineering 2015, 982420. Section numbers and
    equations below are the paper's.

    Database (section 2.1): every guide star (V <= ``mag_limit``) is a master; its
    ``n_slaves`` nearest stars with ``d_min_deg <= angle <= d_max_deg`` (8.728 <= D_ms <= 872.8 in
    the paper's units: chord x 10000; starid's default d_max is 6 deg, see below) are slaves s1..s4,
    nearest first; the 6 triangles (m, s_i, s_j), i < j, have sides a = |r1-r2|, b = |r2-r3|, c = |r1-r3| (eq. 1) with
    r1 = m, r2 = s_i, r3 = s_j. PCA over all triangles gives the projection axis u_max; each
    triangle is stored by its projection p_r = u_max^T (Delta - mean) (eq. 3), sorted, with a
    k-vector (eqs. 15-16).

    Identification (section 2.2): every observed star is a master with the same slave rule; each
    triangle's projection (eq. 5) is searched in ``[p_r - beta sigma_p, p_r + beta sigma_p]``
    with sigma_p from eqs. 6-14 and sigma = ``sigma_px`` / f_px; candidates must pass the
    three-side check. Validation (section 2.3, Table 3): see :func:`identify_kernel`.

    Choices the paper leaves open, each a parameter (method step by step, parameters, paper vs
    reconstructed and every measurement: docs/algorithms/ptp.md):

    * double stars: the paper's lower limit d_min = 0.05 deg is there "to avoid double star
      interference". Two guide stars closer than that have near-identical triangles and cannot
      be told apart at 1 px noise, so (``exclude_doubles``, reconstruction) both are dropped from
      the guide list, and image stars closer than d_min to another detection are left
      unidentified;
    * vertex order r1 = master, r2 = nearer slave, r3 = farther (paper's listing of s1..s4);
      when the two slaves' distances differ by less than the side tolerance, the swapped order is
      also tried (``swap_slaves``, reconstruction);
    * the three-side check uses the same ``side_beta`` = 3 sigma bound propagated to each side,
      sigma_side = sigma sqrt(2 - side^2 / 2) ~ sqrt(2) sigma (eq. 11) (reconstruction);
    * sharing-star validation accepts a matched triangle when ``min_shared`` = 1 of its star
      pairings is also proposed by another observed triangle, which is how Table 3 validates
      triangle 1 (it shares only star 11 with triangle 3);
    * conflicting pairings: the paper declares a star whose triangles disagree a failure. At a
      3-sigma window, near-congruent triangles (an isosceles triangle with its two equal sides'
      roles swapped, a neighbouring look-alike) are matched too and would wipe out true stars, so
      by default the pairing proposed by more distinct observed triangles wins (``majority``,
      reconstruction); ``majority=False`` drops every conflicting star;
    * readings of the paper's open steps, off by default and measured against Tables 5 and 6
      (docs/algorithms/ptp.md, "Paper versus reconstruction"): ``unique_only`` (only a triangle with one
      catalog match votes), ``conflict_fails`` (a conflict fails the image), ``stop_first`` (masters
      brightest first, stop at the first after which validation gives >= 3 stars), ``lone_triangles``
      (nothing validated: matched triangles stand if none conflicts), ``radial_sigma`` (sigma is the 2-D
      noise); ``ptp:paper`` uses the last three with ``majority`` and ``sigma_floor_px=0.1``;
    * ``sigma_px`` is the centroid noise the tolerances assume (1 px in Table 6). It follows the
      simulator (``None``, the default: the harness sets it to the simulated noise), with a floor
      ``sigma_floor_px`` so a noise-free world still gets windows wide enough for the catalog's and the
      float32 tables' rounding (and today's 1 px results are unchanged);
    * camera-dependent, ``None`` = derived from the camera (:meth:`derived` by :func:`camera_rules`; the
      values used are also stored in the database as ``d_min_deg`` and ``sigma_floor_px``): with
      r = ``camera.pixel_ratio`` = f_paper / f_px the camera's pixel in Table 4 pixels (exactly 1 on the
      Table 4 camera),
      ``d_min_deg`` = 0.05 max(1, r) (the paper's 0.05 deg is 5.1 px on its camera: two stars closer than
      about the pixel-based tolerance are swapped) and ``sigma_floor_px`` = min(1, 1/r) (1 px on the
      paper's camera, 35.2 arcsec: the rounding it covers is an angle). Both are the paper's on the
      Table 4 camera and on finer pixels; on Luo et al.'s 20 deg / 1024 px camera 0.10 deg and 0.50 px
      (noise-free, the old 0.05 deg / 1 px misidentified 4.8 % of the images, seed 11: stars 3-6 px
      apart were swapped inside the 3 sqrt(2) x 1 px = 300 arcsec tolerance). Above 1 px of assumed noise
      (``sigma_px``, set from the simulator before :meth:`derived`) d_min grows with it,
      0.05 max(1, r max(1, sigma_px)) deg, so it stays 1.2 times the 3 sqrt(2) sigma side tolerance
      (Luo's camera at 2 px: 0.20 deg = 10.2 px; the 5.1 px d_min misidentified 6.4 % of the images there,
      detections 5-10 px from a guide star taking its id);
    * ``nearest_check`` (starid's extension, on by default): after the checks above, the attitude of all
      the pairings (Wahba) predicts each paired guide star; a pairing whose detection lies beyond the pair
      tolerance (3 sqrt(2) sigma) from its prediction while another detection lies nearer it is dropped
      (Luo's camera at 2 px: the swaps 9-14 px apart that d_min does not cover; on the Table 4 camera at
      1 px it turned 3 of Table 6's 10,000 real-sky images from misidentified to identified);
    * ``verify`` (starid's extension, on by default): the paper stops after the sharing-star
      validation and computes the attitude "from the correctly identified stars"; starid checks
      the pairings' mutual angular distances first, because under the harness's rule one wrong
      id makes the whole image wrong, and at 1 px noise the sharing-star rule alone validates
      clusters of spurious triangles (``verify=False`` gives the paper-literal algorithm);
    * ``confirm_fraction`` (starid's extension, 0 switches it off): a small self-consistent
      cluster of wrong pairings passes the pairwise check; its attitude, though, predicts guide
      stars where none are seen. The identification stands only if at least this fraction of
      the guide stars its attitude puts in the image is observed (magnitude noise hides some
      true ones, so not all).
    * ``max_stars`` (time bound): only the brightest ``max_stars`` detections take part (100: never
      binding on the Table 4 camera); ``max_candidates``: an image triangle whose window holds more
      database triangles than this is skipped as uninformative (on very wide fields 1 px is degrees
      and every triangle matches everything; 64 never binds on the Table 4 camera). Coincident
      detections (distance 0) are never slaves, whatever ``d_min_deg``;
    * ``image_slaves`` (starid's extension, 6): the image side forms the triangles of each master's
      6 nearest stars, a superset of the database's 4-slave triangles, so a star missing from the
      database (a V > 6 star noise brought in) among the nearest does not break every triangle;
      ``image_slaves=4`` is the paper's rule;
    * ``mag_margin`` (flight precaution): detections measured fainter than ``mag_limit + mag_margin``
      make no pattern; with ``max_stars`` the brightest are used first;
    * ``assign_all`` (the standard final step, off by default): the attitude assigns every detection
      to the deep catalog star (V <= ``deep_mag_limit``, stored in the database) predicted within
      the tolerance. Tuned on seed 7, evaluated on seed 11.
    * ``hypotheses`` (starid's extension, 32; 0 = the paper's method): when the sharing-star validation
      (and the checks above) leave fewer than three stars, each matched triangle alone becomes a
      hypothesis, best supported first, at most ``hypotheses`` of them. Its attitude must explain the
      whole image: at least ``max(check_min_stars, check_fraction * n)`` detections (5, 0.5) must lie
      within the tolerance of a predicted catalog star, among the guide stars and the stars to
      ``check_mag_limit`` (V 7: unit vectors only, 0.126 MB), its own three stars included
      (``starid.kernels.reproject_assign``, ``wahba_rows``). A real sensor images every star to its limit, so in
      sparse fields a single database triangle is often all there is; the whole-image check keeps
      misidentification at the level of the validated path;
    * ``d_max_deg`` is 6 deg (the paper: 5): sparse fields have guide stars with fewer than four
      neighbours within 5 deg (real sky, seed 7: 95.00 -> 95.65 %; database 0.924 -> 0.939 MB).
    """

    name: ClassVar[str] = "ptp"
    #: the paper's method (section 2): no pairwise verification, confirmation or hypotheses, 4 image
    #: slaves, 0.05 deg <= D_ms <= 5 deg on every camera; of the readings the text leaves open, the one
    #: closest to Tables 5 and 6 (docs/algorithms/ptp.md, "Paper versus reconstruction"): windows that
    #: follow the simulated noise (floor 0.1 px, so noise-free windows are not 1 px wide), sigma read as
    #: the 2-D noise, the search stops at the first master that validates 3 stars, conflicts go to the
    #: better supported pairing, and mutually consistent unvalidated matches stand when nothing validates
    published: ClassVar[dict] = {"verify": False, "confirm_fraction": 0.0, "image_slaves": 4, "hypotheses": 0,
                                 "d_max_deg": 5.0, "majority": True, "d_min_deg": D_MIN_DEG,
                                 "nearest_check": False, "sigma_floor_px": 0.1, "radial_sigma": True,
                                 "stop_first": True, "lone_triangles": True}
    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}

    mag_limit: float = param(6.0, help="guide stars (masters) have V <= this (paper, section 2.1)", unit="mag")
    sigma_px: float | None = param(
        None, help="centroid noise the windows assume; None follows the simulator (floor sigma_floor_px)", unit="px")
    sigma_floor_px: float | None = param(
        None, help="least noise the windows assume; None = derived from the camera, min(1, 1/pixel_ratio)", unit="px")
    n_slaves: int = param(4, help="nearest neighbours of a master that form its triangles in the database (paper: 4)")
    d_min_deg: float | None = param(
        None, unit="deg",
        help="least master-slave distance, against doubles (paper: 0.05); None = derived from the camera")
    d_max_deg: float = param(6.0, unit="deg",
                             help="largest master-slave distance (paper: 5; 6 in starid for sparse fields)")
    beta: float = param(3.0, help="half-width of the projection search window in units of sigma_p (paper: 3)")
    side_beta: float = param(
        3.0, help="three-side check bound in units of each side's propagated sigma (starid's reconstruction)")
    exclude_doubles: bool = param(True,
                                  help="drop guide stars and detections closer than d_min (starid's reconstruction)")
    swap_slaves: bool = param(
        True,
        help="also try the swapped slave order when their distances are within tolerance (starid's reconstruction)")
    min_shared: int = param(
        1, help="star pairings a triangle must share with another observed triangle to be validated (paper)")
    majority: bool = param(
        True, help="a conflicting star takes the pairing of more triangles; False drops it (starid's reconstruction)")
    verify: bool = param(True,
                         help="check the pairings' mutual angular distances after validation (starid's extension)")
    verify_min_fraction: float = param(
        0.5, help="fraction of a pairing's distances to the others that must agree in the pairwise check")
    confirm_fraction: float = param(
        0.5, help="fraction of the guide stars the attitude predicts that must be seen; 0 = off (starid's extension)")
    max_stars: int = param(100, help="brightest detections that take part (a time bound)")
    max_candidates: int = param(64,
                                help="an image triangle with more database matches than this is skipped (time bound)")
    image_slaves: int = param(
        6, help="nearest neighbours of an image master that form its triangles (paper: 4; starid's extension: 6)")
    mag_margin: float = param(0.5, unit="mag",
                              help="detections fainter than mag_limit + this make no pattern (flight precaution)")
    assign_all: bool = param(
        False, help="assign every detection to the deep catalog star its attitude predicts (standard final step)")
    deep_mag_limit: float = param(7.5, unit="mag",
                                  help="faintest catalog star assign_all can assign, stored in the database")
    hypotheses: int = param(
        32, help="single-triangle hypotheses tried when validation leaves < 3 stars; 0 = paper (starid's extension)")
    check_mag_limit: float = param(7.0, unit="mag",
                                   help="catalog stars to this V are predicted in a hypothesis's whole-image check")
    check_min_stars: int = param(5, help="least detections a hypothesis's attitude must explain")
    check_fraction: float = param(0.5, help="fraction of the detections a hypothesis's attitude must explain")
    nearest_check: bool = param(
        True, help="drop a pairing when another detection lies nearer its predicted star (starid's extension)")
    unique_only: bool = param(
        False, help="only an image triangle with exactly one catalog match votes (reading of section 2.2)")
    conflict_fails: bool = param(
        False, help="any conflicting star among the validated triangles fails the whole image (reading of 2.3)")
    lone_triangles: bool = param(
        False, help="when validation gives < 3 stars, accept the matched triangles if none conflicts (a reading)")
    radial_sigma: bool = param(
        False, help="read sigma_px as the 2-D (radial) centroid noise: the windows use sigma_px / sqrt(2) per axis")
    stop_first: bool = param(
        False, help="stop at the first master (brightest first) after which validation gives >= 3 stars (reading)")

    def __post_init__(self):
        check_number("mag_limit", self.mag_limit)
        if self.sigma_px is not None:
            check_number("sigma_px", self.sigma_px, lo=0)   # None: follow the simulator
        check_whole("n_slaves", self.n_slaves, 2)
        if self.sigma_floor_px is not None:
            check_number("sigma_floor_px", self.sigma_floor_px, lo=0, lo_open=True)   # None: from the camera
        check_number("d_max_deg", self.d_max_deg, hi=90, hi_open=True)
        if self.d_min_deg is not None:                   # None: from the camera
            check_number("d_min_deg", self.d_min_deg, lo=0)
            if not self.d_min_deg < self.d_max_deg:
                raise ConfigError(f"d_min_deg ({self.d_min_deg!r}) must be smaller than d_max_deg "
                                  f"({self.d_max_deg!r})")
        for name in ("beta", "side_beta"):
            check_number(name, getattr(self, name), lo=0, lo_open=True)
        check_whole("min_shared", self.min_shared, 0, 3)
        check_whole("max_stars", self.max_stars, 3, 10_000)
        check_whole("max_candidates", self.max_candidates, 1)
        check_whole("image_slaves", self.image_slaves, 2)
        check_number("mag_margin", self.mag_margin)
        check_number("deep_mag_limit", self.deep_mag_limit)
        check_flag("assign_all", self.assign_all)
        check_whole("hypotheses", self.hypotheses, 0, 10_000)
        check_number("check_mag_limit", self.check_mag_limit)
        check_whole("check_min_stars", self.check_min_stars, 4)
        check_number("check_fraction", self.check_fraction, lo=0, hi=1)
        for name in ("verify_min_fraction", "confirm_fraction"):
            check_number(name, getattr(self, name), lo=0, hi=1)
        for name in ("exclude_doubles", "swap_slaves", "majority", "verify", "nearest_check", "unique_only",
                     "conflict_fails", "stop_first", "radial_sigma",
                     "lone_triangles"):
            check_flag(name, getattr(self, name))

    def derived(self, catalog: Catalog, camera: Camera) -> PTP:
        """``d_min_deg`` and ``sigma_floor_px`` left None set by :func:`camera_rules` for ``camera`` and
        ``sigma_px`` (the harness has already set it from the simulator; None = noise-free)."""
        d_min_deg, floor_px = camera_rules(camera, self.sigma_px)
        return dataclasses.replace(self, d_min_deg=d_min_deg if self.d_min_deg is None else self.d_min_deg,
                                   sigma_floor_px=floor_px if self.sigma_floor_px is None else self.sigma_floor_px)

    def sigma_eff_px(self, sigma_floor_px: float = SIGMA_FLOOR_PX) -> float:
        """The centroid noise the windows use: ``sigma_px`` (None = 0) floored at ``sigma_floor_px``
        (the database's; the default is the paper camera's 1 px); with ``radial_sigma`` divided by sqrt(2)
        (the per-axis share of a 2-D noise of that size)."""
        sigma = max(self.sigma_px or 0.0, sigma_floor_px)
        return sigma / math.sqrt(2.0) if self.radial_sigma else sigma

    def tolerances(self, database: PTPDatabase) -> Tolerances:
        """The parameters as the kernel's tolerance bundle; d_min and the noise floor, when left None
        (an instance that was not :meth:`derived`, e.g. outside the harness), are the database's."""
        if self.d_min_deg is None or self.sigma_floor_px is None:
            return _tolerances(self, database.d_min_deg, database.sigma_floor_px)
        return self._derived_tol

    @cached_property
    def _derived_tol(self) -> Tolerances:
        return self._tol(self.d_min_deg, self.sigma_floor_px)

    @cached_property
    def _d_max(self) -> float:
        """d_max as a scaled chord (872.8 for 5 deg)."""
        return CHORD_SCALE * rad_to_chord(math.radians(self.d_max_deg))

    def _tol(self, d_min_deg: float, sigma_floor_px: float) -> Tolerances:
        return Tolerances(self.sigma_eff_px(sigma_floor_px), CHORD_SCALE, _chord(d_min_deg), self._d_max,
                          int(self.n_slaves),
                          float(self.beta), float(self.side_beta), bool(self.exclude_doubles),
                          bool(self.swap_slaves), int(self.min_shared), bool(self.majority), bool(self.verify),
                          float(self.verify_min_fraction), float(self.confirm_fraction), int(self.max_stars),
                          int(self.max_candidates), int(self.image_slaves), float(self.mag_limit + self.mag_margin),
                          bool(self.assign_all), int(self.hypotheses), int(self.check_min_stars),
                          float(self.check_fraction), bool(self.nearest_check), bool(self.unique_only),
                          bool(self.conflict_fails), bool(self.stop_first), bool(self.lone_triangles))

    def build(self, catalog: Catalog, camera: Camera) -> PTPDatabase:
        settled = self.derived(catalog, camera)
        d_min_deg, sigma_floor_px = float(settled.d_min_deg), float(settled.sigma_floor_px)
        if not d_min_deg < self.d_max_deg:
            raise ConfigError(f"ptp: d_min ({d_min_deg:g} deg on this camera) must be smaller than d_max_deg "
                              f"({self.d_max_deg!r})")
        d_min = _chord(d_min_deg)
        guide = catalog.brighter_than(self.mag_limit)
        if self.exclude_doubles:
            pairs = cKDTree(guide.unit_icrs).query_pairs(d_min / CHORD_SCALE, output_type="ndarray")
            double = np.zeros(len(guide), dtype=bool)
            double[pairs.ravel()] = True
            guide = guide.subset(~double)
        if len(guide) < 3:
            raise ConfigError(f"ptp: only {len(guide)} catalog stars have V <= {self.mag_limit}")
        by_z = np.argsort(guide.unit_icrs[:, 2], kind="stable")   # guide rows in declination order
        unit = np.ascontiguousarray(guide.unit_icrs[by_z])
        guide_hip = guide.hip[by_z]
        tree = cKDTree(unit)
        lists = tree.query_ball_point(unit, self._d_max / CHORD_SCALE)
        neighbours, offsets = [], [0]
        for i, js in enumerate(lists):
            js = np.asarray(js, dtype=np.int64)
            d = CHORD_SCALE * np.linalg.norm(unit[js] - unit[i], axis=1)
            ok = (js != i) & (d >= d_min) & (d <= self._d_max)
            js, d = js[ok], d[ok]
            neighbours.append(js[np.argsort(d, kind="stable")])
            offsets.append(offsets[-1] + js.size)
        ids, sides = build_triangles(unit, np.concatenate(neighbours), np.asarray(offsets, dtype=np.int64),
                                     d_min, self._d_max, int(self.n_slaves), CHORD_SCALE)
        if len(ids) < 2:
            raise ConfigError("ptp: the catalog yields fewer than two feature triangles")
        mean = sides.mean(axis=0)
        q = sides - mean
        eigval, eigvec = np.linalg.eigh(q.T @ q)         # C = Q Q^T (section 2.1, step 2)
        axis = eigvec[:, -1] * np.sign(eigvec[:, -1].sum())
        proj = q @ axis                                   # eq. 3
        order = np.argsort(proj, kind="stable")
        kv = kvector_make(proj[order], values_dtype=np.float32, index_dtype=_index_dtype(len(order)))
        return PTPDatabase(kv=kv, ids=ids[order].astype(_index_dtype(len(guide))),
                           mean=mean, axis=axis,
                           guide_hip=guide_hip.astype(np.int64), guide_unit=unit.astype(np.float32),
                           deep=deep_sky(catalog, self.deep_mag_limit if self.assign_all else -math.inf),
                           extra_unit=check_stars(catalog, guide_hip,
                                                  self.check_mag_limit if self.hypotheses else -math.inf),
                           explained_variance=float(eigval[-1] / eigval.sum()),
                           index=side_index(np.ascontiguousarray(sides[order].T, dtype=np.float32)),
                           d_min_deg=d_min_deg, sigma_floor_px=sigma_floor_px)

    def identify(self, database: PTPDatabase, observation: Observation) -> Identification:
        """:func:`~starid_algorithms.ptp.kernels.identify_kernel`, then (``assign_all``) the attitude of the
        identified stars (Wahba) assigns every detection to the deep catalog star predicted within the
        tolerance (``starid.kernels.assign_all``, one-to-one only). Counters: :data:`WORK_NAMES`."""
        camera = observation.camera
        tol, params, (narrow, wide), view = self.kept("kernel_call", (database, camera),
                                                      lambda: self._kernel_call(database, camera))
        x_px = observation.x_px
        hip, counts, tail = identify_kernel(x_px, observation.y_px, observation.mag, params, narrow, wide)
        if tol.assign_all:
            sel, rows = unpack_tail(tail)
            if database.deep.unit.shape[0] > 0 and np.count_nonzero(rows >= 0) >= 3:
                frame = view.frame    # the kernel's unit vectors of the detections that took part, the same bits
                unit = backproject_px(x_px[sel], observation.y_px[sel], frame.f_px, frame.cx_px, frame.cy_px)
                attitude = wahba_rows(unit, np.ascontiguousarray(rows), database.guide_unit)
                assign_all(attitude, observation.x_px, observation.y_px, view.frame, database.deep,
                           tol.side_beta * math.sqrt(2.0) * tol.sigma_px / view.frame.f_px, hip)
        return Identification(hip, counters=dict(zip(WORK_NAMES, counts, strict=True)))

    def _kernel_call(self, database: PTPDatabase, camera: Camera) -> tuple:
        """What :meth:`identify` hands the kernel for one (database, camera), kept by identity
        (:meth:`~starid.plugin.Algorithm.kept`: one test per image instead of the tolerances', the view's
        and the parameter array's look-ups, some 5 us of a call whose Python objects are out of the cache):
        ``(tolerances, params_of(view, tolerances), packed tables, view)``."""
        view = _view(camera)
        tol = self.tolerances(database)
        return tol, params_of(view, tol), database.packed, view

    def explain(self, database: PTPDatabase, observation: Observation) -> Explanation:
        """The image triangles PTP formed (every master with its nearest slaves) as segments; bold:
        the sides of the first image triangle whose three identified stars form a database triangle."""
        n = len(observation)
        hip = self.identify(database, observation).hip
        x, y, mag = observation.x_px, observation.y_px, observation.mag
        sel = select_stars(x, y, mag, self.max_stars) if n else np.zeros(0, dtype=np.int64)
        tol = self.tolerances(database)
        sel = sel[mag[sel] <= tol.star_mag_max]
        unit = observation.camera.backproject(x[sel], y[sel])
        dist = CHORD_SCALE * np.linalg.norm(unit[:, None] - unit[None], axis=2)
        usable = np.ones(sel.size, dtype=bool)
        if self.exclude_doubles:
            close = (dist < tol.d_min) & ~np.eye(sel.size, dtype=bool)
            usable = ~close.any(axis=1)
        n_img = max(self.n_slaves, self.image_slaves)
        out = np.empty(n_img, dtype=np.int64)
        triangles = []
        for m in range(sel.size):
            if not usable[m]:
                continue
            k = nearest_slaves(dist[m], unit, usable, m, tol.d_min, self._d_max, n_img, out)
            triangles += [(m, out[a], out[b]) for a in range(k) for b in range(a + 1, k)]
        db_tri = {frozenset(t) for t in database.guide_hip[database.ids.astype(np.int64)].tolist()}
        segments, highlight, seen, matched = [], [], set(), None
        for tri in triangles:
            key = frozenset(int(v) for v in tri)
            if key in seen:
                continue
            seen.add(key)
            ids = [int(hip[sel[v]]) for v in tri]
            base = len(segments)
            for a, b in ((0, 1), (1, 2), (0, 2)):
                i, j = sel[tri[a]], sel[tri[b]]
                segments.append([[x[i], y[i]], [x[j], y[j]]])
            if matched is None and min(ids) >= 0 and frozenset(ids) in db_tri:
                matched = tri
                highlight = [base, base + 1, base + 2]
        points = np.stack([x, y], axis=1) if n else np.zeros((0, 2))
        labels = tuple(str(h) if h >= 0 else "" for h in hip)
        n_id = int(np.sum(hip >= 0))
        caption = (f"PTP: {len(seen)} image triangles (each detection a master with its {n_img} nearest slaves); "
                   + (f"bold: a matched triangle; {n_id} of {n} stars identified." if matched is not None
                      else f"no triangle matched a validated database triangle; {n_id} of {n} stars identified."))
        polygons = () if matched is None else (np.array([[x[sel[v]], y[sel[v]]] for v in matched]),)
        return Explanation(segments=np.array(segments).reshape(-1, 2, 2), polygons=polygons, points=points,
                           labels=labels, caption=caption, highlight=np.array(highlight, dtype=np.int64))
