"""Experiments as data: algorithm variants, studies (grids of simulator settings) and their TOML form.

An :class:`Experiment` is a name, a camera, base simulator settings, a seed, a number of trials
per grid point and one or more :class:`Study` s. A study is a set of algorithm
:class:`Variant` s run at every point of a :class:`Grid` (a product or a zip of simulator
settings). Trial ``k`` is the same attitude at every point and for every algorithm (common
random numbers, :mod:`starid.simulate`). The same experiment can be written as TOML::

    name = "noise-sweep"
    trials = 1000
    seed = 0
    [camera]                   # starid.Camera fields, or fov_deg (+ resolution_px), or preset = "NAME"|"FILE"
                               # (+ fields overriding it); camera = "NAME" at the top level is the same
    fov_deg = 10
    [sim]                      # starid.SimConfig fields, or sky = "paper" / "real"
    sigma_mag = 0.5
    sky = "paper"
    [[study]]
    name = "position noise"
    algorithms = ["ptp", "pvector", "ptp[n_slaves=3]"]
    grid = { sigma_px = [0.0, 0.5, 1.0, 1.5, 2.0] }   # mode = "zip" pairs equal-length lists

A single-study experiment may give ``algorithms`` and ``grid`` at the top level.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import re
import tomllib
import typing
from dataclasses import dataclass, field
from pathlib import Path

from ..camera import Camera
from ..errors import ConfigError
from ..plugin import Algorithm
from ..registry import get_algorithm
from ..simulate import SKIES, SimConfig

#: The suffix of the "as published" variant of a plugin (its ``published`` overrides).
PAPER_SUFFIX = ":paper"
#: the source name of ``published`` (``NAME:paper``); every other source is a key of ``published_readings``
PAPER_SOURCE = PAPER_SUFFIX[1:]
#: the most points one study's grid may have (a typo such as a range of 10**6 values is refused before any work)
MAX_GRID_POINTS = 100_000
#: keys an experiment definition and each of its studies may hold, and the type each must be
_TOP_KEYS = {"name": str, "trials": int, "seed": int, "camera": (dict, str), "sim": dict, "description": str,
             "studies": list, "study": list, "algorithms": list, "grid": dict, "mode": str}
_STUDY_KEYS = {"name": str, "algorithms": list, "variants": list, "grid": dict, "mode": str, "trials": int,
               "camera": (dict, str)}
#: what separates a plugin's name from the source of one of its published readings (``pyramid:galvizo2018``)
SOURCE_SEP = ":"
_LABEL = re.compile(r"^\s*([A-Za-z_][\w.-]*)(?:" + SOURCE_SEP + r"([A-Za-z_]\w*))?\s*(?:\[(.*)\])?\s*$")


def _format_value(value) -> str:
    return json.dumps(value) if isinstance(value, str) and re.search(r"[,\]=\s]", value) else str(value)


def coerce(cls: type[Algorithm], key: str, value):
    """``value`` (possibly text from a command line) as the type of ``cls``'s field ``key``.

    Unknown keys are refused listing the valid ones; text is converted by the field's declared
    type (``int`` accepts only plain integers: ``1_0`` is not 10), never guessed.
    """
    fields = {f.name: f for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else {}
    if key not in fields:
        valid = ", ".join(fields) or "none"
        raise ConfigError(f"{cls.name} has no parameter {key!r}; valid: {valid}")
    hints = typing.get_type_hints(cls)
    kind = hints.get(key, type(fields[key].default))
    if not isinstance(value, str):
        return value
    text = value.strip()
    options = typing.get_args(kind) or (kind,)
    if type(None) in options and text.lower() in ("none", "null", ""):
        return None
    for option in options:
        if option is bool and text.lower() in ("true", "false", "1", "0", "yes", "no"):
            return text.lower() in ("true", "1", "yes")
        if option is int and re.fullmatch(r"[+-]?\d+", text):
            return int(text)
        if option is float and re.fullmatch(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|[+-]?inf", text):
            return float(text)
        if option is str:
            return text
    names = " or ".join(getattr(o, "__name__", str(o)) for o in options)
    raise ConfigError(f"{cls.name}.{key} must be {names}, got {value!r}")


def readings_of(cls: type[Algorithm]) -> dict[str, dict]:
    """Every published reading of ``cls`` by source: ``paper`` (its ``published``, when it declares one)
    first, then its ``published_readings`` in their order."""
    out = {PAPER_SOURCE: dict(cls.published)} if getattr(cls, "published", None) else {}
    out.update({str(k): dict(v) for k, v in (getattr(cls, "published_readings", None) or {}).items()})
    return out


@dataclass(frozen=True)
class Variant:
    """An algorithm with parameter overrides; its ``label`` is the grouping key of every result.

    ``Variant("ptp")`` is labelled ``ptp``; ``Variant("ptp", (("n_slaves", 3),))`` is labelled
    ``ptp[n_slaves=3]`` (benchopt's parametrized names); a ``label`` given explicitly wins.
    """

    name: str
    params: tuple = ()
    label: str = ""

    def __post_init__(self):
        params = self.params.items() if isinstance(self.params, dict) else self.params
        object.__setattr__(self, "params", tuple((str(k), v) for k, v in params))
        if not self.label:
            inner = ",".join(f"{k}={_format_value(v)}" for k, v in self.params)
            object.__setattr__(self, "label", f"{self.name}[{inner}]" if inner else self.name)

    @classmethod
    def as_published(cls, name: str, **params) -> Variant:
        """``NAME:paper``: the plugin's ``published`` overrides, then ``params`` on top
        (labelled ``NAME:paper[KEY=VALUE,...]``)."""
        return cls.as_reading(name, PAPER_SOURCE, **params)

    @classmethod
    def as_reading(cls, name: str, source: str, **params) -> Variant:
        """``NAME:SOURCE``: the plugin's published reading ``source`` (``paper`` = its ``published``
        overrides, any other = ``published_readings[source]``), then ``params`` on top (labelled
        ``NAME:SOURCE[KEY=VALUE,...]``). An unknown source is refused listing the plugin's sources."""
        algo = get_algorithm(name)
        readings = readings_of(algo)
        if source not in readings:
            if source == PAPER_SOURCE and not readings:
                raise ConfigError(f"{name} declares no 'published' parameters: its defaults are the paper's method")
            valid = ", ".join(f"{name}{SOURCE_SEP}{s}" for s in readings) or "none"
            raise ConfigError(f"{name} has no published reading {source!r}; valid: {valid}")
        inner = ",".join(f"{k}={_format_value(v)}" for k, v in params.items())
        label = f"{name}{SOURCE_SEP}{source}" + (f"[{inner}]" if inner else "")
        return cls(name, tuple({**readings[source], **params}.items()), label)

    @classmethod
    def parse(cls, text: str) -> Variant:
        """``"ptp"``, ``"ptp[n_slaves=3,verify=false]"`` (values coerced by the field types),
        ``"ptp:paper"`` or ``"ptp:paper[n_slaves=3]"`` (:meth:`as_published`), ``"pyramid:galvizo2018"``
        (a reading named by its source, :meth:`as_reading`)."""
        m = _LABEL.match(text)
        if not m:
            raise ConfigError(f"cannot read algorithm {text!r}; expected NAME, NAME[KEY=VALUE,...] or "
                              f"NAME{SOURCE_SEP}SOURCE[KEY=VALUE,...] (SOURCE: paper or a published reading)")
        name, source, inner = m.group(1), m.group(2), m.group(3)
        params = []
        if inner and inner.strip():
            algo = get_algorithm(name)
            for item in inner.split(","):
                key, sep, value = item.partition("=")
                if not sep:
                    raise ConfigError(f"{text!r}: expected KEY=VALUE, got {item!r}")
                params.append((key.strip(), coerce(algo, key.strip(), value)))
        return cls.as_reading(name, source, **dict(params)) if source else cls(name, tuple(params))

    def with_params(self, **params) -> Variant:
        """The same variant with more overrides (the label follows unless it was set explicitly)."""
        merged = dict(self.params)
        merged.update(params)
        auto = Variant(self.name, self.params).label == self.label
        return Variant(self.name, tuple(merged.items()), "" if auto else self.label)

    def make(self) -> Algorithm:
        """An instance of the registered algorithm with these overrides."""
        cls = get_algorithm(self.name)
        params = {k: coerce(cls, k, v) for k, v in self.params}
        try:
            return cls(**params)
        except (TypeError, ConfigError) as exc:
            raise ConfigError(f"{self.label}: {exc}") from None

    def to_dict(self) -> dict:
        return {"name": self.name, "params": dict(self.params), "label": self.label}


@dataclass(frozen=True)
class Grid:
    """Points of simulator settings: the product (default) or the zip of the value lists.

    Axis names are :class:`~starid.simulate.SimConfig` fields or ``sky`` (a name in
    :data:`~starid.simulate.SKIES`). An empty grid is one point with the base settings.
    """

    axes: tuple = ()
    mode: str = "product"

    def __post_init__(self):
        axes = self.axes.items() if isinstance(self.axes, dict) else self.axes
        axes = tuple((str(k), tuple(v) if isinstance(v, (list, tuple)) else (v,)) for k, v in axes)
        object.__setattr__(self, "axes", axes)
        if self.mode not in ("product", "zip"):
            raise ConfigError(f"grid mode must be 'product' or 'zip', got {self.mode!r}")
        known = {f.name for f in dataclasses.fields(SimConfig)} | {"sky"}
        for name, values in axes:
            if name not in known:
                raise ConfigError(f"grid axis {name!r} is not a simulator setting; valid: {', '.join(sorted(known))}")
            if not values:
                raise ConfigError(f"grid axis {name!r} has no values")
        if self.mode == "zip" and len({len(v) for _, v in axes}) > 1:
            raise ConfigError("a zip grid needs value lists of equal length")
        n = len(axes[0][1]) if axes and self.mode == "zip" else 1
        for _, values in axes if self.mode == "product" else ():
            n *= len(values)
        if n > MAX_GRID_POINTS:
            raise ConfigError(f"grid of {n:,} points ({' x '.join(f'{k}: {len(v)}' for k, v in axes)}) exceeds "
                              f"{MAX_GRID_POINTS:,} points; split it into studies")

    def points(self) -> list[dict]:
        if not self.axes:
            return [{}]
        names = [n for n, _ in self.axes]
        values = [v for _, v in self.axes]
        combos = itertools.product(*values) if self.mode == "product" else zip(*values, strict=True)
        return [dict(zip(names, c, strict=True)) for c in combos]


def sim_settings(base: dict, point: dict) -> dict:
    """Base simulator settings updated by a grid point, ``sky`` names expanded: every
    :class:`~starid.simulate.SimConfig` field, checked (so equal worlds have equal settings)."""
    settings = {**base, **point}
    sky = settings.pop("sky", None)
    if sky is not None:
        if sky not in SKIES:
            raise ConfigError(f"unknown sky {sky!r}; known: {', '.join(SKIES)}")
        settings = {**SKIES[sky], **{k: v for k, v in settings.items() if k not in SKIES[sky] or k in point}}
    try:
        return SimConfig(**settings).as_dict()
    except TypeError as exc:
        raise ConfigError(f"simulator settings: {exc}") from None


@dataclass(frozen=True)
class Study:
    """Some algorithm variants at every point of a grid.

    ``trials`` (images per point) and ``camera`` (a camera spec as :attr:`Experiment.camera`)
    override the experiment's for this study alone; None keeps the experiment's.
    """

    name: str
    variants: tuple
    grid: Grid = field(default_factory=Grid)
    trials: int | None = None
    camera: dict | None = None

    def __post_init__(self):
        variants = tuple(v if isinstance(v, Variant) else Variant.parse(v) for v in self.variants)
        object.__setattr__(self, "variants", variants)
        labels = [v.label for v in variants]
        dup = sorted({x for x in labels if labels.count(x) > 1})
        if dup:
            raise ConfigError(f"study {self.name!r}: algorithm label(s) {dup} appear twice; "
                              f"give each variant its own parameters or label")
        if not variants:
            raise ConfigError(f"study {self.name!r} has no algorithms")
        if self.trials is not None and (isinstance(self.trials, bool) or not isinstance(self.trials, int)
                                        or not 1 <= self.trials <= 10_000_000):
            raise ConfigError(f"study {self.name!r}: trials must be an integer from 1 to 10,000,000, "
                              f"got {self.trials!r}")


@dataclass(frozen=True)
class Experiment:
    """A named set of studies on one camera, seed and number of trials per point."""

    name: str
    studies: tuple
    trials: int = 1000
    seed: int = 0
    camera: dict = field(default_factory=dict)
    sim: dict = field(default_factory=dict)
    description: str = ""

    def __post_init__(self):
        if not re.fullmatch(r"[\w.-]+", self.name or ""):
            raise ConfigError(f"experiment name {self.name!r} must be letters, digits, '_', '-' or '.'")
        if isinstance(self.trials, bool) or not isinstance(self.trials, int) or not 1 <= self.trials <= 10_000_000:
            raise ConfigError(f"trials must be an integer from 1 to 10,000,000, got {self.trials!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"seed must be an integer >= 0, got {self.seed!r}")
        object.__setattr__(self, "studies", tuple(self.studies))
        names = [s.name for s in self.studies]
        if len(set(names)) != len(names) or not names:
            raise ConfigError("an experiment needs at least one study, each with its own name")
        self.make_camera()
        for study in self.studies:
            self.study_camera(study)
            for point in study.grid.points():
                sim_settings(self.sim, point)

    def study_trials(self, study: Study) -> int:
        """Images per point of ``study``: its own ``trials``, else the experiment's."""
        return study.trials if study.trials is not None else self.trials

    def study_camera(self, study: Study) -> Camera:
        """The camera of ``study``: its own ``camera`` spec, else the experiment's."""
        return self.make_camera() if study.camera is None else Experiment(
            self.name, (Study(study.name, study.variants),), camera=dict(study.camera)).make_camera()

    def make_camera(self) -> Camera:
        spec = dict(self.camera)
        if "preset" in spec or ("fov_deg" in spec and {"width_px", "height_px"} & set(spec)) \
                or {"distortion", "name", "source", "exposure_s"} & set(spec):
            from ..cameras import camera_from_spec  # a preset or camera file, its fields overridden

            return camera_from_spec(spec)
        if "fov_deg" in spec:
            fov = spec.pop("fov_deg")
            res = spec.pop("resolution_px", 1024)
            cam = Camera.from_fov(fov, res, spec.pop("pixel_um", 12.0))
            if spec:
                raise ConfigError(f"camera: with fov_deg give only resolution_px and pixel_um, not {sorted(spec)}")
            return cam
        try:
            return Camera(**spec)
        except TypeError as exc:
            raise ConfigError(f"camera: {exc}") from None

    def to_dict(self) -> dict:
        return {"name": self.name, "description": self.description, "trials": self.trials, "seed": self.seed,
                "camera": dict(self.camera), "sim": dict(self.sim),
                "studies": [{"name": s.name, "variants": [v.to_dict() for v in s.variants],
                             "grid": {"axes": {k: list(v) for k, v in s.grid.axes}, "mode": s.grid.mode},
                             **({"trials": s.trials} if s.trials is not None else {}),
                             **({"camera": dict(s.camera)} if s.camera is not None else {})}
                            for s in self.studies]}

    def digest(self) -> str:
        """A hash of the definition (what it computes, not its description)."""
        d = self.to_dict()
        d.pop("description")
        return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:16]

    @classmethod
    def from_dict(cls, d: dict) -> Experiment:
        _check_shape(d)
        try:
            return cls._from_dict(d)
        except ConfigError:
            raise
        except (TypeError, ValueError, KeyError, AttributeError) as exc:    # a shape _check_shape did not foresee
            raise ConfigError(f"malformed experiment definition: {type(exc).__name__}: {exc}") from None

    @classmethod
    def _from_dict(cls, d: dict) -> Experiment:
        d = dict(d)
        studies = d.pop("studies", None) or d.pop("study", None)
        if studies is None:
            studies = [{"name": d.get("name", "main"), "algorithms": d.pop("algorithms", None),
                        "grid": d.pop("grid", {}), "mode": d.pop("mode", "product")}]
        out = []
        for s in studies:
            s = dict(s)
            if "variants" in s:
                variants = [Variant(v["name"], tuple(v.get("params", {}).items()), v.get("label", ""))
                            for v in s["variants"]]
            else:
                algos = s.get("algorithms")
                if not algos:
                    raise ConfigError(f"study {s.get('name')!r}: 'algorithms' is missing")
                variants = [Variant.parse(a) if isinstance(a, str)
                            else Variant(a["name"], tuple(a.get("params", {}).items()), a.get("label", ""))
                            for a in algos]
            grid = s.get("grid", {})
            if "axes" in grid:
                grid_obj = Grid(grid["axes"], grid.get("mode", "product"))
            else:
                grid_obj = Grid(grid, s.get("mode", "product"))
            camera = s.get("camera")
            out.append(Study(s.get("name", "main"), tuple(variants), grid_obj, s.get("trials"),
                             {"preset": camera} if isinstance(camera, str) else camera))
        unknown = set(d) - {"name", "trials", "seed", "camera", "sim", "description"}
        if unknown:
            raise ConfigError(f"unknown experiment key(s) {sorted(unknown)}")
        return cls(name=d.get("name", ""), studies=tuple(out), trials=d.get("trials", 1000), seed=d.get("seed", 0),
                   camera=({"preset": d["camera"]} if isinstance(d.get("camera"), str) else d.get("camera", {})),
                   sim=d.get("sim", {}), description=d.get("description", ""))

    @classmethod
    def from_toml(cls, path: str | Path) -> Experiment:
        path = Path(path)
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8-sig"))
        except OSError as exc:
            raise ConfigError(f"cannot read {path}: {exc.strerror}") from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise ConfigError(f"{path}: not valid TOML: {exc}") from None
        try:
            return cls.from_dict(data)
        except ConfigError as exc:
            raise ConfigError(f"{path}: {exc}") from None


def _type_name(kind) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    return " or ".join({dict: "a table", list: "a list", str: "a string", int: "an integer"}[k] for k in kinds)


def _check_keys(d: dict, allowed: dict, where: str) -> None:
    unknown = sorted(str(k) for k in d if k not in allowed)
    if unknown:
        raise ConfigError(f"unknown {where}key(s) {unknown}; valid: {', '.join(sorted(allowed))}")
    for key, kind in allowed.items():
        value = d.get(key)
        if key in d and (not isinstance(value, kind) or (kind is int and isinstance(value, bool))):
            raise ConfigError(f"{where}{key!r} must be {_type_name(kind)}, got {value!r}")


def _check_shape(d) -> None:
    """The keys and types of an experiment definition (a parsed TOML file), each wrong one named."""
    if not isinstance(d, dict):
        raise ConfigError(f"an experiment definition is a table, got {type(d).__name__}")
    _check_keys(d, _TOP_KEYS, "")
    for k, study in enumerate(d.get("studies") or d.get("study") or []):
        if not isinstance(study, dict):
            raise ConfigError(f"studies[{k}] must be a table, got {study!r}")
        _check_keys(study, _STUDY_KEYS, f"study {study.get('name', k)!r}: ")
        for a in study.get("algorithms") or []:
            if not isinstance(a, (str, dict)):
                raise ConfigError(f"study {study.get('name', k)!r}: 'algorithms' entries are names or tables, "
                                  f"got {a!r}")
