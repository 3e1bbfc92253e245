"""The P-vector algorithm class: parameters, database build, identify (see :class:`PVector`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np
from scipy.spatial import cKDTree

from starid.camera import REFERENCE_CAMERA, Camera
from starid.catalog import Catalog
from starid.errors import ConfigError
from starid.kernels import (
    DeepSky,
    KVector,
    assign_all,
    camera_frame,
    check_stars,
    deep_sky,
    kvector_make,
    rad_to_chord,
)
from starid.observation import Observation
from starid.params import check_choice, check_flag, check_number, check_whole, param
from starid.plugin import Algorithm, Database, Explanation, Identification

from . import kernels as K

#: Smallest centroid noise (px) the tolerances assume, whatever ``sigma_px`` says.
SIGMA_FLOOR_PX = 1.0
SIDE_ORDERS = ("sorted", "role")
NEIGHBOUR_RULES = ("brightest", "nearest")
MAIN_ORDERS = ("centre", "brightness")
SEARCHES = ("kvector", "linear")


_last_frame: tuple = (None, None, None)


def _frame(camera: Camera) -> tuple:
    """``camera_frame(camera)`` and the same as a plain tuple (the kernel's argument); the last camera's kept
    by identity (a run identifies every image with one camera object; building the frame costs about a
    microsecond per image)."""
    global _last_frame
    cam, frame, frame_t = _last_frame
    if cam is not camera:
        frame = camera_frame(camera)
        frame_t = tuple(frame)
        _last_frame = (camera, frame, frame_t)    # one assignment: threads see a consistent triple
    return frame, frame_t


@dataclass(frozen=True, eq=False)
class PVectorDatabase(Database):
    """One triangle per guide star, sorted by its P value, plus the guide stars.

    p_axis : float64 (3,) the P vector (first principal axis of the side vectors, sum > 0).
    kv : :class:`starid.kernels.KVector`: ``kv.values`` float32 (m,) the keys P = p . d of every
        triangle, ascending, stored only for ``search='linear'`` (empty otherwise: see :attr:`key`);
        ``kv.k`` uint16/int32 (m,) the k-vector; ``kv.m``, ``kv.q`` its line (Mortari & Neta 2000).
    tri_sides : uint16 (m, 3) the side vector d in the order the key uses, in units of ``side_step_rad``
        (2R / 65535: about 3 urad at R = 5 deg, 0.02 px on the Table 4 camera, far below the tolerance).
    side_step_rad : float, the unit of ``tri_sides``.
    tri_rows : int16/int32 (m, 3) guide rows of (S, N1, N2): main star, brighter (or nearer)
        neighbour, the other neighbour.
    unit_icrs : float32 (n, 3) guide-star unit vectors, sorted by z (declination bands).
    hip : int64 (n,) the catalog id (HIP) of each guide row.
    deep : :class:`starid.kernels.DeepSky`, the stars to V <= ``deep_mag_limit`` for ``assign_all``
        (empty unless ``assign_all``).
    explained_variance : fraction of the side-vector variance along p (build diagnostic).
    """

    p_axis: np.ndarray
    kv: KVector
    tri_sides: np.ndarray
    side_step_rad: float
    tri_rows: np.ndarray
    unit_icrs: np.ndarray
    hip: np.ndarray
    deep: DeepSky
    extra_unit: np.ndarray
    explained_variance: float = float("nan")

    @property
    def key(self) -> np.ndarray:
        """The sorted keys P: ``kv.values`` when stored (``search='linear'``), else recomputed from the
        stored sides (the k-vector search does not read them)."""
        if self.kv.values.size == self.tri_sides.shape[0]:
            return self.kv.values
        return ((self.tri_sides * self.side_step_rad) @ self.p_axis).astype(np.float32)

    def tables(self) -> K.Tables:
        """The arrays identify reads, as one kernel argument."""
        return K.Tables(self.p_axis, self.kv, self.tri_sides, float(self.side_step_rad), self.tri_rows,
                        self.unit_icrs, self.hip, self.deep, self.extra_unit)

    @cached_property
    def plain_tables(self) -> tuple:
        """:meth:`tables` as plain tuples (:func:`kernels.plain`), as :func:`kernels.identify_rows` takes it
        (built once, not per image)."""
        return K.plain(self.tables())


def _unique_triangles(rows: np.ndarray) -> np.ndarray:
    """Each star triple once. With sorted sides a triangle's key and sides do not depend on which of
    its stars is the main one, and identify tries all six vertex correspondences, so the copy stored
    under a second main star (its neighbours' neighbours overlap) only repeats a candidate that
    identify skips as "the same correspondence" (47,957 -> 38,884 triangles at K = 5, R = 5 deg).
    The first row of each triple in row order is kept."""
    _, first = np.unique(np.sort(rows, axis=1), axis=0, return_index=True)
    return rows[np.sort(first)]


def _key_index(sorted_key: np.ndarray, keep_keys: bool) -> KVector:
    """The k-vector over the sorted keys; the keys themselves (4 bytes a triangle) are kept only for
    the linear search, which scans them: the k-vector search takes its untrimmed slice
    (:func:`starid.kernels.kvector_slice`) and checks every candidate's three sides anyway."""
    kv = kvector_make(sorted_key, values_dtype=np.float32,
                      index_dtype=np.uint16 if sorted_key.size <= np.iinfo(np.uint16).max else np.int32)
    return kv if keep_keys else kv._replace(values=np.zeros(0, dtype=np.float32))


@dataclass(frozen=True)
class PVector(Algorithm):
    """P-vector triangle identification: two brightest neighbours, 1-D PCA key, k-vector (Yang, Zhang & Jiang 2007).

    Reference: Yang J., Zhang G.-J., Jiang J., "Fast star identification algorithm using P
    vector", Acta Aeronautica et Astronautica Sinica 28(4):897-900, 2007, as described in the
    Introduction of Zhou & Ye 2015 (PTP, Math. Probl. Eng. 982420); method, parameters and
    measurements: docs/algorithms/pvector.md. The method section of the 2007 paper was not available, so
    everything below except "triangle of a guide star and its two brightest neighbours", "one
    scalar P from the three sides by PCA", "candidates within an error range of P" and "a
    verification step" is a RECONSTRUCTION, each choice a parameter.

    Database: for every guide star S (V <= ``mag_limit``) the guide stars at
    angular distance in [``min_sep_deg``, ``pattern_radius_deg``] are its neighbours; the two
    brightest (``neighbour_rule``; ties: nearer first) are N1 (brighter) and N2; with
    ``triangles_per_star`` K > 2 every pair of the K brightest forms a triangle. The side vector
    is d = (theta(S,N1), theta(S,N2), theta(N1,N2)) in radians, sorted ascending
    when ``side_order='sorted'``. PCA over all d: p = unit eigenvector of the largest
    eigenvalue of the covariance (sign: sum(p) > 0), P = p . d (not mean-centred: centring, as
    in PTP eq. 3, only shifts every key by a constant). Records sorted by P, with a k-vector
    (PTP eqs. 15-19; starid.kernels). Stored compactly: float32 keys/sides/unit vectors,
    int16 star rows (int32 when there are more than 32,767 guide stars).

    Identification, one numba call per image:

    1. Main-star order (``main_order``): 'centre' (reconstructed, default) tries the stars
       farthest from the image edge first, i.e. those whose R-disc lies inside the image come
       first and then the ones whose disc sticks out least; 'brightness' tries the brightest
       first. ``disc_inside_only`` keeps only main stars whose disc (radius f tan R, px) lies
       inside the image. Only stars with *measured* magnitude <= ``mag_limit`` can be main
       stars or neighbours, and the two neighbours are picked by the measured
       magnitudes: this is the P-vector's documented weakness under magnitude noise (PTP
       paper, Introduction and section 3.5), kept on purpose.
    2. eps_d = ``beta`` * sqrt(2) * ``sigma_px`` / f_px (angle noise of a side);
       the k-vector window is P_obs +- ||p||_1 eps_d.
    3. Per-side check |d_obs,k - d_k| <= eps_d for the three sides.
    4. Vertex correspondence: 'role' maps S, N1, N2 directly; 'sorted' tries the six
       correspondences whose three sides match within eps_d and whose handedness
       (sign of b_S . (b_N1 x b_N2)) agrees, the sign being tested only when the triangle is
       far enough from collinear (|triple| > eps_d * longest side).
    5. Verification (reconstructed;): each correspondence identifies the
       other observed stars by their angular distances (chords) to the three identified stars:
       guide star G and observed star o match when the three distances agree within eps_d,
       one-to-one only. A correspondence is confirmed when at least ``k_min`` other stars
       match. The main star is accepted when exactly one distinct correspondence is confirmed
       (two different ones = ambiguous, next main star). Then (a) the proposals are pruned
       until every pair of them is angularly consistent within eps_d
       (``starid.kernels.verify_pairwise`` with ``min_fraction=1``; a fixed minimum support let
       a wrong star through when the triangle is thin and the star far from it), (b) the attitude is solved
       from them (Wahba, SVD/polar factor) and (c) every observed star is re-identified as the
       guide star predicted within eps_d of it (one-to-one), twice (the second attitude uses
       the larger, better spread set). The image is reported when at least 3 + ``k_min`` stars
       are identified this way, else the next main star is tried.
    6. The image fails (all -1) when every main star has been tried.

    Reported: every star identified in step 5c (the triangle stars are re-identified there too;
    identifying the stars beyond the triangle is this reconstruction's addition, so that an
    image reports as many verified stars as possible), and the attitude.

    Pattern radius: the usual reading suggests R = FOV/2 = 5 deg, but then no main star's R-disc ever
    lies inside the 10 x 10 deg image, and a catalog neighbour outside the image breaks the triangle.
    With one triangle per guide star R = 4 deg was the best on noise-free trials (seed 1: 3.5 / 4 / 4.5
    / 5 deg gave 95.6 / 96.1 / 94.9 / 92.9 %). With K = 5 triangles per star and the whole-image pass,
    R = 5 deg is better in the real sky (seed 7: R = 4 / 4.5 / 5 / 6 deg at K = 3: 91.4 / 92.7 / 92.4 /
    89.1 %; K = 5, R = 5: 95.65 %). Both are reconstructions.

    Extensions (each a parameter, measured in docs/algorithms/pvector.md): ``triangles_per_star``
    K = 5 (the triangles of every pair of the 5 brightest neighbours, so two of them in the image
    suffice; chosen on the real-sky rate, seed 7; the database, 0.77 MB with compact uint16 sides and
    k-vector, each star triple once and no stored keys, is 1.4x the paper's 0.537 MB),
    ``image_neighbours`` (the image side's K, a superset of the database's), ``hypotheses`` (64; 0 = off:
    when no triangle is confirmed by ``k_min`` guide-star distance matches, the correspondences that
    passed the side and handedness checks are tried again, each confirmed when its attitude explains the
    whole image: ``max(check_min_stars, check_fraction * n)`` (5, 0.5) detections within eps_d of a
    predicted star among the guide stars and the stars to ``check_mag_limit`` (V 7), its own three
    included; a real sensor images every star to its limit, so a sparse field often holds a single
    database triangle and too few guide stars for k_min), ``search`` ('linear': the search of a sorted
    table without an index, which explains why the paper's P-vector is slower than PTP), ``mag_margin``
    (flight precaution), ``assign_all`` (the standard final step), ``confirm_fraction``, ``max_stars``,
    ``max_candidates`` (bounds for very wide or crowded images). Tuned on seed 7, evaluated on seed 11.
    The form closest to the paper: ``triangles_per_star=2, hypotheses=0`` (``pattern_radius_deg=4``).

    Tolerances and other numbers the paper does not give (r_min = 0.2 deg, beta = 3,
    k_min = 2) are reconstructions (docs/algorithms/pvector.md).
    """

    name: ClassVar[str] = "pvector"
    #: closest to the paper's numbers (Table 6, Figs. 12-13, 0.537 MB; docs/algorithms/pvector.md): the
    #: triangles of each guide star's three brightest neighbours within 4 deg (K = 3, 0.352 MB). The PTP
    #: paper describes one triangle of the two brightest (K = 2, 0.188 MB), which reads 5-11 points below
    #: its Table 6 and Fig. 13 numbers. No whole-image pass; the sorted table searched without a k-vector;
    #: the tolerance fixed at the paper's 1 px (Table 6's noise) instead of following the simulator, so the
    #: rate falls with centroid noise above 1 px as Fig. 12's does (``pvector:paper``)
    published: ClassVar[dict] = {"triangles_per_star": 3, "pattern_radius_deg": 4.0, "image_neighbours": 3,
                                 "hypotheses": 0, "search": "linear", "unique_triangles": False, "sigma_px": 1.0}
    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}
    query_only: ClassVar[tuple[str, ...]] = ('sigma_px',)   # only identify reads them (conformance 'query_only')

    mag_limit: float = param(6.0, unit="mag",
                             help="guide-star limit, applied to the catalog and to the measured magnitudes")
    """Guide-star limit (V); applied to the catalog and to the measured magnitudes."""
    sigma_px: float | None = param(
        None, help="centroid noise every tolerance assumes; None follows the simulator (floor 1 px)", unit="px")
    """Assumed centroid noise (px) from which every tolerance is derived (Table 6: 1 px). ``None``
    (default) follows the simulator; floored at ``SIGMA_FLOOR_PX`` = 1 px, so a noise-free world
    still gets a window."""
    pattern_radius_deg: float = param(5.0, unit="deg",
                                      help="R: neighbours lie within R of the main star (starid's reconstruction)")
    """R: neighbours lie within R of the main star (reconstructed; see the class docstring)."""
    min_sep_deg: float = param(0.2, help="r_min: closer neighbours are ignored (starid's reconstruction)", unit="deg")
    """r_min: closer neighbours are ignored (close pairs;: 0.2-0.5 deg, reconstructed)."""
    beta: float = param(3.0, help="tolerance factor: eps_d = beta sqrt(2) sigma_px / f_px (starid's reconstruction)")
    """Tolerance factor (3 sigma)."""
    k_min: int = param(2, help="other stars a correspondence must identify to be confirmed (starid's reconstruction)")
    """Other stars a correspondence must identify to be confirmed (reconstructed); raised per image when
    a wrong correspondence would reach it by chance (``chance_tail``)."""
    side_order: str = param(
        "sorted", help="'sorted' (sides ascending, default) or 'role' (S-N1, S-N2, N1-N2) (starid's reconstruction)")
    """'sorted' (d ascending, reconstructed default) or 'role' (S-N1, S-N2, N1-N2)."""
    neighbour_rule: str = param(
        "brightest", help="'brightest' (paper, per the PTP Introduction) or 'nearest' neighbours form the triangle")
    """'brightest' (the paper's, per the PTP Introduction) or 'nearest' (alternative)."""
    main_order: str = param(
        "centre",
        help="main stars tried 'centre' (farthest from the edge) or 'brightness' first (starid's reconstruction)")
    """'centre' (edge distance) or 'brightness' (reconstructed alternatives)."""
    disc_inside_only: bool = param(False,
                                   help="use only main stars whose R-disc lies inside the image (strict reading)")
    """Only use main stars whose R-disc lies inside the image (strict reading)."""
    max_stars: int = param(100, help="brightest detections that take part (a time bound)")
    """Only the brightest ``max_stars`` detections take part (a time bound for crowded or wide images)."""
    max_candidates: int = param(
        16, help="a triangle matching more database triangles than this is skipped (scaled with eps_d^3)")
    """A triangle matching more database triangles than this is skipped (uninformative; never binds on
    the Table 4 camera: 1,000 real-sky trials identical with 64; a 40 deg field 30x faster). The cap used is
    ``max_candidates * (eps_d / eps_ref)^3`` when eps_d is wider than eps_ref, the tolerance of the reference
    camera (``starid.camera.REFERENCE_CAMERA``) at 1 px: the window's volume in side space grows as eps_d^3,
    and so does the number of triangles it holds by chance (1,050 on a 20 deg, 1024 px camera at 2 px),
    at most ``max_candidates_wide``."""
    max_candidates_wide: int = param(64, help="upper bound of the eps_d-scaled max_candidates (a time bound)")
    """The scaled cap never exceeds this. It is a time bound, tuned on seed 7 (Luo's camera at 2 px, 100
    images; a bound of 16 / 32 / 64 / 128 / 256 identified 25 / 77 / 94 / 93 / 93 %, median 17 / 27 / 15 / 73 /
    62 ms): beyond 64 the extra triangles are almost all chance matches, each checked against the whole image."""
    confirm_fraction: float = param(
        0.5, help="fraction of the predicted guide stars that must be seen in the image; 0 = off (starid's extension)")
    """The attitude must find at least this fraction of the guide stars it puts in the image (0: off)."""
    triangles_per_star: int = param(
        5, help="K: triangles of every pair of a guide star's K brightest neighbours (2 = paper; starid's extension)")
    """K: each guide star stores the triangles of its K brightest neighbours, K(K-1)/2 of them
    (2 = one triangle per star; reconstruction, see docs/algorithms/pvector.md)."""
    search: str = param("kvector",
                        help="'kvector' (the same index as PTP) or 'linear' (a scan of the sorted keys, paper-like)")
    """'kvector' (fair default, the same index as PTP) or 'linear' (a scan of the sorted keys)."""
    mag_margin: float = param(0.5, unit="mag",
                              help="detections fainter than mag_limit + this make no pattern (flight precaution)")
    """Image stars measured fainter than ``mag_limit + mag_margin`` make no pattern (flight precaution)."""
    assign_all: bool = param(
        False, help="assign every detection to the deep catalog star its attitude predicts (standard final step)")
    """Final step: once the attitude is known, assign every detection to the deep catalog star
    (V <= ``deep_mag_limit``) predicted within the tolerance."""
    deep_mag_limit: float = param(7.5, unit="mag",
                                  help="faintest catalog star assign_all can assign, stored only with assign_all")
    """Depth of the catalog kept for ``assign_all`` (stored only when ``assign_all``)."""
    image_neighbours: int = param(
        5, help="brightest neighbours of an image main star that form its triangles (starid's extension)")
    """Extension: the image side forms the triangles of each main star's this many brightest neighbours, a
    superset of the database's ``triangles_per_star`` (a V > 6 star that noise brought in, or a missing
    guide star, among the brightest does not break every triangle); ``image_neighbours <=
    triangles_per_star`` is the database's own rule."""
    hypotheses: int = param(
        64,
        help="correspondences retried by the whole-image check when none is confirmed; 0 = off (starid's extension)")
    """Extension (0 = off): when no triangle is confirmed, up to this many of the correspondences that passed
    the side and handedness checks are tried again, each confirmed by its attitude explaining the whole image
    (guide stars and the stars to ``check_mag_limit``) instead of by ``k_min`` guide-star distance matches."""
    check_mag_limit: float = param(7.0, unit="mag",
                                   help="catalog stars to this V are predicted in the whole-image check")
    """Depth of the whole-image check's star list (unit vectors only; stored only when ``hypotheses`` > 0)."""
    check_min_stars: int = param(
        5, help="least detections (triangle included) the attitude must explain in the whole-image check")
    """Detections (triangle included) the attitude must explain, at least."""
    check_fraction: float = param(0.5,
                                  help="fraction of the detections the attitude must explain in the whole-image check")
    """... and at least this fraction of the detections."""
    chance_tail: float = param(
        0.05, help="k_min is raised until a wrong match reaches it with at most this probability; 0 = off")
    """The confirmation count actually required is max(``k_min``, k), k the smallest count a wrong
    correspondence reaches by chance with probability <= ``chance_tail`` (Poisson, mean n_obs n_guide
    eps_d^2 / pi: :func:`kernels.chance_k_min`); 0 = ``k_min`` alone. 2 on the Table 4 camera at 1 px
    (unchanged), 4 on a 20 deg, 1024 px camera at 2 px."""
    unique_triangles: bool = param(
        True, help="store each star triple once, not once per main star (starid's storage choice)")
    """Storage (starid's): with sorted sides each star triple is stored once, not once per main star
    that forms it (the paper's one triangle per guide star: ``False``); identify tries every vertex
    correspondence, so the copies only repeat candidates (47,957 -> 38,884 triangles, 1.09 -> 0.77 MB
    with the unstored keys of the k-vector search)."""

    def __post_init__(self):
        check_number("mag_limit", self.mag_limit)
        if self.sigma_px is not None:
            check_number("sigma_px", self.sigma_px, lo=0)   # None: follow the simulator
        check_number("pattern_radius_deg", self.pattern_radius_deg, lo=0, hi=90, lo_open=True, hi_open=True)
        check_number("min_sep_deg", self.min_sep_deg, lo=0)
        check_number("beta", self.beta, lo=0, lo_open=True)
        if not self.min_sep_deg < self.pattern_radius_deg:
            raise ConfigError(f"min_sep_deg ({self.min_sep_deg!r}) must be smaller than "
                              f"pattern_radius_deg ({self.pattern_radius_deg!r})")
        check_whole("k_min", self.k_min, 0)
        check_choice("side_order", self.side_order, SIDE_ORDERS)
        check_choice("neighbour_rule", self.neighbour_rule, NEIGHBOUR_RULES)
        check_choice("main_order", self.main_order, MAIN_ORDERS)
        check_flag("disc_inside_only", self.disc_inside_only)
        check_whole("max_stars", self.max_stars, 3, 10_000)
        check_whole("max_candidates", self.max_candidates, 1)
        check_whole("max_candidates_wide", self.max_candidates_wide, 1)
        check_number("confirm_fraction", self.confirm_fraction, lo=0, hi=1)
        check_whole("triangles_per_star", self.triangles_per_star, 2, 10)
        check_choice("search", self.search, SEARCHES)
        check_number("mag_margin", self.mag_margin)
        check_flag("assign_all", self.assign_all)
        check_flag("unique_triangles", self.unique_triangles)
        check_number("deep_mag_limit", self.deep_mag_limit)
        check_whole("hypotheses", self.hypotheses, 0, 10_000)
        check_whole("image_neighbours", self.image_neighbours, 2, 20)
        check_number("check_mag_limit", self.check_mag_limit)
        check_whole("check_min_stars", self.check_min_stars, 4)
        check_number("check_fraction", self.check_fraction, lo=0, hi=1)
        check_number("chance_tail", self.chance_tail, lo=0, hi=1)
        tol = K.Tolerances(
            mag_limit=float(self.mag_limit),
            c_rmin=rad_to_chord(math.radians(self.min_sep_deg)),
            c_r=rad_to_chord(math.radians(self.pattern_radius_deg)),
            r_rad=math.radians(self.pattern_radius_deg),
            sigma_px=max(self.sigma_px or 0.0, SIGMA_FLOOR_PX),
            beta=float(self.beta),
            k_min=int(self.k_min),
            sorted_sides=self.side_order == "sorted",
            brightest=self.neighbour_rule == "brightest",
            centre_first=self.main_order == "centre",
            inside_only=bool(self.disc_inside_only),
            max_stars=int(self.max_stars),
            max_candidates=int(self.max_candidates),
            confirm_fraction=float(self.confirm_fraction),
            triangles_per_star=int(self.triangles_per_star),
            linear_search=self.search == "linear",
            assign_all=bool(self.assign_all),
            mag_margin=float(self.mag_margin),
            hypotheses=int(self.hypotheses),
            image_neighbours=int(self.image_neighbours),
            check_min_stars=int(self.check_min_stars),
            check_fraction=float(self.check_fraction),
            chance_tail=float(self.chance_tail),
            eps_ref=float(self.beta) * math.sqrt(2.0) * SIGMA_FLOOR_PX / REFERENCE_CAMERA.f_px,
            max_candidates_wide=int(self.max_candidates_wide))
        object.__setattr__(self, "_tol", tol)
        object.__setattr__(self, "_tol_t", tuple(tol))

    # ------------------------------------------------------------------ build
    def _triangles(self, unit, v_mag, hip):
        """(S, N1, N2) rows of every guide star that has two neighbours, in row order."""
        c_rmin = self._tol.c_rmin
        c_r = self._tol.c_r
        tree = cKDTree(unit)
        pairs = tree.query_pairs(c_r, output_type="ndarray")
        i = np.concatenate([pairs[:, 0], pairs[:, 1]])
        j = np.concatenate([pairs[:, 1], pairs[:, 0]])
        d = np.linalg.norm(unit[i] - unit[j], axis=1)
        keep = (d >= c_rmin) & (d <= c_r)
        i, j, d = i[keep], j[keep], d[keep]
        rank = v_mag[j] if self.neighbour_rule == "brightest" else d
        # per main star i: rank key, then distance, then HIP (no image position in the catalog)
        order = np.lexsort((hip[j], d, rank, i))
        i, j = i[order], j[order]
        first = np.searchsorted(i, np.arange(unit.shape[0]), side="left")
        count = np.bincount(i, minlength=unit.shape[0])
        k = int(self.triangles_per_star)
        out = []
        for b in range(1, k):          # brightest pair first, as identify tries them
            for a in range(b):
                has = np.flatnonzero(count >= b + 1)
                out.append(np.stack([has, j[first[has] + a], j[first[has] + b]], axis=1))
        rows = np.concatenate(out)
        return rows[np.lexsort((rows[:, 2], rows[:, 1], rows[:, 0]))]

    def build(self, catalog: Catalog, camera: Camera) -> PVectorDatabase:
        guide = catalog.brighter_than(self.mag_limit)
        if len(guide) < 3:
            raise ConfigError(f"only {len(guide)} catalog stars are brighter than mag_limit={self.mag_limit}")
        by_z = np.lexsort((guide.hip, guide.unit_icrs[:, 2]))
        unit = np.ascontiguousarray(guide.unit_icrs[by_z])
        v_mag = guide.v_mag[by_z]
        hip = guide.hip[by_z]
        rows = self._triangles(unit, v_mag, hip)
        if self.unique_triangles and self.side_order == "sorted":
            rows = _unique_triangles(rows)
        if rows.shape[0] < 2:
            raise ConfigError("fewer than two guide stars have two neighbours within pattern_radius_deg")
        s, n1, n2 = unit[rows[:, 0]], unit[rows[:, 1]], unit[rows[:, 2]]

        def angle(a, b):
            return 2.0 * np.arcsin(np.minimum(1.0, 0.5 * np.linalg.norm(a - b, axis=1)))

        sides = np.stack([angle(s, n1), angle(s, n2), angle(n1, n2)], axis=1)
        if self.side_order == "sorted":
            sides = np.sort(sides, axis=1)
        cov = np.cov(sides.T, bias=True)
        eigval, eigvec = np.linalg.eigh(cov)
        p_axis = eigvec[:, -1]
        if p_axis.sum() < 0:
            p_axis = -p_axis
        key = (sides @ p_axis).astype(np.float32)
        order = np.argsort(key, kind="stable")
        step = float(sides.max()) / np.iinfo(np.uint16).max
        row_dtype = np.int16 if unit.shape[0] <= np.iinfo(np.int16).max else np.int32
        return PVectorDatabase(
            p_axis=np.ascontiguousarray(p_axis, dtype=np.float64),
            kv=_key_index(key[order], keep_keys=self.search == "linear"),
            tri_sides=np.ascontiguousarray(np.rint(sides[order] / step), dtype=np.uint16),
            side_step_rad=step,
            tri_rows=np.ascontiguousarray(rows[order], dtype=row_dtype),
            unit_icrs=np.ascontiguousarray(unit, dtype=np.float32),
            hip=hip.astype(np.int64),
            deep=deep_sky(catalog, self.deep_mag_limit if self.assign_all else -math.inf),
            extra_unit=check_stars(catalog, hip, self.check_mag_limit if self.hypotheses else -math.inf),
            explained_variance=float(eigval[-1] / eigval.sum()),
        )

    # --------------------------------------------------------------- identify
    def _run(self, database: PVectorDatabase, observation: Observation):
        """:func:`kernels.identify_rows`, then (``assign_all``) the attitude assigns every detection to the deep
        catalog star predicted within the tolerance (``starid.kernels.assign_all``, one-to-one only)."""
        (frame, frame_t), tol = _frame(observation.camera), self._tol
        hip, attitude, ok, tri, work = K.identify_rows(observation.x_px, observation.y_px, observation.mag, frame_t,
                                                       database.plain_tables, self._tol_t)
        if ok and tol.assign_all and database.deep.unit.shape[0] > 0:
            eps = tol.beta * math.sqrt(2.0) * tol.sigma_px / frame.f_px
            assign_all(attitude, observation.x_px, observation.y_px, frame, database.deep, eps, hip)
        return hip, attitude, ok, tri, work

    def identify(self, database: PVectorDatabase, observation: Observation) -> Identification:
        n = observation.x_px.shape[0]
        if n < 3:
            return Identification(np.full(n, -1, dtype=np.int64), counters=dict.fromkeys(K.WORK_NAMES, 0))
        hip, attitude, ok, _, work = self._run(database, observation)
        return Identification(hip, attitude if ok else None, counters=dict(zip(K.WORK_NAMES, work.tolist(),
                                                                               strict=True)))

    def explain(self, database: PVectorDatabase, observation: Observation) -> Explanation:
        """The accepted main (guide) star and the two neighbours of its triangle, as three bold segments."""
        n = len(observation)
        x, y = observation.x_px, observation.y_px
        points = np.stack([x, y], axis=1) if n else np.zeros((0, 2))
        if n < 3:
            return Explanation(points=points, labels=("",) * n, caption=f"P-vector: {n} stars, no triangle.")
        hip, _, ok, tri, _ = self._run(database, observation)
        labels = tuple(str(h) if h >= 0 else "" for h in hip)
        if not ok:
            return Explanation(points=points, labels=labels,
                               caption="P-vector: no main star's triangle was confirmed; nothing identified.")
        s, n1, n2 = (int(v) for v in tri)
        segments = [[[x[a], y[a]], [x[b], y[b]]] for a, b in ((s, n1), (s, n2), (n1, n2))]
        caption = (f"P-vector: main star {int(hip[s])} with its neighbours {int(hip[n1])} and {int(hip[n2])} "
                   f"(bold triangle, key P = p . sides) identified the image; {int(np.sum(hip >= 0))} of {n} "
                   f"stars identified.")
        return Explanation(segments=np.array(segments), polygons=(np.array([[x[v], y[v]] for v in (s, n1, n2)]),),
                           points=points, labels=labels, caption=caption, highlight=np.arange(3))
