"""Damaged results folders (issue #26): a truncated or corrupted chunk is reported, set aside and recomputed."""

import json
import shutil

import pandas as pd
import pytest

from starid.errors import ConfigError, StarIDWarning
from starid.experiment import Experiment, Study, Variant, run_experiment, runner
from starid.experiment.store import CHECKSUMS, damaged_chunks, file_sha256
from starid.report.build import load

TIMES = ["time_us", "build_s", "compile_s"]


def _experiment():
    return Experiment("damaged", (Study("s", (Variant("ptp"),)),), trials=60, seed=5)


def _run(out, monkeypatch):
    monkeypatch.setattr(runner, "BLOCK", 20)        # 3 chunks of 20 trials
    return run_experiment(_experiment(), out, jobs=1, progress=False)


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """One uninterrupted run (3 chunks), kept as a template folder."""
    mp = pytest.MonkeyPatch()
    try:
        out = tmp_path_factory.mktemp("store") / "whole"
        frame = _run(out, mp)
    finally:
        mp.undo()
    return out, frame


def _same(a: pd.DataFrame, b: pd.DataFrame) -> None:
    pd.testing.assert_frame_equal(a.drop(columns=TIMES), b.drop(columns=TIMES))


def test_the_manifest_holds_every_chunk_checksum(finished):
    out, _ = finished
    manifest = json.loads((out / "manifest.json").read_text())
    assert len(manifest["chunks"]) == 3
    assert manifest[CHECKSUMS] == {k: file_sha256(out / "chunks" / f"{k}.parquet") for k in manifest["chunks"]}
    assert damaged_chunks(out) == []


def test_truncated_and_corrupted_chunks_are_set_aside_and_recomputed(finished, tmp_path, monkeypatch):
    template, whole = finished
    out = tmp_path / "out"
    shutil.copytree(template, out)
    keys = json.loads((out / "manifest.json").read_text())["chunks"]
    first, second = (out / "chunks" / f"{k}.parquet" for k in keys[:2])
    first.write_bytes(first.read_bytes()[: first.stat().st_size // 2])        # truncated (a full disk)
    data = bytearray(second.read_bytes())
    data[len(data) // 2] ^= 0xFF                                               # one byte flipped, same size
    second.write_bytes(bytes(data))
    (out / "results.parquet").unlink()
    # the report names the damaged chunks instead of failing on them
    with pytest.raises(ConfigError, match=rf"2 damaged chunk\(s\).*{keys[0]}\.parquet \(checksum mismatch"):
        load(out)
    assert [k for k, _ in damaged_chunks(out)] == keys[:2]
    with pytest.warns(StarIDWarning) as record:
        frame = _run(out, monkeypatch)
    lines = [str(w.message) for w in record if "damaged" in str(w.message)]
    assert len(lines) == 2 and all("set aside" in line and "\n" not in line for line in lines)
    assert sorted(p.name for p in (out / "chunks").glob("*.damaged")) == sorted(f"{k}.parquet.damaged"
                                                                              for k in keys[:2])
    _same(frame, whole)
    _same(pd.read_parquet(out / "results.parquet"), whole)
    assert damaged_chunks(out) == []
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["computed_chunks"] == 2 and manifest["reused_chunks"] == 1


def test_a_chunk_without_checksum_must_read(finished, tmp_path, monkeypatch):
    """A chunk written before the manifest caught up (a killed run) has no checksum: it is kept when it
    reads as Parquet, set aside when it does not."""
    template, whole = finished
    out = tmp_path / "out"
    shutil.copytree(template, out)
    manifest = json.loads((out / "manifest.json").read_text())
    keys = manifest["chunks"]
    manifest[CHECKSUMS] = {}
    (out / "manifest.json").write_text(json.dumps(manifest))
    bad = out / "chunks" / f"{keys[2]}.parquet"
    bad.write_bytes(bad.read_bytes()[:100])
    assert damaged_chunks(out) == [(keys[2], damaged_chunks(out)[0][1])]
    assert "unreadable" in damaged_chunks(out)[0][1]
    with pytest.warns(StarIDWarning, match=rf"chunk {keys[2]} .* damaged: unreadable"):
        frame = _run(out, monkeypatch)
    _same(frame, whole)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["computed_chunks"] == 1 and set(manifest[CHECKSUMS]) == set(keys)
