"""Tetra: four-star pattern hashing (Brown 2017; the idea behind tetra3 / cedar-solve)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import ClassVar

import numpy as np
from scipy.spatial import cKDTree

from starid.camera import Camera
from starid.catalog import Catalog
from starid.errors import ConfigError
from starid.kernels import backproject_px, project_cam, rad_to_chord, wahba_rows
from starid.observation import Observation
from starid.params import check_number, check_whole, param
from starid.plugin import Algorithm, Database, Explanation, Identification

from .kernels import EMPTY, PAIRS, Settings, Tables, field_patterns, identify_kernel, pattern_keys, table_insert

#: Largest number of bins per ratio: keys (< bins^5) must fit in 32 bits.
MAX_BINS = 84
#: Largest number of guide stars: pattern rows are packed 16 bits each while building.
MAX_GUIDE = 65535


@dataclass(frozen=True, eq=False)
class TetraDatabase(Database):
    """The pattern hash table and the guide stars.

    table_word : uint64 (S,) per slot ``key << 16 | edge`` (all ones = free), S = patterns /
        ``load_factor``; ``edge`` is the pattern's largest edge as a fraction of ``edge_scale``
        times 65535.
    table_pattern : uint16 (S, 4) guide rows of each slot's pattern, in canonical order.
    guide_unit : float32 (g, 3) ICRS unit vectors of the guide stars, sorted by z.
    guide_hip : int32 or int64 (g,) catalog id of each guide row.
    reportable : bool (g,) guide stars without a catalog companion within ``double_star_deg``:
        only these form patterns and are reported (the others still count in verification).
    guide_mag : float32 (g,) catalog magnitude of each guide row (the report's magnitude check).
    bins : bins per edge ratio; edge_scale : the chord an edge of 65535 stands for;
    n_patterns : patterns stored; n_fields : lattice fields used;
    longest_probe : longest linear-probe run while inserting (build diagnostics).
    """

    table_word: np.ndarray
    table_pattern: np.ndarray
    guide_unit: np.ndarray
    guide_hip: np.ndarray
    reportable: np.ndarray
    guide_mag: np.ndarray
    bins: int
    edge_scale: float
    n_patterns: int
    n_fields: int
    longest_probe: int


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly uniform unit vectors (the Fibonacci lattice), (n, 3)."""
    i = np.arange(n, dtype=np.float64) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = math.pi * (3.0 - math.sqrt(5.0)) * i
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


@dataclass(frozen=True)
class Tetra(Algorithm):
    """Tetra: four-star patterns keyed by their five edge ratios in a hash table, first verified match wins.

    Brown J., "Tetra: star identification with hash tables", Proceedings of the AIAA/USU
    Conference on Small Satellites, 2017 (the method behind the open-source tetra3 and its fork
    cedar-solve). The paper itself was not at hand, so no equation numbers are quoted: this is a
    reconstruction from the published idea, written from scratch in numba (no tetra3 code).
    Method, parameters and measurements: ``docs/algorithms/tetra.md``.

    The published idea:

    * a pattern is four stars; its six edge lengths, sorted and divided by the largest, give
      five ratios that depend on neither attitude nor scale; quantised into ``bins`` bins they
      form the key of an open-addressing hash table of catalogue patterns, each stored as its
      four star indices;
    * the catalogue patterns are chosen so that every field of view has its brightest stars
      covered: fields on a lattice over the sky, the brightest guide stars of each contributing
      their 4-star patterns;
    * the image side forms the 4-star patterns of its brightest stars, brightest first, looks
      up every key within the ratio tolerance (neighbouring bins), matches star to star in a
      canonical order (distance from the pattern centroid), solves the attitude and verifies
      it with the other stars; the first verified pattern is the answer.

    Reconstructed (this library's choices, each a parameter):

    * guide stars: V <= ``mag_limit`` = 6.5, half a magnitude deeper than the 6.0 detection
      limit, so that the stars magnitude noise pushes into the image (V 6-6.5) are in patterns
      and count in verification (the "magnitude margin"); a guide star with any catalog star
      brighter than ``mag_limit + companion_margin_mag`` within ``double_star_deg`` is in no
      pattern and never reported (either may be the detection), but still counts when verifying;
    * lattice: Fibonacci lattice, spacing ``lattice_step`` x the camera's half-width; each field
      is the circle of ``field_radius`` x the half-diagonal around a lattice point; its
      ``field_stars`` brightest pattern stars give every 4-subset whose largest edge lies
      between ``min_span`` x the image width and the image diagonal;
    * hash: key = the five bin numbers as base-``bins`` digits (largest ratio most significant),
      Fibonacci hashing multiply-shifted onto ``patterns / load_factor`` slots, linear probing;
      a slot holds one 64-bit word, key and the pattern's largest edge quantised to 16 bits,
      so foreign keys and patterns of the wrong absolute size are skipped without geometry (the
      focal length is known here, unlike in tetra3's setting);
    * tolerance: ratio window +-``beta`` propagated sigmas, sigma_r = sqrt(2) sigma
      sqrt(1 + r^2) / e_max, sigma = ``sigma_px`` / f_px (``sigma_px`` follows the simulator,
      floored at 1 px so a noise-free world still gets a window); every key of the product of
      touched bins is looked up (a pattern touching more than ``max_keys`` keys is skipped);
      candidates must agree on all six edges within ``beta`` sqrt(2) sigma;
    * canonical order: ascending chord to the mean of the four unit vectors (ties by row);
      image stars whose distances agree within the edge tolerance may swap;
    * image side: the ``image_stars`` brightest detections by noisy magnitude (ties by
      position), patterns breadth-first (all of the 4 brightest, then those adding the 5th...);
    * verification: Wahba on the four pairs (``starid.kernels.wahba_rows``), reprojection of
      the guide stars (``starid.kernels.reproject_assign``, radius ``beta`` sqrt(2) sigma); the
      four must be re-found, at least ``min_extra`` more seen, and the chance of seeing that
      many by accident, Binomial(predicted - 4, q) with q the fraction of the sensor within the
      radius of a detection, at most ``max_mismatch`` (tetra3-style mismatch probability);
    * report: the attitude refined on every confirmed star, stars assigned again within
      ``report_beta`` sigma (0: keep the verification's assignment); a star is reported only
      if its measured magnitude is within ``mag_beta`` x ``sigma_mag`` (follows the simulator,
      floored at 0.5 mag; ``mag_beta`` = 0 switches the check off) of the catalog's, so a
      false star or an intruder that lands on an undetected guide star is not labelled.
    """

    name: ClassVar[str] = "tetra"
    follows: ClassVar[dict] = {"sigma_px": "sigma_px", "sigma_mag": "sigma_mag"}
    #: only identify reads them (conformance check 'query_only')
    query_only: ClassVar[tuple[str, ...]] = ('sigma_px', 'sigma_mag')

    mag_limit: float = param(
        6.5, unit="mag",
        help="guide stars have V <= this, half a magnitude deeper than the detection limit (starid's reconstruction)")
    sigma_px: float | None = param(None, unit="px",
                                   help="centroid noise the tolerances assume; None follows the simulator (floor 1 px)")
    double_star_deg: float = param(
        0.05, unit="deg",
        help="a guide star with a bright catalog star within this is in no pattern (starid's reconstruction)")
    companion_margin_mag: float = param(
        1.0, unit="mag",
        help="companions brighter than mag_limit + this make a guide star a double (starid's reconstruction)")
    field_stars: int = param(
        10, help="brightest pattern stars of each lattice field whose 4-subsets are stored (starid's reconstruction)")
    field_radius: float = param(
        0.8, help="lattice field radius in units of the camera's half-diagonal (starid's reconstruction)")
    lattice_step: float = param(
        0.5, help="Fibonacci lattice spacing in units of the camera's half-width (starid's reconstruction)")
    min_span: float = param(
        0.1, help="least largest edge of a stored pattern in units of the image width (starid's reconstruction)")
    bins: int = param(
        50, help="quantisation bins of each of the five edge ratios in the hash key (starid's reconstruction)")
    load_factor: float = param(0.75, help="stored patterns per hash-table slot (starid's reconstruction)")
    image_stars: int = param(
        10, help="brightest detections (by measured magnitude) the image patterns use (starid's reconstruction)")
    beta: float = param(3.0, help="ratio and edge tolerance in units of the propagated sigma (starid's reconstruction)")
    max_keys: int = param(
        256, help="an image pattern whose tolerance touches more hash keys is skipped (starid's reconstruction)")
    min_extra: int = param(
        1, help="guide stars beyond the pattern's four the attitude must see to verify it (starid's reconstruction)")
    max_mismatch: float = param(
        1e-4, help="largest tetra3-style chance of seeing that many stars by accident (starid's reconstruction)")
    report_beta: float = param(
        3.0, help="stars assigned again within this many sigma for the report; 0 = keep (starid's reconstruction)")
    sigma_mag: float | None = param(
        None, help="magnitude noise the report check assumes; None follows the simulator (floor 0.5)", unit="mag")
    mag_beta: float = param(
        3.0,
        help="report a star only within mag_beta sigma_mag of the catalog magnitude; 0 = off (starid's reconstruction)")

    def __post_init__(self):
        check_number("mag_limit", self.mag_limit)
        if self.sigma_px is not None:
            check_number("sigma_px", self.sigma_px, lo=0)
        check_number("double_star_deg", self.double_star_deg, lo=0, hi=90)
        check_number("companion_margin_mag", self.companion_margin_mag, lo=0)
        check_whole("field_stars", self.field_stars, 4, 30)
        check_number("field_radius", self.field_radius, lo=0, lo_open=True, hi=4)
        check_number("lattice_step", self.lattice_step, lo=0.02, hi=4)
        check_number("min_span", self.min_span, lo=0, hi=1, hi_open=True)
        check_whole("bins", self.bins, 2, MAX_BINS)
        check_number("load_factor", self.load_factor, lo=0.05, hi=0.95)
        check_whole("image_stars", self.image_stars, 4, 40)
        check_number("beta", self.beta, lo=0, lo_open=True)
        check_whole("max_keys", self.max_keys, 1)
        check_whole("min_extra", self.min_extra, 0)
        check_number("max_mismatch", self.max_mismatch, lo=0, hi=1)
        check_number("report_beta", self.report_beta, lo=0)
        if self.sigma_mag is not None:
            check_number("sigma_mag", self.sigma_mag, lo=0)
        check_number("mag_beta", self.mag_beta, lo=0)

    @cached_property
    def _sigma_px(self) -> float:
        """The centroid noise the windows assume: ``sigma_px`` floored at 1 px (noise-free worlds too)."""
        return max(self.sigma_px or 0.0, 1.0)

    @cached_property
    def _sigma_mag(self) -> float:
        """The magnitude noise the report check assumes: ``sigma_mag`` floored at 0.5 mag (the
        Table 6 noise; a noise-free world still merges pairs, 0.75 mag brighter for equal stars)."""
        return max(self.sigma_mag or 0.0, 0.5)

    # ------------------------------------------------------------------ build

    def _spans(self, camera: Camera) -> tuple[float, float]:
        """Smallest and largest allowed largest-edge of a pattern, as chords."""
        width_rad = 2.0 * math.atan(min(camera.width_px, camera.height_px) / 2.0 / camera.f_px)
        return rad_to_chord(self.min_span * width_rad), rad_to_chord(2.0 * camera.half_diagonal_rad)

    def build(self, catalog: Catalog, camera: Camera) -> TetraDatabase:
        guide = catalog.brighter_than(self.mag_limit)
        if len(guide) < 4:
            raise ConfigError(f"tetra: only {len(guide)} catalog stars have V <= {self.mag_limit}")
        if len(guide) > MAX_GUIDE:
            raise ConfigError(f"tetra: {len(guide)} guide stars exceed the {MAX_GUIDE} this database can index; "
                              f"lower mag_limit")
        by_z = np.argsort(guide.unit_icrs[:, 2], kind="stable")
        unit = np.ascontiguousarray(guide.unit_icrs[by_z])
        v_mag = guide.v_mag[by_z]
        hip = guide.hip[by_z]
        tree = cKDTree(unit)
        # guide stars with a catalog companion that may be detected instead of them or beside them
        pattern_ok = np.ones(len(unit), dtype=bool)
        if self.double_star_deg > 0:
            deep = catalog.brighter_than(self.mag_limit + self.companion_margin_mag)
            near = cKDTree(deep.unit_icrs).query_ball_point(unit, rad_to_chord(math.radians(self.double_star_deg)),
                                                            return_length=True)
            pattern_ok = near <= 1   # only itself
        half_width_rad = math.atan(min(camera.width_px, camera.height_px) / 2.0 / camera.f_px)
        step_rad = self.lattice_step * half_width_rad
        n_fields = int(min(2_000_000, max(12, math.ceil(4.0 * math.pi / step_rad ** 2))))
        centres = fibonacci_sphere(n_fields)
        radius_rad = min(math.pi, self.field_radius * camera.half_diagonal_rad)
        members = tree.query_ball_point(centres, rad_to_chord(radius_rad))
        # brightest pattern stars of each field (ties by row, so the build is deterministic)
        rank = np.lexsort((np.arange(len(unit)), v_mag))
        rank_of = np.empty(len(unit), dtype=np.int64)
        rank_of[rank] = np.arange(len(unit))
        chosen, offsets = [], [0]
        for js in members:
            js = np.asarray(js, dtype=np.int64)
            js = js[pattern_ok[js]]
            js = np.sort(js[np.argsort(rank_of[js])][: self.field_stars])
            chosen.append(js)
            offsets.append(offsets[-1] + js.size)
        field_rows = np.concatenate(chosen) if chosen else np.zeros(0, dtype=np.int64)
        min_edge, max_edge = self._spans(camera)
        packed = np.sort(field_patterns(unit, field_rows, np.asarray(offsets, dtype=np.int64), min_edge, max_edge))
        packed = packed[np.concatenate(([True], packed[1:] != packed[:-1]))] if packed.size else packed
        if packed.size == 0:
            raise ConfigError("tetra: the catalog yields no 4-star pattern that fits in the image")
        patterns = np.stack([(packed >> s) & 0xFFFF for s in (48, 32, 16, 0)], axis=1).astype(np.int64)
        largest = np.empty(len(patterns))
        keys = pattern_keys(unit, patterns, self.bins, largest)
        size = max(packed.size + 1, math.ceil(packed.size / self.load_factor))
        edges = np.round(np.minimum(largest / max_edge, 1.0) * 65535).astype(np.uint16)
        table_word = np.full(size, EMPTY, dtype=np.uint64)
        row_dtype = np.uint16 if len(unit) <= np.iinfo(np.uint16).max else np.int32
        table_pattern = np.zeros((size, 4), dtype=row_dtype)
        longest = table_insert(table_word, table_pattern, keys, edges, patterns.astype(row_dtype))
        hip_dtype = np.int32 if hip.max() <= np.iinfo(np.int32).max else np.int64
        return TetraDatabase(table_word=table_word, table_pattern=table_pattern, guide_unit=unit.astype(np.float32),
                             guide_hip=hip.astype(hip_dtype), reportable=pattern_ok,
                             guide_mag=v_mag.astype(np.float32), bins=int(self.bins),
                             edge_scale=float(max_edge), n_patterns=int(packed.size),
                             n_fields=n_fields, longest_probe=int(longest))

    # ------------------------------------------------------------------ identify

    def _bundles(self, database: TetraDatabase, camera: Camera) -> tuple[Tables, Settings]:
        return _bundles(self, database, camera)

    def _run(self, database: TetraDatabase, observation: Observation):
        tables, settings = _bundles(self, database, observation.camera)
        record = np.empty(12, dtype=np.int64)   # 9 explain slots, 3 work counters
        hip, rows = identify_kernel(observation.x_px, observation.y_px, observation.mag, tables, settings, record)
        return hip, rows, record

    def identify(self, database: TetraDatabase, observation: Observation) -> Identification:
        hip, _, record = self._run(database, observation)
        counters = {"patterns": max(int(record[8]), 0), "hash_lookups": int(record[9]), "candidates": int(record[10]),
                    "verifications": int(record[11])}
        return Identification(hip, counters=counters)

    def explain(self, database: TetraDatabase, observation: Observation) -> Explanation:
        """The 4-star pattern that matched (its six edges, bold) and the verified stars with their HIP."""
        _, rows, record = self._run(database, observation)
        x, y = observation.x_px, observation.y_px
        found = np.flatnonzero(rows >= 0)
        points = np.stack([x[found], y[found]], axis=1) if found.size else np.zeros((0, 2))
        labels = tuple(f"HIP {int(database.guide_hip[rows[i]])}" for i in found)
        if record[0] < 0:
            return Explanation(points=points, labels=labels,
                               caption=f"No 4-star pattern of the {min(len(observation), self.image_stars)} "
                                       f"brightest stars was verified ({max(int(record[8]), 0)} patterns tried).")
        img = record[:4]
        seg = np.array([[[x[img[a]], y[img[a]]], [x[img[b]], y[img[b]]]] for a, b in PAIRS])
        # the catalogue pattern, projected with the final attitude, as a polygon over the image pattern
        cam = observation.camera
        v = backproject_px(x, y, cam.f_px, cam.cx_px, cam.cy_px)
        A = wahba_rows(v, rows, database.guide_unit)
        cat = database.guide_unit[record[4:8]].astype(np.float64) @ A.T
        cx, cy = project_cam(np.ascontiguousarray(cat), cam.f_px, cam.cx_px, cam.cy_px)
        centre = np.array([cx.mean(), cy.mean()])
        angle = np.argsort(np.arctan2(cy - centre[1], cx - centre[0]))
        polygon = np.stack([cx[angle], cy[angle]], axis=1)
        hips = ", ".join(str(int(database.guide_hip[r])) for r in record[4:8])
        caption = (f"4-star pattern no. {int(record[8])} of the {min(len(observation), self.image_stars)} brightest "
                   f"stars matched HIP {hips} (its six edges bold, the catalogue pattern outlined); "
                   f"{found.size} stars identified by reprojection.")
        return Explanation(segments=seg, polygons=(polygon,), points=points, labels=labels, caption=caption,
                           highlight=np.arange(6))


@lru_cache(maxsize=4)
def _bundles(algorithm: Tetra, database: TetraDatabase, camera: Camera) -> tuple[Tables, Settings]:
    """The kernel bundles of one (algorithm, database, camera), built once."""
    f_px = camera.f_px
    sigma = algorithm._sigma_px / f_px
    min_edge, max_edge = algorithm._spans(camera)
    settings = Settings(sigma=sigma, beta=float(algorithm.beta), min_edge=min_edge, max_edge=max_edge,
                        max_keys=int(algorithm.max_keys), eps=algorithm.beta * math.sqrt(2.0) * sigma,
                        report_eps=algorithm.report_beta * sigma,
                        mag_window=algorithm.mag_beta * algorithm._sigma_mag,
                        c_fov=rad_to_chord(camera.half_diagonal_rad), min_extra=int(algorithm.min_extra),
                        max_mismatch=float(algorithm.max_mismatch), n_image=int(algorithm.image_stars),
                        f_px=float(f_px), cx_px=float(camera.cx_px), cy_px=float(camera.cy_px),
                        width_px=int(camera.width_px), height_px=int(camera.height_px))
    tables = Tables(database.table_word, database.table_pattern, int(database.bins),
                    float(database.edge_scale), database.guide_unit, database.reportable, database.guide_hip,
                    database.guide_mag)
    return tables, settings
