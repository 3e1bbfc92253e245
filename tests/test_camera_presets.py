"""Camera presets, camera files, --camera with overrides, --resolution WxH, and the camera in results (#23)."""

import json

import numpy as np
import pandas as pd
import pytest

from starid import Camera, ConfigError, SimConfig, Simulator, harness
from starid.cameras import load_camera, preset_names
from starid.cli import main
from starid.cli.options import resolution_type
from starid.registry import get_algorithm

REQUIRED_PRESETS = {"table4", "luo2015", "tetra3_test"}


def test_presets_load_and_are_listed(capsys):
    names = preset_names()
    assert len(names) >= 6 and REQUIRED_PRESETS <= set(names)
    assert load_camera("table4") == Camera(name=load_camera("table4").name, source=load_camera("table4").source)
    tetra = load_camera("tetra3_test")
    assert (tetra.width_px, tetra.height_px) == (1024, 768) and tetra.fov_x_deg == pytest.approx(11.4, abs=0.01)
    for name in names:
        cam = load_camera(name)
        assert cam.name == name and cam.source            # every preset says where it comes from
    assert main(["cameras"]) == 0
    lines = capsys.readouterr().out.splitlines()
    listed = {line.split()[0] for line in lines[1:]}
    assert listed == set(names)
    row = next(line for line in lines if line.startswith("tetra3_test "))
    assert "1024x768" in row and "11.40 x" in row
    assert main(["cameras", "tetra3_test"]) == 0
    assert "focal_mm     61.5549" in capsys.readouterr().out


def _write(path, body: str):
    path.write_text("[camera]\n" + body)
    return path


def test_camera_file_round_trip(tmp_path):
    cam = Camera(800, 600, 5.5, 20.0, 401.5, 299.0, (-0.1, 0.02, 1e-4, -2e-4, 0.0), "mine", "a datasheet", 0.2)
    body = "\n".join(f"{k} = {json.dumps(v)}" for k, v in cam.spec().items()) + "\n"
    assert load_camera(_write(tmp_path / "c.toml", body)) == cam


@pytest.mark.parametrize("body, named", [
    ("width_px = 10\nheight_px = 10\npixel_um = 5\nfocal_mm = 5\nfocal_length = 3\n", "focal_length"),
    ("width_px = 'big'\nheight_px = 10\npixel_um = 5\nfocal_mm = 5\n", "width_px"),
    ("width_px = 10\nheight_px = 10\npixel_um = 5\nfocal_mm = 5\ndistortion = [0.1]\n", "distortion"),
    ("width_px = 10\nheight_px = 10\npixel_um = 5\n", "focal_mm"),
])
def test_bad_camera_file_is_exit_2_naming_the_key(tmp_path, capsys, body, named):
    path = _write(tmp_path / "bad.toml", body)
    with pytest.raises(ConfigError, match=named):
        load_camera(path)
    for argv in (["cameras", str(path)], ["simulate", "--camera", str(path), "--trials", "1",
                                           "--out", str(tmp_path / "o.csv")]):
        assert main(argv) == 2
        assert named in capsys.readouterr().err
    assert not (tmp_path / "o.csv").exists()
    assert main(["cameras", "no_such_camera"]) == 2 and "no_such_camera" in capsys.readouterr().err


def test_resolution_type():
    assert resolution_type("1024") == (1024, 1024)
    assert resolution_type("1024x768") == (1024, 768) and resolution_type("640X480") == (640, 480)
    for bad in ("1024x", "axb", "1x2x3"):
        with pytest.raises(Exception, match="WIDTHxHEIGHT"):
            resolution_type(bad)


@pytest.fixture(scope="module")
def preset_run(tmp_path_factory):
    """``run`` with a preset and overriding options: one tiny results folder for the next test."""
    out = tmp_path_factory.mktemp("preset_run")
    assert main(["run", "pvector", "--trials", "2", "--camera", "tetra3_test", "--resolution", "900x700",
                 "--focal-mm", "50", "--jobs", "1", "--quiet", "--out", str(out)]) == 0
    return out


def test_camera_options_override_the_preset_and_results_record_the_camera(preset_run):
    expected = Camera(900, 700, 12.0, 50.0, name="tetra3_test", source=load_camera("tetra3_test").source)
    rows = pd.read_csv(preset_run / "trials.csv")
    for key, value in expected.as_dict().items():
        assert (rows[f"camera_{key}"] == value).all(), key
    assert json.loads((preset_run / "manifest.json").read_text())["camera"] == expected.as_dict()


@pytest.fixture(scope="module")
def rectangular_obs(tmp_path_factory, catalog):
    """12 images of a 1024 x 768 sensor (10 deg across), as an OBS.csv, and their trial set."""
    sensor = Camera(width_px=1024, height_px=768)
    trials = Simulator(catalog, sensor, SimConfig(sigma_px=0.5), seed=7).generate(12)
    path = tmp_path_factory.mktemp("rect") / "obs.csv"
    rows = [pd.DataFrame({"trial": i, "x_px": o.x_px, "y_px": o.y_px, "mag": o.mag, "truth_hip": o.truth_hip})
            for i, o in ((i, trials.observation(i)) for i in range(len(trials)))]
    pd.concat(rows, ignore_index=True).to_csv(path, index=False)
    return path, trials


def test_rectangular_sensor_identifies_as_through_the_api(rectangular_obs, catalog, tmp_path):
    """Done when: --resolution 1024x768 gives exactly the Python API's identifications with the true
    sensor; the square 1024 px sensor does not (p-vector's whole-image pass expects stars in rows
    768..1023 that do not exist, and the principal point is 128 px off)."""
    path, trials = rectangular_obs
    api = harness.run([get_algorithm("pvector")()], trials, catalog, keep_ids=True)
    got = {}
    for res in ("1024x768", "1024"):
        out = tmp_path / res
        assert main(["identify", "pvector", str(path), "--resolution", res, "--out", str(out), "--quiet"]) == 0
        ids = pd.read_csv(out / "identifications.csv")
        got[res] = [ids.loc[ids["trial"] == i, "hip"].to_numpy() for i in range(len(trials))]
        rows = pd.read_csv(out / "trials.csv")
        assert (rows["camera_width_px"] == 1024).all()
        assert (rows["camera_height_px"] == int(res.split("x")[-1])).all()
    assert all(np.array_equal(g, np.asarray(a)) for g, a in zip(got["1024x768"], api["ids"], strict=True))
    assert not all(np.array_equal(g, np.asarray(a)) for g, a in zip(got["1024"], api["ids"], strict=True))
