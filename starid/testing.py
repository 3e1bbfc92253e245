"""Conformance suite every algorithm plugin should pass, one explicit check at a time.

Use it from your plugin's tests, one pytest case per check (so ``pytest -k few_stars`` runs one)::

    import pytest
    from starid.testing import CHECKS, check_algorithm
    from my_plugin import MyAlgorithm

    @pytest.mark.parametrize("check", CHECKS)
    def test_conformance(check):
        check_algorithm(MyAlgorithm, checks=[check])

or from the shell: ``starid check NAME`` (a registered name, or a distribution: every algorithm it
registers). Checks: the class is default-constructible and documented; identify is deterministic;
0-3 stars and coincident detections are handled; only valid catalog ids or -1 are returned,
never one id for two stars; the order of the input stars does not change the answer; noise-free
trials are identified; 200 fields of 10 to 40 random points (no real star) give no id at all; the
observation is not written to; ``explain``, when present, returns valid drawable data;
``derived`` keeps pinned parameters, returns the same class and is idempotent; every
``query_only`` parameter, moved alone (its world setting 0 -> 3, x -> 0.75 x), leaves ``derived``
and the database unchanged (compared array by array). The
checks raise :class:`ConformanceError` (not ``assert``, so ``python -O`` cannot skip them).
Databases are built once per (class, catalog, camera) and cached.
"""

from __future__ import annotations

import dataclasses
import re
import time
from functools import lru_cache

import numpy as np

from .camera import Camera
from .catalog import Catalog, load_hipparcos
from .errors import StarIDError
from .observation import Observation
from .plugin import Algorithm, Database, Explanation, check_identification
from .scoring import CORRECT, MISIDENTIFIED, SuccessRule, score_trial
from .simulate import SimConfig, Simulator

CHECKS = ("default_constructible", "deterministic", "few_stars", "coincident_stars", "valid_ids", "order_invariant",
          "noise_free_identified", "random_fields", "read_only_input", "large_ids", "explain", "derived", "query_only")

#: Trials the checks use (fixed, so a failure can be reproduced with ``Simulator(..., seed=SEED)``).
SEED = 20151
NOISY = SimConfig(sigma_px=1.0, sigma_mag=0.5, false_stars=2)
NOISE_FREE = SimConfig()
#: Fields of uniformly random points (no real star): how many, and the range of their sizes (a
#: field of ``n`` points, ``n`` uniform in ``RANDOM_POINTS``, positions uniform on the sensor,
#: magnitudes uniform in 2-6). A star tracker that names a star in noise is wrong: none may be named.
RANDOM_FIELDS, RANDOM_POINTS = 200, (10, 40)
#: Catalog ids must survive beyond 32 bits.
LARGE_ID_OFFSET = 2**31


class ConformanceError(AssertionError):
    """A plugin failed a conformance check (the message names the check and what went wrong)."""


def _require(ok: bool, message: str) -> None:
    if not ok:
        raise ConformanceError(message)


@lru_cache(maxsize=8)
def _database(cls: type[Algorithm], catalog: Catalog, camera: Camera) -> Database:
    db = cls().build(catalog, camera)
    _require(isinstance(db, Database), f"{cls.__name__}.build must return a starid.plugin.Database")
    return db


@lru_cache(maxsize=4)
def _trials(catalog: Catalog, camera: Camera, config: SimConfig, n: int):
    sim = Simulator(catalog, camera, config, seed=SEED)
    return [sim.observation(t) for t in range(n)]


def _identify(algorithm: Algorithm, db: Database, obs: Observation, catalog: Catalog) -> np.ndarray:
    result = algorithm.identify(db, obs.for_plugin())
    try:
        return np.asarray(check_identification(result, len(obs), catalog.hip).hip)
    except StarIDError as exc:
        raise ConformanceError(str(exc)) from None


def _check_default_constructible(cls, algorithm, db, catalog, camera):
    _require(isinstance(cls.name, str) and bool(cls.name), f"{cls.__name__} needs a non-empty class attribute 'name'")
    _require(bool(cls.summary()), f"{cls.__name__} needs a docstring (first line = summary, then the reference)")
    _require(isinstance(algorithm.params(), dict), "params() must return a dict")
    _require(isinstance(db.nbytes, int) and db.nbytes > 0, "database.nbytes must be a positive int")
    _require(isinstance(cls.published, dict), "'published' must be a dict of parameter overrides")
    if cls.published:
        try:
            published = cls(**cls.published)
        except TypeError as exc:
            raise ConformanceError(f"'published' names a parameter {cls.__name__} does not take: {exc}") from None
        _require(published.params() != algorithm.params(), "'published' changes no parameter: leave it empty")
    readings = getattr(cls, "published_readings", {})
    _require(isinstance(readings, dict), "'published_readings' must be a dict: source name -> parameter overrides")
    for source, overrides in readings.items():
        _require(isinstance(source, str) and re.fullmatch(r"[A-Za-z_]\w*", source) is not None and source != "paper",
                 f"'published_readings' source {source!r} must be an identifier other than 'paper' "
                 "(that one is 'published')")
        _require(isinstance(overrides, dict) and bool(overrides),
                 f"'published_readings[{source!r}]' must be a non-empty dict of parameter overrides")
        try:
            reading = cls(**overrides)
        except TypeError as exc:
            raise ConformanceError(f"'published_readings[{source!r}]' names a parameter {cls.__name__} does not "
                                   f"take: {exc}") from None
        _require(reading.params() != algorithm.params(),
                 f"'published_readings[{source!r}]' changes no parameter: drop it")


def _check_deterministic(cls, algorithm, db, catalog, camera):
    for obs in _trials(catalog, camera, NOISY, 5):
        first = _identify(algorithm, db, obs, catalog)
        second = _identify(cls(), db, obs, catalog)
        _require(np.array_equal(first, second), "identify gave different answers for the same input")


def _check_few_stars(cls, algorithm, db, catalog, camera):
    obs = _trials(catalog, camera, NOISE_FREE, 1)[0]
    for k in range(4):
        small = Observation(obs.x_px[:k], obs.y_px[:k], obs.mag[:k], obs.camera)
        _require(_identify(algorithm, db, small, catalog).shape == (k,), f"wrong result length for {k} stars")


def _check_coincident_stars(cls, algorithm, db, catalog, camera):
    obs = _trials(catalog, camera, NOISE_FREE, 1)[0]
    x = np.concatenate([obs.x_px, obs.x_px[:2]])
    y = np.concatenate([obs.y_px, obs.y_px[:2]])
    m = np.concatenate([obs.mag, obs.mag[:2]])
    _identify(algorithm, db, Observation(x, y, m, obs.camera), catalog)
    one = Observation(np.full(5, 100.0), np.full(5, 200.0), np.full(5, 4.0), obs.camera)
    _identify(algorithm, db, one, catalog)


def _check_valid_ids(cls, algorithm, db, catalog, camera):
    for obs in _trials(catalog, camera, NOISY, 20):
        _identify(algorithm, db, obs, catalog)


def _check_order_invariant(cls, algorithm, db, catalog, camera):
    rng = np.random.default_rng(SEED)
    for obs in _trials(catalog, camera, NOISY, 10):
        base = _identify(algorithm, db, obs, catalog)
        for order in (np.arange(len(obs))[::-1], rng.permutation(len(obs))):
            permuted = _identify(algorithm, db, obs.permuted(order), catalog)
            _require(np.array_equal(permuted, base[order]), "reordering the input stars changed the answer")


def _check_noise_free_identified(cls, algorithm, db, catalog, camera):
    statuses = [score_trial(_identify(algorithm, db, obs, catalog), obs.truth_hip, SuccessRule())["status"]
                for obs in _trials(catalog, camera, NOISE_FREE, 10)]
    _require(MISIDENTIFIED not in statuses, f"noise-free trials misidentified: {statuses}")
    _require(statuses.count(CORRECT) >= 8, f"fewer than 8 of 10 noise-free trials identified: {statuses}")


def random_fields(camera: Camera, fields: int = RANDOM_FIELDS, points: tuple[int, int] = RANDOM_POINTS):
    """The random-field check's observations: ``fields`` fields of ``points[0]``..``points[1]`` (inclusive)
    points uniform on the sensor, magnitudes uniform in [2, 6], drawn from ``default_rng(SEED)``."""
    rng = np.random.default_rng(SEED)
    for _ in range(fields):
        n = int(rng.integers(points[0], points[1] + 1))
        x = rng.uniform(0, camera.width_px, n)
        y = rng.uniform(0, camera.height_px, n)
        m = rng.uniform(2.0, 6.0, n)
        yield Observation(x, y, m, camera)


def _check_random_fields(cls, algorithm, db, catalog, camera):
    claimed = []
    for k, obs in enumerate(random_fields(camera)):
        named = int((_identify(algorithm, db, obs, catalog) != -1).sum())
        if named:
            claimed.append(f"field {k} ({len(obs)} points): {named} ids")
    _require(not claimed,
             f"identified stars in {len(claimed)} of {RANDOM_FIELDS} fields of {RANDOM_POINTS[0]} to "
             f"{RANDOM_POINTS[1]} uniformly random points (no real star; none may be named): "
             f"{'; '.join(claimed[:5])}; verification is too lax (the fields: starid.testing.random_fields)")


def _check_read_only_input(cls, algorithm, db, catalog, camera):
    obs = _trials(catalog, camera, NOISY, 1)[0]
    view = obs.for_plugin()
    before = (view.x_px.copy(), view.y_px.copy(), view.mag.copy())
    algorithm.identify(db, view)
    _require(all(np.array_equal(a, b) for a, b in zip(before, (view.x_px, view.y_px, view.mag), strict=True)),
             "identify changed the observation it was handed")


@lru_cache(maxsize=2)
def _offset_catalog(catalog: Catalog) -> Catalog:
    return Catalog.from_arrays(catalog.hip + LARGE_ID_OFFSET, catalog.ra_deg, catalog.dec_deg, catalog.v_mag,
                               name=f"{catalog.name}+2^31")


def _check_large_ids(cls, algorithm, db, catalog, camera):
    big = _offset_catalog(catalog)
    big_db = _database(cls, big, camera)
    statuses = [score_trial(_identify(algorithm, big_db, obs, big), obs.truth_hip, SuccessRule())["status"]
                for obs in _trials(big, camera, NOISE_FREE, 8)]
    _require(MISIDENTIFIED not in statuses, f"with catalog ids offset by 2^31, misidentified: {statuses}")
    _require(statuses.count(CORRECT) >= 6, f"with catalog ids offset by 2^31 fewer than 6 of 8 noise-free "
                                           f"trials identified: {statuses} (ids must stay int64 end to end)")


def _check_explain(cls, algorithm, db, catalog, camera):
    method = getattr(algorithm, "explain", None)
    if not callable(method):
        return
    for obs in _trials(catalog, camera, NOISY, 3):
        result = method(db, obs.for_plugin())
        _require(isinstance(result, Explanation), f"explain must return a starid.plugin.Explanation, got "
                                                  f"{type(result).__name__}")


def _check_derived(cls, algorithm, db, catalog, camera):
    derived = algorithm.derived(catalog, camera)
    _require(type(derived) is cls, f"derived() must return a {cls.__name__}, got {type(derived).__name__}")
    before, after = algorithm.params(), derived.params()
    _require(before.keys() == after.keys(), "derived() changed which parameters there are")
    changed = sorted(k for k in before if before[k] is not None and after[k] != before[k])
    _require(not changed, f"derived() changed pinned parameter(s) {changed}; it may only fill those left None")
    again = derived.derived(catalog, camera).params()
    _require(again == after, "derived() is not idempotent: deriving the derived algorithm changed "
                             f"{sorted(k for k in after if again[k] != after[k])}")


def same_database(a, b, where: str = "database") -> str:
    """Where two databases differ (their fields compared recursively: arrays by dtype, shape and
    value, NaN equal to NaN), or ``""`` when they are the same."""
    if type(a) is not type(b):
        return f"{where}: {type(a).__name__} against {type(b).__name__}"
    if isinstance(a, np.ndarray):
        if a.dtype != b.dtype or a.shape != b.shape:
            return f"{where}: {a.dtype}{a.shape} against {b.dtype}{b.shape}"
        same = np.array_equal(a, b, equal_nan=a.dtype.kind in "fc")
        return "" if same else f"{where}: values differ"
    if dataclasses.is_dataclass(a):
        items = [(f.name, getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a)]
    elif isinstance(a, tuple) and hasattr(a, "_fields"):
        items = [(k, x, y) for k, x, y in zip(a._fields, a, b, strict=True)]
    elif isinstance(a, (tuple, list)):
        if len(a) != len(b):
            return f"{where}: {len(a)} against {len(b)} items"
        items = [(str(k), x, y) for k, (x, y) in enumerate(zip(a, b, strict=True))]
    elif isinstance(a, dict):
        if a.keys() != b.keys():
            return f"{where}: keys {sorted(a)} against {sorted(b)}"
        items = [(str(k), a[k], b[k]) for k in a]
    else:
        same = a == b or (isinstance(a, float) and a != a and b != b)
        return "" if same else f"{where}: {a!r} against {b!r}"
    for name, x, y in items:
        found = same_database(x, y, f"{where}.{name}")
        if found:
            return found
    return ""


def _other_world(world: SimConfig, key: str) -> SimConfig:
    """``world`` with its setting ``key`` moved well away: 0 -> 3, any other value x -> 0.75 x."""
    value = getattr(world, key)
    return dataclasses.replace(world, **{key: type(value)(value * 0.75 if value else 3)})


def _check_query_only(cls, algorithm, db, catalog, camera):
    names = tuple(getattr(cls, "query_only", ()) or ())
    unknown = sorted(set(names) - set(cls.follows))
    _require(not unknown, f"query_only names {unknown}, which are not 'follows' parameters {sorted(cls.follows)}")
    if not names:
        return
    base = algorithm.resolved(NOISE_FREE).derived(catalog, camera)
    base_db = base.build(catalog, camera)
    for name in names:        # one at a time: each moved alone must leave derived() and the database as they are
        moved = algorithm.resolved(_other_world(NOISE_FREE, cls.follows[name])).derived(catalog, camera)
        p0, p1 = base.params(), moved.params()
        _require(p0[name] != p1[name], f"query_only {name!r}: resolved() did not move it (does it follow "
                                       f"{cls.follows[name]!r}?)")
        changed = sorted(k for k in p0 if k != name and p0[k] != p1[k])
        _require(not changed, f"query_only {name!r}: derived() reads it (it set {changed} differently)")
        differ = same_database(base_db, moved.build(catalog, camera))
        _require(not differ, f"query_only {name!r}: build() reads it (the databases differ at {differ})")


_FUNCTIONS = {name: globals()[f"_check_{name}"] for name in CHECKS}


def cost_ratio(one, batch, n_batch: int, repeats: int = 5) -> float:
    """How many times one call of ``one()`` costs one of the ``n_batch`` items ``batch()`` does: the best
    of ``repeats`` timings of each, ``one`` / (``batch`` / ``n_batch``). For plugin tests that bound a
    slow case (a wide field, a dense image) by a multiple of a normal one measured in the same run, never
    by seconds: absolute times follow the machine's load. Time the normal images as one batch (~10 ms),
    not one ~0.1 ms call: on a loaded machine a short call fits between preemptions and a long one does
    not, which inflated such ratios 6x. Call both once before (compilation)."""

    def best(fn) -> float:
        out = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            out = min(out, time.perf_counter() - t0)
        return out

    return best(one) / (best(batch) / n_batch)


def check_algorithm(algorithm: type[Algorithm], checks=None, catalog: Catalog | None = None,
                    camera: Camera | None = None) -> list[str]:
    """Run the named checks (default: all) on an algorithm class; :class:`ConformanceError` on the first failure."""
    if not (isinstance(algorithm, type) and issubclass(algorithm, Algorithm)):
        raise TypeError(f"check_algorithm needs an Algorithm subclass, got {algorithm!r}")
    names = list(CHECKS if checks is None else checks)
    unknown = [c for c in names if c not in _FUNCTIONS]
    if unknown:
        raise ValueError(f"unknown check(s) {unknown}; known: {CHECKS}")
    catalog = catalog or load_hipparcos()
    camera = camera or Camera()
    instance = algorithm()
    db = _database(algorithm, catalog, camera)
    for name in names:
        try:
            _FUNCTIONS[name](algorithm, instance, db, catalog, camera)
        except ConformanceError as exc:
            raise ConformanceError(f"{algorithm.name}: check {name!r} failed: {exc}") from None
        except Exception as exc:
            raise ConformanceError(f"{algorithm.name}: check {name!r} raised {type(exc).__name__}: {exc}") from exc
    return names


def run_checks(algorithm: type[Algorithm], catalog: Catalog | None = None, camera: Camera | None = None):
    """Every check, one at a time: yields ``(check, "ok" | "FAILED", message)`` (the shell's ``starid check``)."""
    for name in CHECKS:
        try:
            check_algorithm(algorithm, [name], catalog, camera)
            yield name, "ok", ""
        except ConformanceError as exc:
            yield name, "FAILED", str(exc)


__all__ = ["CHECKS", "ConformanceError", "check_algorithm", "random_fields", "run_checks", "same_database"]
