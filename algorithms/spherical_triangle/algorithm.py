"""The spherical-triangle plugin (Cole & Crassidis 2004, as Galvizo & Lim 2018 ran it): parameters,
triangle database, identify, explain (over ``kernels.py`` and ``starid.kernels.triangles``)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from starid_algorithms.pyramid.algorithm import d_min_for

from starid.camera import Camera
from starid.catalog import Catalog
from starid.kernels import camera_frame, rad_to_chord
from starid.kernels.triangles import SPHERICAL, TriangleIndex, guide_triangles
from starid.observation import Observation
from starid.params import check_flag, check_number, check_whole, param
from starid.plugin import Algorithm, Database, Explanation, Identification

from .kernels import WORK_NAMES, SphTol, identified_hip, packed_params, spherical_packed

#: centroid-noise floor of the windows (px): a noise-free world still gets a window
SIGMA_FLOOR_PX = 1.0

#: ``max_hits`` left None: this fraction of the stored triangles, at least ``MAX_HITS_FLOOR``. A window
#: scaled with the field (sigma in rad ~ fov / px) holds a fixed fraction of the database (triangle count
#: ~ fov^4, area density ~ fov^2, window width ~ fov^2), so a fixed count skips every window on a wider
#: camera: 50,000 is 4.4 % of Table 6's 1.14 M triangles but 0.5 % of the 17.7 deg camera's 10.1 M,
#: where it left spherical_triangle 0.33 and composite_pyramid 0.01 (docs/algorithms/spherical_triangle.md).
MAX_HITS_FRACTION = 0.04
MAX_HITS_FLOOR = 50000

#: Galvizo & Lim's reading (hoku at commit 0cb340e): fixed query sigmas 1e-9 on area and moment (their
#: section V-B), SQL LIMIT 500 on the area query, Cole's pivot, |R| = 1, the direct-match test without
#: side check or confirmation, nu_max = 50,000 trios, every image star, hoku's moment depth 3, triangles
#: of any positive area.
GALVIZO2018 = {"sigma_area": 1e-9, "sigma_moment": 1e-9, "max_hits": 500, "truncate_hits": True, "pivot": True,
               "unique_candidate": True, "match_sides": False, "min_extra": 0, "confirm_fraction": 0.0,
               "max_trios": 50000, "max_stars": 100, "max_candidates": 500, "moment_depth": 3,
               "min_area_fov2": 0.0}


def short_side_deg(camera: Camera) -> float:
    """The sensor's short-side field of view rounded down to 0.01 deg (10.0 on the Table 4 camera)."""
    return math.floor(min(camera.fov_x_deg, camera.fov_y_deg) * 100.0 + 1e-6) / 100.0


@dataclass(frozen=True, eq=False)
class TriangleDatabase(Database):
    """Guide-star triangles indexed by (area, moment), and the guide stars.

    index: ``starid.kernels.triangles.TriangleIndex`` (k-vector over the areas, moment-sorted blocks,
        uint16 star rows); guide_unit: float64 (g, 3) ICRS unit vectors sorted by z; guide_hip: int64 (g,).
    fov_db_deg, d_min_deg: the values the database was built with (derived when the parameters are None).
    """

    index: TriangleIndex
    guide_unit: np.ndarray
    guide_hip: np.ndarray
    fov_db_deg: float
    d_min_deg: float


def hip_of(database, rows: np.ndarray) -> np.ndarray:
    """Catalog ids of guide rows (-1 stays -1)."""
    return np.where(rows >= 0, database.guide_hip[np.maximum(rows, 0)], -1).astype(np.int64)


def triangle_explanation(database, observation, rows, trio, n_trios, method, fourth: int = -1) -> Explanation:
    """The matched image triangle as a polygon, its sides bold, every identified star labelled (the
    fourth star ``fourth``, if any, as such)."""
    hip = hip_of(database, rows)
    xy = np.stack([observation.x_px, observation.y_px], axis=1)
    found = np.flatnonzero(hip >= 0)
    corners = [int(s) for s in trio if s >= 0]
    segments = [[xy[corners[a]], xy[corners[(a + 1) % 3]]] for a in range(3)] if len(corners) == 3 else []
    if corners:
        caption = (f"{method}: triangle matched after {n_trios} trio(s);\n"
                   f"{found.size} stars identified by reprojection.")
    else:
        caption = f"{method}: no triangle confirmed after {n_trios} trio(s)."
    return Explanation(segments=np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2),
                       polygons=(xy[corners],) if corners else (), points=xy[found],
                       labels=tuple(f"4th: HIP {hip[s]}" if s == fourth else f"HIP {hip[s]}"
                                    for s in found.tolist()), caption=caption,
                       highlight=np.arange(len(segments)))


def check_triangle_params(algo, min_stars: int, flags: tuple[str, ...]) -> None:
    """The parameter checks the two triangle-feature plugins share (``composite_pyramid`` too)."""
    check_number("mag_limit", algo.mag_limit)
    if algo.fov_db_deg is not None:
        check_number("fov_db_deg", algo.fov_db_deg, lo=0, lo_open=True, hi=90)
    check_number("min_area_fov2", algo.min_area_fov2, lo=0, hi=1)
    if algo.sigma_px is not None:
        check_number("sigma_px", algo.sigma_px, lo=0)
    check_number("beta", algo.beta, lo=0, lo_open=True)
    for key in ("sigma_area", "sigma_moment"):
        if getattr(algo, key) is not None:
            check_number(key, getattr(algo, key), lo=0, lo_open=True)
    check_whole("max_stars", algo.max_stars, min_stars)
    check_whole("max_trios", algo.max_trios, 1)
    if algo.max_hits is not None:
        check_whole("max_hits", algo.max_hits, 1)
    check_whole("max_candidates", algo.max_candidates, 1)
    for key in ("truncate_hits", "unique_candidate", "match_sides", *flags):
        check_flag(key, getattr(algo, key))
    check_whole("min_extra", algo.min_extra, 0)
    check_number("confirm_fraction", algo.confirm_fraction, lo=0, hi=1)
    if algo.d_min_deg is not None:
        check_number("d_min_deg", algo.d_min_deg, lo=0, hi=1)


def derive_triangle_params(algo, camera: Camera):
    """``fov_db_deg`` left None: the sensor's short side; ``d_min_deg`` left None: pyramid's 5.11 px."""
    fill = {}
    if algo.fov_db_deg is None:
        fill["fov_db_deg"] = short_side_deg(camera)
    if algo.d_min_deg is None:
        fill["d_min_deg"] = d_min_for(camera)
    return dataclasses.replace(algo, **fill) if fill else algo


def build_triangle_database(algo, catalog: Catalog, camera: Camera, kind: int, depth: int) -> TriangleDatabase:
    """The :class:`TriangleDatabase` of ``algo``'s (derived) parameters, features of ``kind``."""
    d = algo.derived(catalog, camera)
    min_area = d.min_area_fov2 * math.radians(d.fov_db_deg) ** 2
    index, unit, hip = guide_triangles(catalog, d.mag_limit, d.fov_db_deg, kind, depth, min_area, algo.name)
    return TriangleDatabase(index=index, guide_unit=unit, guide_hip=hip, fov_db_deg=float(d.fov_db_deg),
                            d_min_deg=float(d.d_min_deg))


def max_hits_for(algo, database) -> int:
    """``max_hits``, or when None ``MAX_HITS_FRACTION`` of ``database``'s triangles (at least
    ``MAX_HITS_FLOOR``): the work bound follows the database as the windows do."""
    if algo.max_hits is not None:
        return int(algo.max_hits)
    return max(MAX_HITS_FLOOR, int(math.ceil(MAX_HITS_FRACTION * database.index.area.shape[0])))


def common_tolerances(algo, camera: Camera, database) -> dict:
    """The tolerance fields both plugins' kernels read: the windows from the centroid noise (floor
    ``SIGMA_FLOOR_PX``) or fixed (``sigma_area`` / ``sigma_moment``; one pinned leaves the other open),
    the match radius eps = ``beta`` sqrt(2) sigma, and the work bounds."""
    sigma = max(algo.sigma_px or 0.0, SIGMA_FLOOR_PX) / camera.f_px
    eps = algo.beta * math.sqrt(2.0) * sigma
    fixed_a = algo.beta * algo.sigma_area if algo.sigma_area is not None else 0.0
    fixed_m = algo.beta * algo.sigma_moment if algo.sigma_moment is not None else 0.0
    if fixed_a > 0.0 and fixed_m <= 0.0:
        fixed_m = math.inf
    if fixed_m > 0.0 and fixed_a <= 0.0:
        fixed_a = math.inf
    return dict(sigma_rad=sigma, beta=float(algo.beta), fixed_area=float(fixed_a), fixed_moment=float(fixed_m),
                chord_max=rad_to_chord(math.radians(database.fov_db_deg)), max_hits=max_hits_for(algo, database),
                truncate=bool(algo.truncate_hits), max_candidates=int(algo.max_candidates), eps=eps,
                match_sides=bool(algo.match_sides), eps_side=eps if algo.match_sides else 0.0,
                c_fov=rad_to_chord(camera.half_diagonal_rad), min_extra=int(algo.min_extra),
                confirm_fraction=float(algo.confirm_fraction), max_stars=int(algo.max_stars),
                d_min=max(rad_to_chord(math.radians(database.d_min_deg)), eps), max_trios=int(algo.max_trios))


class PackedTriangleCalls:
    """``kernel_args``, ``_run`` and ``identify`` of a plugin whose kernel, :attr:`packed_kernel`, takes the stars,
    the :class:`TriangleDatabase`'s index and guide vectors and :func:`packed_params` of the plugin's tolerances
    and camera frame, and returns ``(rows, attitude, stars, work)``: spherical triangle's and composite
    pyramid's (their classes name their kernel and define ``tolerances``)."""

    packed_kernel: ClassVar   # a numba kernel: (x_px, y_px, mag, index, guide_unit, params) -> (rows, attitude, ...)

    def kernel_args(self, database: TriangleDatabase, camera: Camera) -> np.ndarray:
        """The kernel's tolerances and camera frame for one (database, camera) as one float64 array
        (``packed_params``), built once and kept by identity (:meth:`~starid.plugin.Algorithm.kept`) rather
        than per image (the tolerances and frame cost some 7-9 us a call, their unboxing some 5 us)."""
        return self.kept("kernel_args", (database, camera),
                         lambda: packed_params(self.tolerances(camera, database), camera_frame(camera)))

    def _run(self, database: TriangleDatabase, observation: Observation):
        return type(self).packed_kernel(observation.x_px, observation.y_px, observation.mag, database.index,
                                        database.guide_unit, self.kernel_args(database, observation.camera))

    def identify(self, database: TriangleDatabase, observation: Observation) -> Identification:
        rows, attitude, _, work = self._run(database, observation)
        hip, found = identified_hip(database.guide_hip, rows, work)   # to_r: every query made when none left one
        return Identification(hip, attitude if found else None,
                              counters=dict(zip(WORK_NAMES, work.tolist(), strict=True)))


@dataclass(frozen=True)
class SphericalTriangle(PackedTriangleCalls, Algorithm):
    """Spherical-triangle area + polar-moment identification (Cole & Crassidis, JSR 41(1):117-121, 2004).

    As Galvizo & Lim ran it ("Empirical Analysis of Common Subgraph Isomorphism Approaches to the
    Lost-in-Space Star Identification Problem", arXiv 1808.08686, 2018, section IV-C; hoku at commit
    0cb340eca0e9af891acfa8a069776530b111c863). Full description and measurements:
    ``docs/algorithms/spherical_triangle.md``.

    Database: every triple of guide stars (V <= ``mag_limit``) whose three sides are <= ``fov_db_deg``
    (hoku's ``within_angle``) and whose area is >= ``min_area_fov2`` x ``fov_db_deg``^2, with its
    spherical area (spherical excess) and polar moment (sum of area x squared distance to the centroid
    over the 4^``moment_depth`` sub-triangles of a midpoint subdivision), indexed by area
    (``starid.kernels.triangles``).

    Identification: image trios in the naive order i < j < k over the ``max_stars`` brightest usable
    detections (at most ``max_trios``); R = the catalog triangles whose area and moment are within
    ``beta`` sigma of the trio's; with ``pivot`` and |R| != 1, Cole's pivot (replace the third star, keep
    the candidates sharing two stars); then the direct-match test: the vertex bijections, an attitude
    each, the one explaining most detections by reprojection wins.

    starid's default (sound) and the reconstruction choices, each a parameter:

    * windows from the centroid noise (``sigma_px``, ``follows`` the simulator, floor 1 px): the
      linearised variance of each feature (Cole's approach; derivatives by finite differences), half-width
      ``beta`` = 3 sigma; ``sigma_area`` / ``sigma_moment`` (Galvizo's reading: 1e-9) pin them instead;
    * ``unique_candidate = False`` and ``pivot = False``: every candidate of a trio goes through the
      direct-match test and the trio is accepted when exactly one stands (with 1 px windows |R| is
      rarely 1 and the pivot drops the true triangle when a window misses it);
    * ``match_sides``: a bijection must agree in its three chords (within eps = ``beta`` sqrt(2) sigma)
      and in chirality; ``min_extra`` / ``confirm_fraction``: the attitude must explain that many further
      detections and that fraction of the guide stars it puts on the sensor (keeps random fields
      unidentified);
    * ``max_hits`` / ``max_candidates``: work bounds (an area window or candidate set larger is skipped;
      ``truncate_hits``: searched up to ``max_hits`` instead, as hoku's SQL LIMIT);
    * ``d_min_deg``: detections closer than this to another are unused (None: pyramid's 5.11 px).
    """

    name: ClassVar[str] = "spherical_triangle"
    packed_kernel: ClassVar = spherical_packed
    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}
    query_only: ClassVar[tuple[str, ...]] = ('sigma_px',)   # only identify reads them (conformance 'query_only')
    published: ClassVar[dict] = GALVIZO2018
    published_readings: ClassVar[dict] = {"galvizo2018": GALVIZO2018}
    kind: ClassVar[int] = SPHERICAL

    mag_limit: float = param(6.0, help="guide stars have V <= this (paper: V < 6)", unit="mag")
    fov_db_deg: float | None = param(None, unit="deg",
                                     help="largest side of a stored triangle; None = the sensor's short side")
    min_area_fov2: float = param(1e-3, help="smallest stored triangle area, as a fraction of fov_db_deg^2")
    moment_depth: int = param(2, help="midpoint-subdivision depth of the polar moment (hoku: 3)")
    sigma_px: float | None = param(None, unit="px",
                                   help="centroid noise the windows assume; None follows the simulator (floor 1 px)")
    beta: float = param(3.0, help="window half-width in sigmas")
    sigma_area: float | None = param(None, unit="sr",
                                     help="fixed area query sigma; None = from the centroid noise (paper: 1e-9)")
    sigma_moment: float | None = param(
        None, help="fixed moment query sigma (sr rad^2); None = from the centroid noise (paper: 1e-9)")
    max_stars: int = param(8, help="brightest usable detections the trios are formed from")
    max_trios: int = param(1000, help="iteration cutoff: most trios tried (hoku's nu_max: 50,000)")
    max_hits: int | None = param(None, help="an area window holding more triangles is skipped (work bound); "
                                 "None = 4 % of the stored triangles, at least 50,000")
    truncate_hits: bool = param(False, help="over max_hits, search the smallest-area max_hits (hoku's SQL LIMIT)")
    max_candidates: int = param(64, help="a trio with more (area, moment) candidates is skipped")
    pivot: bool = param(False, help="Cole's pivot when |R| != 1 (paper)")
    unique_candidate: bool = param(False, help="the direct-match test only when |R| = 1 (paper)")
    match_sides: bool = param(True, help="a bijection must agree in chords and chirality (starid)")
    min_extra: int = param(2, help="detections besides the trio the attitude must explain (starid; 0 = off)")
    confirm_fraction: float = param(
        0.5, help="fraction of the predicted guide stars that must be seen (starid; 0 = off)")
    d_min_deg: float | None = param(None, unit="deg",
                                    help="detections closer than this to another are unused; None = 5.11 px")

    def __post_init__(self):
        check_triangle_params(self, 3, ("pivot",))
        check_whole("moment_depth", self.moment_depth, 1, 5)

    def derived(self, catalog: Catalog, camera: Camera):
        """``fov_db_deg`` left None: the sensor's short side; ``d_min_deg`` left None: pyramid's 5.11 px."""
        return derive_triangle_params(self, camera)

    def build(self, catalog: Catalog, camera: Camera) -> TriangleDatabase:
        return build_triangle_database(self, catalog, camera, self.kind, int(self.moment_depth))

    def tolerances(self, camera: Camera, database) -> SphTol:
        return SphTol(kind=self.kind, depth=int(self.moment_depth), pivot=bool(self.pivot),
                      unique=bool(self.unique_candidate), **common_tolerances(self, camera, database))

    def explain(self, database: TriangleDatabase, observation: Observation) -> Explanation:
        """The matched trio's triangle and the identified stars."""
        rows, _, trio, work = self._run(database, observation)
        return triangle_explanation(database, observation, rows, trio, int(work[0]), "Spherical triangle")
