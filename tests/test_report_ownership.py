"""A results folder belongs to one definition (#27): another command into it exits 2 naming what it
holds, unless --overwrite (cleared, reports included) or --extend (same experiment, chunks reused);
resuming works; derived files record the digest they were made from and a stale one is never shown."""

from __future__ import annotations

import json

import pytest

from starid.cli import main
from starid.errors import ConfigError
from starid.experiment import Experiment, Study, read_manifest
from starid.experiment.store import (
    DERIVED,
    Store,
    claim_folder,
    clear_folder,
    read_derived,
    record_derived,
    stale_derived,
)

RUN = ["run", "--trials", "6", "--jobs", "1", "--quiet", "--pos-noise-px", "1", "--false-stars", "2", "--seed", "4"]


@pytest.fixture(scope="module")
def ptp_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("own") / "r"
    assert main([*RUN[:1], "ptp", *RUN[1:], "--out", str(out)]) == 0
    return out


def _copy(src, dst):
    import shutil

    shutil.copytree(src, dst)
    return dst


def test_another_command_is_refused_naming_what_the_folder_holds(ptp_folder, tmp_path, capsys):
    out = _copy(ptp_folder, tmp_path / "r")
    before = {p.name: p.read_bytes() for p in out.glob("*.csv")}
    manifest = (out / "manifest.json").read_text()
    capsys.readouterr()
    assert main(["run", "pvector", *RUN[1:], "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "holds experiment 'run'" in err and "ptp" in err and "6 trials" in err and "--overwrite" in err
    assert "pvector" in err                                       # what differs: the studies
    # nothing was touched
    assert {p.name: p.read_bytes() for p in out.glob("*.csv")} == before
    assert (out / "manifest.json").read_text() == manifest
    # another world (noise) is another definition too, named key by key
    assert main(["run", "ptp", *RUN[1:], "--pos-noise-px", "0.5", "--out", str(out)]) == 2
    assert "sim.sigma_px" in capsys.readouterr().err
    # and another command (a sweep) into it
    assert main(["sweep", "ptp", "--param", "sigma_px=0,1", *RUN[1:], "--out", str(out)]) == 2
    assert "holds experiment 'run'" in capsys.readouterr().err


def test_same_command_resumes(ptp_folder, tmp_path):
    out = _copy(ptp_folder, tmp_path / "r")
    assert main(["run", "ptp", *RUN[1:], "--out", str(out)]) == 0
    m = read_manifest(out)
    assert m["computed_chunks"] == 0 and m["reused_chunks"] == len(m["chunks"])


def _fake_report(out):
    """A report as ``starid report`` records it (its own test is in test_report.py), without drawing it."""
    (out / "report.md").write_text("# report\n")
    (out / "figures").mkdir()
    (out / "figures" / "time.png").write_bytes(b"png")
    record_derived(out, [out / "report.md", out / "figures" / "time.png"])


def test_overwrite_clears_the_folder_reports_included(ptp_folder, tmp_path):
    out = _copy(ptp_folder, tmp_path / "r")
    digest = read_manifest(out)["digest"]
    _fake_report(out)
    rec = read_derived(out)
    assert rec["report.md"]["digest"] == digest and rec["results.parquet"]["digest"] == digest
    assert rec["trials.csv"]["digest"] == digest and rec["figures/time.png"]["digest"] == digest
    (out / "notes.txt").write_text("mine")
    assert main(["run", "ptp", *RUN[1:], "--seed", "1", "--out", str(out), "--overwrite"]) == 0   # last --seed wins
    assert not (out / "report.md").exists() and not (out / "figures").exists() and not (out / "notes.txt").exists()
    m = read_manifest(out)
    assert m["digest"] != digest and m["reused_chunks"] == 0 and m["experiment"]["seed"] == 1
    assert set(json.loads((out / DERIVED).read_text())) == {"results.parquet", "trials.csv", "trials.parquet",
                                                            "summary.csv", "summary.parquet"}


def test_overwrite_never_clears_a_folder_that_is_not_a_results_folder(tmp_path, capsys):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("precious")
    assert main(["run", "ptp", *RUN[1:], "--out", str(tmp_path / "mine"), "--overwrite"]) == 2
    assert "not a starid results folder" in capsys.readouterr().err
    assert (tmp_path / "mine" / "thesis.tex").read_text() == "precious"
    with pytest.raises(ConfigError, match="nothing deleted"):
        clear_folder(tmp_path / "mine")


def test_extend_keeps_chunks_and_retires_the_old_reports(ptp_folder, tmp_path, capsys):
    out = _copy(ptp_folder, tmp_path / "r")
    _fake_report(out)
    chunks = sorted(p.name for p in (out / "chunks").iterdir())
    exp = Experiment("run", (Study("run", ("ptp", "pvector")),), trials=6, seed=4)
    with pytest.raises(ConfigError, match="--extend"):
        claim_folder(out, exp)
    assert claim_folder(out, exp, extend=True) == "extend"
    # --extend is for the same experiment only
    with pytest.raises(ConfigError, match="holds experiment 'run'"):
        claim_folder(out, Experiment("sweep", (Study("run", ("ptp",)),), trials=6), extend=True)
    # the moment the changed definition takes the folder, what was derived from the old one goes
    Store(out, exp)
    for name in ("report.md", "figures/time.png", "results.parquet", "trials.csv", "summary.parquet"):
        assert not (out / name).exists(), name
    assert sorted(p.name for p in (out / "chunks").iterdir()) == chunks      # the chunks stay, for reuse
    assert stale_derived(out, exp.digest()) == []
    assert main(["report", str(out)]) == 2                      # nothing stale is shown as current
    assert "no results.parquet" in capsys.readouterr().err


def test_a_stale_results_file_is_refused_by_the_report(ptp_folder, tmp_path, capsys):
    """A folder whose results.parquet was recorded from another definition (a changed run killed before
    it finished, in an older layout) is refused, naming both digests."""
    out = _copy(ptp_folder, tmp_path / "r")
    data = json.loads((out / DERIVED).read_text())
    data["results.parquet"]["digest"] = "0123456789abcdef"
    (out / DERIVED).write_text(json.dumps(data))
    assert main(["report", str(out), "--format", "md"]) == 2
    err = capsys.readouterr().err
    assert "0123456789abcdef" in err and read_manifest(out)["digest"] in err


# ---------------------------------------------------------------------------------------------- show DIR --trial K

def test_show_redraws_the_image_the_folder_scored(ptp_folder, tmp_path, capsys, monkeypatch):
    """The redrawn observation is the trial the folder scored: its world (1 px noise, 2 false stars),
    camera and seed come from the manifest; star count and centroids equal a re-simulation with those
    settings, and differ from the noise-free default world ``starid show ptp --trial K`` draws."""
    import numpy as np
    import pandas as pd

    from starid import Catalog, SimConfig, Simulator
    from starid.report.show import show_folder

    k = 3
    shown, rows = show_folder(ptp_folder, k, ["ptp"])
    row = rows.iloc[0]
    exp = Experiment.from_dict(read_manifest(ptp_folder)["experiment"])
    sim = Simulator(Catalog.embedded(), exp.make_camera(), SimConfig(sigma_px=1.0, false_stars=2), seed=4)
    again = sim.generate(1, k).observation(0)
    assert len(shown.stars) == len(again) == row["n_stars"]
    assert int((shown.stars["truth_hip"] >= 0).sum()) == row["n_true_stars"]
    np.testing.assert_array_equal(shown.stars["x_px"], again.x_px)
    np.testing.assert_array_equal(shown.stars["y_px"], again.y_px)
    # the same algorithm on the same image: the same outcome as the folder recorded
    res = shown.results.iloc[0]
    assert res["folder_status"] == row["status"] == res["status"] and res["n_correct"] == row["n_correct"]
    noise_free = Simulator(Catalog.embedded(), exp.make_camera(), SimConfig(), seed=4).generate(1, k).observation(0)
    assert len(noise_free) != len(again) or not np.array_equal(noise_free.x_px, again.x_px)
    assert isinstance(rows, pd.DataFrame)
    # the command line (the redraw above reused, not recomputed): the PNG, and the folder's status in the printed
    # table; bad K / label / study exit 2
    import starid.report.show as show_module

    calls = []
    monkeypatch.setattr(show_module, "show_folder", lambda *a, **kw: calls.append(a) or (shown, rows))
    png = tmp_path / "t3.png"
    capsys.readouterr()
    assert main(["show", str(ptp_folder), "--trial", str(k), "--label", "ptp", "--out", str(png)]) == 0
    out = capsys.readouterr().out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"{len(again)} detections" in out
    assert row["status"] in out and calls[0][:3] == (ptp_folder, k, ["ptp"])
    monkeypatch.undo()
    assert main(["show", str(ptp_folder), "--trial", "6", "--out", str(png)]) == 2
    assert "holds trials 0..5" in capsys.readouterr().err
    assert main(["show", str(ptp_folder), "--trial", "1", "--label", "pvector", "--out", str(png)]) == 2
    assert "--label 'pvector'" in capsys.readouterr().err
    assert main(["show", str(ptp_folder), "--trial", "1", "--study", "nope", "--out", str(png)]) == 2
    assert main(["show", "ptp", "--trial", "1", "--label", "ptp", "--out", str(png)]) == 2
