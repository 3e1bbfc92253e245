"""Grid star identification (Padgett & Kreutz-Delgado 1997) with modified-grid robustness options."""

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

from ..lpt_improved.planar import (
    PlanarAlgorithm,
    acceptance,
    effective_double_px,
    explain_pattern,
    neighbour_lists,
    new_trace,
    pack_params,
    prepare_image,
    select_guides,
)
from .kernels import GridSpec, GridTable, build_patterns, by_cell, by_pattern, identify_kernel


@dataclass(frozen=True, eq=False)
class GridDatabase(Database):
    """One sparse binary grid per guide star (per orientation choice).

    patterns : uint16 (int32 beyond 65536 patterns) the patterns holding each cell, ascending,
        grouped by cell (row * g + col): cell c's are ``patterns[cell_start[c]:cell_start[c+1]]``.
    cell_start : int32 (g * g + 1,) offsets into ``patterns``.
    start : int32 (k + 1,) pattern p has ``start[p+1] - start[p]`` occupied cells (:attr:`cells`
        lists them: ``cells[start[p]:start[p+1]]``, sorted).
    guide, orient : int16/int32 (k,) guide rows of each pattern's reference and orientation star.
    guide_unit : float32 (g, 3) ICRS unit vectors of the guide stars, sorted by z.
    guide_hip : int64 (g,) their catalog ids.
    radius_deg : half side of the pattern square (the pattern radius); f_px, double_px: geometry.
    """

    patterns: np.ndarray
    cell_start: np.ndarray
    start: np.ndarray
    guide: np.ndarray
    orient: np.ndarray
    guide_unit: np.ndarray
    guide_hip: np.ndarray
    radius_deg: float
    f_px: float
    double_px: float

    @property
    def cells(self) -> np.ndarray:
        """uint16 sorted occupied cells of every pattern, concatenated (from the cell index; not stored)."""
        return by_pattern(self.patterns, self.cell_start)[0].astype(np.uint16)

    @property
    def table(self) -> GridTable:
        return GridTable(self.patterns, self.cell_start, self.start, self.guide, self.orient)


@dataclass(frozen=True)
class Grid(PlanarAlgorithm):
    """Grid algorithm (Padgett & Kreutz-Delgado, IEEE TAES 1997) with the modified-grid options (Na et al. 2009).

    Padgett C., Kreutz-Delgado K., "A grid algorithm for autonomous star identification", IEEE
    Transactions on Aerospace and Electronic Systems 33(1):202-213 (1997); Na M., Zheng D.,
    Jia P., "Modified grid algorithm for noisy all-sky autonomous star identification", IEEE
    TAES 45(2):516-522 (2009). Neither paper was at hand: Padgett's method is rebuilt from its
    abstract and Cole & Crassidis' summary, the modified grid from its title and purpose
    (noise robustness); every choice is a parameter (``docs/algorithms/grid.md``).

    1. Guide stars V <= ``mag_limit``, pairs closer than ``double_px`` dropped (as in the
       log-polar plugins).
    2. Pattern of a reference star, in the plane tangent at it (algorithm notes 1.4): its
       nearest neighbour at least ``buffer_px`` away is the orientation star (Padgett: "a grid
       centred and aligned using two stars"); the plane is rotated to put it on +x; a
       ``grid_size`` x ``grid_size`` grid covers the square of half side R (``radius_deg``,
       default as in ``lpt_improved``) and each neighbour sets its cell. Padgett; grid size,
       buffer and R reconstructed.
    3. Match: every database pattern (the whole database, as Padgett and Luo et al. describe
       it) is scored by the number of its cells also set in the image pattern (the AND of the
       two bit grids). Padgett. The database is indexed by cell, so the scores are accumulated
       from the image's cells over the patterns holding them (the same sums, added in the same
       order, as a pattern-by-pattern scan).
    4. Modified-grid options (reconstructed interpretation of Na et al.; defaults on, since
       Luo et al. compare against the modified grid): ``soft_edge``/``soft_diag`` credit for a
       database cell next to an image star's cell (0.4 / 0.2; 0 / 0 = Padgett's exact cells);
       ``image_orientations`` nearest neighbours beyond the buffer tried as orientation star
       (2; 1 = Padgett), ``db_orientations`` likewise in the database (1); ``normalise``
       divides the score by sqrt(n_image n_pattern) (off).
    5. The ``n_candidates`` best patterns scoring at least ``min_score`` seed an attitude
       (reference and orientation star, Wahba) confirmed by reprojection as in
       ``lpt_improved`` (``min_matches``, ``confirm_fraction``, ``beta``, ``sigma_px`` with a
       1 px floor, following the simulator); reference stars from the image centre outwards
       (Padgett prefers central stars), at most ``max_refs``. starid's verification.
    """

    name: ClassVar[str] = "grid"
    #: the paper's procedure: one reference star (nearest the centre), its best match only, one
    #: orientation (``grid:paper``)
    published: ClassVar[dict] = {"max_refs": 1, "n_candidates": 1, "image_orientations": 1}

    buffer_px: float = param(
        30.0, help="nearest neighbour at least this far is the orientation star (starid's reconstruction)", unit="px")
    grid_size: int = param(
        40, help="cells per side of the pattern grid over the square of half side R (starid's reconstruction)")
    soft_edge: float = param(
        0.4, help="credit for a database cell edge-adjacent to an image cell (modified grid; 0 = Padgett)")
    soft_diag: float = param(0.2,
                             help="credit for a database cell diagonal to an image cell (modified grid; 0 = Padgett)")
    image_orientations: int = param(
        2, help="nearest image neighbours beyond the buffer tried as orientation star (1 = Padgett)")
    db_orientations: int = param(
        1, help="nearest catalog neighbours beyond the buffer stored as orientation stars (modified grid)")
    normalise: bool = param(False,
                            help="divide the score by sqrt(n_image n_pattern) (modified grid, starid's reconstruction)")
    min_score: float = param(3.0, help="score a database pattern needs to seed an attitude")

    def __post_init__(self):
        super().__post_init__()
        check_number("buffer_px", self.buffer_px, lo=0)
        check_whole("grid_size", self.grid_size, 2, 255)
        for name in ("soft_edge", "soft_diag"):
            check_number(name, getattr(self, name), lo=0, hi=1)
        check_whole("image_orientations", self.image_orientations, 1)
        check_whole("db_orientations", self.db_orientations, 1)
        check_flag("normalise", self.normalise)
        check_number("min_score", self.min_score, lo=0)

    def _spec(self, radius_deg: float, double_px: float) -> GridSpec:
        half = math.tan(math.radians(radius_deg))
        return GridSpec(self.grid_size, 0.0, float(self.buffer_px), math.cos(math.atan(math.sqrt(2.0) * half)),
                        float(self.soft_edge), float(self.soft_diag), bool(self.normalise), float(self.min_score),
                        self.max_refs, self.image_orientations, self.n_candidates, float(double_px))

    def _spec_for(self, db: GridDatabase) -> GridSpec:
        return self._spec(db.radius_deg, db.double_px)._replace(half_px=db.f_px * math.tan(math.radians(db.radius_deg)))

    def build(self, catalog: Catalog, camera: Camera) -> GridDatabase:
        settled = self.derived(catalog, camera)
        radius = settled.radius_deg
        double_px = effective_double_px(self.double_px, radius, camera)
        guides = select_guides(catalog, settled.mag_limit, double_px, camera, self.name)
        spec = self._spec(radius, double_px)._replace(half_px=camera.f_px * math.tan(math.radians(radius)))
        nbr, off = neighbour_lists(guides.unit, math.acos(spec.cos_radius))
        cells, start, guide, orient = build_patterns(guides.unit.astype(np.float64), nbr, off, float(camera.f_px),
                                                     spec, self.db_orientations)
        rd = np.int16 if len(guides.hip) <= np.iinfo(np.int16).max else np.int32
        patterns, cell_start = by_cell(cells, start, self.grid_size ** 2)
        return GridDatabase(patterns, cell_start, start.astype(np.int32), guide.astype(rd), orient.astype(rd),
                            guides.unit, guides.hip, radius, float(camera.f_px), double_px)

    def _make_kernel_args(self, db: GridDatabase, cam: Camera) -> tuple:
        acc = acceptance(cam, self.sigma_px, self.beta, self.min_matches, self.confirm_fraction)
        return (pack_params(camera_frame(cam), acc, self._spec_for(db)), *db.table, db.guide_unit)

    def _run(self, db: GridDatabase, observation: Observation):
        trace = new_trace()
        rows, attitude, ok = identify_kernel(observation.x_px, observation.y_px,
                                             *self._kernel_args(db, observation.camera), trace)
        return rows, attitude, ok, trace

    def explain(self, database: GridDatabase, observation: Observation) -> Explanation:
        """The reference star, its orientation star, its neighbours and the oriented grid's outline and lines."""
        rows, _, ok, trace = self._run(database, observation)
        x, y = observation.x_px, observation.y_px
        ref, orient = int(trace[0]), int(trace[1])
        if ref < 0:
            _, usable, order = prepare_image(x, y, camera_frame(observation.camera), database.double_px)
            if len(order) >= 2:
                ref = int(order[0])
                d = np.hypot(x - x[ref], y - y[ref])
                d[~usable | (d < self.buffer_px)] = np.inf
                d[ref] = np.inf
                orient = int(np.argmin(d)) if np.isfinite(d.min()) else -1
        half = observation.camera.f_px * math.tan(math.radians(database.radius_deg))
        ex = explain_pattern(observation, rows, database.guide_hip, ref, orient,
                             half * math.sqrt(2.0), database.double_px, np.zeros(0), "")
        segments = list(ex.segments)
        if ref >= 0 and orient >= 0:
            base = math.atan2(y[orient] - y[ref], x[orient] - x[ref])
            c, s = math.cos(base), math.sin(base)

            def to_px(u, v):
                return [x[ref] + c * u - s * v, y[ref] + s * u + c * v]
            step = 2 * half / self.grid_size
            every = max(1, self.grid_size // 10)
            for i in range(0, self.grid_size + 1, every):
                t = -half + i * step
                segments.append([to_px(t, -half), to_px(t, half)])
                segments.append([to_px(-half, t), to_px(half, t)])
        every = max(1, self.grid_size // 10)
        caption = (f"Grid: reference star, orientation star (bold) and neighbours; every {every}th "
                   f"line of the {self.grid_size} x {self.grid_size} oriented grid. Best pattern scored "
                   f"{trace[3] / 1000:g}; {int((rows >= 0).sum())} stars confirmed by reprojection." if ok else
                   "Grid: no match was confirmed; the first reference star's oriented grid is shown.")
        return Explanation(segments=np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2), points=ex.points,
                           labels=ex.labels, caption=caption, highlight=ex.highlight)
