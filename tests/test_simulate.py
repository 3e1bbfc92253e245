import numpy as np
import pytest

from starid import Catalog, ConfigError, SimConfig, Simulator


def test_trial_reproducible_from_seed_and_index(catalog):
    sim = Simulator(catalog, config=SimConfig(sigma_px=1, sigma_mag=0.5, false_stars=1), seed=7)
    batch = sim.generate(5)
    again = Simulator(catalog, config=SimConfig(sigma_px=1, sigma_mag=0.5, false_stars=1), seed=7)
    one = again.observation(3)
    obs3 = batch.observation(3)
    assert np.array_equal(one.x_px, obs3.x_px) and np.array_equal(one.truth_hip, obs3.truth_hip)
    other = Simulator(catalog, config=SimConfig(sigma_px=1, sigma_mag=0.5, false_stars=1), seed=8).observation(3)
    assert not np.array_equal(other.x_px[:3], one.x_px[:3])


def test_generate_start_offset(catalog):
    sim = Simulator(catalog, seed=1)
    a = sim.generate(4)
    b = sim.generate(2, start=2)
    assert np.array_equal(a.observation(2).x_px, b.observation(0).x_px)
    assert b.trial.tolist() == [2, 3]


def test_noise_free_positions_are_exact_projections(catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(merge_radius_px=0.0), seed=3)
    attitude, x, y, mag, hip, _ = sim.draw(0)
    rows = catalog.index_of(hip)
    assert (rows >= 0).all()
    x2, y2 = camera.project(catalog.unit_icrs[rows] @ attitude.T)
    assert np.allclose(x, x2) and np.allclose(y, y2)
    assert np.allclose(mag, catalog.v_mag[rows])
    assert len(hip) == len(set(hip.tolist()))


def test_every_visible_guide_star_is_detected(catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(merge_radius_px=0.0), seed=4)
    attitude, x, y, mag, hip, _ = sim.draw(5)
    v = catalog.unit_icrs @ attitude.T
    front = v[:, 2] > 0
    px, py = camera.project(v[front])
    visible = camera.in_image(px, py) & (catalog.v_mag[front] <= 6.0)
    assert set(catalog.hip[front][visible].tolist()) == set(hip.tolist())


def test_min_stars_filter_and_redraws(catalog):
    sim = Simulator(catalog, config=SimConfig(min_stars=25), seed=0)
    ts = sim.generate(20)
    assert (ts.n_stars() >= 25).all()
    assert ts.n_redraws.sum() > 0


def test_false_and_lost_stars(catalog, camera):
    base = Simulator(catalog, camera, SimConfig(sigma_px=0.5), seed=2).generate(30)
    ts = Simulator(catalog, camera, SimConfig(sigma_px=0.5, false_stars=3, lost_stars=2), seed=2).generate(30)
    for i in range(30):
        obs = ts.observation(i)
        assert (obs.truth_hip == -1).sum() == 3
        assert camera.in_image(obs.x_px, obs.y_px).all()
        assert (obs.mag <= 6.0).all()
    # the attitude is the first draw of a trial, so trials drawn without redraws look at the same sky
    same = (base.n_redraws == 0) & (ts.n_redraws == 0)
    assert same.sum() > 20
    assert np.array_equal(ts.n_stars()[same], base.n_stars()[same] - 2 + 3)


def test_detections_are_shuffled(catalog):
    ts = Simulator(catalog, seed=5).generate(20)
    sorted_trials = sum(np.all(np.diff(ts.observation(i).truth_hip) > 0) for i in range(20))
    assert sorted_trials < 3


def test_close_stars_merge(camera):
    # two stars 1 px apart near the boresight of a tiny sky, plus far-apart fillers
    f = camera.f_px
    off = np.degrees(np.arctan(np.arange(8) * 60 / f))
    ra = np.concatenate([[0.0, np.degrees(np.arctan(1.0 / f))], off[1:]])
    dec = np.concatenate([[0.0, 0.0], off[1:] * 0 + 0.5])
    cat = Catalog.from_arrays(np.arange(1, ra.size + 1), ra % 360, dec, np.full(ra.size, 3.0))
    sim = Simulator(cat, camera, SimConfig(min_stars=1), seed=0)
    # look straight at (ra, dec) = (0, 0): camera z = +x_icrs
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    x, y, mag, hip, _ = sim._merge(*camera.project(cat.unit_icrs[:2] @ A.T), cat.v_mag[:2], cat.hip[:2])
    assert len(hip) == 1 and hip[0] == 1
    assert mag[0] == pytest.approx(3.0 - 2.5 * np.log10(2))


@pytest.mark.parametrize("kwargs", [{"sigma_px": -1}, {"false_stars": 1.5}, {"min_stars": -1},
                                    {"sigma_mag": float("nan")}])
def test_invalid_config(kwargs):
    with pytest.raises(ConfigError):
        SimConfig(**kwargs)


def test_impossible_min_stars_raises(catalog):
    with pytest.raises(ConfigError, match="min_stars"):
        Simulator(catalog, config=SimConfig(min_stars=10_000), seed=0).draw(0)
