"""The experiment engine: chunks, resuming, changed definitions, parallel and Dask runs, isolation."""

import os
import signal
import subprocess
import sys
import time

import pandas as pd
import pytest

from starid.errors import ConfigError
from starid.experiment import Experiment, Grid, Study, Variant, read_manifest, run_experiment, runner

MEASURED = ["time_us", "build_s", "compile_s"]


def small(trials=40, algorithms=("ptp", "pvector"), sigma=(0.0, 1.0), name="small"):
    return Experiment(name, (Study("s", algorithms, Grid({"sigma_px": list(sigma)})),), trials=trials, seed=3,
                      sim={"sigma_mag": 0.2})


def same(a: pd.DataFrame, b: pd.DataFrame):
    pd.testing.assert_frame_equal(a.drop(columns=MEASURED).reset_index(drop=True),
                                  b.drop(columns=MEASURED).reset_index(drop=True), check_dtype=False)


@pytest.fixture(scope="module")
def reference():
    return run_experiment(small(), None, jobs=1, progress=False)


def test_frame_shape_and_common_random_numbers(reference):
    assert len(reference) == 2 * 2 * 40
    assert {"study", "point", "grid_sigma_px", "label", "trial", "status", "sim_sigma_px", "param_n_slaves",
            "seed", "starid_version", "plugin_dist"} <= set(reference.columns)
    assert set(reference["plugin_dist"]) == {"starid-bench"}
    # trial k has the same attitude at every point: the true star count barely moves with 1 px noise
    a = reference[(reference["label"] == "ptp") & (reference["grid_sigma_px"] == 0.0)]["n_true_stars"].to_numpy()
    b = reference[(reference["label"] == "ptp") & (reference["grid_sigma_px"] == 1.0)]["n_true_stars"].to_numpy()
    assert (abs(a - b) <= 1).mean() > 0.9


def test_jobs_do_not_change_results(reference):
    same(reference, run_experiment(small(), None, jobs=2, progress=False))


def test_dask_local_cluster_gives_the_same_frame(reference):
    pytest.importorskip("distributed")
    same(reference, run_experiment(small(), None, jobs=2, executor="dask", progress=False))


def test_changed_experiment_recomputes_only_what_changed(tmp_path, monkeypatch, reference):
    out = tmp_path / "r"
    first = run_experiment(small(), out, jobs=2, progress=False)
    same(reference, first)
    assert read_manifest(out)["computed_chunks"] == 4
    # one more point and one more variant: only their chunks are computed
    changed = small(algorithms=("ptp", "pvector", "ptp[n_slaves=3]"), sigma=(0.0, 1.0, 2.0))
    second = run_experiment(changed, out, jobs=2, progress=False)
    manifest = read_manifest(out)
    assert manifest["computed_chunks"] == 9 - 4 and manifest["reused_chunks"] == 4
    assert len(second) == 9 * 40
    same(second[second["label"].isin(["ptp", "pvector"]) & (second["grid_sigma_px"] < 2)], reference)
    # going back reuses everything, and the frame holds only the current definition's rows
    third = run_experiment(small(), out, jobs=1, progress=False)
    assert read_manifest(out)["computed_chunks"] == 0
    same(third, reference)


def test_store_refuses_foreign_folders(tmp_path):
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="not a starid results folder"):
        run_experiment(small(trials=5), tmp_path / "other", jobs=1, progress=False)
    run_experiment(small(trials=5), tmp_path / "a", jobs=1, progress=False)
    with pytest.raises(ConfigError, match="results of experiment 'small'"):
        run_experiment(small(trials=5, name="another"), tmp_path / "a", jobs=1, progress=False)
    (tmp_path / "file").write_text("")
    with pytest.raises(ConfigError, match="is a file"):
        run_experiment(small(trials=5), tmp_path / "file", jobs=1, progress=False)


SCRIPT = """
import sys
from starid.experiment import Experiment, Grid, Study, run_experiment
exp = Experiment("killed", (Study("s", ("ptp", "pvector"), Grid({"sigma_px": [0.0, 1.0]})),),
                 trials=int(sys.argv[2]), seed=1)
run_experiment(exp, sys.argv[1], jobs=1, progress=False)
"""


def test_killed_run_resumes_without_recomputing(tmp_path, monkeypatch):
    monkeypatch.setattr(runner, "BLOCK", 50)
    out = tmp_path / "k"
    script = tmp_path / "run.py"
    script.write_text(SCRIPT.replace("from starid.experiment import", "import starid.experiment.runner as r\n"
                                     "r.BLOCK = 50\nfrom starid.experiment import"))
    proc = subprocess.Popen([sys.executable, str(script), str(out), "200"], start_new_session=True)
    chunks = out / "chunks"
    deadline = time.time() + 240
    while time.time() < deadline and (not chunks.is_dir() or len(list(chunks.glob("*.parquet"))) < 3):
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    finished = {p.name: p.stat().st_mtime_ns for p in chunks.glob("*.parquet")}
    assert 3 <= len(finished) < 16, "the run was not interrupted mid-way"
    # what a write killed mid-way leaves behind: a truncated temp file beside a missing chunk; never read
    missing = next(key for key in read_manifest(out)["chunks"] if f"{key}.parquet" not in finished)
    leftover = chunks / f".{missing}.parquet.killed.tmp"
    leftover.write_bytes(b"PAR1 truncated")
    exp = Experiment("killed", (Study("s", ("ptp", "pvector"), Grid({"sigma_px": [0.0, 1.0]})),),
                     trials=200, seed=1)
    resumed = run_experiment(exp, out, jobs=2, progress=False)
    manifest = read_manifest(out)
    assert manifest["reused_chunks"] == len(finished) and manifest["computed_chunks"] == 16 - len(finished)
    for name, mtime in finished.items():
        assert (chunks / name).stat().st_mtime_ns == mtime, "a finished chunk was recomputed"
    assert (chunks / f"{missing}.parquet").is_file() and leftover.read_bytes() == b"PAR1 truncated"
    fresh = run_experiment(exp, None, jobs=2, progress=False)
    same(resumed, fresh)


@pytest.fixture
def misbehaving():
    from misbehaving import register_all, unregister_all

    register_all()
    yield
    unregister_all()


def _one(mode, **kw):
    return Experiment("iso", (Study("s", ("ptp", f"misbehaving[mode={mode}]")),), trials=12, seed=2, **kw)


@pytest.mark.parametrize("mode, status", [("hang", "timeout"), ("crash", "crashed"), ("exit", "error"),
                                          ("build_raises", "error"), ("cheat", "error")])
def test_a_failing_plugin_is_its_own_recorded_failure(misbehaving, mode, status):
    frame = run_experiment(_one(mode), None, jobs=2, time_limit_s=1.0, progress=False)
    ptp = frame[frame["label"] == "ptp"]
    bad = frame[frame["label"] == f"misbehaving[mode={mode}]"]
    assert len(ptp) == len(bad) == 12
    assert (ptp["status"] == "correct").mean() > 0.8, "the well-behaved algorithm suffered"
    assert (bad["status"] == status).any()
    if mode in ("hang", "crash", "exit"):
        hit = bad["n_stars"] % 3 == 0
        assert (bad.loc[hit, "status"] == status).all() and (bad.loc[~hit, "status"] == "no_result").all()


def test_a_plugin_cannot_change_the_images_of_the_next(misbehaving, reference):
    frame = run_experiment(Experiment("mut", (Study("s", ("misbehaving[mode=mutate]", "ptp")),), trials=20, seed=3),
                           None, jobs=1, progress=False)
    assert (frame[frame["label"] == "misbehaving[mode=mutate]"]["status"] == "error").all()
    clean = run_experiment(Experiment("mut", (Study("s", ("ptp",)),), trials=20, seed=3), None, jobs=1,
                           progress=False)
    same(frame.loc[frame["label"] == "ptp", list(clean.columns)].reset_index(drop=True), clean)


def test_variant_labels_and_parsing():
    v = Variant.parse("ptp[n_slaves=3,verify=false]")
    assert v.label == "ptp[n_slaves=3,verify=False]" and dict(v.params) == {"n_slaves": 3, "verify": False}
    with pytest.raises(ConfigError, match="valid: "):
        Variant.parse("ptp[nope=1]")
    with pytest.raises(ConfigError, match="must be int"):
        Variant.parse("ptp[n_slaves=1_0]")
    with pytest.raises(ConfigError, match="appear twice"):
        Study("s", ("ptp", "ptp"))


def test_toml_experiment_and_cli(tmp_path, capsys):
    from starid.cli import main

    (tmp_path / "e.toml").write_text(
        'name = "toml-exp"\ntrials = 10\nseed = 4\n[sim]\nsigma_mag = 0.5\nsky = "paper"\n'
        '[[study]]\nname = "noise"\nalgorithms = ["ptp", "ptp[n_slaves=3]"]\ngrid = { sigma_px = [0.0, 1.5] }\n')
    assert main(["experiment", "run", str(tmp_path / "e.toml"), "--out", str(tmp_path / "o"), "--jobs", "1",
                 "--quiet"]) == 0
    frame = pd.read_parquet(tmp_path / "o" / "results.parquet")
    assert len(frame) == 2 * 2 * 10 and (frame["sim_sky_mag_limit"] == 6.0).all()
    assert main(["sweep", "ptp", "--param", "false_stars=0:2:1", "--trials", "8", "--out", str(tmp_path / "s"),
                 "--jobs", "1", "--quiet"]) == 0
    assert sorted(pd.read_csv(tmp_path / "s" / "summary.csv")["grid_false_stars"]) == [0, 1, 2]
    (tmp_path / "bad.toml").write_text("name = 'x'\n[[study]]\nname='a'\nalgorithms=['ptp']\ngrid={nope=[1]}\n")
    assert main(["experiment", "run", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "b")]) == 2
    assert "grid axis 'nope'" in capsys.readouterr().err


def test_image_pipeline_reports_extraction_beside_the_rates():
    from starid.stats import IMAGE_COLUMNS, summarize

    exp = Experiment("img", (Study("s", ("ptp",), Grid({"pipeline": ["centroids", "image"]})),), trials=6, seed=4)
    frame = run_experiment(exp, None, jobs=1, progress=False)
    image = frame[frame["grid_pipeline"] == "image"]
    assert image["img_n_detectable"].gt(0).all() and frame.loc[frame["grid_pipeline"] == "centroids",
                                                                "img_n_detectable"].isna().all()
    s = summarize(image)
    assert set(IMAGE_COLUMNS) <= set(s.columns)
    assert 0.5 < s["detection_rate"].iloc[0] <= 1 and 0 < s["rms_centroid_err_px"].iloc[0] < 1.5
