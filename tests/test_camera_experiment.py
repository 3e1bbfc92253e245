"""``starid reproduce cameras`` (#23): its parts (one per true camera), the joined frame, its tables,
and the CLI path; on few trials with one fast plugin."""

import dataclasses

import pandas as pd
import pytest

from starid.cameras import load_camera
from starid.experiment import run_experiment
from starid.experiments import MODULES, cameras


def test_k1_moves_the_corner_by_the_shift():
    for name in ("table4", "cubesat_wide"):
        cam = load_camera(name)
        k1 = cameras.k1_for_corner_shift(cam, 10.0)
        lens = cam.replace(distortion=(k1, 0.0, 0.0, 0.0, 0.0))
        pin = cam.backproject([0.0], [0.0])
        x, y = lens.project(pin)
        assert ((x[0] - 0.0) ** 2 + (y[0] - 0.0) ** 2) ** 0.5 == pytest.approx(10.0, rel=1e-9)


def test_parts_cover_the_issue_and_each_has_one_camera():
    assert "cameras" in MODULES
    parts = cameras.parts(10, 0, algos=("pyramid",))
    names = [e.name for e, _ in parts]
    assert len(set(names)) == len(names)
    finals = {final for _, join in parts for final, _ in join.values()}
    assert finals == {"distortion_table4", "distortion_table4_calibrated", "distortion_cubesat_wide",
                      "distortion_cubesat_wide_calibrated", "focal", "roundtrip", "presets"}
    presets = {e.make_camera().name for e, join in parts if any(f == "presets" for f, _ in join.values())}
    assert presets == set(cameras.PRESETS)
    rt = next(e for e, _ in parts if e.name == "cameras-roundtrip").make_camera()
    assert rt.distortion[0] == cameras.ROUNDTRIP_K1 and rt.fov_x_deg == pytest.approx(10.0)
    whole = cameras.experiment(10, 0)
    assert {s.name for s in whole.studies} == finals


@pytest.fixture(scope="module")
def joined():
    """The Table 4 part at 0 px (without the focal and preset studies) and the round trip, 6 trials,
    pvector (the fastest build)."""
    keep = {"cameras-table4-0px", "cameras-roundtrip"}
    pieces = []
    for e, j in cameras.parts(6, 0, algos=("pvector",)):
        if e.name in keep:
            e = dataclasses.replace(e, studies=tuple(s for s in e.studies if s.name not in ("focal", "preset")))
            pieces.append((e, j, run_experiment(e, None, jobs=1, progress=False)))
    return cameras.join_frames(pieces)


def test_joined_frame_and_tables(joined):
    frame = joined
    d = frame[frame["study"] == "distortion_table4"]
    cal = frame[frame["study"] == "distortion_table4_calibrated"]      # its 0 px point: the same rows
    assert d["grid_corner_shift_px"].tolist() == cal["grid_corner_shift_px"].tolist() == [0.0] * 6
    assert d["status"].tolist() == cal["status"].tolist()
    rt = frame[frame["study"] == "roundtrip"]
    assert sorted(rt["point"].unique()) == [0, 1] and sorted(set(rt["trial"])) == sorted(set(d["trial"]))
    assert set(frame.loc[frame["study"] == "roundtrip", "lens"]) == {"k1 = 0.5, calibrated",
                                                                      "k1 = 0.5, pinhole assumed"}
    assert frame["grid_assumed_distortion"].isna().all()
    tables = {t.name: t for t in cameras.tables(frame, cameras.experiment(6, 0))}
    assert {"cameras_distortion_table4", "cameras_distortion_table4_calibrated", "cameras_roundtrip"} <= set(tables)
    text = tables["cameras_roundtrip"].markdown
    assert "within 1 pt" in text and "loss uncalibrated" in text
    s = tables["cameras_roundtrip"].frame
    by = s.set_index("lens")["id_rate"]
    assert by["undistorted"] >= 0.8 and abs(by["k1 = 0.5, calibrated"] - by["undistorted"]) <= 1 / 6 + 1e-9
    assert isinstance(frame, pd.DataFrame) and frame["point"].dtype.kind == "i"
