"""The Composite Pyramid plugin (Galvizo & Lim 2018, after Toloei et al.): parameters, triangle
database, identify, explain (over ``kernels.py`` and ``starid.kernels.triangles``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from starid_algorithms.spherical_triangle.algorithm import (
    PackedTriangleCalls,
    TriangleDatabase,
    build_triangle_database,
    check_triangle_params,
    common_tolerances,
    derive_triangle_params,
    triangle_explanation,
)

from starid.camera import Camera
from starid.catalog import Catalog
from starid.kernels.triangles import PLANAR
from starid.observation import Observation
from starid.params import check_whole, param
from starid.plugin import Algorithm, Explanation

from .kernels import ComTol, composite_packed

#: Galvizo & Lim's reading (hoku at commit 0cb340e): fixed query sigmas 1e-9 on planar area and moment
#: (their section V-B), SQL LIMIT 500, |R| = 1, one fourth star, the direct-match test without side check
#: or confirmation, nu_max = 50,000 trios, every image star, triangles of any positive area.
GALVIZO2018 = {"sigma_area": 1e-9, "sigma_moment": 1e-9, "max_hits": 500, "truncate_hits": True,
               "unique_candidate": True, "fourth_tries": 1, "match_sides": False, "min_extra": 0,
               "confirm_fraction": 0.0, "max_trios": 50000, "max_stars": 100, "max_candidates": 500,
               "min_area_fov2": 0.0}


@dataclass(frozen=True)
class CompositePyramid(PackedTriangleCalls, Algorithm):
    """Composite Pyramid: Mortari's trio order, planar-triangle (area, moment) features, a fourth-star test.

    Galvizo G., Lim L., "Empirical Analysis of Common Subgraph Isomorphism Approaches to the
    Lost-in-Space Star Identification Problem", arXiv 1808.08686, 2018, section IV-F and Algorithm 4
    (after Toloei et al.'s composite identification); hoku at commit
    0cb340eca0e9af891acfa8a069776530b111c863 (``CompositePyramid``). Full description and measurements:
    ``docs/algorithms/composite_pyramid.md``.

    Database: hoku uses the planar-triangle table: every guide-star (V <= ``mag_limit``) triple with all
    sides <= ``fov_db_deg`` and area >= ``min_area_fov2`` x ``fov_db_deg``^2, with its planar area and
    polar moment ``A (a^2 + b^2 + c^2) / 36`` (Cole & Crassidis 2006 eq. 16), indexed by area
    (``starid.kernels.triangles``).

    Identification: trios (i, j, k) in Mortari's order over the ``max_stars`` brightest usable
    detections (at most ``max_trios``); R = catalog triangles within ``beta`` sigma in area and moment;
    (``unique_candidate``: only |R| = 1 goes on); a fourth star beta is verified by querying the trios
    (b_i, b_j, beta), (b_i, b_k, beta), (b_j, b_k, beta): exactly one catalog star must complete a
    candidate's pair in all three windows; then the direct-match test (every vertex bijection, an
    attitude each, the one explaining most detections wins); a trio is accepted when exactly one
    candidate stands.

    starid's default (sound) and the reconstruction choices, each a parameter:

    * windows from the centroid noise (``sigma_px``, ``follows`` the simulator, floor 1 px): linearised
      feature variances, half-width ``beta`` = 3 sigma; ``sigma_area`` / ``sigma_moment`` pin them
      (Galvizo's reading: 1e-9);
    * ``unique_candidate = False``: every candidate of a trio is tested (at 1 px |R| is rarely 1);
    * ``fourth_tries``: fourth stars tried per trio, brightest first, until one passes (hoku: one random
      star);
    * ``match_sides``, ``min_extra``, ``confirm_fraction``: the bijection must agree in chords and
      chirality, and its attitude must explain further detections (keeps random fields unidentified);
    * ``max_hits`` / ``max_candidates`` / ``truncate_hits``: work bounds (hoku: SQL LIMIT 500);
    * ``d_min_deg``: detections closer than this to another are unused (None: pyramid's 5.11 px).
    """

    name: ClassVar[str] = "composite_pyramid"
    packed_kernel: ClassVar = composite_packed
    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}
    query_only: ClassVar[tuple[str, ...]] = ('sigma_px',)   # only identify reads them (conformance 'query_only')
    published: ClassVar[dict] = GALVIZO2018
    published_readings: ClassVar[dict] = {"galvizo2018": GALVIZO2018}

    mag_limit: float = param(6.0, help="guide stars have V <= this (paper: V < 6)", unit="mag")
    fov_db_deg: float | None = param(None, unit="deg",
                                     help="largest side of a stored triangle; None = the sensor's short side")
    min_area_fov2: float = param(1e-3, help="smallest stored triangle area, as a fraction of fov_db_deg^2")
    sigma_px: float | None = param(None, unit="px",
                                   help="centroid noise the windows assume; None follows the simulator (floor 1 px)")
    beta: float = param(3.0, help="window half-width in sigmas")
    sigma_area: float | None = param(None, help="fixed area query sigma; None = from the centroid noise (paper: 1e-9)")
    sigma_moment: float | None = param(
        None, help="fixed moment query sigma; None = from the centroid noise (paper: 1e-9)")
    max_stars: int = param(8, help="brightest usable detections the trios are formed from")
    max_trios: int = param(1000, help="iteration cutoff: most trios tried (hoku's nu_max: 50,000)")
    max_hits: int | None = param(None, help="an area window holding more triangles is skipped (work bound); "
                                 "None = 4 % of the stored triangles, at least 50,000")
    truncate_hits: bool = param(False, help="over max_hits, search the smallest-area max_hits (hoku's SQL LIMIT)")
    max_candidates: int = param(64, help="a trio with more (area, moment) candidates is skipped")
    unique_candidate: bool = param(False, help="only a trio with |R| = 1 goes on (paper)")
    fourth_tries: int = param(40, help="fourth stars tried per trio, brightest first (paper: one)")
    match_sides: bool = param(True, help="a bijection must agree in chords and chirality (starid)")
    min_extra: int = param(1, help="detections besides the trio the attitude must explain (starid; 0 = off)")
    confirm_fraction: float = param(
        0.5, help="fraction of the predicted guide stars that must be seen (starid; 0 = off)")
    d_min_deg: float | None = param(None, unit="deg",
                                    help="detections closer than this to another are unused; None = 5.11 px")

    def __post_init__(self):
        check_triangle_params(self, 4, ())
        check_whole("fourth_tries", self.fourth_tries, 1)

    def derived(self, catalog: Catalog, camera: Camera):
        """``fov_db_deg`` left None: the sensor's short side; ``d_min_deg`` left None: pyramid's 5.11 px."""
        return derive_triangle_params(self, camera)

    def build(self, catalog: Catalog, camera: Camera) -> TriangleDatabase:
        return build_triangle_database(self, catalog, camera, PLANAR, 1)

    def tolerances(self, camera: Camera, database) -> ComTol:
        return ComTol(kind=PLANAR, depth=1, unique=bool(self.unique_candidate), fourth_tries=int(self.fourth_tries),
                      **common_tolerances(self, camera, database))

    def explain(self, database: TriangleDatabase, observation: Observation) -> Explanation:
        """The matched trio's triangle, the identified stars (the fourth star labelled)."""
        rows, _, four, work = self._run(database, observation)
        return triangle_explanation(database, observation, rows, four[:3], int(work[0]), "Composite pyramid",
                                    int(four[3]))
