"""The interior-angle method as Galvizo & Lim (2018) ran it ("INT"): parameters, identify, explain.

The star-pair database is pyramid's (:func:`starid_algorithms.pyramid.algorithm.build_pair_database`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from starid_algorithms.angle.algorithm import PairKernelCalls
from starid_algorithms.pyramid.algorithm import (
    D_MIN_MAX_DEG,
    SIGMA_FLOOR_PX,
    PairDatabase,
    build_pair_database,
    d_min_for,
    window_eps,
)

from starid.camera import Camera
from starid.catalog import Catalog
from starid.kernels import rad_to_chord
from starid.observation import Observation
from starid.params import check_flag, check_number, check_whole, param
from starid.plugin import Algorithm, Explanation

from .kernels import WORK_NAMES, InteriorTol, identify_kernel

#: the reading of Galvizo & Lim 2018 (arXiv 1808.08686, LaTeX at glennga/hoku commit
#: 0cb340eca0e9af891acfa8a069776530b111c863): sigma_theta = sigma_phi = 1e-2 deg with 3 sigma windows,
#: |R| = 1, theta(C, C1) < theta(C, C2) on the catalog trio, unsigned interior angle, every star the
#: central star in turn, trios stored up to 20 deg, no double-star exclusion and no verification
GALVIZO2018 = {"sigma_query_deg": 1e-2, "sigma_phi_deg": 1e-2, "unique": True, "ordered": True, "chirality": False,
               "max_stars": 1000, "max_centres": 1000, "max_candidates": 500, "d_min_deg": 0.0,
               "confirm_fraction": 0.0, "min_extra": 0}


@dataclass(frozen=True)
class InteriorAngle(PairKernelCalls, Algorithm):
    """The interior-angle method: a central star, its two nearest neighbours, two angles and the angle between.

    Galvizo G., Lim L., "Empirical Analysis of Common Subgraph Isomorphism Approaches to the
    Lost-in-Space Star Identification Problem", arXiv:1808.08686, 2018 (Algorithm 2, "INT", after
    Liebe 1992; code glennga/hoku, paper at commit 0cb340eca0e9af891acfa8a069776530b111c863). Full
    description, parameters and measurements: ``docs/algorithms/interior_angle.md``.

    Database: pyramid's star-pair k-vector and per-star partner lists; the paper's permutation table
    of trios is searched through them (the first angle in the k-vector, either end of a pair being
    the central star; the second in the central star's partner list) instead of being stored.

    Identification (the paper's steps):

    1. each star in turn is the central star b_c (brightest first in starid; at most
       ``max_centres``), with its two nearest stars b_c1, b_c2;
    2. the query: catalog trios with theta(C, C1) and theta(C, C2) within the windows of the image's
       and the interior angle phi at C within its window (the paper's predicate P_theta,phi;
       ``ordered``: also theta(C, C1) < theta(C, C2)); ``unique`` keeps the |R| = 1 rule;
    3. the trio's attitude, and the rest of the stars by reprojection.

    Choices that are starid's (each a parameter; ``GALVIZO2018`` sets them back to the paper's):

    * windows from the simulator's centroid noise: eps = ``beta`` sqrt(2) max(``sigma_px``, 1 px) / f_px
      for the angles, and for phi ``beta`` sigma sqrt(2/t1^2 + 2/t2^2 + 2/(t1 t2)) (the error of an
      angle whose sides are t1, t2 long); the paper: fixed 3 x ``sigma_query_deg`` / ``sigma_phi_deg``;
    * a signed interior angle (``chirality``), several candidate trios tried (``unique`` off), each
      confirmed by reprojection (``confirm_fraction``, ``min_extra``): the paper verifies nothing;
    * detections and guide stars closer than ``d_min_deg`` to another are not used (pyramid's rule).
    """

    name: ClassVar[str] = "interior_angle"
    pair_kernel: ClassVar = identify_kernel
    work_names: ClassVar[tuple[str, ...]] = WORK_NAMES
    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}
    query_only: ClassVar[tuple[str, ...]] = ('sigma_px',)   # only identify reads them (conformance 'query_only')
    published: ClassVar[dict] = GALVIZO2018
    published_readings: ClassVar[dict] = {"galvizo2018": GALVIZO2018}

    mag_limit: float = param(6.0, help="guide stars have V <= this", unit="mag")
    sigma_px: float | None = param(None, unit="px",
                                   help="centroid noise the windows assume; None follows the simulator (floor 1 px)")
    beta: float = param(3.0, help="windows are beta standard deviations wide (starid's reconstruction)")
    sigma_query_deg: float | None = param(
        None, unit="deg", help="fixed sigma of both angles, window 3 sigma (the paper: 1e-2); None = from sigma_px")
    sigma_phi_deg: float | None = param(
        None, unit="deg", help="fixed sigma of the interior angle, window 3 sigma (paper: 1e-2); None = from sigma_px")
    d_min_deg: float | None = param(
        None, unit="deg", help="stars closer than this to another are unused (doubles); None = 5.11 px (pyramid's)")
    max_pair_deg: float = param(20.0, unit="deg", help="largest separation of a stored pair (the paper: 20)")
    max_stars: int = param(12, help="brightest detections the trios are formed from")
    max_centres: int = param(12, help="iteration cutoff: central stars tried")
    max_window: int = param(5000, help="an image pair whose window holds more catalog pairs is not used")
    max_candidates: int = param(64, help="a query returning more catalog trios is skipped")
    unique: bool = param(False, help="use only a query returning exactly one trio (the paper's |R| = 1)")
    ordered: bool = param(False, help="the catalog trio must have theta(C, C1) < theta(C, C2) (the paper)")
    chirality: bool = param(True, help="the catalog trio must have the image trio's handedness (starid's)")
    widen: float = param(3.0, help="first reprojection pass within widen x the window, to re-solve the attitude")
    confirm_fraction: float = param(
        0.5, help="fraction of the guide stars the attitude predicts that must be seen; 0 = off (starid's)")
    min_extra: int = param(2, help="stars besides the trio reprojection must identify; 0 = off (starid's)")

    def __post_init__(self):
        check_number("mag_limit", self.mag_limit)
        if self.sigma_px is not None:
            check_number("sigma_px", self.sigma_px, lo=0)
        check_number("beta", self.beta, lo=0, lo_open=True)
        for name in ("sigma_query_deg", "sigma_phi_deg"):
            if getattr(self, name) is not None:
                check_number(name, getattr(self, name), lo=0, lo_open=True, hi=10)
        if self.d_min_deg is not None:
            check_number("d_min_deg", self.d_min_deg, lo=0, hi=D_MIN_MAX_DEG)
        check_number("max_pair_deg", self.max_pair_deg, lo=0, lo_open=True, hi=180)
        check_whole("max_stars", self.max_stars, 3)
        check_whole("max_centres", self.max_centres, 1)
        check_whole("max_window", self.max_window, 1)
        check_whole("max_candidates", self.max_candidates, 1)
        for name in ("unique", "ordered", "chirality"):
            check_flag(name, getattr(self, name))
        check_number("confirm_fraction", self.confirm_fraction, lo=0, hi=1)
        check_whole("min_extra", self.min_extra, 0)
        check_number("widen", self.widen, lo=1, hi=100)

    def tolerances(self, camera: Camera, database: PairDatabase) -> InteriorTol:
        if self.sigma_query_deg is None:
            eps = window_eps(camera, self.sigma_px, self.beta)
        else:
            eps = rad_to_chord(math.radians(3.0 * self.sigma_query_deg))
        eps_phi = 0.0 if self.sigma_phi_deg is None else math.radians(3.0 * self.sigma_phi_deg)
        d_min = rad_to_chord(math.radians(database.d_min_deg))
        if self.d_min_deg != 0.0:                   # a detection within eps of another cannot be confirmed
            d_min = max(d_min, eps)
        return InteriorTol(eps=eps, eps_phi=eps_phi, phi_sigma=max(self.sigma_px or 0.0, SIGMA_FLOOR_PX) / camera.f_px,
                           phi_beta=float(self.beta), d_min=d_min, c_max=database.c_max,
                           c_fov=rad_to_chord(camera.half_diagonal_rad), max_window=int(self.max_window),
                           max_stars=int(self.max_stars), max_centres=int(self.max_centres), unique=bool(self.unique),
                           ordered=bool(self.ordered), chirality=bool(self.chirality),
                           max_candidates=int(self.max_candidates), confirm_fraction=float(self.confirm_fraction),
                           min_extra=int(self.min_extra), widen=float(self.widen))

    def derived(self, catalog: Catalog, camera: Camera) -> InteriorAngle:
        """``d_min_deg`` left None set to pyramid's :func:`d_min_for` ``camera``."""
        if self.d_min_deg is None:
            return dataclasses.replace(self, d_min_deg=d_min_for(camera))
        return self

    def build(self, catalog: Catalog, camera: Camera) -> PairDatabase:
        d_min_deg = self.derived(catalog, camera).d_min_deg
        return build_pair_database(catalog, camera, self.mag_limit, d_min_deg, self.max_pair_deg, self.name)

    def explain(self, database: PairDatabase, observation: Observation) -> Explanation:
        """The central star's two edges (bold) and the trio's triangle, every identified star labelled."""
        _, trio, work, hip, _, _ = self._call(database, observation)
        n_centres = int(work[0])
        xy = np.stack([observation.x_px, observation.y_px], axis=1)
        found = np.flatnonzero(hip >= 0)
        role = {int(s): name for s, name in zip(trio, ("c (central)", "c1", "c2"), strict=True) if s >= 0}
        labels = tuple(f"{role[s]}: HIP {hip[s]}" if s in role else f"HIP {hip[s]}" for s in found.tolist())
        if trio[0] >= 0:
            segments = np.asarray([[xy[trio[0]], xy[trio[1]]], [xy[trio[0]], xy[trio[2]]]], dtype=np.float64)
            polygons = (xy[trio],)
            highlight = np.asarray([0, 1])
            caption = (f"Central star c and its two nearest stars matched by two angles and the interior angle "
                       f"(central star {n_centres}); {found.size} stars identified by reprojection.")
        else:
            segments, polygons, highlight = np.zeros((0, 2, 2)), (), np.zeros(0, dtype=np.int64)
            caption = f"No trio matched after {n_centres} central star(s): nothing identified."
        return Explanation(segments=segments, polygons=polygons, points=xy[found], labels=labels, caption=caption,
                           highlight=highlight)
