from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest

from starid import SimConfig, Simulator
from starid.harness import SUMMARY_COLUMNS, SuccessRule, run, score_trial, summarize, wilson_interval
from starid.plugin import Algorithm, Database, Identification


@dataclass(frozen=True, eq=False)
class _DB(Database):
    hip: np.ndarray


@dataclass(frozen=True)
class Oracle(Algorithm):
    """Test double: reads the truth (which real plugins must never do) and can misbehave on purpose."""

    name: ClassVar[str] = "oracle"
    mode: str = "truth"

    def build(self, catalog, camera):
        return _DB(catalog.hip.copy())

    def identify(self, database, observation):
        hip = observation.truth_hip.copy()
        if self.mode == "raise_on_odd" and len(observation) % 2:
            raise RuntimeError("odd star count")
        if self.mode == "one_wrong":
            hip[0] = database.hip[0] if hip[0] != database.hip[0] else database.hip[1]
        if self.mode == "duplicate":
            hip[1] = hip[0]
        if self.mode == "wrong_length":
            hip = hip[:-1]
        return Identification(hip)


@pytest.fixture(scope="module")
def setup(catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, false_stars=1), seed=3)
    return sim, sim.generate(40)


def test_score_trial_rules():
    truth = np.array([10, 11, 12, 13, -1])
    assert score_trial(np.array([10, 11, 12, -1, -1]), truth, SuccessRule())["status"] == "correct"
    assert score_trial(np.array([10, 11, -1, -1, -1]), truth, SuccessRule())["status"] == "no_result"
    assert score_trial(np.array([10, 11, 12, 13, 99]), truth, SuccessRule())["status"] == "misidentified"
    assert score_trial(np.array([10, 11, 12, 14, -1]), truth, SuccessRule())["status"] == "misidentified"
    assert score_trial(np.array([10, 11, -1, -1, -1]), truth, SuccessRule(min_correct=2))["status"] == "correct"


def test_wilson_interval_known_values():
    lo, hi = wilson_interval(81, 100)
    assert lo == pytest.approx(0.7222, abs=1e-4) and hi == pytest.approx(0.8749, abs=1e-4)
    assert wilson_interval(0, 10)[0] == 0.0
    assert np.isnan(wilson_interval(0, 0)[0])


def test_oracle_scores_perfectly(setup, catalog):
    sim, trials = setup
    df = run([Oracle()], trials, catalog, sim)
    assert len(df) == 40 and (df["status"] == "correct").all()
    assert df["attitude_err_arcsec"].median() < 200       # 1 px = 35 arcsec noise, mostly roll error
    s = summarize(df)
    assert list(s.columns) == SUMMARY_COLUMNS
    assert s["id_rate"].iloc[0] == 1.0 and s["star_precision"].iloc[0] == 1.0 and s["star_recall"].iloc[0] == 1.0
    for col in ("seed", "sim_sigma_px", "sim_false_stars", "starid_version", "numba_version", "algorithm_params"):
        assert col in df.columns
    assert (df["seed"] == 3).all()


def test_attitude_error_is_zero_without_noise(catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(merge_radius_px=0.0), seed=4)   # merged blends are offset
    df = run([Oracle()], sim.generate(10), catalog, sim)
    assert df["attitude_err_arcsec"].max() < 1e-3


@pytest.mark.parametrize("mode, status", [("one_wrong", "misidentified"), ("duplicate", "error"),
                                          ("wrong_length", "error")])
def test_misbehaviour_is_scored_not_raised(setup, catalog, mode, status):
    sim, trials = setup
    df = run([Oracle(mode=mode)], trials, catalog, sim)
    assert (df["status"] == status).all()


def test_exception_in_one_trial_is_recorded_and_run_goes_on(setup, catalog):
    sim, trials = setup
    df = run([Oracle(mode="raise_on_odd")], trials, catalog, sim)
    odd = df["n_stars"] % 2 == 1
    assert odd.any() and (~odd).any()
    assert (df.loc[odd, "status"] == "error").all()
    assert df.loc[odd, "error"].str.contains("odd star count").all()
    assert (df.loc[~odd, "status"] == "correct").all()
    assert summarize(df)["error_rate"].iloc[0] == pytest.approx(odd.mean())


def test_same_trials_for_every_algorithm(setup, catalog):
    sim, trials = setup
    df = run([Oracle(), Oracle(mode="one_wrong")], trials, catalog, sim)
    a, b = (g.reset_index(drop=True) for _, g in df.groupby("algorithm_params", sort=False))
    pd.testing.assert_series_equal(a["trial"], b["trial"])
    pd.testing.assert_series_equal(a["n_stars"], b["n_stars"])


def test_parallel_run_matches_serial(setup, catalog):
    sim, trials = setup
    serial = run([Oracle(), Oracle(mode="raise_on_odd")], trials, catalog, sim, jobs=1)
    parallel = run([Oracle(), Oracle(mode="raise_on_odd")], trials, catalog, sim, jobs=2)
    cols = [c for c in serial.columns if c not in ("time_us", "build_s", "compile_s")]
    pd.testing.assert_frame_equal(serial[cols], parallel[cols])
