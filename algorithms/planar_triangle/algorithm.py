"""The planar-triangle plugin: parameters, database build and identify (over ``kernels.py``)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.spatial import cKDTree

from starid.camera import REFERENCE_CAMERA, Camera
from starid.catalog import Catalog
from starid.errors import ConfigError
from starid.kernels import DeepSky, KVector, camera_frame, deep_sky, kvector_make, rad_to_chord
from starid.observation import Observation
from starid.params import check_flag, check_number, check_whole, param
from starid.plugin import Algorithm, Database, Explanation, Identification

from .kernels import (
    MOMENT_BLOCK,
    WORK_COUNTERS,
    Finish,
    Rules,
    Tables,
    Tolerance,
    choose_stars,
    deep_v_mag,
    entry_triangles,
    finish,
    identify_rows,
    identify_subsets,
    moment_blocks,
    moment_fence,
    scan_triangles,
)

MAX_GUIDE_STARS = 65536  # star indices are stored as uint16
DEG2_TO_CHORD2 = (math.pi / 180.0) ** 2


SIGMA_FLOOR_PX = 1.0  # smallest centroid noise the windows assume (px)

#: ``mag_limit=None``: the database keeps the mean number of guide stars in the field that V <= 6.2 gives
#: on the reference camera (Table 4, 10 x 10 deg; 15.2 with the embedded catalog): the faintest
#: limit needed, on a grid of ``MAG_STEP``, so that catalog stars x field solid angle >= the reference's.
REFERENCE_MAG_LIMIT = 6.2
MAG_STEP = 0.1
#: ``min_area_deg2=None``: this fraction of ``fov_db_deg`` squared (0.1 deg^2 at 10 deg), the same
#: triangle shape at any field: the height over the longest side is >= 0.002 ``fov_db_deg``.
MIN_AREA_FOV2 = 1e-3


def derived_mag_limit(catalog: Catalog, camera: Camera) -> float:
    """The guide-star limit with the reference's mean number of guide stars in the field (see
    :data:`REFERENCE_MAG_LIMIT`): the smallest multiple of ``MAG_STEP`` with N(V <= m) x solid
    angle >= N(V <= 6.2) x the reference camera's solid angle; the catalog's faintest star at most.
    Exactly 6.2 on the reference camera (whatever the catalog)."""
    v = np.sort(np.asarray(catalog.v_mag, dtype=np.float64))
    target = np.count_nonzero(v <= REFERENCE_MAG_LIMIT) * REFERENCE_CAMERA.solid_angle_sr
    omega = camera.solid_angle_sr
    top = math.ceil(float(v[-1]) / MAG_STEP)
    for k in range(math.floor(float(v[0]) / MAG_STEP), top + 1):
        m = round(k * MAG_STEP, 1)
        if np.searchsorted(v, m, side="right") * omega >= target:
            return m
    return round(top * MAG_STEP, 1)


def derived_fov_db_deg(camera: Camera) -> float:
    """The largest circle that fits in the sensor at any roll: the short side's field of view,
    rounded down to 0.01 deg (10.0 on the Table 4 camera, whose side is 10.000006 deg)."""
    return math.floor(min(camera.fov_x_deg, camera.fov_y_deg) * 100.0 + 1e-6) / 100.0


@dataclass(frozen=True, eq=False)
class PlanarTriangleDatabase(Database):
    """Cole's triangle catalog plus what verification reads.

    tri_stars: uint16 (N, 3) guide-star rows of the triangle of each entry of the moment index
        (below; entry ``p`` is triangle ``p - p % MOMENT_BLOCK + tri_moment_perm[p]`` of the area order),
        ascending within a row: the kernels name a catalog triangle by its entry, and the hits of one
        block are consecutive entries, so their stars lie together (:meth:`stars_by_area` gives the
        area order).
    tri_area: KVector of float32 (N,) chord-triangle areas, ascending, and their int32
        Mortari k-vector.
    tri_moment: float32 (N,) polar moment ``J`` of the same triangles, sorted within each block of
        ``kernels.MOMENT_BLOCK`` consecutive triangles (the moment index); tri_moment_perm: uint8 (N,)
        offset in its block of the triangle of each entry (:func:`moment_of` reads one triangle's);
        tri_moment_fence: float32 (blocks, 16) every 16th entry of each block (``kernels.moment_fence``),
        where a block's search starts.
    guide_hip: int64 (n,) HIP of each guide star; guide_unit: float64 (n, 3) ICRS unit vectors.
    nbr_ptr: int32 (n + 1,), nbr_idx: uint16 -- guide-star neighbours within the sensor
        diagonal (read only by the distance extension).
    rules: what a stored triangle satisfies (chord of ``fov_db_rad``, ``fov_db_rad``, the
        smallest stored area in chord units).
    mag_limit, fov_db_deg, min_area_deg2: the values the database was built with (the parameters,
        or when None the values derived from the catalog and camera).
    deep: every catalog star (``starid.kernels.DeepSky``: float32 unit vectors sorted by z, int64
        ids), for the coverage check and ``assign_all``; deep_v_mag: float32 their V magnitudes.
    """

    tri_stars: np.ndarray
    tri_area: KVector
    tri_moment: np.ndarray
    tri_moment_perm: np.ndarray
    tri_moment_fence: np.ndarray
    guide_hip: np.ndarray
    guide_unit: np.ndarray
    nbr_ptr: np.ndarray
    nbr_idx: np.ndarray
    rules: Rules
    deep: DeepSky
    deep_v_mag: np.ndarray
    mag_limit: float
    fov_db_deg: float
    min_area_deg2: float

    def moment_of(self, t: int) -> float:
        """Polar moment of triangle ``t`` (area order)."""
        base = t - t % MOMENT_BLOCK
        block = self.tri_moment_perm[base:base + MOMENT_BLOCK]
        return float(self.tri_moment[base + int(np.flatnonzero(block == t - base)[0])])

    def stars_by_area(self) -> np.ndarray:
        """``tri_stars`` in area order (row ``t``: the stars of triangle ``t``)."""
        out = np.empty_like(self.tri_stars)
        out[entry_triangles(self.tri_moment_perm)] = self.tri_stars
        return out

    def tables(self) -> Tables:
        """The arrays the kernels read, as one bundle."""
        return Tables(self.tri_stars, self.tri_area, self.tri_moment, self.tri_moment_fence, self.tri_moment_perm,
                      self.guide_unit, self.nbr_ptr, self.nbr_idx, self.rules)


def _neighbour_csr(unit: np.ndarray, chord_max: float, symmetric: bool) -> tuple[np.ndarray, np.ndarray]:
    """CSR lists of the stars within ``chord_max`` of each star (only ``j > i`` unless symmetric)."""
    pairs = cKDTree(unit).query_pairs(chord_max, output_type="ndarray").astype(np.int64)
    if symmetric:
        pairs = np.concatenate([pairs, pairs[:, ::-1]])
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    ptr = np.zeros(unit.shape[0] + 1, dtype=np.int64)
    np.add.at(ptr, pairs[:, 0] + 1, 1)
    return np.cumsum(ptr), pairs[:, 1].copy()


@dataclass(frozen=True)
class PlanarTriangle(Algorithm):
    """Planar-triangle area + polar-moment pivoting (Cole & Crassidis, JGCD 29(1):64-71, 2006).

    Features (Cole & Crassidis section II): every star triple is a planar triangle whose sides
    are the chords between unit vectors; its area ``A`` (Heron) and polar moment
    ``J = A (a^2 + b^2 + c^2) / 36`` (paper eq. 16) are attitude invariant. Their variances
    (paper eqs. 9-20, QUEST noise model ``R_i = sigma^2 (I - b_i b_i^T)``, ``sigma =
    sigma_px / f_px``; in a numerically stable cross-product form) give the search windows
    ``[x - beta sigma_x, x + beta sigma_x]``, ``beta = 3`` (Cole's ``sigx``).

    Database (Cole's catalog of planar triangles): every triple of guide stars
    (V <= ``mag_limit``) whose smallest enclosing circle (``CalcFOV.m``) has an angular diameter
    <= ``fov_db_deg`` and whose area is >= ``min_area_deg2``, sorted by area and indexed by the
    k-vector (the shared linear one; Cole's parabolic line is an indexing detail that does not
    change the hits). Stored compactly: uint16 star rows, float32 area and moment (float32
    resolves an area to ~6e-8 relative, far below the narrowest search window, see tests).

    Identification (``MatchStarsWPlanarTris.m``): all image triangles within ``fov_db_deg``
    are looked up by area; those with more than ``climit`` hits are dropped. The start triangle
    is the largest-area one; the chain adds, up to ``pivot_limit`` times, the unused triangle
    of largest area sharing two stars with the previous one. Finalists = start hits whose ``J``
    is in its window; each pivot keeps the (finalist, candidate) pairs whose catalog triangles
    share two stars (candidates filtered by area, then ``J``); the search stops at one
    finalist (success) or none (failure) and is abandoned when the finalists grow
    (``abort_if_finalists_grow``, the paper's rule).

    Parameters and the reconstructed / extension choices:

    * ``sigma_px = None`` (follows the simulator's centroid noise, ``follows``): the noise the
      windows assume; None outside the harness means 1 px, and the windows never assume less than
      ``SIGMA_FLOOR_PX = 1`` px (a noise-free world still needs a window; at <= 1 px the results
      are those of the former fixed 1 px).

    Camera-dependent parameters default to None = derived from the catalog and camera
    (:meth:`derived`, which the harness calls before ``build``; the values used are also stored in
    the database, ``mag_limit`` / ``fov_db_deg`` / ``min_area_deg2``); on the Table 4 camera the
    rules give exactly the former fixed 6.2, 10 and 0.1:

    * ``fov_db_deg = None``: the sensor's short-side field of view rounded down to 0.01 deg
      (``derived_fov_db_deg``; 10 on Table 4, 20 on Luo's camera): the triangle must fit in the
      square sensor; a circle of that diameter is the largest that fits at any roll. A fixed 10
      deg on a 20 deg field left the triples of the 8 brightest stars (median enclosing circle
      14 deg) mostly unstored: 42-47 % of noise-free images identified. Cole's 6.94 deg (for an
      8 deg circular FOV) came from his quad-tree level, not from the method.
    * ``min_area_deg2 = None``: ``MIN_AREA_FOV2 * fov_db_deg^2`` (0.1 at 10 deg, 0.4 at 20): rejects
      nearly collinear triangles: the height over the longest side stays >= 0.002 ``fov_db_deg``
      (0.02 deg, ~2 px of a 1024 px sensor), below which chirality is within the noise.
    * ``climit = 100_000`` (paper 10,000): Cole's limit was for sigma ~ 21-27 urad and 663k
      triangles; hits grow with the window width (sigma = 171 urad here, x6.3) and the
      database size (1.1 M, x1.7), so the same guard is ~10x larger. With 10,000 most image
      triangles are dropped at 1 px (noise-free id rate 0.67 on 1,000 trials).
    * ``pivot_limit = None`` (no limit; the paper reports both 2 pivots and no limit, 94 vs
      95 % at its 0.1 px noise). At 1 px the finalists need 3-4 pivots (measured: median
      chain of 4 triangles), so a limit of 2 leaves most images inconclusive.
    * ``consistent_chain`` (reconstructed, default on; Cole: off): a finalist chain must share
      its stars exactly as the image chain does (equal sorted membership signatures), i.e.
      the pair a pivot shares is the same pair of stars throughout. Cole compares only with
      the last triangle, which lets wrong chains survive indefinitely (0.78 vs 0.94).
    * per-star correspondences (reconstructed; Cole output only the set of stars): every vertex
      order of the start triangle is propagated down the chain; the unique assignment whose
      triangles agree in chords (within ``beta * sqrt(2) * sigma``) and chirality, and whose
      stars agree pairwise, is kept -- none or several: no result.
    * ``extend`` (extension, default on): after a unique chain, further observed stars are
      identified when exactly one guide star agrees in angular distance with every chain star;
      then every reported star must agree pairwise with ``min_support`` others
      (``starid.kernels.verify_pairwise``) and at least ``min_verified`` stars must remain
      (Cole: the method needs 4 stars, i.e. one pivot, for a success).
    * ``restarts = 0`` (reconstructed): after a failure, start again from the next-largest
      triangle, up to ``restarts`` more times. Cole's own code tries only the largest-area start
      triangle (``restarts=0``). The former default 3 was chosen on the seed it was evaluated on;
      re-tuned on seed 7 (500 images, 1 px / 0.5 Mv, real sky) it buys nothing once star subsets
      are tried (90.8 % with 0 and 1 at V <= 6, 96.2 % with 0 and 1 at the default V <= 6.2) and
      costs 1.5x the mean time, so 0; without subsets (the paper's pivoting on all stars, V <= 6)
      3 restarts give 15.0 % vs 9.4 % in the real sky.

    Flight precautions and final step (extensions, not in the paper; docs/algorithms/planar_triangle.md
    has the measured table):

    * ``max_stars = 8``, ``mag_margin = 1.0``: triangles are built only from image stars with
      measured magnitude <= ``mag_limit + mag_margin`` (fainter ones cannot be guide stars), the
      ``max_stars`` brightest of them. In the V <= 8 sky about 4 image stars per field are not in
      the V <= 6 database; every pivot chain through one of them breaks (14-20 % identified).
      The chosen stars are max(``max_stars``, ``wide_stars``).
    * ``subset_size = 5``, ``max_subsets = 56``: the pivoting runs on subsets of ``subset_size``
      of the chosen stars, brightest combination first, until one identifies (all C(8, 5) = 56
      by default); a subset without the stray faint star succeeds. ``None``: all chosen stars at
      once. Measured (seed 7, 500 images, real sky, V <= 6): 9.4 % for all stars at once,
      90.8 % with subsets of 5 of the 8 brightest.
    * ``small_subset_size = 4``, ``max_small_subsets = 70`` (last stage, after every
      ``subset_size`` subset failed): subsets of 4 of the chosen stars, brightest first (all
      C(8, 4) = 70), for fields whose brightest detections hold only 4 guide stars. One pivot
      chain of 4 stars is weak evidence, so such a result must be confirmed by the whole image:
      the attitude must give, by reprojection (the final step below), ids to at least
      max(min(``small_confirm``, others), ceil(``small_confirm_fraction`` x others)) of the
      ``others`` image stars outside the subset (defaults 1 and 0.5), and pass the coverage
      check. ``None``: no last stage.
    * ``wide_stars = None`` (off; an optional middle stage): subsets of ``subset_size`` of the
      ``wide_stars`` brightest stars that contain at least one star beyond the ``max_stars``
      brightest, at most ``max_wide_subsets``. Measured (seed 7, real sky, V <= 6 database, with
      the 4-star stage): +0.4 to +1.3 points (500 and 1,000 images) for 1.2x the mean time; with
      the V <= 6.2 database it rescued 2 of 1,000 images, so it is not the default.
    * ``mag_limit = None`` (``derived_mag_limit``): the smallest multiple of 0.1 mag whose guide
      stars are, per field of this camera, at least as many on average as V <= 6.2 gives on the
      Table 4 camera (15.2 per field with the embedded catalog): 6.2 there, 5.0 on a 20 deg field,
      6.6 on an 8 deg one. The same field statistics at any field size; a fixed 6.2 with 20 deg
      triangles would hold 29.8 M triangles (14x; V <= 5.0: 0.56 M, 12 MB). Why 6.2 on Table 4
      (extension; the paper's database is V <= 6, ``mag_limit=6.0``): in the real sky magnitude
      noise brings V 6-6.5 stars among the brightest detections; a database
      0.2 mag deeper holds most of them (41.9 MB, 2.1 M triangles; the paper's was 178 MB).
      Measured on seed 7 (1,000 images, real sky, 1 px / 0.5 Mv, same process): V <= 6.0 with
      the 4-star stage 93.1 %, V <= 6.1 95.1 %, V <= 6.2 96.5 % (0.1 % misidentified).
    * Work shared between subsets (implementation, not a parameter): the image triangles of all
      chosen stars, their area hits and their moment-filtered candidates (with a hash table of
      the candidates' star pairs, what a pivot matches on) are computed once per image and
      reused by every subset that contains them; the moment filter reads a per-block moment
      index (``tri_moment`` sorted within blocks of 256 area-ordered triangles) instead of
      scanning every area hit. Same identifications as recomputing them (tests), 0.6x the mean
      time.
    * ``assign_all`` (default on): once the attitude is known (Wahba from the identified stars),
      every other image star gets the catalog star (any V, the ``deep`` list) that projects within
      ``beta sqrt(2) sigma`` of it (``starid.kernels.reproject_assign``), unless that star is more
      than ``mag_margin`` fainter than measured; star recall 0.91 in the real sky (seed 11).
    * coverage check (``coverage_mag_margin = 0.75``, ``max_missed_fraction = 1/3``; 1 turns it
      off): the attitude must explain the bright stars of its field -- of the catalog stars with
      V <= min(``mag_limit``, faintest image star) - ``coverage_mag_margin`` that it puts on the
      sensor, at most max(1, ``max_missed_fraction`` x their number) may lack an identified star.
      With 56 subsets tried, 30 random points otherwise give chance 4-star matches.

    ``sigma_deg`` (off by default) pins the centroid noise the windows assume in degrees, without the
    1 px floor: the fixed tolerance of Galvizo & Lim's comparison (``planar_triangle:galvizo2018``).

    The paper's simulation is not "only guide stars imaged": Zhou & Ye (section 3.5), whose
    Table 6 compares this method, add magnitude noise that both adds and removes stars; the sky
    with only V <= 6 stars (``--sky-mag-limit 6``) is this library's calibration of their star
    counts, and the V <= 8 sky (the default) is the real one.

    Method step by step, parameters, paper vs reconstructed and measurements:
    ``docs/algorithms/planar_triangle.md``.
    """

    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}
    query_only: ClassVar[tuple[str, ...]] = ('sigma_px',)   # only identify reads them (conformance 'query_only')
    name: ClassVar[str] = "planar_triangle"
    #: the paper's method: V <= 6 catalog, pivoting over every image star, no subsets, no coverage
    #: check, only the pivot's stars reported; after a failure it starts again from the next-largest
    #: triangle twice (closest to Zhou & Ye's Table 6, docs/algorithms/planar_triangle.md) (``planar_triangle:paper``)
    published: ClassVar[dict] = {"mag_limit": 6.0, "max_stars": None, "subset_size": None, "small_subset_size": None,
                                 "assign_all": False, "max_missed_fraction": 1.0, "restarts": 2}
    #: Galvizo & Lim (2018) ran it (hoku) on V < 6 stars, trios within 20 deg, with fixed windows
    #: (sigma_a = sigma_tau = 1e-9); here the windows stay Cole & Crassidis' propagated ones for a fixed
    #: 5e-5 deg centroid noise (no 1 px floor); no extension: only the pivot's stars are reported, as
    #: hoku's map h (so 3 verified stars suffice); a new start triangle after a failure while the
    #: 500-access limit lasts (about 53 accesses per failed start: 9 restarts); the 24 brightest
    #: stars (hoku's limit queries at most 500 triangles; this kernel looks up every image triangle
    #: first and reserves room for each: C(24, 3) = 2,024 of them, 2 GB of address space)
    #: (``planar_triangle:galvizo2018``; docs/experiments.md)
    published_readings: ClassVar[dict] = {"galvizo2018": {
        **published, "max_stars": 24, "restarts": 9, "extend": False, "min_verified": 3, "sigma_deg": 5e-5,
        "fov_db_deg": 20.0}}

    mag_limit: float | None = param(
        None, unit="mag",
        help="guide stars have V <= this; None = as many per field as V <= 6.2 on Table 4 (paper: 6.0)")
    sigma_px: float | None = param(None, unit="px",
                                   help="centroid noise the windows assume; None follows the simulator (floor 1 px)")
    fov_db_deg: float | None = param(
        None, unit="deg",
        help="largest enclosing-circle diameter of a stored triangle; None = the short-side field of view")
    min_area_deg2: float | None = param(
        None, help="least area of a stored triangle, against collinear ones; None = 0.001 fov_db_deg^2", unit="deg^2")
    beta: float = param(3.0, help="half-width of the area and moment windows in units of sigma (paper: 3)")
    climit: int = param(100_000, help="image triangles with more area hits than this are dropped (paper: 10,000)")
    pivot_limit: int | None = param(None, help="most pivots of a chain; None = no limit (paper: 2 or no limit)")
    abort_if_finalists_grow: bool = param(True, help="abandon the search when the finalists grow (paper)")
    consistent_chain: bool = param(
        True, help="finalist chains must share stars exactly as the image chain (starid's reconstruction)")
    restarts: int = param(0, help="further start triangles tried after a failure, next-largest first (paper: 0)")
    extend: bool = param(
        True, help="identify further stars by distances to the chain stars, then verify (starid's extension)")
    min_support: int = param(
        2, help="others every reported star must agree with pairwise after extend (starid's extension)")
    min_verified: int = param(4, help="least stars that must remain after the pairwise check (starid's extension)")
    max_stars: int | None = param(
        8, help="brightest image stars triangles are built from; None = all (starid's extension)")
    mag_margin: float = param(1.0, unit="mag",
                              help="image stars fainter than mag_limit + this build no triangle (starid's extension)")
    assign_all: bool = param(
        True, help="assign every other image star the catalog star the attitude projects on it (starid's extension)")
    subset_size: int | None = param(
        5, help="pivoting runs on subsets of this many chosen stars; None = all at once (starid's extension)")
    max_subsets: int = param(56,
                             help="most subsets of subset_size tried, brightest combination first (starid's extension)")
    wide_stars: int | None = param(
        None, help="middle stage: subsets reaching into this many brightest stars; None = off (starid's extension)")
    max_wide_subsets: int = param(196, help="most subsets tried in the wide_stars stage (starid's extension)")
    small_subset_size: int | None = param(
        4, help="last stage: subsets of this many stars, confirmed by the image; None = off (starid's extension)")
    max_small_subsets: int = param(70, help="most subsets tried in the small_subset_size stage (starid's extension)")
    small_confirm: int = param(
        1, help="other image stars a small-subset result must identify by reprojection (starid's extension)")
    small_confirm_fraction: float = param(
        0.5, help="fraction of the other image stars a small-subset result must identify (starid's extension)")
    coverage_mag_margin: float = param(
        0.75, unit="mag",
        help="coverage check: catalog stars this much brighter than the limit must be seen (starid's extension)")
    max_missed_fraction: float = param(
        1.0 / 3.0, help="coverage check: largest fraction of those bright stars missed; 1 = off (starid's extension)")
    sigma_deg: float | None = param(
        None, unit="deg",
        help="fixed centroid noise the windows assume, no floor; None = from sigma_px (a fixed tolerance, as hoku's)")

    @property
    def sigma_window_px(self) -> float:
        """The centroid noise the windows assume: ``sigma_px`` (the simulator's when None), at least
        ``SIGMA_FLOOR_PX`` so that a noise-free world still gets a window."""
        return max(self.sigma_px or 0.0, SIGMA_FLOOR_PX)

    def __post_init__(self):
        if self.mag_limit is not None:
            check_number("mag_limit (or None: from the field's size)", self.mag_limit)
        if self.sigma_px is not None:
            check_number("sigma_px (or None: follow the simulator)", self.sigma_px, lo=0)
        if self.sigma_deg is not None:
            check_number("sigma_deg (or None: from sigma_px)", self.sigma_deg, lo=0, hi=10, lo_open=True)
        if self.fov_db_deg is not None:
            check_number("fov_db_deg (or None: the sensor's)", self.fov_db_deg, lo=0, hi=90, lo_open=True, hi_open=True)
        if self.min_area_deg2 is not None:
            check_number("min_area_deg2 (or None: from fov_db_deg)", self.min_area_deg2, lo=0)
        check_number("beta", self.beta, lo=0, lo_open=True)
        if self.pivot_limit is not None:
            check_whole("pivot_limit (or None: no limit)", self.pivot_limit, 0)
        for field, low in (("climit", 1), ("restarts", 0), ("min_support", 0), ("min_verified", 1)):
            check_whole(field, getattr(self, field), low)
        if self.max_stars is not None:
            check_whole("max_stars (or None: every star)", self.max_stars, 3)
        check_number("mag_margin", self.mag_margin, lo=0)
        if self.subset_size is not None:
            check_whole("subset_size (or None: all chosen stars at once)", self.subset_size, 3)
        check_whole("max_subsets", self.max_subsets, 1)
        if self.wide_stars is not None:
            check_whole("wide_stars (or None: no wider stage)", self.wide_stars, 3)
        check_whole("max_wide_subsets", self.max_wide_subsets, 0)
        if self.small_subset_size is not None:
            check_whole("small_subset_size (or None: no last stage)", self.small_subset_size, 3)
        check_whole("max_small_subsets", self.max_small_subsets, 0)
        check_whole("small_confirm", self.small_confirm, 0)
        check_number("small_confirm_fraction", self.small_confirm_fraction, lo=0, hi=1)
        check_number("coverage_mag_margin", self.coverage_mag_margin)
        check_number("max_missed_fraction", self.max_missed_fraction, lo=0, hi=1)
        for field in ("abort_if_finalists_grow", "consistent_chain", "extend", "assign_all"):
            check_flag(field, getattr(self, field))

    def derived(self, catalog: Catalog, camera: Camera) -> PlanarTriangle:
        """``mag_limit``, ``fov_db_deg`` and ``min_area_deg2`` left None set for ``camera``
        (:func:`derived_mag_limit`, :func:`derived_fov_db_deg`, ``MIN_AREA_FOV2 * fov_db_deg ** 2``);
        6.2, 10 and 0.1 on the Table 4 camera."""
        mag_limit = float(self.mag_limit) if self.mag_limit is not None else derived_mag_limit(catalog, camera)
        fov_db_deg = float(self.fov_db_deg) if self.fov_db_deg is not None else derived_fov_db_deg(camera)
        min_area = (float(self.min_area_deg2) if self.min_area_deg2 is not None
                    else round(MIN_AREA_FOV2 * fov_db_deg * fov_db_deg, 12))
        return dataclasses.replace(self, mag_limit=mag_limit, fov_db_deg=fov_db_deg, min_area_deg2=min_area)

    def build(self, catalog: Catalog, camera: Camera) -> PlanarTriangleDatabase:
        settled = self.derived(catalog, camera)
        mag_limit, fov_db_deg, min_area_deg2 = settled.mag_limit, settled.fov_db_deg, settled.min_area_deg2
        guide = catalog.brighter_than(mag_limit)
        n = len(guide)
        if n < 3:
            raise ConfigError(f"only {n} guide stars with V <= {mag_limit}; need at least 3")
        if n > MAX_GUIDE_STARS:
            raise ConfigError(f"{n} guide stars exceed the uint16 index limit of {MAX_GUIDE_STARS}")
        unit = np.ascontiguousarray(guide.unit_icrs)
        fov_db_rad = math.radians(fov_db_deg)
        rules = Rules(float(rad_to_chord(fov_db_rad)), fov_db_rad, min_area_deg2 * DEG2_TO_CHORD2)
        ptr, idx = _neighbour_csr(unit, rules.chord_max, symmetric=False)
        stars, area, moment = scan_triangles(unit, ptr, idx, rules)
        if area.shape[0] >= 2**31:
            raise ConfigError(f"{area.shape[0]} triangles exceed the int32 k-vector")
        area32 = area.astype(np.float32)
        order = np.argsort(area32, kind="stable")
        moment_sorted, moment_perm = moment_blocks(moment[order])
        # the stars in the moment index's order (entry p: area-order triangle entry_triangles(perm)[p])
        tri_stars = np.ascontiguousarray(stars[order][entry_triangles(moment_perm)])
        # Neighbours for the distance extension: anything two observed stars can be apart.
        diag_chord = float(rad_to_chord(2.0 * min(camera.half_diagonal_rad, math.pi / 2)))
        nptr, nidx = _neighbour_csr(unit, diag_chord * 1.01, symmetric=True)
        deep = deep_sky(catalog)
        return PlanarTriangleDatabase(
            tri_stars=tri_stars,
            tri_area=kvector_make(area32[order], np.float32, np.int32),
            tri_moment=moment_sorted, tri_moment_perm=moment_perm, tri_moment_fence=moment_fence(moment_sorted),
            guide_hip=guide.hip.astype(np.int64),
            guide_unit=unit, nbr_ptr=nptr.astype(np.int32), nbr_idx=nidx.astype(np.uint16), rules=rules,
            deep=deep, deep_v_mag=deep_v_mag(catalog, deep), mag_limit=mag_limit, fov_db_deg=fov_db_deg,
            min_area_deg2=min_area_deg2)

    def _stages(self, n_chosen: int) -> np.ndarray:
        """Rows ``(size, pool, max_subsets)`` of the subset stages (see ``kernels.identify_subsets``)."""
        stages = [[int(self.subset_size), min(self.max_stars or n_chosen, n_chosen), int(self.max_subsets)]]
        if self.wide_stars is not None and self.max_stars is not None and self.wide_stars > self.max_stars:
            stages.append([int(self.subset_size), int(self.wide_stars), int(self.max_wide_subsets)])
        if self.small_subset_size is not None and self.small_subset_size < self.subset_size:
            stages.append([int(self.small_subset_size), n_chosen, int(self.max_small_subsets)])
        return np.array(stages, dtype=np.int64)

    def _n_chosen(self) -> int | None:
        if self.max_stars is None:
            return None
        return max(self.max_stars, self.wide_stars or 0)

    def _held(self, database: PlanarTriangleDatabase, cam: Camera) -> tuple:
        """What every image of one camera and database shares, built once and kept for the last pair
        (an identification's images share one; rebuilt for another camera or database object):
        ``(database, cam, tables, tol, magnitude cut, n_chosen or -1, stages by chosen-star count,
        index of the small stage or -1, camera frame, Finish rules, Finish rules of the small stage)``."""
        return self.kept("prep", (database, cam), lambda: self._prep(database, cam))

    def _prep(self, database: PlanarTriangleDatabase, cam: Camera) -> tuple:
        tol = self._tolerance(cam)
        n_chosen = self._n_chosen()
        small_stage = -1
        if self.subset_size is not None and self.small_subset_size is not None:
            n_stages = len(self._stages(1))
            if n_stages - 1 > 0:  # the last stage is the small one
                small_stage = n_stages - 1
        eps = tol.beta * math.sqrt(2.0) * tol.sigma_rad
        common = (eps, float(self.mag_margin), float(database.mag_limit), float(self.coverage_mag_margin),
                  float(self.max_missed_fraction))
        return (database, cam, database.tables(), tol, database.mag_limit + self.mag_margin,
                -1 if n_chosen is None else n_chosen, {}, small_stage, camera_frame(cam),
                Finish(*common, bool(self.assign_all)), Finish(*common, True))

    def _run(self, database: PlanarTriangleDatabase, observation: Observation):
        """``(rows per observed star, chain as observed-star indices (L, 3), stage, counters)`` of one
        image; ``stage`` is the subset stage that identified (-1: none; 0 without subsets);
        ``counters`` the kernel's work counters (``None`` when it did not run)."""
        n = len(observation)
        none = np.full(n, -1, dtype=np.int64), np.zeros((0, 3), dtype=np.int64), -1, None
        if n < 3:
            return none
        cam = observation.camera
        held = self._held(database, cam)
        # The stars the triangles are built from: those bright enough to be guide stars (with a
        # margin for magnitude noise), at most ``max_stars`` (``wide_stars``) of them, brightest first,
        # in a canonical order by geometry (the answer does not depend on the input order).
        order, v_cam, rank = choose_stars(observation.x_px, observation.y_px, observation.mag, held[4], held[5],
                                          cam.f_px, cam.cx_px, cam.cy_px)
        if order.size < 3:
            return none
        if cam.distorted:
            v_cam = cam.backproject(observation.x_px[order], observation.y_px[order])
        tables, tol = held[2], held[3]
        if self.subset_size is None:
            rows, chain, work = identify_rows(v_cam, tables, tol)
            stage = 0 if rows.max() >= 0 else -1
        else:
            stages = held[6].get(order.size)
            if stages is None:
                stages = held[6][order.size] = self._stages(order.size)
            rows, chain, stage, work = identify_subsets(v_cam, rank, tables, tol, stages)
        all_rows = np.full(n, -1, dtype=np.int64)
        all_rows[order] = rows
        counts = work.tolist()
        if not counts[9]:
            counts[9] = counts[8] + counts[1]  # to_r: every query made when none left one finalist
        return all_rows, order[chain], int(stage), dict(zip(WORK_COUNTERS, counts, strict=True))

    def identify(self, database: PlanarTriangleDatabase, observation: Observation) -> Identification:
        all_rows, _, stage, counters = self._run(database, observation)
        if stage < 0:  # no stage identified: every row is -1
            return Identification(np.full(len(observation), -1, dtype=np.int64), counters=counters)
        cam = observation.camera
        held = self._held(database, cam)
        small = stage == held[7]
        hip, attitude, accepted = finish(observation.x_px, observation.y_px, observation.mag, all_rows,
                                         database.guide_unit, database.guide_hip, database.deep, database.deep_v_mag,
                                         held[8], held[10] if small else held[9])
        if accepted and small:
            # last stage (few stars): the attitude must also explain ``small_confirm`` further image stars
            guide = all_rows >= 0
            others = int(np.count_nonzero(~guide))
            need = max(min(self.small_confirm, others), math.ceil(self.small_confirm_fraction * others))
            if int(np.count_nonzero(hip[~guide] >= 0)) < need:
                return Identification(np.full(len(observation), -1, dtype=np.int64), counters=counters)
            if not self.assign_all:
                hip = np.where(guide, hip, -1)
        return Identification(hip, attitude if accepted else None, counters=counters)

    def explain(self, database: PlanarTriangleDatabase, observation: Observation) -> Explanation:
        """The pivot sequence of image triangles (the accepted one's last triangle highlighted)."""
        _, chain, _, _ = self._run(database, observation)
        hip = self.identify(database, observation).hip
        x, y = observation.x_px, observation.y_px
        segments, polygons = [], []
        for tri in chain:
            polygons.append(np.c_[x[tri], y[tri]])
            for a, b in ((0, 1), (1, 2), (0, 2)):
                segments.append([[x[tri[a]], y[tri[a]]], [x[tri[b]], y[tri[b]]]])
        accepted = bool(np.any(hip >= 0)) and len(chain) > 0
        highlight = np.arange(3 * len(chain) - 3, 3 * len(chain)) if accepted else np.zeros(0, dtype=np.int64)
        found = np.flatnonzero(hip >= 0)
        caption = (f"Pivot sequence of {len(chain)} image triangles (area, then polar moment); "
                   + (f"one catalog chain survived at the highlighted triangle; {found.size} stars identified."
                      if accepted else "no unique catalog chain: no identification."))
        return Explanation(segments=np.array(segments).reshape(-1, 2, 2), polygons=tuple(polygons),
                           points=np.c_[x[found], y[found]], labels=tuple(f"HIP {h}" for h in hip[found]),
                           caption=caption, highlight=highlight)

    def _tolerance(self, cam: Camera) -> Tolerance:
        return Tolerance(
            sigma_rad=(math.radians(self.sigma_deg) if self.sigma_deg is not None else self.sigma_window_px / cam.f_px),
            beta=float(self.beta), climit=int(self.climit),
            pivot_limit=-1 if self.pivot_limit is None else int(self.pivot_limit),
            abort_if_grow=bool(self.abort_if_finalists_grow), consistent_chain=bool(self.consistent_chain),
            restarts=int(self.restarts), extend=bool(self.extend), min_support=int(self.min_support),
            min_verified=int(self.min_verified))
