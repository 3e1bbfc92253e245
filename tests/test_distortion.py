"""Lens distortion (OpenCV model), the undistorted plugin frame, and true versus assumed cameras."""

import numpy as np
import pytest

from starid import Camera, ConfigError, SimConfig, Simulator
from starid.kernels import backproject_px, project_cam
from starid.kernels.distortion import distort_norm, undistort_norm

LENSES = [
    Camera(distortion=(0.5, 0.0, 0.0, 0.0, 0.0)),                                   # the k1 = 0.5
    Camera(distortion=(-0.3, 0.1, 1e-3, -2e-3, 0.05)),                              # every coefficient
    Camera(1280, 1024, 4.8, 8.0, 650.0, 500.0, (-0.25, 0.08, 5e-4, 3e-4, -0.01)),   # wide, strong barrel
]


def _opencv_forward(x, y, k1, k2, p1, p2, k3):
    """OpenCV's documented equations, written out independently of the kernel."""
    r2 = x ** 2 + y ** 2
    radial = 1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3
    return (x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x ** 2),
            y * radial + p1 * (r2 + 2 * y ** 2) + 2 * p2 * x * y)


@pytest.mark.parametrize("cam", LENSES)
def test_forward_model_is_opencv(cam):
    rng = np.random.default_rng(0)
    for x, y in rng.uniform(-0.3, 0.3, (50, 2)):
        assert distort_norm(x, y, *cam.distortion) == pytest.approx(_opencv_forward(x, y, *cam.distortion), abs=1e-15)


@pytest.mark.parametrize("cam", LENSES)
def test_undistortion_inverts_the_forward_model_over_the_whole_sensor(cam):
    xs, ys = np.meshgrid(np.linspace(0, cam.width_px, 41), np.linspace(0, cam.height_px, 41))
    x, y = xs.ravel(), ys.ravel()
    v = cam.backproject(x, y)
    assert np.allclose(np.linalg.norm(v, axis=1), 1.0)
    x2, y2 = cam.project(v)
    assert np.max(np.hypot(x2 - x, y2 - y)) < 1e-3
    # and the frame a plugin sees: the same directions through the pinhole frame
    ux, uy = cam.undistort(x, y)
    frame = cam.pinhole_frame
    assert not frame.distorted and frame.in_image(ux, uy).all()
    assert np.allclose(frame.backproject(ux, uy), v, atol=1e-12)


def test_newton_on_a_single_point():
    x, y = undistort_norm(*_opencv_forward(0.1, -0.07, 0.5, 0.0, 0.0, 0.0, 0.0), 0.5, 0.0, 0.0, 0.0, 0.0)
    assert (x, y) == pytest.approx((0.1, -0.07), abs=1e-14)


def test_zero_distortion_is_the_pinhole_bit_for_bit(camera):
    rng = np.random.default_rng(1)
    v = rng.normal(size=(200, 3)) * [0.05, 0.05, 0.0] + [0, 0, 1]
    x, y = camera.project(v)
    x0, y0 = project_cam(np.ascontiguousarray(v), camera.f_px, camera.cx_px, camera.cy_px)
    assert np.array_equal(x, x0) and np.array_equal(y, y0)
    assert np.array_equal(camera.backproject(x, y), backproject_px(x, y, camera.f_px, camera.cx_px, camera.cy_px))
    assert camera.pinhole_frame is camera


def test_k1_moves_the_corner_outwards():
    pin, lens = Camera(), Camera(distortion=(0.5, 0, 0, 0, 0))
    v = pin.backproject(np.array([0.0]), np.array([0.0]))
    x, y = lens.project(v)
    assert x[0] < -3.0 and y[0] < -3.0                 # pincushion: the corner leaves the sensor by ~3.9 px


def test_bad_distortion_is_refused():
    with pytest.raises(ConfigError, match="distortion"):
        Camera(distortion=(0.1, 0.2))
    with pytest.raises(ConfigError, match="k2"):
        Camera(distortion=(0.1, float("nan"), 0, 0, 0))


def test_plugin_sees_undistorted_centroids_in_a_pinhole_frame(catalog):
    lens = LENSES[0]
    sim = Simulator(catalog, lens, SimConfig(), seed=3)
    obs = sim.observation(0)
    view = obs.for_plugin()
    assert view.camera == lens.pinhole_frame and not view.camera.distorted
    assert np.allclose(view.unit_cam(), obs.unit_cam(), atol=1e-12)
    assert not np.allclose(view.x_px, obs.x_px)


def test_true_versus_assumed_camera_keeps_common_random_numbers(catalog):
    lens = LENSES[0]
    base = Simulator(catalog, lens, SimConfig(sigma_px=0.5), seed=2).generate(5)
    for cfg, check in [(SimConfig(sigma_px=0.5, assumed_distortion="none"), lambda c: not c.distorted),
                       (SimConfig(sigma_px=0.5, focal_error_pct=2.0),
                        lambda c: c.focal_mm == pytest.approx(lens.focal_mm * 1.02)),
                       (SimConfig(sigma_px=0.5, principal_point_error_px=2.0),
                        lambda c: np.hypot(c.cx_px - lens.cx_px, c.cy_px - lens.cy_px) == pytest.approx(2.0))]:
        other = Simulator(catalog, lens, cfg, seed=2).generate(5)
        assert np.array_equal(other.x_px, base.x_px) and np.array_equal(other.attitude, base.attitude)
        assert check(other.camera) and other.true_camera == lens
    with pytest.raises(ConfigError, match="assumed_distortion"):
        SimConfig(assumed_distortion="maybe")


def test_calibrated_distortion_round_trip_keeps_the_id_rate(catalog):
    """k1 = 0.5 on the 10 deg camera, identified with the calibration: within 1 point of no lens."""
    from starid import harness
    from starid.registry import get_algorithm

    rates = {}
    for name, cam in [("pinhole", Camera()), ("lens", LENSES[0])]:
        sim = Simulator(catalog, cam, SimConfig(sigma_px=0.5), seed=5)
        df = harness.run([get_algorithm("ptp")()], sim.generate(100), catalog, sim)
        rates[name] = (df["status"] == "correct").mean()
    assert abs(rates["lens"] - rates["pinhole"]) <= 0.01
