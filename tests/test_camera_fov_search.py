"""The field-of-view search of ``starid identify`` (#23): it keeps the camera's distortion, and
``--fov-range MIN:MAX`` on centroid files (a wrong field of view found) and its bad input."""

import numpy as np
import pandas as pd
import pytest

from starid import Camera, SimConfig, Simulator, harness, load_hipparcos
from starid.cli import main
from starid.cli.images import _with_f, range_scales, solve_image
from starid.registry import get_algorithm

LENS = Camera(distortion=(0.5, 0.01, 1e-4, -2e-4, 0.0), cx_px=515.0, cy_px=509.0, name="lens", source="test")


@pytest.fixture(scope="module")
def catalog():
    return load_hipparcos()


def test_rescaling_the_focal_length_keeps_everything_else():
    cam = _with_f(LENS, LENS.f_px * 1.03)
    assert cam.f_px == pytest.approx(LENS.f_px * 1.03)
    assert cam.distortion == LENS.distortion                      # dropped before the fix
    assert (cam.width_px, cam.height_px, cam.pixel_um, cam.cx_px, cam.cy_px, cam.name, cam.source) == \
        (LENS.width_px, LENS.height_px, LENS.pixel_um, LENS.cx_px, LENS.cy_px, LENS.name, LENS.source)


def test_search_on_a_distorted_camera_refines_the_true_focal_length(catalog):
    """A k1 = 0.5 lens given 2 % off: the search lands on the distorted camera and the refined focal
    length is the true one (the fit on undistorted positions)."""
    trials = Simulator(catalog, LENS, SimConfig(), seed=5).generate(2)
    guess = _with_f(LENS, LENS.f_px * 1.02)
    prepared = harness.prepare(get_algorithm("pvector")(), catalog, guess, None)
    for i in range(len(trials)):
        o = trials.observation(i)
        obs = type(o)(o.x_px, o.y_px, o.mag, guess)
        hip, cam, attitude, resid, error = solve_image(prepared, obs, catalog)
        assert not error and attitude is not None
        assert cam.distortion == LENS.distortion and (cam.cx_px, cam.cy_px) == (LENS.cx_px, LENS.cy_px)
        assert cam.f_px == pytest.approx(LENS.f_px, rel=2e-4)
        ok = hip != -1
        assert ok.sum() >= 3 and (hip[ok] == o.truth_hip[ok]).all()


def test_range_scales_cover_the_range_from_the_given_focal_length():
    cam = Camera.from_fov(10.0)
    scales = range_scales(cam, (9.0, 12.0))
    assert scales[0] == 1.0
    fovs = [_with_f(cam, cam.f_px * s).fov_x_deg for s in scales]
    assert min(fovs) >= 9.0 - 1e-9 and max(fovs) <= 12.0 + 1e-9
    assert min(fovs) < 9.05 and max(fovs) > 11.93
    outside = range_scales(cam, (20.0, 30.0))                     # the given one out of range: its middle
    assert 20.0 <= _with_f(cam, cam.f_px * outside[0]).fov_x_deg <= 30.0


@pytest.fixture(scope="module")
def obs_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("obs") / "obs.csv"
    assert main(["simulate", "--trials", "2", "--seed", "3", "--out", str(path)]) == 0
    return path


def test_fov_range_on_centroid_files_finds_a_wrong_field_of_view(obs_csv, tmp_path):
    """10 deg centroids given as 10.4 deg: no search, nothing; --fov-range 9.8:10.6, every image."""
    assert main(["identify", "pvector", str(obs_csv), "--fov-deg", "10.4", "--out", str(tmp_path / "a"),
                 "--quiet"]) == 0
    assert (pd.read_csv(tmp_path / "a" / "trials.csv")["status"] != "correct").all()
    assert main(["identify", "pvector", str(obs_csv), "--fov-deg", "10.4", "--fov-range", "9.8:10.6",
                 "--out", str(tmp_path / "b"), "--quiet"]) == 0
    rows = pd.read_csv(tmp_path / "b" / "trials.csv")
    assert (rows["status"] == "correct").all() and np.isfinite(rows["time_us"]).all()


@pytest.mark.parametrize("text, named", [("12:9", "MIN must be below MAX"), ("a:b", "MIN:MAX"), ("9", "MIN:MAX"),
                                         ("-1:9", "above 0"), ("9:nan", "above 0"), ("0:9", "above 0")])
def test_bad_fov_range_is_exit_2_naming_the_flag(obs_csv, tmp_path, capsys, text, named):
    assert main(["identify", "pyramid", str(obs_csv), f"--fov-range={text}", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "--fov-range" in err and named in err
    assert not (tmp_path / "x").exists()
