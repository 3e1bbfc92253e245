import pandas as pd
import pytest

from starid import SimConfig, Simulator
from starid.cli import main

SUMMARY = ["algorithm", "trials", "id_rate", "id_rate_lo", "id_rate_hi", "misid_rate", "no_result_rate",
           "star_recall", "star_precision", "time_median_us", "time_mean_us", "time_p95_us", "db_mb", "build_s",
           "compile_s"]


def test_list(capsys):
    assert main(["list"]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("ptp "))
    assert line.split()[1] == "ok" and "PTP" in line


def test_run_writes_contract_files(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "ptp", "--trials", "30", "--seed", "1", "--pos-noise-px", "1", "--mag-noise", "0.5",
                 "--false-stars", "1", "--out", str(out), "--quiet"]) == 0
    summary = pd.read_csv(out / "summary.csv")
    assert list(summary.columns[:len(SUMMARY)]) == SUMMARY
    trials = pd.read_csv(out / "trials.csv")
    assert len(trials) == 30 and set(trials["status"]) <= {"correct", "misidentified", "no_result", "error"}
    assert (trials["sim_false_stars"] == 1).all() and (trials["seed"] == 1).all()
    assert "id_rate" in capsys.readouterr().out


def test_run_is_reproducible(tmp_path):
    for name in ("a", "b"):
        main(["run", "ptp", "--trials", "15", "--seed", "3", "--pos-noise-px", "0.5", "--out", str(tmp_path / name),
              "--quiet"])
    cols = ["trial", "status", "n_stars", "n_correct", "n_wrong"]
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "a" / "trials.csv")[cols],
                                  pd.read_csv(tmp_path / "b" / "trials.csv")[cols])


def test_run_parameter_override_and_errors(tmp_path, capsys):
    assert main(["run", "ptp", "--trials", "5", "--set", "ptp.verify=false", "--out", str(tmp_path), "--quiet"]) == 0
    assert not pd.read_csv(tmp_path / "trials.csv")["param_verify"].iloc[0]
    assert main(["run", "ptp", "--trials", "5", "--set", "ptp.nope=1"]) == 2
    assert main(["run", "nope", "--trials", "5"]) == 2
    assert main(["run", "ptp", "--trials", "5", "--pos-noise-px", "-1"]) == 2
    assert "error" in capsys.readouterr().err


def _obs_csv(path, catalog, camera, n=6, truth=True):
    sim = Simulator(catalog, camera, SimConfig(), seed=11)
    rows = []
    for t in range(n):
        obs = sim.observation(t)
        for j in range(len(obs)):
            rows.append({"trial": 100 + t, "x_px": obs.x_px[j], "y_px": obs.y_px[j], "mag": obs.mag[j],
                         **({"truth_hip": obs.truth_hip[j]} if truth else {})})
    pd.DataFrame(rows).to_csv(path, index=False)
    return pd.DataFrame(rows)


def test_identify_roundtrip(tmp_path, catalog, camera):
    obs = _obs_csv(tmp_path / "obs.csv", catalog, camera)
    out = tmp_path / "id"
    assert main(["identify", "ptp", str(tmp_path / "obs.csv"), "--out", str(out)]) == 0
    ids = pd.read_csv(out / "identifications.csv")
    assert list(ids.columns[:3]) == ["trial", "star", "hip"] and len(ids) == len(obs)
    assert {"x_px", "y_px", "mag", "truth_hip", "label"} <= set(ids.columns)
    assert list(pd.read_csv(out / "trials.csv").columns[:4]) == ["trial", "status", "n_identified", "time_us"]
    reported = ids["hip"] != -1
    assert reported.sum() > len(ids) / 2
    assert (ids["hip"][reported].to_numpy() == obs["truth_hip"][reported.to_numpy()].to_numpy()).all()
    assert list(pd.read_csv(out / "summary.csv").columns[:len(SUMMARY)]) == SUMMARY


def test_identify_without_truth_and_custom_camera(tmp_path, catalog, camera):
    _obs_csv(tmp_path / "obs.csv", catalog, camera, n=2, truth=False)
    out = tmp_path / "id"
    assert main(["identify", "ptp", str(tmp_path / "obs.csv"), "--out", str(out), "--fov-deg", "10"]) == 0
    assert not (out / "summary.csv").exists()
    assert set(pd.read_csv(out / "trials.csv")["status"]) <= {"identified", "no_result"}


@pytest.mark.parametrize("text, message", [
    ("trial,x_px,y_px\n0,1,2\n", "line 1: missing column"),
    ("trial,x_px,y_px,mag\n0,1,2,3\n0,abc,2,3\n", "line 3: non-numeric"),
    ("trial,x_px,y_px,mag\n0,1,2,3\n0,nan,2,3\n", "line 3: NaN"),
    ("trial,x_px,y_px,mag\n0,1,2,3\n0,2000,2,3\n", "line 3: .* outside"),
    ("trial,x_px,y_px,mag\n0.5,1,2,3\n", "line 2: trial"),
])
def test_identify_refuses_malformed_input_and_writes_nothing(tmp_path, capsys, text, message):
    (tmp_path / "obs.csv").write_text(text)
    out = tmp_path / "id"
    assert main(["identify", "ptp", str(tmp_path / "obs.csv"), "--out", str(out)]) == 2
    import re
    assert re.search(message, capsys.readouterr().err)
    assert not out.exists()


def test_a_closed_output_pipe_ends_quietly():
    """``starid info ptp | head -1``: the reader is gone before starid prints; no traceback."""
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "starid", "info", "ptp"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader leaves before starid has imported, let alone printed
    stderr = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141
    assert "Traceback" not in stderr and "BrokenPipe" not in stderr, stderr
