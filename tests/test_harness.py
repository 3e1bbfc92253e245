from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest

import starid
from starid import SimConfig, Simulator
from starid.harness import run
from starid.plugin import Algorithm, Database, Identification
from starid.scoring import SuccessRule, score_trial
from starid.stats import SUMMARY_COLUMNS, summarize, wilson_interval


@dataclass(frozen=True, eq=False)
class _DB(Database):
    hip: np.ndarray


#: What the test knows and the harness never hands a plugin: each image's truth, by its first centroid.
TRUTH: dict = {}


def learn_truth(trials):
    for i in range(len(trials)):
        obs = trials.observation(i)
        TRUTH[(obs.x_px[0], obs.y_px[0], len(obs))] = obs.truth_hip.copy()
    return trials


@dataclass(frozen=True)
class Oracle(Algorithm):
    """Test double: knows the truth through the test (the harness hands plugins none) and can misbehave."""

    name: ClassVar[str] = "oracle"
    mode: str = "truth"

    def build(self, catalog, camera):
        return _DB(catalog.hip.copy())

    def identify(self, database, observation):
        assert observation.truth_hip is None, "the harness handed a plugin the truth"
        assert not observation.x_px.flags.writeable, "the harness handed a plugin writeable arrays"
        hip = TRUTH[(observation.x_px[0], observation.y_px[0], len(observation))].copy()
        if self.mode == "raise_on_odd" and len(observation) % 2:
            raise RuntimeError("odd star count")
        if self.mode == "one_wrong":
            hip[0] = database.hip[0] if hip[0] != database.hip[0] else database.hip[1]
        if self.mode == "duplicate":
            a = int(np.flatnonzero(hip >= 0)[0])
            hip[(a + 1) % len(hip)] = hip[a]
        if self.mode == "wrong_length":
            hip = hip[:-1]
        return Identification(hip)


@pytest.fixture(scope="module")
def setup(catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, false_stars=1), seed=3)
    return sim, learn_truth(sim.generate(40))


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
    for col in ("seed", "sim_sigma_px", "sim_false_stars", "starid_version", "numba_version", "param_mode", "label"):
        assert col in df.columns
    assert (df["seed"] == 3).all()


def test_attitude_error_is_zero_without_noise(catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(merge_radius_px=0.0), seed=4)   # merged blends are offset
    df = run([Oracle()], learn_truth(sim.generate(10)), catalog, sim)
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
    df = run([Oracle(), ("oracle[mode=one_wrong]", Oracle(mode="one_wrong"))], trials, catalog, sim)
    assert list(summarize(df)["label"]) == ["oracle", "oracle[mode=one_wrong]"]
    a, b = (g.reset_index(drop=True) for _, g in df.groupby("label", sort=False))
    pd.testing.assert_series_equal(a["trial"], b["trial"])
    pd.testing.assert_series_equal(a["n_stars"], b["n_stars"])


def test_duplicate_labels_are_refused(setup, catalog):
    sim, trials = setup
    with pytest.raises(starid.ConfigError, match="given twice"):
        run([Oracle(), Oracle(mode="one_wrong")], trials, catalog, sim)


def test_wilson_matches_scipy_reference():
    # the closed form, as a check on scipy's method="wilson"
    k, n, z = 37, 50, 1.959963984540054
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    assert wilson_interval(k, n) == pytest.approx((centre - half, centre + half), abs=1e-9)
