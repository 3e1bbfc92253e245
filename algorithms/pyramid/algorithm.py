"""The Pyramid plugin class (Mortari et al. 2004): parameters, star-pair database, identify, explain.

The star-pair database (:class:`PairDatabase`, :func:`build_pair_database`) is shared with the
geometric-voting plugin.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import lru_cache
from typing import ClassVar

import numpy as np
from scipy.spatial import cKDTree

from starid.camera import REFERENCE_CAMERA, Camera
from starid.catalog import Catalog
from starid.errors import ConfigError
from starid.kernels import KVector, camera_frame, kvector_make, rad_to_chord
from starid.observation import Observation
from starid.params import check_flag, check_number, check_whole, param
from starid.plugin import Algorithm, Database, Explanation, Identification

from .kernels import TRIANGLE_CAP, WORK_COUNTERS, PairTol, pyramid_kernel

#: centroid-noise floor of every window: a noise-free world still gets a 1 px tolerance
SIGMA_FLOOR_PX = 1.0

#: pyramid's double-star separation on :data:`starid.camera.REFERENCE_CAMERA` (5.1 of its pixels)
D_MIN_REFERENCE_DEG = 0.05
#: largest double-star separation (deg): the parameter's upper bound, and the cap of the derived value
D_MIN_MAX_DEG = 1.0


def d_min_for(camera: Camera) -> float:
    """Pyramid's default double-star separation on ``camera``, in degrees: a fixed number of pixels.

    0.05 deg on the reference camera (5.11 px, wider than the 4.24 px reprojection radius of the
    1 px window floor), scaled by the camera's pixel angle, so that it stays wider than that radius on
    any camera: exactly 0.05 on the reference camera, 0.1008 on a 20 deg, 1024 px one. Capped at
    ``D_MIN_MAX_DEG`` (the parameter's own upper bound), which only binds on fish-eye lenses (f below
    293 px: fields wider than about 121 deg on 1024 px), where 5.11 px would clear the sky of guide stars.
    """
    return min(D_MIN_MAX_DEG, D_MIN_REFERENCE_DEG * camera.pixel_ratio)


def pair_limit_rad(camera: Camera, max_pair_deg: float) -> float:
    """The largest pair angle the pair database stores: the field's diagonal, at most ``max_pair_deg``."""
    return min(2.0 * camera.half_diagonal_rad, math.radians(max_pair_deg))


def window_eps(camera: Camera, sigma_px: float | None, beta: float) -> float:
    """Half-width of the pair windows (radians, ~chord): ``beta`` sqrt(2) max(``sigma_px``, 1 px) / f."""
    return beta * math.sqrt(2.0) * max(sigma_px or 0.0, SIGMA_FLOOR_PX) / camera.f_px


def max_triangles_for(camera: Camera, sigma_px: float | None, beta: float, max_window: int) -> int:
    """Pyramid's default cap on the catalog triangles of one triad: ``TRIANGLE_CAP`` (64) scaled with eps^3.

    A triad's chance catalog triangles grow as eps^3 (each of the three sides is a window of width
    2 eps over the same guide-star density): 64 is the cap at the reference camera's 1 px window
    floor, and the cap follows the window to keep cutting the same tail -- exactly 64 there, 512 at
    2 px on the reference camera, 523 at 1 px and 4,191 at 2 px on a 20 deg / 1024 px camera (whose
    true triads match a median of about 330 catalog triangles at 2 px).
    Never below 64, and at most ``max_window`` (the work bound per pair window; only wide-angle
    cameras reach it).
    """
    ratio = window_eps(camera, sigma_px, beta) / window_eps(REFERENCE_CAMERA, None, 3.0)
    return int(min(max(TRIANGLE_CAP, math.floor(TRIANGLE_CAP * ratio ** 3 + 1e-9)), max(max_window, TRIANGLE_CAP)))


@dataclass(frozen=True, eq=False)
class PairDatabase(Database):
    """Every pair of guide stars closer than the field's diagonal, by chord, with its k-vector.

    kv : :class:`~starid.kernels.KVector` over the ascending pair chords (float32 keys, int32 k).
    pairs : uint16 (p, 2) guide rows of each pair (int32 beyond 65,535 guide stars), row order
        ``pairs[p, 0] < pairs[p, 1]``.
    guide_unit : float32 (g, 3) ICRS unit vectors of the guide stars, sorted by z (declination),
        as :func:`starid.kernels.reproject_assign` requires.
    guide_hip : int64 (g,) catalog id of each guide row.
    nbr, nbr_chord, nbr_start : the same pairs per star (``neighbour_lists``; empty otherwise):
        the partners of guide row g are ``nbr[nbr_start[g]:nbr_start[g + 1]]`` (uint16/int32),
        sorted by their chord ``nbr_chord`` (float32); int32 offsets ``nbr_start`` (g + 1,).
    degree : uint16/int32 (g,) how many pairs each guide star belongs to (its neighbours within
        ``c_max``), for geometric voting's expected random votes.
    c_max : the largest pair chord stored (not read by identify as an array).
    d_min_deg : the double-star separation the guide stars were cut with (degrees; the value used,
        reported where the parameter was left to the camera).
    """

    kv: KVector
    pairs: np.ndarray
    guide_unit: np.ndarray
    guide_hip: np.ndarray
    nbr: np.ndarray
    nbr_chord: np.ndarray
    nbr_start: np.ndarray
    degree: np.ndarray
    c_max: float
    d_min_deg: float = 0.0


def build_pair_database(catalog: Catalog, camera: Camera, mag_limit: float, d_min_deg: float,
                        max_pair_deg: float, who: str, neighbour_lists: bool = True) -> PairDatabase:
    """Guide stars with V <= ``mag_limit`` (both stars of a pair closer than ``d_min_deg``
    dropped), and every pair of them closer than min(field diagonal, ``max_pair_deg``); with
    ``neighbour_lists`` also each star's partners sorted by chord."""
    guide = catalog.brighter_than(mag_limit)
    if d_min_deg > 0 and len(guide) >= 2:
        close = cKDTree(guide.unit_icrs).query_pairs(rad_to_chord(math.radians(d_min_deg)), output_type="ndarray")
        double = np.zeros(len(guide), dtype=bool)
        double[close.ravel()] = True
        guide = guide.subset(~double)
    if len(guide) < 3:
        raise ConfigError(f"{who}: only {len(guide)} usable catalog stars have V <= {mag_limit}")
    by_z = np.lexsort((guide.hip, guide.unit_icrs[:, 2]))
    unit = np.ascontiguousarray(guide.unit_icrs[by_z])
    theta_max = pair_limit_rad(camera, max_pair_deg)
    c_max = rad_to_chord(theta_max)
    pairs = cKDTree(unit).query_pairs(c_max, output_type="ndarray").astype(np.int64)
    if len(pairs) < 2:
        raise ConfigError(f"{who}: fewer than two catalog pairs fit in the field of view")
    pairs.sort(axis=1)
    chord = np.linalg.norm(unit[pairs[:, 0]] - unit[pairs[:, 1]], axis=1).astype(np.float32)
    order = np.lexsort((pairs[:, 1], pairs[:, 0], chord))
    row_dtype = np.uint16 if len(guide) <= np.iinfo(np.uint16).max else np.int32
    if neighbour_lists:
        star = np.concatenate([pairs[:, 0], pairs[:, 1]])
        other = np.concatenate([pairs[:, 1], pairs[:, 0]])
        both = np.concatenate([chord, chord])
        by_star = np.lexsort((other, both, star))
        nbr, nbr_chord = other[by_star].astype(row_dtype), both[by_star]
        nbr_start = np.searchsorted(star[by_star], np.arange(len(guide) + 1)).astype(np.int32)
    else:
        nbr, nbr_chord, nbr_start = np.zeros(0, row_dtype), np.zeros(0, np.float32), np.zeros(1, np.int32)
    degree = np.bincount(pairs.ravel(), minlength=len(guide))
    deg_dtype = np.uint16 if degree.max() <= np.iinfo(np.uint16).max else np.int32
    return PairDatabase(kv=kvector_make(chord[order], np.float32, np.int32),
                        pairs=np.ascontiguousarray(pairs[order].astype(row_dtype)),
                        guide_unit=unit.astype(np.float32), guide_hip=guide.hip[by_z].astype(np.int64),
                        nbr=nbr, nbr_chord=nbr_chord, nbr_start=nbr_start,
                        degree=degree.astype(deg_dtype), c_max=float(c_max), d_min_deg=float(d_min_deg))


def check_pair_params(algo) -> None:
    """Checks of the parameters both pair-angle plugins share."""
    if algo.mag_limit is not None:                  # None: derived from the camera (geometric voting)
        check_number("mag_limit", algo.mag_limit)
    if algo.sigma_px is not None:
        check_number("sigma_px", algo.sigma_px, lo=0)
    check_number("beta", algo.beta, lo=0, lo_open=True)
    if algo.d_min_deg is not None:
        check_number("d_min_deg", algo.d_min_deg, lo=0, hi=D_MIN_MAX_DEG)
    check_number("max_pair_deg", algo.max_pair_deg, lo=0, lo_open=True, hi=180)
    check_whole("max_stars", algo.max_stars, 3)
    check_whole("max_window", algo.max_window, 1)
    check_number("confirm_fraction", algo.confirm_fraction, lo=0, hi=1)
    check_whole("min_extra", algo.min_extra, 0)


def hip_of(database: PairDatabase, rows: np.ndarray) -> np.ndarray:
    """Catalog ids of guide rows (-1 stays -1)."""
    return np.where(rows >= 0, database.guide_hip[np.maximum(rows, 0)], -1).astype(np.int64)


@dataclass(frozen=True)
class Pyramid(Algorithm):
    """Pyramid: star-pair k-vector, Mortari's triad order, chirality, a fourth star confirming the triangle.

    Mortari D., Samaan M. A., Bruccoleri C., Junkins J. L., "The Pyramid star identification
    technique", Navigation 51(3):171-183, 2004; the k-vector from the same paper's appendix
    (Mortari & Neta 2000). Full description, parameters and measurements:
    ``docs/algorithms/pyramid.md``.

    Database: every guide star (V <= ``mag_limit``) pair closer than the field's diagonal
    (capped at ``max_pair_deg``), keyed by its chord 2 sin(theta/2) and searched with the
    k-vector (``starid.kernels.KVector``).

    Identification (the paper's algorithm; its numbered steps):

    1. every image pair's angle selects the catalog pairs within +-eps (k-vector range query);
    2. triads (i, j, k) are taken in the paper's order ``for dj, for dk, for i: j = i + dj,
       k = j + dk`` (stars indexed brightest first), which moves all three stars between
       consecutive triads so one spurious star cannot spoil a long run of them; iteration
       cutoff ``max_triads``;
    3. catalog triangles (I, J, K) with (I, J), (J, K), (I, K) in the three windows, and the
       same sign of the triple products b_i.(b_j x b_k) and r_I.(r_J x r_K) (chirality,
       "spectral" test); the triangle must be unique (``unique_triangle``);
    4. a fourth star r with exactly one catalog star R at the right distance from I, J and K
       confirms the triangle: the pyramid (with ``unique_triangle=False``, each candidate
       triangle's pyramid goes through the confirmation below, and the triad is accepted when
       exactly one of them is confirmed);
    5. the remaining stars are identified from the pyramid's attitude (Wahba,
       ``starid.kernels.wahba_rows``) by reprojection (``starid.kernels.reproject_assign``,
       the same +-eps), and the attitude is re-solved from all of them.

    Choices the paper leaves open or that are starid's (each a parameter):

    * eps = ``beta`` sqrt(2) sigma, sigma = max(``sigma_px``, 1 px) / f_px (reconstructed: the
      paper sets eps from the centroid accuracy; the 1 px floor gives noise-free worlds a window;
      ``sigma_px`` follows the simulator's centroid noise when left None);
    * detections closer than ``d_min_deg`` to another, and guide stars with such a neighbour,
      are not used (double stars; reconstructed, as in starid's PTP); left None it is derived from
      the camera (:meth:`derived`) as a fixed 5.11 px (0.05 deg on the Table 4 camera, scaled by
      the pixel angle: :func:`d_min_for`), so that it stays wider than the 4.24 px reprojection
      radius of the 1 px window floor; the value used is also the database's ``d_min_deg``;
    * triads are formed from the ``max_stars`` brightest detections (reconstructed; the paper
      uses its input order, starid needs an order independent of the input's);
    * ``unique_triangle=False`` (LOST's reading) tries every candidate triangle of a triad and
      accepts the triad when exactly one of them completes a pyramid;
    * ``confirm_fraction`` and ``min_extra`` (starid's extension, both 0 switch it off): of the
      guide stars the pyramid's attitude puts on the sensor besides its own four, at least
      ``min_extra`` and this fraction must be seen, else the pyramid is discarded and the search
      goes on -- the safeguard that keeps random fields unidentified;
    * ``accept_triangle`` (the paper's n = 3 case): with exactly three usable stars a unique
      triangle is reported without a fourth star (off by default: no confirmation possible);
    * ``max_window``: an image pair whose window holds more catalog pairs is not used (keeps
      wide-angle cameras fast);
    * ``max_triangles``: a triad matching more catalog triangles is skipped; left None it is derived
      (:meth:`derived`, :func:`max_triangles_for`) as 64 scaled with eps^3, since chance triangles
      grow as eps^3: 64 at the reference camera's 1 px window, ~4,200 at 2 px on a 20 deg / 1024 px
      camera, whose true triads match ~330 catalog triangles (a fixed 64 skipped every triad there);
    * ``window_deg`` (off by default) pins eps in degrees instead: the fixed 3 sigma_theta = 3e-4 deg
      window of Galvizo & Lim's comparison (``pyramid:galvizo2018``);
    * in the image, a detection closer than max(``d_min_deg``, eps) to another is set aside: within
      eps, reprojection sees two detections near its prediction and can never confirm it.
    """

    name: ClassVar[str] = "pyramid"
    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}

    mag_limit: float = param(6.0, help="guide stars have V <= this", unit="mag")
    sigma_px: float | None = param(None, unit="px",
                                   help="centroid noise the windows assume; None follows the simulator (floor 1 px)")
    beta: float = param(3.0, help="window eps = beta sqrt(2) sigma (starid's reconstruction)")
    d_min_deg: float | None = param(
        None, unit="deg",
        help="stars closer than this to another are unused (doubles); None = 5.11 px (starid's reconstruction)")
    max_pair_deg: float = param(20.0, unit="deg",
                                help="largest separation of a stored pair (also capped at the field's diagonal)")
    max_stars: int = param(40, help="brightest detections the triads are formed from (starid's reconstruction)")
    max_triads: int = param(1000, help="iteration cutoff: most triads tried (paper)")
    max_window: int = param(
        10000, help="an image pair whose window holds more catalog pairs than this is not used (a time bound)")
    max_triangles: int | None = param(
        None, help="a triad matching more catalog triangles is skipped; None = derived, 64 scaled with eps^3")
    unique_triangle: bool = param(
        False, help="a triad must match exactly one catalog triangle; False tries each (LOST's reading)")
    confirm_fraction: float = param(
        0.5,
        help="fraction of the other guide stars its attitude predicts that must be seen; 0 = off (starid's extension)")
    min_extra: int = param(
        1, help="other guide stars the pyramid's attitude predicts that must be seen; 0 = off (starid's extension)")
    accept_triangle: bool = param(
        False, help="with exactly three usable stars, report a unique triangle without a fourth (paper, n = 3)")
    window_deg: float | None = param(
        None, unit="deg",
        help="fixed half-width of every pair window; None = from sigma_px and beta (a fixed tolerance, as hoku's)")

    #: Galvizo & Lim (2018) ran Pyramid (hoku, its Section IV) with a fixed query window
    #: |theta_r - theta_b| < 3 sigma_theta, sigma_theta = 1e-4 deg; every triangle unique (|T_i| = 1);
    #: a fourth star confirming it and nothing else (no attitude check); all stars, no double-star
    #: cut; a 500 catalog-access limit (3 per triad: 166 triads) (``pyramid:galvizo2018``)
    published_readings: ClassVar[dict] = {"galvizo2018": {
        "window_deg": 3e-4, "unique_triangle": True, "confirm_fraction": 0.0, "min_extra": 0, "d_min_deg": 0.0,
        "max_stars": 100, "max_triads": 166}}

    def __post_init__(self):
        check_pair_params(self)
        if self.window_deg is not None:
            check_number("window_deg (or None: from sigma_px)", self.window_deg, lo=0, hi=10, lo_open=True)
        check_whole("max_triads", self.max_triads, 1)
        if self.max_triangles is not None:
            check_whole("max_triangles", self.max_triangles, 1)
        check_flag("unique_triangle", self.unique_triangle)
        check_flag("accept_triangle", self.accept_triangle)

    def tolerances(self, camera: Camera, database: PairDatabase) -> PairTol:
        half_diag = camera.half_diagonal_rad
        eps = self.window_chord(camera)
        # a detection with another one within eps of it can never be confirmed by reprojection (two
        # detections near its prediction), so the image's isolation radius is at least eps
        return PairTol(eps=eps, d_min=max(rad_to_chord(math.radians(database.d_min_deg)), eps),
                       c_max=database.c_max, c_fov=rad_to_chord(half_diag), max_window=int(self.max_window),
                       max_stars=int(self.max_stars), max_triads=int(self.max_triads),
                       confirm_fraction=float(self.confirm_fraction), min_extra=int(self.min_extra))

    def window_chord(self, camera: Camera) -> float:
        """Half-width of the pair windows (chord): ``window_deg`` when pinned, else :func:`window_eps`."""
        if self.window_deg is not None:
            return float(rad_to_chord(math.radians(self.window_deg)))
        return window_eps(camera, self.sigma_px, self.beta)

    def derived(self, catalog: Catalog, camera: Camera) -> Pyramid:
        """``d_min_deg`` left None set to :func:`d_min_for` ``camera``, ``max_triangles`` left None to
        :func:`max_triangles_for` the camera and this window."""
        fill = {}
        if self.d_min_deg is None:
            fill["d_min_deg"] = d_min_for(camera)
        if self.max_triangles is None:
            fill["max_triangles"] = max_triangles_for(camera, self.sigma_px, self.beta, self.max_window)
        return dataclasses.replace(self, **fill) if fill else self

    def build(self, catalog: Catalog, camera: Camera) -> PairDatabase:
        d_min_deg = self.derived(catalog, camera).d_min_deg
        return build_pair_database(catalog, camera, self.mag_limit, d_min_deg, self.max_pair_deg, self.name)

    def _run(self, database: PairDatabase, observation: Observation):
        db = database
        tol, frame, max_triangles = _bundles(self, observation.camera, db.c_max, db.d_min_deg)
        return pyramid_kernel(observation.x_px, observation.y_px, observation.mag, db.kv, db.pairs, db.nbr,
                              db.nbr_chord, db.nbr_start, db.guide_unit, db.guide_hip, tol, frame,
                              self.unique_triangle, self.accept_triangle, max_triangles)

    def identify(self, database: PairDatabase, observation: Observation) -> Identification:
        _, hip, attitude, pyramid, work = self._run(database, observation)
        counters = dict(zip(WORK_COUNTERS, work.tolist(), strict=True))
        return Identification(hip, attitude if pyramid[0] >= 0 else None, counters=counters)

    def explain(self, database: PairDatabase, observation: Observation) -> Explanation:
        """The pyramid found: its six edges (the three to the confirming fourth star in bold),
        the triad's triangle as a polygon, and each identified star labelled with its id."""
        _, hip, _, pyramid, work = self._run(database, observation)
        n_triads = int(work[0])
        xy = np.stack([observation.x_px, observation.y_px], axis=1)
        found = np.flatnonzero(hip >= 0)
        role = {int(s): name for s, name in zip(pyramid, ("i", "j", "k", "r (4th)"), strict=True) if s >= 0}
        points = xy[found]
        labels = tuple(f"{role[s]}: HIP {hip[s]}" if s in role else f"HIP {hip[s]}" for s in found.tolist())
        corners = [int(s) for s in pyramid if s >= 0]
        segments, highlight = [], []
        for a in range(len(corners)):
            for b in range(a + 1, len(corners)):
                if b == 3:
                    highlight.append(len(segments))
                segments.append([xy[corners[a]], xy[corners[b]]])
        polygons = (xy[corners[:3]],) if len(corners) >= 3 else ()
        if len(corners) == 4:
            caption = (f"Pyramid found after {n_triads} triad(s): triangle i-j-k matched uniquely, confirmed by "
                       f"the fourth star r (bold edges); {found.size} stars identified by reprojection.")
        elif len(corners) == 3:
            caption = f"Three stars only: the unique triangle i-j-k was accepted after {n_triads} triad(s)."
        else:
            caption = f"No confirmed pyramid after {n_triads} triad(s): nothing identified."
        return Explanation(segments=np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2), polygons=polygons,
                           points=points, labels=labels, caption=caption, highlight=np.asarray(highlight))


@lru_cache(maxsize=64)
def _bundles(algorithm: Pyramid, camera: Camera, c_max: float, d_min_deg: float) -> tuple[PairTol, tuple, int]:
    """The kernel's tolerances, camera frame and triangle cap for one (algorithm, camera, database
    chord limit and double-star distance), built once rather than per image (immutable tuples)."""
    database = _Limits(c_max, d_min_deg)
    max_triangles = algorithm.max_triangles or max_triangles_for(camera, algorithm.sigma_px, algorithm.beta,
                                                                 algorithm.max_window)
    return algorithm.tolerances(camera, database), camera_frame(camera), max_triangles


@dataclass(frozen=True)
class _Limits:
    """The two fields of a :class:`PairDatabase` that :meth:`Pyramid.tolerances` reads."""

    c_max: float
    d_min_deg: float
