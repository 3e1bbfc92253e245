"""``query_only`` parameters: a database built at one noise level serves every other (issue #25), and
the conformance check holds a plugin's declaration to what its ``build`` and ``derived`` read."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from starid.experiment import Experiment, Grid, Study
from starid.experiment.executors import _CACHE, Task, execute_task
from starid.experiment.runner import plan
from starid.harness import build_key
from starid.plugin import Algorithm, Database, Identification
from starid.registry import register, unregister
from starid.testing import ConformanceError, check_algorithm, same_database

BUILDS: list[float] = []


@dataclass(frozen=True, eq=False)
class _Db(Database):
    hip: np.ndarray
    width: np.ndarray


@dataclass
class _Counting(Algorithm):
    """Counts its builds; its database does not depend on the noise it follows."""

    name: ClassVar[str] = "qo_counting"
    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}
    query_only: ClassVar[tuple] = ("sigma_px",)
    sigma_px: float | None = None
    n_keep: int = 50

    def build(self, catalog, camera):
        BUILDS.append(self.sigma_px)
        return _Db(catalog.hip[: self.n_keep].copy(), np.zeros(1))

    def identify(self, database, observation):
        return Identification(np.full(len(observation), -1, dtype=np.int64))


@dataclass
class _Lying(_Counting):
    """Declares sigma_px query-only, but its database is built from it."""

    name: ClassVar[str] = "qo_lying"

    def build(self, catalog, camera):
        return _Db(catalog.hip[: self.n_keep].copy(), np.array([max(self.sigma_px or 0.0, 1.0)]))


@pytest.fixture
def counting():
    register(_Counting)
    yield
    unregister("qo_counting")


def test_one_build_serves_every_noise_level(counting):
    exp = Experiment("qo", (Study("noise", ("qo_counting", "qo_counting[n_keep=60]"),
                                  Grid({"sigma_px": [0.0, 1.0, 2.0]})),), trials=3)
    placements = plan(exp, _catalog())
    camera = exp.make_camera()
    for key in ("prepared", "databases"):
        _CACHE[key].clear()
    BUILDS.clear()
    frames = [execute_task(Task(i, p.chunk, "", camera, 0, 6)) for i, p in enumerate(placements)]
    assert BUILDS == [0.0, 0.0]              # once per n_keep, at the first noise level
    by_label = {}
    for p, f in zip(placements, frames, strict=True):
        by_label.setdefault(p.chunk.variant.label, []).append(f)
    for fs in by_label.values():
        assert [f["param_sigma_px"].iloc[0] for f in fs] == [0.0, 1.0, 2.0]     # each point's own parameters
        assert len({f["build_s"].iloc[0] for f in fs}) == 1 and len({f["db_mb"].iloc[0] for f in fs}) == 1
    assert build_key(_Counting(sigma_px=0.0)) == build_key(_Counting(sigma_px=2.0))
    assert build_key(_Counting(n_keep=1)) != build_key(_Counting(n_keep=2))


def test_conformance_refuses_a_query_only_parameter_the_build_reads():
    check_algorithm(_Counting, ["query_only"], catalog=_catalog())
    with pytest.raises(ConformanceError, match=r"query_only 'sigma_px': build\(\) reads it .*width: values differ"):
        check_algorithm(_Lying, ["query_only"], catalog=_catalog())

    @dataclass
    class _NotFollowed(_Counting):
        name: ClassVar[str] = "qo_not_followed"
        query_only: ClassVar[tuple] = ("n_keep",)

    with pytest.raises(ConformanceError, match=r"query_only names \['n_keep'\], which are not 'follows'"):
        check_algorithm(_NotFollowed, ["query_only"], catalog=_catalog())


def test_same_database_names_the_first_difference():
    a = _Db(np.arange(3), np.zeros(2))
    assert same_database(a, _Db(np.arange(3), np.zeros(2))) == ""
    assert same_database(a, _Db(np.arange(3), np.zeros(3))) == "database.width: float64(2,) against float64(3,)"
    assert same_database(a, _Db(np.arange(3), np.array([0.0, np.nan]))) == "database.width: values differ"
    assert same_database(_Db(np.arange(3), np.array([np.nan])), _Db(np.arange(3), np.array([np.nan]))) == ""


def _catalog():
    from starid import load_hipparcos

    return load_hipparcos()
