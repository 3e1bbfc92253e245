"""What a new user meets first: --version, python -m starid, starid info, simulate -> identify, the API."""

import subprocess
import sys

import pandas as pd
import pytest

import starid
from starid.cli import main


def test_version_and_python_m(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"starid {starid.__version__}"
    out = subprocess.run([sys.executable, "-m", "starid", "list"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "ptp" in out.stdout


@pytest.mark.parametrize("name", starid.available())
def test_info_for_every_registered_algorithm(name, capsys):
    assert main(["info", name, "--no-build"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{name}: ") and "parameters" in out and f"docs/algorithms/{name}.md" in out


def test_help_shows_defaults_and_examples(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = capsys.readouterr().out
    assert "(default: 1000)" in out and "examples:" in out and "starid list" in out


def test_simulate_identify_round_trip_matches_run(tmp_path, capsys):
    args = ["--trials", "60", "--seed", "4", "--pos-noise-px", "1", "--mag-noise", "0.5"]
    assert main(["simulate", *args, "--out", str(tmp_path / "obs.csv")]) == 0
    assert main(["identify", "ptp", "pvector", str(tmp_path / "obs.csv"), "--out", str(tmp_path / "id")]) == 0
    assert main(["run", "ptp", "pvector", *args, "--jobs", "1", "--quiet", "--out", str(tmp_path / "run")]) == 0
    ident = pd.read_csv(tmp_path / "id" / "summary.csv").set_index("label")
    run = pd.read_csv(tmp_path / "run" / "summary.csv").set_index("label")
    for label in ("ptp", "pvector"):
        assert ident.loc[label, "id_rate"] == run.loc[label, "id_rate"]
        assert ident.loc[label, "misid_rate"] == run.loc[label, "misid_rate"]
    ids = pd.read_csv(tmp_path / "id" / "identifications.csv")
    assert set(ids["label"]) == {"ptp", "pvector"} and {"x_px", "truth_hip"} <= set(ids.columns)
    statuses = set(pd.read_csv(tmp_path / "id" / "trials.csv")["status"])
    assert statuses <= set(starid.scoring.STATUSES)


def test_python_api_for_notebooks(catalog):
    assert {"run", "summarize", "mcnemar", "Simulator", "get_algorithm", "available"} <= set(starid.__all__)
    assert not hasattr(starid, "PackageNotFoundError") and not hasattr(starid, "version")
    sim = starid.Simulator(starid.Catalog.embedded(), starid.Camera(), starid.SimConfig(sigma_px=1.0), seed=1)
    trials = sim.generate(5)
    assert list(trials.to_frame().columns) == ["trial", "star", "x_px", "y_px", "mag", "truth_hip"]
    assert len(starid.Catalog.embedded().to_frame()) == len(catalog)
    rows = starid.run([starid.get_algorithm("ptp")()], trials, catalog, sim, keep_ids=True)
    assert len(rows["ids"].iloc[0]) == rows["n_stars"].iloc[0]
    assert rows["param_sigma_px"].notna().all()
