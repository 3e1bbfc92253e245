"""The plugin API every star-identification algorithm implements.

An algorithm is a small class (a frozen dataclass is the easy way) that

* has a class attribute ``name`` (its registered name = its folder in ``algorithms/``) and a
  docstring whose first line is a one-line summary and which cites its reference;
* stores only parameters in ``__init__`` (every parameter has a default, so the class is
  default-constructible);
* ``build(catalog, camera)`` returns a :class:`Database` (a frozen dataclass of numpy arrays
  whose ``nbytes`` is the memory the identify step reads);
* ``identify(database, observation)`` returns an :class:`Identification`: per observed star a
  catalog id or -1, and optionally an attitude;
* optionally ``explain(database, observation)`` returns an :class:`Explanation`: plain drawable
  data (segments, polygons, labelled points, a caption) showing its reasoning on one image;
* optionally lists in ``follows`` the parameters that describe the simulated world rather than
  the method (e.g. ``{"sigma_px": "sigma_px"}``: the centroid noise its tolerances assume). Such a
  parameter defaults to ``None`` = "follow the simulator": :meth:`Algorithm.resolved` fills it
  from the simulator's settings before the database is built, so ``--pos-noise-px 3`` retunes
  the algorithm unless the user pins the parameter. A plugin must still work when it is ``None``
  (called outside the harness) and applies its own floor (a 0 px world still needs a window);
* optionally lists in ``published`` the parameter overrides that turn its defaults into the
  method exactly as its paper publishes it (starid's extensions and flight precautions off), so
  "as published" and "as improved" can run side by side: the variant ``NAME:paper``;
* optionally lists in ``published_readings`` further published readings, each named by its
  source (``{"galvizo2018": {...overrides...}}``): the method as that source ran it (e.g. another
  paper's comparison with its own fixed tolerances), the variant ``NAME:SOURCE``. ``paper`` is
  not a source name (it is ``published``);
* optionally overrides :meth:`Algorithm.derived` when some defaults depend on the sensor (a
  radius from the field of view, a tolerance from the pixel scale, a magnitude limit from the
  star density): such a parameter defaults to ``None`` = "derive it from the catalog and camera",
  ``derived`` returns the algorithm with those values filled in, and ``build`` uses the same
  method, so one rule serves both. The harness builds and records the derived instance, so result
  rows show the values used.

The harness, not the plugin, decides whether an identification is correct. Plugins register
through the entry-point group ``starid.algorithms`` (see ``pyproject.toml``), or in process
with :func:`starid.register`.
"""

from __future__ import annotations

import abc
import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .camera import Camera
from .catalog import Catalog
from .errors import PluginError
from .kernels.score import ID_NOT_IN_CATALOG, ID_TWICE, check_ids
from .observation import Observation


def _nbytes(value) -> int:
    if isinstance(value, np.ndarray):
        return int(value.nbytes)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return sum(_nbytes(getattr(value, f.name)) for f in dataclasses.fields(value))
    if isinstance(value, (tuple, list)):
        return sum(_nbytes(v) for v in value)
    return 0


@dataclass(frozen=True, eq=False)
class Database:
    """Base class of algorithm databases: subclass it as a frozen dataclass of numpy arrays.

    ``nbytes`` sums the ``nbytes`` of every array field (nested dataclasses included). Fields
    that identify does not read (e.g. build diagnostics) should not be arrays.
    """

    @property
    def nbytes(self) -> int:
        return _nbytes(self)


@dataclass(frozen=True, eq=False)
class Identification:
    """What ``identify`` returns.

    hip : int64 (n,) catalog id per observed star, in input order, -1 where unidentified.
    attitude : optional 3x3 ICRS -> camera rotation the algorithm estimated.
    counters : optional small dict ``{name: int}`` of the work done on this image (e.g.
        ``{"kvector_searches": 12, "candidates": 340, "verifications": 2}``), machine-independent;
        the harness records each as a trial-row column ``n_<name>`` (absent: no column / NaN).
    """

    hip: np.ndarray
    attitude: np.ndarray | None = None
    counters: dict | None = None

    @classmethod
    def none(cls, n: int) -> Identification:
        """No star identified."""
        return cls(np.full(n, -1, dtype=np.int64))


@dataclass(frozen=True, eq=False)
class Explanation:
    """What an algorithm did on one image, as plain drawable data in pixel coordinates.

    segments : float (k, 2, 2) line segments ``[[x0, y0], [x1, y1]]`` (e.g. a triangle's sides).
    polygons : tuple of float (m, 2) closed outlines (e.g. the triangle that matched).
    points : float (p, 2) marked positions; ``labels`` : tuple of p strings beside them.
    caption : one or two sentences saying what the picture shows.
    highlight : int (k,) indices of ``segments`` to draw bold (the decisive ones); may be empty.
    """

    segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    polygons: tuple = ()
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    labels: tuple = ()
    caption: str = ""
    highlight: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self):
        seg = np.asarray(self.segments, dtype=np.float64).reshape(-1, 2, 2)
        pts = np.asarray(self.points, dtype=np.float64).reshape(-1, 2)
        polys = tuple(np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in self.polygons)
        hl = np.asarray(self.highlight, dtype=np.int64).ravel()
        if len(self.labels) not in (0, len(pts)):
            raise PluginError(f"explain: {len(self.labels)} labels for {len(pts)} points")
        if hl.size and (hl.min() < 0 or hl.max() >= len(seg)):
            raise PluginError("explain: highlight indexes a segment that does not exist")
        for name, arr in (("segments", seg), ("points", pts), *((f"polygon {i}", p) for i, p in enumerate(polys))):
            if not np.all(np.isfinite(arr)):
                raise PluginError(f"explain: {name} has non-finite coordinates")
        object.__setattr__(self, "segments", seg)
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "polygons", polys)
        object.__setattr__(self, "labels", tuple(str(x) for x in self.labels))
        object.__setattr__(self, "highlight", hl)


class Algorithm(abc.ABC):
    """Abstract base of every star-identification plugin (see the module docstring)."""

    name: ClassVar[str] = ""
    #: parameter name -> :class:`starid.simulate.SimConfig` field it follows when left ``None``
    follows: ClassVar[dict] = {}
    #: the ``follows`` parameters that only ``identify`` reads (``derived`` and ``build`` never do), so a
    #: database built with other values of them is the same database: an experiment sweeping the noise
    #: builds it once per worker, not once per noise level. The conformance check ``query_only`` builds
    #: with two values of each and compares the databases array by array.
    query_only: ClassVar[tuple[str, ...]] = ()
    #: parameter overrides giving the method as published (the ``NAME:paper`` variant); empty when
    #: the defaults are the paper's
    published: ClassVar[dict] = {}
    #: source name -> parameter overrides giving the method as that source ran it (the
    #: ``NAME:SOURCE`` variant, e.g. ``pyramid:galvizo2018``); empty when no other source is read
    published_readings: ClassVar[dict[str, dict]] = {}

    def params(self) -> dict:
        """The parameters of this instance, as a plain dict (for result rows)."""
        if dataclasses.is_dataclass(self):
            return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        return {k: v for k, v in vars(self).items() if not k.startswith("_")}

    def kept(self, name: str, key: tuple, build):
        """``build()``, made once for the objects in ``key`` (compared by identity: a database, a camera)
        and kept on this algorithm until it is asked for ``name`` with other objects. For the bundles a
        plugin's ``identify`` would otherwise rebuild in Python for every image of one run (tolerances,
        kernel arguments). A cache, not a parameter: it is set on frozen dataclasses too and is never
        pickled (a worker receives the algorithm without it). The key's objects stay referenced, so
        another object cannot take their identity while the value is kept."""
        cache = self.__dict__.get("_kept")
        if cache is None:
            cache = {}
            object.__setattr__(self, "_kept", cache)
        held = cache.get(name)
        if held is not None and len(held[0]) == len(key):
            for a, b in zip(held[0], key, strict=True):   # a loop, not all(generator): called for every image
                if a is not b:
                    break
            else:
                return held[1]
        value = build()
        cache[name] = (key, value)
        return value

    def __getstate__(self):
        state = super().__getstate__()
        if isinstance(state, dict) and "_kept" in state:  # databases and cameras: not part of the algorithm
            state = {k: v for k, v in state.items() if k != "_kept"}
        return state

    @abc.abstractmethod
    def build(self, catalog: Catalog, camera: Camera) -> Database:
        """Build the database from the full catalog (choose the guide stars inside)."""

    @abc.abstractmethod
    def identify(self, database: Database, observation: Observation) -> Identification:
        """Identify the observed stars; must not read ``observation.truth_hip``."""

    def resolved(self, world) -> Algorithm:
        """This algorithm with every ``follows`` parameter left ``None`` set from ``world``.

        ``world`` is the simulator's :class:`~starid.simulate.SimConfig`; pinned parameters
        (not ``None``) are kept. The result is what gets built, timed and recorded.
        """
        fill = {p: getattr(world, key) for p, key in self.follows.items() if getattr(self, p, 0) is None}
        if not fill:
            return self
        if not dataclasses.is_dataclass(self):
            raise PluginError(f"{self.name}: 'follows' needs the algorithm to be a dataclass")
        return dataclasses.replace(self, **fill)

    def derived(self, catalog: Catalog, camera: Camera) -> Algorithm:
        """This algorithm with every parameter it derives from ``catalog`` and ``camera`` when left
        ``None`` set to the value ``build`` uses; pinned parameters are kept.

        The default derives nothing and returns ``self``. A plugin whose defaults depend on the
        sensor overrides it (and calls it in ``build``); the conformance check ``derived`` holds it
        to keeping pinned values and to being idempotent. The harness builds, times and records the
        result, so ``param_*`` columns show the values actually used.
        """
        return self

    @classmethod
    def summary(cls) -> str:
        """First line of the docstring."""
        doc = (cls.__doc__ or "").strip()
        return doc.splitlines()[0].strip() if doc else ""


def check_identification(result, n_stars: int, catalog_hip: np.ndarray) -> Identification:
    """Validate what a plugin returned; raise :class:`PluginError` saying what is wrong."""
    if not isinstance(result, Identification):
        raise PluginError(f"identify must return an Identification, got {type(result).__name__}")
    hip = np.asarray(result.hip)
    if hip.shape != (n_stars,):
        raise PluginError(f"identify returned {hip.shape} ids for {n_stars} stars")
    if not np.issubdtype(hip.dtype, np.integer):
        raise PluginError(f"identify returned ids of dtype {hip.dtype}, expected integers")
    if hip.dtype.kind == "u" and hip.size and hip.max() > np.iinfo(np.int64).max:
        raise PluginError(f"identify returned id {int(hip.max())}, which is neither -1 nor in the catalog")
    # one compiled call (starid.kernels.score); a writable int64 copy, so numba compiles one signature
    code, bad = check_ids(np.array(hip, dtype=np.int64), np.ascontiguousarray(catalog_hip, dtype=np.int64))
    if code == ID_NOT_IN_CATALOG:
        raise PluginError(f"identify returned id {int(bad)}, which is neither -1 nor in the catalog")
    if code == ID_TWICE:    # the smallest id given twice
        raise PluginError(f"identify gave id {int(bad)} to more than one star")
    if result.attitude is not None and np.asarray(result.attitude).shape != (3, 3):
        raise PluginError(f"identify returned an attitude of shape {np.asarray(result.attitude).shape}")
    if result.counters is not None:
        if not isinstance(result.counters, dict):
            raise PluginError(f"identify returned counters of type {type(result.counters).__name__}, expected a dict")
        for key, value in result.counters.items():
            if not isinstance(key, str) or not key.isidentifier():
                raise PluginError(f"identify returned a counter named {key!r}; names must be identifiers")
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise PluginError(f"identify returned counter {key}={value!r}; counters are non-negative integers")
    return result
