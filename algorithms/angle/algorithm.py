"""The two-star angle method as Galvizo & Lim (2018) ran it ("ANG"): parameters, identify, explain.

The star-pair database is pyramid's (:func:`starid_algorithms.pyramid.algorithm.build_pair_database`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from starid_algorithms.pyramid.algorithm import (
    D_MIN_MAX_DEG,
    PairDatabase,
    build_pair_database,
    d_min_for,
    window_eps,
)

from starid.camera import Camera
from starid.catalog import Catalog
from starid.kernels import camera_frame, rad_to_chord
from starid.observation import Observation
from starid.params import check_flag, check_number, check_whole, param
from starid.plugin import Algorithm, Explanation, Identification

from .kernels import WORK_NAMES, AngleTol, identify_kernel, params_of

#: the reading of Galvizo & Lim 2018 (arXiv 1808.08686, LaTeX at glennga/hoku commit
#: 0cb340eca0e9af891acfa8a069776530b111c863): query sigma_theta = 1e-4 deg with the 3 sigma window,
#: |R| = 1, the direct-match test comparing both orientations (the one with more overlaying stars,
#: ties to the second; not confident when neither overlays a star), overlay sigma_o = 1e-5 deg (hoku's
#: CONFIG.ini), pairs stored up to 20 deg, every image pair tried in index order (nu_max = 50,000),
#: no double-star exclusion and no confirmation
GALVIZO2018 = {"sigma_query_deg": 1e-4, "sigma_overlay_deg": 1e-5, "unique_window": True, "compare": True,
               "n_check": 1000, "min_support": 1, "chirality": False, "max_stars": 1000, "max_pairs": 50000,
               "max_window": 5000, "d_min_deg": 0.0, "confirm_fraction": 0.0, "min_extra": 0}


class PairKernelCalls:
    """``_kernel_params``, ``_call``, ``_run`` and ``identify`` of a plugin over pyramid's :class:`PairDatabase`
    whose kernel, :attr:`pair_kernel`, takes the stars, the database's arrays and :func:`params_of` the camera
    frame and the plugin's tolerances, and returns ``(rows, stars, work, hip, attitude, found)``: angle's and
    interior angle's (their classes name their kernel and counters and define ``tolerances``)."""

    pair_kernel: ClassVar   # a numba kernel (angle's or interior angle's ``identify_kernel``)
    work_names: ClassVar[tuple[str, ...]]   # the names of ``work``'s slots, ``Identification.counters``' keys

    def _kernel_params(self, database: PairDatabase, camera: Camera) -> np.ndarray:
        """The camera frame and the tolerances as the kernel's float64 array (:func:`params_of`), built once
        per (database, camera) and kept (:meth:`~starid.plugin.Algorithm.kept`) rather than for every image
        (issue #25: ~5.7 us a call, and 2 us of numba's unboxing of the named tuples)."""
        return self.kept("kernel_params", (database, camera),
                         lambda: params_of(camera_frame(camera), self.tolerances(camera, database)))

    def _call(self, database: PairDatabase, observation: Observation):
        """:attr:`pair_kernel` on one image: ``(rows, stars, work, hip, attitude, found)``, ``stars`` the matched
        pair (angle) or trio (interior angle)."""
        db = database
        return type(self).pair_kernel(observation.x_px, observation.y_px, observation.mag, db.kv, db.pairs, db.nbr,
                                      db.nbr_chord, db.nbr_start, db.guide_unit, db.guide_hip,
                                      self._kernel_params(db, observation.camera))

    def _run(self, database: PairDatabase, observation: Observation):
        """The search's ``(rows, stars, work)`` (of :meth:`_call`)."""
        rows, stars, work, _, _, _ = self._call(database, observation)
        return rows, stars, work

    def identify(self, database: PairDatabase, observation: Observation) -> Identification:
        _, _, work, hip, attitude, found = self._call(database, observation)
        return Identification(hip, attitude if found else None,
                              counters=dict(zip(self.work_names, work.tolist(), strict=True)))


@dataclass(frozen=True)
class Angle(PairKernelCalls, Algorithm):
    """The angle method: one star pair matched by its angle, checked by a direct-match test.

    Galvizo G., Lim L., "Empirical Analysis of Common Subgraph Isomorphism Approaches to the
    Lost-in-Space Star Identification Problem", arXiv:1808.08686, 2018 (Algorithm 1, "ANG"; code
    glennga/hoku, paper at commit 0cb340eca0e9af891acfa8a069776530b111c863). Full description,
    parameters and measurements: ``docs/algorithms/angle.md``.

    Database: pyramid's star-pair k-vector (every guide-star pair closer than the field's diagonal,
    capped at ``max_pair_deg``; each star's partners sorted by chord).

    Identification (the paper's steps):

    1. image pairs (i, j) in the order ``for i: for j > i`` (brightest first in starid), at most
       ``max_pairs`` of them (hoku's nu_max);
    2. the catalog query: the pairs whose angle lies within the 3 sigma window of the image pair's
       (the paper's predicate P_theta); ``unique_window`` keeps hoku's |R| = 1 rule;
    3. the direct-match test (Needelman via Tappe): each orientation of a candidate pair gives an
       attitude, and the image stars that overlay a catalog star under it count; here the overlay
       is tested through the two distances to the pair (I's partner list), which is the same test
       as rotating the star and looking for a catalog star within the overlay radius;
    4. the rest of the stars by reprojection from the pair's attitude.

    Choices that are starid's (each a parameter; ``GALVIZO2018`` sets them back to the paper's):

    * the window eps = ``beta`` sqrt(2) max(``sigma_px``, 1 px) / f_px, following the simulator's
      centroid noise (the paper: a fixed 3 x ``sigma_query_deg``, used when that is set);
    * a candidate pair is tried even when its window holds others (``unique_window`` off), and a
      pairing stands when ``min_support`` of the next ``n_check`` stars overlay with the right
      handedness (``chirality``) and the reprojection confirmation (``confirm_fraction``,
      ``min_extra``) passes -- the safeguard that keeps random fields unidentified;
    * with ``compare`` off, the pairings are not tested one by one: each of the ``n_check`` stars in
      turn anchors the test, and the pairings it supports are the catalog triangles of the image
      pair and the anchor (pyramid's join of two windows), then counted over the other stars;
    * detections and guide stars closer than ``d_min_deg`` to another are not used (pyramid's rule).
    """

    name: ClassVar[str] = "angle"
    pair_kernel: ClassVar = identify_kernel
    work_names: ClassVar[tuple[str, ...]] = WORK_NAMES
    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}
    query_only: ClassVar[tuple[str, ...]] = ('sigma_px',)   # only identify reads them (conformance 'query_only')
    published: ClassVar[dict] = GALVIZO2018
    published_readings: ClassVar[dict] = {"galvizo2018": GALVIZO2018}

    mag_limit: float = param(6.0, help="guide stars have V <= this", unit="mag")
    sigma_px: float | None = param(None, unit="px",
                                   help="centroid noise the windows assume; None follows the simulator (floor 1 px)")
    beta: float = param(3.0, help="window eps = beta sqrt(2) sigma (starid's reconstruction)")
    sigma_query_deg: float | None = param(
        None, unit="deg", help="fixed query sigma, window 3 sigma (the paper: 1e-4); None = from sigma_px")
    sigma_overlay_deg: float | None = param(
        None, unit="deg", help="fixed overlay sigma, radius 3 sigma (hoku: 1e-5); None = the query window")
    d_min_deg: float | None = param(
        None, unit="deg", help="stars closer than this to another are unused (doubles); None = 5.11 px (pyramid's)")
    max_pair_deg: float = param(20.0, unit="deg", help="largest separation of a stored pair (the paper: 20)")
    max_stars: int = param(12, help="brightest detections the pairs are formed from")
    max_pairs: int = param(40, help="iteration cutoff: most image pairs tried (hoku's nu_max)")
    max_window: int = param(5000, help="an image pair whose window holds more catalog pairs is not used")
    unique_window: bool = param(False, help="use only windows holding exactly one catalog pair (the paper's |R| = 1)")
    compare: bool = param(False, help="direct-match test keeps the orientation with more support (the paper)")
    n_check: int = param(8, help="other stars the direct-match test looks at, brightest first")
    min_support: int = param(2, help="of them, how many must overlay a catalog star")
    chirality: bool = param(True, help="a supporting star must have its catalog star's handedness (starid's)")
    widen: float = param(1.0, help="first reprojection pass within widen x the window, to re-solve the attitude")
    confirm_fraction: float = param(
        0.5, help="fraction of the guide stars the attitude predicts that must be seen; 0 = off (starid's)")
    min_extra: int = param(3, help="stars besides the pair reprojection must identify; 0 = off (starid's)")
    max_triangles: int = param(256, help="an anchor star supporting more pairings than this is skipped (starid's)")

    def __post_init__(self):
        check_number("mag_limit", self.mag_limit)
        if self.sigma_px is not None:
            check_number("sigma_px", self.sigma_px, lo=0)
        check_number("beta", self.beta, lo=0, lo_open=True)
        for name in ("sigma_query_deg", "sigma_overlay_deg"):
            if getattr(self, name) is not None:
                check_number(name, getattr(self, name), lo=0, lo_open=True, hi=10)
        if self.d_min_deg is not None:
            check_number("d_min_deg", self.d_min_deg, lo=0, hi=D_MIN_MAX_DEG)
        check_number("max_pair_deg", self.max_pair_deg, lo=0, lo_open=True, hi=180)
        check_whole("max_stars", self.max_stars, 2)
        check_whole("max_pairs", self.max_pairs, 1)
        check_whole("max_window", self.max_window, 1)
        check_whole("n_check", self.n_check, 0)
        check_whole("min_support", self.min_support, 0)
        for name in ("unique_window", "compare", "chirality"):
            check_flag(name, getattr(self, name))
        check_number("confirm_fraction", self.confirm_fraction, lo=0, hi=1)
        check_whole("min_extra", self.min_extra, 0)
        check_number("widen", self.widen, lo=1, hi=100)
        check_whole("max_triangles", self.max_triangles, 1)

    def tolerances(self, camera: Camera, database: PairDatabase) -> AngleTol:
        if self.sigma_query_deg is None:
            eps = window_eps(camera, self.sigma_px, self.beta)
        else:
            eps = rad_to_chord(math.radians(3.0 * self.sigma_query_deg))
        eps_match = eps if self.sigma_overlay_deg is None else rad_to_chord(math.radians(3.0 * self.sigma_overlay_deg))
        d_min = rad_to_chord(math.radians(database.d_min_deg))
        if self.d_min_deg != 0.0:                   # a detection within eps of another cannot be confirmed
            d_min = max(d_min, eps_match)
        return AngleTol(eps=eps, eps_match=eps_match, d_min=d_min, c_max=database.c_max,
                        c_fov=rad_to_chord(camera.half_diagonal_rad), max_window=int(self.max_window),
                        max_stars=int(self.max_stars), max_pairs=int(self.max_pairs),
                        unique_window=bool(self.unique_window), n_check=int(self.n_check),
                        min_support=int(self.min_support), compare=bool(self.compare), chirality=bool(self.chirality),
                        confirm_fraction=float(self.confirm_fraction), min_extra=int(self.min_extra),
                        widen=float(self.widen),
                        max_triangles=int(self.max_triangles))

    def derived(self, catalog: Catalog, camera: Camera) -> Angle:
        """``d_min_deg`` left None set to pyramid's :func:`d_min_for` ``camera``."""
        if self.d_min_deg is None:
            return dataclasses.replace(self, d_min_deg=d_min_for(camera))
        return self

    def build(self, catalog: Catalog, camera: Camera) -> PairDatabase:
        d_min_deg = self.derived(catalog, camera).d_min_deg
        return build_pair_database(catalog, camera, self.mag_limit, d_min_deg, self.max_pair_deg, self.name)

    def explain(self, database: PairDatabase, observation: Observation) -> Explanation:
        """The matched pair as a bold segment, and every identified star labelled with its id."""
        _, pair, work, hip, _, _ = self._call(database, observation)
        n_pairs = int(work[0])
        xy = np.stack([observation.x_px, observation.y_px], axis=1)
        found = np.flatnonzero(hip >= 0)
        role = {int(s): name for s, name in zip(pair, ("i", "j"), strict=True) if s >= 0}
        labels = tuple(f"{role[s]}: HIP {hip[s]}" if s in role else f"HIP {hip[s]}" for s in found.tolist())
        if pair[0] >= 0:
            segments = np.asarray([[xy[pair[0]], xy[pair[1]]]], dtype=np.float64)
            caption = (f"Pair i-j matched by its angle after {n_pairs} image pair(s), its orientation by the "
                       f"direct-match test; {found.size} stars identified by reprojection.")
            highlight = np.asarray([0])
        else:
            segments = np.zeros((0, 2, 2))
            caption = f"No pair passed the direct-match test after {n_pairs} image pair(s): nothing identified."
            highlight = np.zeros(0, dtype=np.int64)
        return Explanation(segments=segments, polygons=(), points=xy[found], labels=labels, caption=caption,
                           highlight=highlight)
