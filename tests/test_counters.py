"""Work counters (issue #25): ``Identification.counters`` -> trial-row columns ``n_<name>`` -> summary means."""

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from starid import SimConfig, Simulator
from starid.errors import PluginError
from starid.harness import TRIAL_COLUMNS, run
from starid.plugin import Algorithm, Database, Identification, check_identification
from starid.stats import summarize


@dataclass(frozen=True, eq=False)
class _DB(Database):
    hip: np.ndarray


@dataclass(frozen=True)
class Counting(Algorithm):
    """Test double: identifies nothing and counts one search per star (none when ``count`` is off)."""

    name: ClassVar[str] = "counting"
    count: bool = True

    def build(self, catalog, camera):
        return _DB(catalog.hip[:1].copy())

    def identify(self, database, observation):
        n = len(observation)
        return Identification(np.full(n, -1, dtype=np.int64),
                              counters={"searches": n, "verifications": 0} if self.count else None)


@pytest.fixture(scope="module")
def trials(catalog, camera):
    return Simulator(catalog, camera, SimConfig(sigma_px=1.0), seed=5).generate(4)


def test_counters_become_columns_and_summary_means(trials, catalog):
    df = run([("with", Counting()), ("without", Counting(count=False))], trials, catalog)
    with_ = df[df["label"] == "with"]
    without = df[df["label"] == "without"]
    assert np.array_equal(with_["n_searches"].to_numpy(), with_["n_stars"].to_numpy())
    assert (with_["n_verifications"] == 0).all()
    assert without["n_searches"].isna().all()      # absent = NaN, not 0
    assert df.columns[:len(TRIAL_COLUMNS)].tolist() == TRIAL_COLUMNS
    s = summarize(df).set_index("label")
    assert s.loc["with", "n_searches_mean"] == pytest.approx(with_["n_stars"].mean())
    assert np.isnan(s.loc["without", "n_searches_mean"])


def test_no_counters_no_columns(trials, catalog):
    df = run([Counting(count=False)], trials, catalog)
    assert not any(c.startswith("n_searches") for c in df.columns)
    assert "n_searches_mean" not in summarize(df).columns


@pytest.mark.parametrize("bad", [[1], {"a b": 1}, {"x": -1}, {"x": 1.5}, {"x": True}])
def test_bad_counters_are_refused(catalog, bad):
    with pytest.raises(PluginError, match="counter"):
        check_identification(Identification(np.full(2, -1), counters=bad), 2, catalog.hip)
