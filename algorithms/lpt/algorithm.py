"""Log-polar-transform star identification with circular string matching (Wei, Zhang & Jiang 2009)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from starid.camera import Camera
from starid.catalog import Catalog
from starid.kernels import camera_frame
from starid.observation import Observation
from starid.params import check_whole, param
from starid.plugin import Database, Explanation

from ..lpt_improved.planar import (
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
from .kernels import Strings, StringSearch, identify_kernel, lpt_string, scan_order, sparse_strings


def build_strings(unit: np.ndarray, nbr: np.ndarray, nbr_off: np.ndarray, f_px: float,
                  search: StringSearch) -> np.ndarray:
    """LPT string of every guide star (rows of ``unit``), dense uint8 ``(g, n_sectors)``.

    Once per database, so plain Python over the guide stars calling the two kernels identify
    compiles anyway (``plane_polar``, ``lpt_string``), with the same argument types: a build kernel
    of its own compiled ~0.6 CPU s on a cold cache (issue #25).
    """
    unit = np.ascontiguousarray(unit, dtype=np.float64)
    rows = np.asarray(nbr, dtype=np.int64)   # int64 rows: plane_polar's one (the image's) signature
    off = np.asarray(nbr_off, dtype=np.int64)
    strings = np.zeros((unit.shape[0], search.n_sectors), dtype=np.uint8)
    longest = max(1, int(np.diff(off).max())) if off.size > 1 else 1
    r_px, phi = np.empty(longest), np.empty(longest)
    out = np.zeros(search.n_sectors, dtype=np.int64)
    owner = np.zeros(search.n_sectors, dtype=np.int64)
    f_px = float(f_px)
    for g in np.flatnonzero(np.diff(off)).tolist():
        lo, hi = int(off[g]), int(off[g + 1])
        plane_polar(unit, g, rows[lo:hi], hi - lo, f_px, r_px, phi)
        lpt_string(r_px, phi, hi - lo, search, out, owner)
        strings[g] = out
    return strings


@dataclass(frozen=True, eq=False)
class LPTDatabase(Database):
    """One LPT string per guide star, stored as its non-zero characters.

    The string of guide row g has character k = log-radius row (1..n_levels) of the nearest
    neighbour in angle sector k of the reference star's log-polar plane, 0 = empty
    (:attr:`strings` gives them all dense, uint8 (g, n_sectors)). Stored, CSR by guide row,
    sectors ascending:
    char_sector : uint8 (uint16 beyond 256 sectors) sectors k of the non-zero characters.
    char_level : uint8 their rows.
    char_start : int32 (g + 1,) guide g's characters are ``char_start[g]:char_start[g+1]``.
    guide_unit : float32 (g, 3) ICRS unit vectors of the guide stars, sorted by z.
    guide_hip : int64 (g,) their catalog ids.
    radius_deg, f_px, double_px, r_min_px, n_sectors : the geometry the strings were built with.
    """

    char_sector: np.ndarray
    char_level: np.ndarray
    char_start: np.ndarray
    guide_unit: np.ndarray
    guide_hip: np.ndarray
    radius_deg: float
    f_px: float
    double_px: float
    r_min_px: float
    n_sectors: int

    @property
    def chars(self) -> Strings:
        return Strings(self.char_sector, self.char_level, self.char_start)

    @property
    def strings(self) -> np.ndarray:
        """The dense strings, uint8 (g, n_sectors) (not stored; for tests and inspection)."""
        out = np.zeros((self.char_start.size - 1, self.n_sectors), dtype=np.uint8)
        g = np.repeat(np.arange(self.char_start.size - 1), np.diff(self.char_start))
        out[g, self.char_sector] = self.char_level
        return out


@dataclass(frozen=True)
class LPT(PlanarAlgorithm):
    """Log-polar transform (Wei, Zhang & Jiang, JACIC 2009): LPT strings matched under every circular shift.

    Wei X., Zhang G., Jiang J., "Star identification algorithm based on log-polar transform",
    Journal of Aerospace Computing, Information, and Communication 6(8):483-490 (2009),
    doi:10.2514/1.30393. Only the abstract and Luo et al.'s (2015) description of it were at
    hand: the method below is a reconstruction, every choice a parameter
    (``docs/algorithms/lpt.md``).

    1. Guide stars V <= ``mag_limit``, pairs closer than ``double_px`` dropped (as in
       ``lpt_improved``, for a like-for-like comparison).
    2. For a reference star, its neighbours within R (``radius_deg``; default as in
       ``lpt_improved``: 6 deg at 20 deg, 4 deg on the 10 deg Table 4 camera) in the plane
       tangent at it (algorithm notes 1.4), in polar coordinates (r, phi) and log-polar
       coordinates (ln r, phi) (paper: the LPT of the star image around the reference star; a
       sensor rotation becomes a circular shift along phi).
    3. String (paper: the LPT result coded as a string, one byte per character, Luo et al.:
       "row numbers" of the LPT image, 0.65 MB for 6685 stars, i.e. ~100 characters):
       ``n_sectors`` = 100 angle sectors; character k = the ln r row (1..``n_levels``, rows
       equal in ln r over [ln ``r_min_px``, ln R]) of the nearest neighbour in sector k, 0 if
       none. Number of rows and the nearest-star rule: reconstructed.
    4. Matching (paper: a modified KMP string match under circular shifts against the whole
       database): the score of a guide star is the largest, over the m circular shifts, number
       of image characters matched by a non-zero database character within ``level_tol`` rows
       and ``sector_tol`` sectors (tolerant matching is not an equality, so KMP cannot be used
       as such; all shifts are scored at once with bit-parallel shift sets over the strings'
       non-zero characters, which gives exactly the brute-force circular comparison's scores,
       and strings that provably cannot enter the candidate list are skipped, visited by length
       from the image string's own, which leaves the list exactly as a full scan makes it).
       Among equal scores the database string with fewer unmatched characters ranks first, then
       the lower guide row (a sparse pattern otherwise ties with every string that contains
       it). Reconstructed.
    5. The ``n_candidates`` best guide stars with at least ``min_score`` matched characters
       seed an attitude (the reference star and the roll the shift gives, refined by the
       matched characters) that must be confirmed by reprojection exactly as in
       ``lpt_improved`` (``min_matches``, ``confirm_fraction``, ``beta``, ``sigma_px`` with a
       1 px floor, following the simulator). Reference stars from the image centre outwards,
       at most ``max_refs``. starid's verification, not the paper's.
    """

    name: ClassVar[str] = "lpt"
    #: the paper's procedure: one reference star (nearest the centre), its best match only (``lpt:paper``)
    published: ClassVar[dict] = {"max_refs": 1, "n_candidates": 1}

    n_sectors: int = param(100, help="angle sectors of the LPT string, one character each (starid's reconstruction)")
    n_levels: int = param(16, help="ln r rows between ln r_min and ln R a character can take (starid's reconstruction)")
    level_tol: int = param(1, help="rows by which a matched database character may differ (starid's reconstruction)")
    sector_tol: int = param(1,
                            help="sectors by which a matched database character may be off (starid's reconstruction)")
    min_score: int = param(2, help="matched characters a guide star needs to be a candidate (starid's reconstruction)")

    def __post_init__(self):
        super().__post_init__()
        check_whole("n_sectors", self.n_sectors, 4, 1024)
        check_whole("n_levels", self.n_levels, 1, 255)
        check_whole("level_tol", self.level_tol, 0)
        check_whole("sector_tol", self.sector_tol, 0, self.n_sectors // 4)
        check_whole("min_score", self.min_score, 1)

    def _search(self, db: LPTDatabase) -> StringSearch:
        r_max_px = db.f_px * math.tan(math.radians(db.radius_deg))
        return StringSearch(self.n_sectors, self.n_levels, math.log(db.r_min_px), math.log(r_max_px),
                            math.cos(math.radians(db.radius_deg)), self.level_tol, self.sector_tol, self.min_score,
                            self.max_refs, self.n_candidates, float(db.double_px))

    def build(self, catalog: Catalog, camera: Camera) -> LPTDatabase:
        settled = self.derived(catalog, camera)
        radius = settled.radius_deg
        double_px = effective_double_px(self.double_px, radius, camera)
        guides = select_guides(catalog, settled.mag_limit, double_px, camera, self.name)
        nbr, off = neighbour_lists(guides.unit, math.radians(radius))
        empty = sparse_strings(np.zeros((0, self.n_sectors), dtype=np.uint8))
        db = LPTDatabase(*empty, guides.unit, guides.hip, radius, float(camera.f_px), double_px, max(double_px, 1.0),
                         self.n_sectors)
        strings = build_strings(guides.unit.astype(np.float64), nbr, off, float(camera.f_px), self._search(db))
        return LPTDatabase(*sparse_strings(strings), guides.unit, guides.hip, radius, float(camera.f_px), double_px,
                           db.r_min_px, self.n_sectors)

    def _make_kernel_args(self, db: LPTDatabase, cam: Camera) -> tuple:
        eps0_extra = math.pi / self.n_sectors * (1 + self.sector_tol) * math.tan(math.radians(db.radius_deg))
        acc = acceptance(cam, self.sigma_px, self.beta, self.min_matches, self.confirm_fraction, eps0_extra)
        order = scan_order(db.chars, self.n_sectors, self.n_levels)
        return (pack_params(camera_frame(cam), acc, self._search(db)), *order.strings, order.guide, order.count_start,
                order.levels, order.counts, db.guide_unit, z_index(db.guide_unit))

    def _run(self, db: LPTDatabase, observation: Observation):
        trace = new_trace()
        rows, attitude, ok = identify_kernel(observation.x_px, observation.y_px,
                                             *self._kernel_args(db, observation.camera), trace)
        return rows, attitude, ok, trace

    def explain(self, database: LPTDatabase, observation: Observation) -> Explanation:
        """The reference star, its neighbours within R and the boundaries of its occupied sectors."""
        rows, _, ok, trace = self._run(database, observation)
        x, y = observation.x_px, observation.y_px
        sensor = camera_frame(observation.camera)
        unit, usable, order = prepare_image(x, y, sensor, database.double_px)
        cos_r = math.cos(math.radians(database.radius_deg))
        nbrs = np.empty(len(x), dtype=np.int64)
        ref, k = -1, 0
        for s in ([int(trace[0])] if trace[0] >= 0 else [int(v) for v in order]):
            k = image_neighbours(unit, usable, x, y, s, cos_r, nbrs)
            if k:
                ref = s
                break
        rays = np.zeros(0)
        align = -1
        if ref >= 0:
            align = int(nbrs[0])   # drawn as the angle origin only: LPT needs no alignment star
            r_px, phi = np.empty(k), np.empty(k)
            plane_polar(unit, ref, nbrs, k, database.f_px, r_px, phi)
            chars, owner = np.zeros(self.n_sectors, dtype=np.int64), np.zeros(self.n_sectors, dtype=np.int64)
            lpt_string(r_px, phi, k, self._search(database), chars, owner)
            width = 2 * math.pi / self.n_sectors
            occupied = np.flatnonzero(chars)
            rays = np.unique(np.concatenate([occupied * width, (occupied + 1) * width])) - phi[0]
        radius_px = observation.camera.f_px * math.tan(math.radians(database.radius_deg))
        caption = (f"LPT: reference star matched {int(trace[3])} string characters under the best circular shift; "
                   f"{int((rows >= 0).sum())} stars confirmed by reprojection. Rays bound the occupied "
                   f"{360 / self.n_sectors:g} deg sectors." if ok else
                   "LPT: no match was confirmed; the first reference star's sectors are shown.")
        return explain_pattern(observation, rows, database.guide_hip, ref, align, radius_px, database.double_px,
                               rays, caption)
