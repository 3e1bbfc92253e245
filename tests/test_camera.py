import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from starid import Camera, ConfigError


def test_default_camera_is_table4(camera):
    assert (camera.width_px, camera.height_px, camera.cx_px, camera.cy_px) == (1024, 1024, 512, 512)
    assert camera.fov_x_deg == pytest.approx(10.0, abs=0.01)
    assert camera.f_px == pytest.approx(70.2262e3 / 12.0)


def test_boresight_lands_on_principal_point(camera):
    x, y = camera.project(np.array([[0.0, 0.0, 1.0]]))
    assert (x[0], y[0]) == (512.0, 512.0)


def test_axes_convention(camera):
    x, y = camera.project(np.array([[0.01, 0.0, 1.0], [0.0, 0.01, 1.0]]))
    assert x[0] > 512 and y[0] == 512      # +x to the right
    assert y[1] > 512 and x[1] == 512      # +y downwards


@settings(max_examples=200, deadline=None)
@given(st.floats(0, 1023.999), st.floats(0, 1023.999))
def test_backproject_then_project_is_identity(x, y):
    cam = Camera()
    v = cam.backproject(np.array([x]), np.array([y]))
    assert np.linalg.norm(v) == pytest.approx(1.0)
    x2, y2 = cam.project(v)
    assert x2[0] == pytest.approx(x, abs=1e-9) and y2[0] == pytest.approx(y, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.floats(-0.08, 0.08), st.floats(-0.08, 0.08))
def test_project_then_backproject_is_identity(vx, vy):
    cam = Camera()
    v = np.array([[vx, vy, 1.0]])
    v /= np.linalg.norm(v)
    x, y = cam.project(v)
    assert np.allclose(cam.backproject(x, y), v, atol=1e-12)


def test_from_fov():
    cam = Camera.from_fov(20.0, 2048)
    assert cam.fov_x_deg == pytest.approx(20.0)
    assert cam.width_px == 2048
    assert cam.half_diagonal_rad == pytest.approx(math.atan(math.sqrt(2) * math.tan(math.radians(10))))


@pytest.mark.parametrize("kwargs", [{"width_px": 0}, {"focal_mm": -1.0}, {"pixel_um": float("nan")}])
def test_invalid_camera(kwargs):
    with pytest.raises(ConfigError):
        Camera(**kwargs)


def test_pixel_ratio_and_solid_angle():
    import math

    from starid.camera import REFERENCE_CAMERA

    assert Camera().pixel_ratio == 1.0 and REFERENCE_CAMERA == Camera()
    wide = Camera.from_fov(20.0, 1024)
    assert wide.pixel_ratio == pytest.approx(math.tan(math.radians(10)) / math.tan(math.radians(5)), rel=1e-6)
    assert Camera.from_fov(90.0, 1000).solid_angle_sr == pytest.approx(4 * math.pi / 6, rel=1e-12)  # a cube face
    # off-centre principal point: the two halves of a sensor add up to the whole
    half = dict(width_px=500, height_px=1000, cx_px=500.0, cy_px=500.0)
    left, right = Camera(**half), Camera(**{**half, "cx_px": 0.0})
    whole = Camera(width_px=1000, height_px=1000).solid_angle_sr
    assert left.solid_angle_sr + right.solid_angle_sr == pytest.approx(whole,
                                                                       rel=1e-12)
