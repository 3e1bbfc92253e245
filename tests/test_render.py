"""starid.render: rendered trials (determinism, photometry, PSF position, noise, saturation) and
the render -> extract -> truth-matching chain."""

import math

import numpy as np
import pytest

from starid import Camera, ConfigError, SimConfig, Simulator
from starid.render import (
    RenderConfig,
    Renderer,
    image_trials,
    match_radius,
    match_truth,
    observation_from_image,
    render_image,
    summarize_stats,
)


@pytest.fixture(scope="module")
def sim(catalog):
    return Simulator(catalog, Camera(), SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=5)


@pytest.fixture(scope="module")
def renderer(sim):
    return Renderer(sim)


def test_same_seed_and_trial_same_image(sim, renderer, catalog):
    a, b = renderer.render(3), Renderer(Simulator(catalog, Camera(), sim.config, seed=5)).render(3)
    assert a.image.dtype == np.uint16 and a.image.shape == (1024, 1024)
    assert np.array_equal(a.image, b.image)
    assert not np.array_equal(a.image, renderer.render(4).image)
    assert not np.array_equal(a.image, Renderer(Simulator(catalog, Camera(), sim.config, seed=6)).render(3).image)
    # the simulator's attitude for (seed, trial)
    assert np.allclose(a.attitude, sim.draw(3)[0])


def test_flux_and_position_of_one_star():
    cfg = RenderConfig(sky_e_per_px=0.0, read_noise_e=0.0, bias_adu=0.0, full_well_e=1e9)
    signal = 40000.0
    img = render_image(np.array([30.25]), np.array([20.75]), np.array([signal]), 64, 48, cfg,
                       np.random.default_rng(0)).astype(float)
    assert img.shape == (48, 64)
    assert abs(img.sum() - signal) < 5 * math.sqrt(signal)       # Poisson total
    yy, xx = np.indices(img.shape)
    # pixel j covers [j, j + 1): its centre is j + 0.5
    assert abs((img * (xx + 0.5)).sum() / img.sum() - 30.25) < 0.02
    assert abs((img * (yy + 0.5)).sum() / img.sum() - 20.75) < 0.02
    var_x = (img * (xx + 0.5 - 30.25) ** 2).sum() / img.sum()
    assert abs(math.sqrt(var_x - 1 / 12) - cfg.psf_sigma_px) < 0.05   # pixel-integrated Gaussian


def test_background_noise_saturation_and_hot_pixels():
    cfg = RenderConfig(sky_e_per_px=100.0, read_noise_e=10.0, bias_adu=200.0, full_well_e=5000.0, hot_pixels=7,
                       hot_pixel_e=3000.0)
    img = render_image(np.array([50.0]), np.array([50.0]), np.array([1e7]), 100, 100, cfg,
                       np.random.default_rng(1)).astype(float)
    sky = img[:, :20]
    assert abs(np.median(sky) - 300.0) < 2.0
    assert abs(sky.std() - math.sqrt(100 + 100)) < 1.0 or (sky > 2000).any()   # a hot pixel may land here
    assert img.max() == 200 + 5000                                             # full well
    assert (img == 5200).sum() > 20                                            # a saturated core
    hot = render_image(np.zeros(0), np.zeros(0), np.zeros(0), 100, 100, cfg, np.random.default_rng(1))
    assert (hot > 2000).sum() == 7


def test_eight_bit_and_config_checks():
    cfg = RenderConfig(bits=8, gain_e_per_adu=20.0, bias_adu=10.0)
    img = render_image(np.array([20.0]), np.array([20.0]), np.array([1e6]), 40, 40, cfg, np.random.default_rng(0))
    assert img.dtype == np.uint8 and img.max() == 255
    for bad in ({"psf_sigma_px": 0}, {"exposure_s": -1}, {"bits": 12}, {"hot_pixels": -1}, {"read_noise_e": -1.0},
                {"zero_point_mag": float("nan")}):
        with pytest.raises(ConfigError):
            RenderConfig(**bad)
    assert RenderConfig().adu_zero_point_mag == pytest.approx(16.9 + 2.5 * math.log10(0.1))


def test_match_truth_brightest_first_one_to_one():
    det_x, det_y = np.array([10.0, 10.5, 50.0, 80.0]), np.array([10.0, 10.0, 50.0, 80.0])
    true_x, true_y, hip = np.array([10.4, 51.0, 90.0]), np.array([10.0, 51.5, 90.0]), np.array([7, 8, 9])
    # the brighter detection (flux) takes the star both are near; the other is false
    truth, row = match_truth(det_x, det_y, true_x, true_y, hip, flux=np.array([1.0, 5.0, 1.0, 1.0]))
    assert truth.tolist() == [-1, 7, 8, -1] and row.tolist() == [-1, 0, 1, -1]
    truth, _ = match_truth(det_x, det_y, true_x, true_y, hip, flux=np.array([5.0, 1.0, 1.0, 1.0]))
    assert truth.tolist() == [7, -1, 8, -1]
    # a blend: the brighter of two stars within the radius, as the simulator merges them
    truth, _ = match_truth(np.array([20.0]), np.array([20.0]), np.array([20.1, 20.8]), np.array([20.0, 20.0]),
                           np.array([1, 2]), true_mag=np.array([7.5, 5.0]))
    assert truth.tolist() == [2]
    assert match_truth(np.zeros(0), np.zeros(0), np.ones(1), np.ones(1), np.ones(1))[0].size == 0


def test_match_radius_widens_at_the_edges():
    r = match_radius(np.array([1.0, 500.0, 1020.0]), np.array([500.0, 500.0, 500.0]), Camera(), 2.0, 2.0)
    assert r.tolist() == [8.0, 2.0, 8.0]


def test_observation_from_image_matches_truth(sim, renderer):
    it = observation_from_image(sim, 2, renderer=renderer)
    obs, st = it.observation, it.stats
    assert len(obs) >= 6 and obs.truth_hip is not None
    assert (obs.truth_hip >= 0).mean() > 0.9
    # the matched detections sit on their true stars to a fraction of a pixel, brightest first
    assert math.sqrt(st["sq_err_px2_sum"] / st["n_matched"]) < 0.5
    assert np.all(np.diff(it.flux) <= 0)
    assert st["n_detected"] >= 0.8 * st["n_detectable"]
    # calibrated magnitudes: the catalog's within a few tenths
    rows = match_truth(obs.x_px, obs.y_px, it.rendered.x_px, it.rendered.y_px, it.rendered.hip)[1]
    ok = rows >= 0
    assert np.median(np.abs(obs.mag[ok] - it.rendered.v_mag[rows[ok]])) < 0.2


def test_image_trials_feed_the_harness(sim, catalog):
    from starid import get_algorithm, run

    trials, stats = image_trials(sim, 4, start=10)
    assert len(trials) == 4 and trials.trial.tolist() == [10, 11, 12, 13] and len(stats) == 4
    assert trials.warmup is not None and np.allclose(trials.attitude[1], sim.draw(11)[0])
    summary = summarize_stats(stats)
    assert summary["detection_rate"] > 0.8 and summary["rms_centroid_err_px"] < 0.5
    rows = run([get_algorithm("ptp")()], trials, catalog, sim)
    assert (rows["status"] == "correct").sum() >= 3
