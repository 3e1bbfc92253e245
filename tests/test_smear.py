"""Motion smear (starid.sky, starid.kernels.smear): centroids at the streak's centre, noise along it."""

import math

import numpy as np
import pytest

from starid import sky
from starid.camera import Camera
from starid.catalog import load_hipparcos
from starid.errors import ConfigError
from starid.kernels.smear import smear_noise, streak_px, streak_samples_px
from starid.render import RenderConfig, Renderer, observation_from_image
from starid.simulate import SimConfig, Simulator


@pytest.fixture(scope="module")
def catalog():
    return load_hipparcos()


def test_streak_centre_is_the_time_average_of_the_positions():
    cam = Camera()
    rng = np.random.default_rng(0)
    v = rng.normal(size=(20, 3)) * [0.05, 0.05, 0.0] + [0, 0, 1]
    v /= np.linalg.norm(v, axis=1)[:, None]
    axis = np.array([0.3, 0.8, 0.5]) / np.linalg.norm([0.3, 0.8, 0.5])
    sweep = math.radians(2.0) * 0.5            # 2 deg/s for 0.5 s: a 1 deg (~100 px) streak
    cdx, cdy, ldx, ldy = streak_px(v, axis, sweep, cam.f_px, cam.cx_px, cam.cy_px)
    dx, dy = streak_samples_px(v, axis, sweep, 4001, cam.f_px, cam.cx_px, cam.cy_px)
    assert np.allclose(cdx, dx.mean(axis=1), atol=1e-3) and np.allclose(cdy, dy.mean(axis=1), atol=1e-3)
    assert np.allclose(np.hypot(ldx, ldy), np.hypot(dx[:, -1] - dx[:, 0], dy[:, -1] - dy[:, 0]), rtol=1e-3)
    # about the boresight's perpendicular y axis, a star at the centre moves f * sweep px along x
    c = streak_px(np.array([[0.0, 0.0, 1.0]]), np.array([0.0, 1.0, 0.0]), sweep, cam.f_px, cam.cx_px, cam.cy_px)
    assert abs(c[2][0]) == pytest.approx(cam.f_px * 2 * math.tan(sweep / 2), rel=1e-9) and abs(c[3][0]) < 1e-9


def test_simulated_smeared_star_lies_on_its_streak_centre(catalog):
    cfg = SimConfig(rate_deg_s=5.0, exposure_s=0.2, rate_axis="1,0,0")
    s0, s1 = Simulator(catalog, Camera(), SimConfig(), seed=4), Simulator(catalog, Camera(), cfg, seed=4)
    a, b = s0.draw(7), s1.draw(7)
    assert np.array_equal(a[0], b[0])                       # same attitude (common random numbers)
    order_a, order_b = np.argsort(a[4]), np.argsort(b[4])
    assert np.array_equal(a[4][order_a], b[4][order_b])
    v = Camera().backproject(a[1][order_a], a[2][order_a])
    cam = Camera()
    cdx, cdy, _, _ = streak_px(v, np.array([1.0, 0.0, 0.0]), math.radians(1.0), cam.f_px, cam.cx_px, cam.cy_px)
    assert np.allclose(b[1][order_b] - a[1][order_a], cdx, atol=1e-6)
    assert np.allclose(b[2][order_b] - a[2][order_a], cdy, atol=1e-6)
    assert np.max(np.abs(cdy)) > 1e-3                       # the streak's sagitta moves the centre


def test_centroid_noise_grows_along_the_streak_only():
    n = 200_000
    rng = np.random.default_rng(1)
    zx, zy = rng.normal(size=n), rng.normal(size=n)
    length = 20.0
    ox, oy = smear_noise(zx, zy, np.full(n, length), np.zeros(n), 2.0)
    assert np.std(ox) == pytest.approx(math.sqrt(1 + length ** 2 / (12 * 4.0)), rel=0.01)
    assert np.array_equal(oy, zy)
    ox, oy = smear_noise(zx, zy, np.zeros(n), np.zeros(n), 2.0)
    assert np.array_equal(ox, zx) and np.array_equal(oy, zy)


def test_simulated_noise_grows_with_rate(catalog):
    def spread(rate):
        sim = Simulator(catalog, Camera(), SimConfig(sigma_px=0.5, rate_deg_s=rate, rate_axis="0,1,0"), seed=2)
        clean = Simulator(catalog, Camera(), SimConfig(rate_deg_s=rate, rate_axis="0,1,0"), seed=2)
        ex = []
        for t in range(40):
            a, b = sim.draw(t), clean.draw(t)
            ia, ib = np.argsort(a[4]), np.argsort(b[4])
            if np.array_equal(a[4][ia], b[4][ib]):
                ex.append(a[1][ia] - b[1][ib])
        return np.std(np.concatenate(ex))
    # 2 deg/s * 0.1 s = 0.2 deg = 20.5 px along x: noise x sqrt(1 + 20.5^2 / 48) = 3.1
    assert spread(2.0) > 2.5 * spread(0.0)


def test_exposure_resolution_and_bad_settings():
    class WithExposure:
        exposure_s = 0.25
    assert sky.exposure_s(SimConfig(), Camera()) == sky.DEFAULT_EXPOSURE_S
    assert sky.exposure_s(SimConfig(), WithExposure()) == 0.25
    assert sky.exposure_s(SimConfig(exposure_s=0.05), WithExposure()) == 0.05
    for bad in ({"rate_deg_s": -1}, {"exposure_s": -0.1}, {"rate_axis": "0,0"}, {"rate_axis": "0,0,0"}):
        with pytest.raises(ConfigError):
            SimConfig(**bad)


def test_image_smear_drops_faint_stars_and_keeps_truth_at_centre(catalog):
    def detected(rate):
        sim = Simulator(catalog, Camera(), SimConfig(rate_deg_s=rate), seed=3)
        r = Renderer(sim, RenderConfig())
        hits = [observation_from_image(sim, t, renderer=r).stats for t in range(4)]
        return sum(h["n_detected"] for h in hits), sum(h["n_detectable"] for h in hits), r
    n0, d0, _ = detected(0.0)
    n1, d1, r = detected(3.0)
    assert d0 == d1 and n1 < 0.8 * n0
    # the peak falls: a bright star's brightest pixel is lower when smeared
    sim0 = Simulator(catalog, Camera(), SimConfig(), seed=3)
    im0 = Renderer(sim0, RenderConfig()).render(0).image
    im1 = r.render(0).image
    assert int(im1.max()) < int(im0.max())
    # rendered truth is each star's streak centre: the mean of its sub-exposures
    rt = r.render(0)
    rt0 = Renderer(sim0, RenderConfig()).render(0)
    assert np.array_equal(rt.hip, rt0.hip)
    shift = np.hypot(rt.x_px - rt0.x_px, rt.y_px - rt0.y_px)
    assert np.all(shift < 0.5) and np.max(shift) > 0


def test_streak_through_a_distorted_lens_is_the_time_average_of_projected_positions():
    cam = Camera(distortion=(0.5, 0.0, 0.0, 0.0, 0.0))
    rng = np.random.default_rng(5)
    v = rng.normal(size=(10, 3)) * [0.06, 0.06, 0.0] + [0, 0, 1]
    v /= np.linalg.norm(v, axis=1)[:, None]
    axis = np.array([0.6, 0.0, 0.8])
    sweep = math.radians(1.0)
    cdx, cdy, ldx, ldy = sky.streak_offsets_px(v, axis, sweep, cam)
    dx, dy = sky.streak_sample_offsets_px(v, axis, sweep, 2001, cam)
    assert np.allclose(cdx, dx.mean(axis=1), atol=1e-3) and np.allclose(cdy, dy.mean(axis=1), atol=1e-3)
    # the pinhole streak differs where the lens distorts (the test fails if the lens is ignored)
    pin = streak_px(v, axis, sweep, cam.f_px, cam.cx_px, cam.cy_px)
    assert np.max(np.abs(np.hypot(ldx, ldy) - np.hypot(pin[2], pin[3]))) > 0.5
