"""Conformance suite every algorithm plugin should pass.

Use it from your plugin's tests, one pytest case per check (so ``pytest -k few_stars`` runs one)::

    import pytest
    from starid.testing import CHECKS, check_algorithm
    from my_plugin import MyAlgorithm

    @pytest.mark.parametrize("check", CHECKS)
    def test_conformance(check):
        check_algorithm(MyAlgorithm, checks=[check])

Checks: the class is default-constructible and documented; identify is deterministic; 0, 1,
2 and 3 stars are handled without an exception; only valid catalog ids or -1 are returned, never
one id for two stars; the order of the input stars does not change the answer; noise-free trials
are identified. Databases are built once per (class, catalog, camera) and cached.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .camera import Camera
from .catalog import Catalog, load_hipparcos
from .scoring import SuccessRule, score_trial
from .observation import Observation
from .plugin import Algorithm, Database, check_identification
from .simulate import SimConfig, Simulator

CHECKS = ("default_constructible", "deterministic", "few_stars", "valid_ids", "order_invariant",
          "noise_free_identified")

#: Trials the checks use (fixed, so a failure can be reproduced with ``Simulator(..., seed=SEED)``).
SEED = 20151
NOISY = SimConfig(sigma_px=1.0, sigma_mag=0.5, false_stars=2)
NOISE_FREE = SimConfig()


@lru_cache(maxsize=8)
def _database(cls: type[Algorithm], catalog: Catalog, camera: Camera) -> Database:
    db = cls().build(catalog, camera)
    assert isinstance(db, Database), f"{cls.__name__}.build must return a starid.plugin.Database"
    return db


@lru_cache(maxsize=4)
def _trials(catalog: Catalog, camera: Camera, config: SimConfig, n: int):
    sim = Simulator(catalog, camera, config, seed=SEED)
    return [sim.observation(t) for t in range(n)]


def _identify(algorithm: Algorithm, db: Database, obs: Observation, catalog: Catalog) -> np.ndarray:
    result = algorithm.identify(db, obs)
    return np.asarray(check_identification(result, len(obs), catalog.hip).hip)


def _check_default_constructible(cls, algorithm, db, catalog, camera):
    assert isinstance(cls.name, str) and cls.name, f"{cls.__name__} needs a non-empty class attribute 'name'"
    assert cls.summary(), f"{cls.__name__} needs a docstring (first line = summary, then the reference)"
    assert isinstance(algorithm.params(), dict)
    assert isinstance(db.nbytes, int) and db.nbytes > 0, "database.nbytes must be a positive int"


def _check_deterministic(cls, algorithm, db, catalog, camera):
    for obs in _trials(catalog, camera, NOISY, 5):
        first = _identify(algorithm, db, obs, catalog)
        second = _identify(cls(), db, obs, catalog)
        assert np.array_equal(first, second), "identify gave different answers for the same input"


def _check_few_stars(cls, algorithm, db, catalog, camera):
    obs = _trials(catalog, camera, NOISE_FREE, 1)[0]
    for k in range(4):
        small = Observation(obs.x_px[:k], obs.y_px[:k], obs.mag[:k], obs.camera)
        hip = _identify(algorithm, db, small, catalog)
        assert hip.shape == (k,)


def _check_valid_ids(cls, algorithm, db, catalog, camera):
    for obs in _trials(catalog, camera, NOISY, 20):
        _identify(algorithm, db, obs, catalog)


def _check_order_invariant(cls, algorithm, db, catalog, camera):
    rng = np.random.default_rng(SEED)
    for obs in _trials(catalog, camera, NOISY, 10):
        base = _identify(algorithm, db, obs, catalog)
        for order in (np.arange(len(obs))[::-1], rng.permutation(len(obs))):
            permuted = _identify(algorithm, db, obs.permuted(order), catalog)
            assert np.array_equal(permuted, base[order]), "reordering the input stars changed the answer"


def _check_noise_free_identified(cls, algorithm, db, catalog, camera):
    statuses = []
    for obs in _trials(catalog, camera, NOISE_FREE, 10):
        statuses.append(score_trial(_identify(algorithm, db, obs, catalog), obs.truth_hip, SuccessRule())["status"])
    assert "misidentified" not in statuses, f"noise-free trials misidentified: {statuses}"
    assert statuses.count("correct") >= 8, f"fewer than 8 of 10 noise-free trials identified: {statuses}"


_FUNCTIONS = {name: globals()[f"_check_{name}"] for name in CHECKS}


def check_algorithm(algorithm: type[Algorithm], checks=None, catalog: Catalog | None = None,
                    camera: Camera | None = None) -> list[str]:
    """Run the named checks (default: all) on an algorithm class; AssertionError on the first failure."""
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
        except AssertionError as exc:
            raise AssertionError(f"{algorithm.name}: check {name!r} failed: {exc}") from None
    return names


__all__ = ["CHECKS", "check_algorithm"]
