"""``starid report OLD NEW``: every metric paired on the same images, intervals that behave at the
edges, a refusal (naming the settings) when the worlds differ, one-sided labels listed, and the
``--fail-on`` gates' exit codes."""

import numpy as np
import pandas as pd
import pytest

from starid.cli import main
from starid.errors import ConfigError
from starid.experiment import Experiment, Grid, Study, Variant, run_experiment
from starid.report.regression import (
    build_regression,
    compare,
    gate,
    newcombe_paired,
    one_sided,
    paired,
    parse_fail_on,
    time_ratio,
)

BROKEN = Variant("ptp", (("beta", 0.05), ("side_beta", 0.05)), label="ptp")   # windows 60 x too narrow: id rate 0


def _exp(variants=("ptp",), sigma_px=1.0, trials=20):
    return Experiment("reg", (Study("s", variants, Grid({})),), trials=trials, seed=3, sim={"sigma_px": sigma_px})


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    root = tmp_path_factory.mktemp("regression")
    made = {}
    for name, exp in (("old", _exp()), ("same", _exp()), ("broken", _exp((BROKEN, "ptp[n_slaves=3]"))),
                      ("noisier", _exp(sigma_px=2.0))):
        run_experiment(exp, root / name, jobs=1, progress=False)
        made[name] = root / name
    return made


def test_different_noise_is_refused_naming_the_setting(folders, tmp_path, capsys):
    with pytest.raises(ConfigError, match="pos_noise_px") as err:
        build_regression(folders["old"], folders["noisier"], tmp_path)
    assert "1 (old) vs 2 (new)" in str(err.value) and "--allow-different-worlds" in str(err.value)
    assert main(["report", str(folders["old"]), str(folders["noisier"]), "--out", str(tmp_path)]) == 2
    assert "pos_noise_px" in capsys.readouterr().err
    assert not (tmp_path / "regression.md").exists()
    # allowed: compared, with the differing setting in the report and the verdict flagged
    written, _ = build_regression(folders["old"], folders["noisier"], tmp_path, allow_different_worlds=True)
    md = written["md"].read_text()
    assert "**The worlds differ**" in md and "pos_noise_px (--pos-noise-px)" in md


def test_same_world_reports_every_metric(folders, tmp_path):
    written, diff = build_regression(folders["old"], folders["same"], tmp_path, svg=False)
    assert written["differences"] == []
    row = diff.iloc[0]
    for col in ("diff", "diff_lo", "diff_hi", "p_value", "misid_diff", "misid_lo", "misid_hi", "misid_p",
                "failed_diff", "failed_p", "failures_old", "time_median_old_us", "time_ratio", "time_ratio_lo",
                "time_ratio_hi", "time_p95_ratio", "db_mb_old", "db_mb_new", "build_s_old", "build_s_new"):
        assert col in diff.columns and not pd.isna(row[col]), col
    # the same images, the same algorithm: no change, yet a proper interval around it (not [+0, +0])
    assert row["diff"] == 0 and row["diff_lo"] < 0 < row["diff_hi"]
    assert row["db_mb_old"] == row["db_mb_new"]
    md = written["md"].read_text()
    for heading in ("## Identification rate", "## Misidentification and failures",
                    "## Time, database size and build time", "## Labels and points on one side only",
                    "median ratio [95% CI]", "DB old / new (MB)", "Newcombe"):
        assert heading in md
    assert "same world" in md


def test_worse_plugin_fails_the_gate_and_one_sided_labels_are_listed(folders, tmp_path, capsys):
    args = ["report", str(folders["old"]), str(folders["broken"]), "--out", str(tmp_path), "--no-svg"]
    assert main(args) == 0                                  # no gate asked: a report, exit 0
    out = capsys.readouterr().out
    assert "only in new: s/ptp[n_slaves=3]" in out
    assert main(args + ["--fail-on", "worse"]) == 1
    assert "FAIL worse: s/ptp" in capsys.readouterr().out
    assert main(args + ["--fail-on-regression"]) == 1      # the old flag means --fail-on worse
    assert main(["report", str(folders["old"]), str(folders["same"]), "--out", str(tmp_path), "--no-svg",
                 "--fail-on", "worse,misid"]) == 0
    md = (tmp_path / "regression.md").read_text()
    assert "**worse**" not in md
    assert main(args + ["--fail-on", "faster"]) == 2


def test_intervals_at_the_edges():
    # every discordant image one way: the old conditional interval ended on the estimate (+5.33 [+3.14, +5.33])
    old = np.ones(150, bool)
    old[:8] = False
    r = paired(old, np.ones(150, bool))
    assert r["diff"] == pytest.approx(8 / 150) and r["lo"] > 0 and r["hi"] > r["diff"] + 0.005
    # no discordant image: not the degenerate [+0.00, +0.00]
    lo, hi = newcombe_paired(100, 0, 0, 0)
    assert lo == pytest.approx(-hi) and 0.03 < hi < 0.045
    # coverage near 95 % on simulated paired data
    rng = np.random.default_rng(1)
    hits = 0
    for _ in range(1000):
        u = rng.random(60)
        a, b = u < 0.8, u < 0.7          # correlated: p_new - p_old = -0.1
        r = paired(a, b)
        hits += r["lo"] <= -0.1 <= r["hi"]
    assert 0.92 <= hits / 1000 <= 0.985


def test_time_ratio_bootstrap_and_gates_on_frames():
    rng = np.random.default_rng(2)
    t = rng.lognormal(6, 0.3, 400)
    est, lo, hi = time_ratio(t, 2 * t, 0.5)
    assert est == pytest.approx(2) and lo == pytest.approx(2) and hi == pytest.approx(2)
    est, lo, hi = time_ratio(t, t * rng.lognormal(0, 0.2, 400), 0.5)
    assert lo < est < hi and time_ratio(t, t, 0.5, seed=0) == time_ratio(t, t, 0.5, seed=0)
    frame = pd.DataFrame({"study": "s", "label": "a", "trial": range(200), "status": "correct",
                          "time_us": t[:200], "db_mb": 1.0, "build_s": 0.1})
    slow = frame.assign(time_us=1.5 * frame["time_us"], status=["misidentified"] * 20 + ["correct"] * 180)
    d = compare(frame, slow)
    assert gate(d, parse_fail_on(["slower:1.2"])) and not gate(d, parse_fail_on(["slower:1.6"]))
    assert gate(d, parse_fail_on(["misid"])) and gate(d, parse_fail_on(["worse"]))
    assert parse_fail_on(["worse,slower:1.2", "misid"]) == [("worse", None), ("slower", 1.2), ("misid", None)]
    for bad in ("slower", "slower:x", "slower:-1", "better"):
        with pytest.raises(ConfigError, match="--fail-on"):
            parse_fail_on([bad])


def test_one_sided_points_and_labels():
    a = pd.DataFrame({"study": "s", "grid_x": [0.0, 0.0, 1.0], "label": ["a", "b", "a"]})
    b = pd.DataFrame({"study": "s", "grid_x": [0.0, 2.0], "label": ["a", "a"]})
    lone = one_sided(a, b)
    got = set(zip(lone["side"], lone["where"], lone["label"], strict=True))
    assert got == {("old", "x=0", "b"), ("old", "x=1", "a"),
                                                                    ("new", "x=2", "a")}
