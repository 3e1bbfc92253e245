"""Planets, aberration, the ecliptic band, boresight columns and the sky settings as grid axes."""

import math

import numpy as np
import pytest

from starid import sky
from starid.camera import Camera
from starid.catalog import load_hipparcos
from starid.errors import ConfigError
from starid.experiment.spec import Grid, sim_settings
from starid.scoring import score_trial
from starid.simulate import SimConfig, Simulator

EPOCH = "2030-01-01T00:00:00"


@pytest.fixture(scope="module")
def catalog():
    return load_hipparcos()


@pytest.mark.filterwarnings("ignore::Warning")
def test_jupiter_lands_within_an_arcmin_of_astropys_place():
    from astropy.coordinates import get_body, solar_system_ephemeris
    from astropy.time import Time

    u, v_mag, hip, body = sky.world_stars(np.zeros((0, 3)), np.zeros(0), np.zeros(0, dtype=np.int64),
                                          SimConfig(planets=True, epoch=EPOCH))
    assert body.all() and np.all(hip == -1) and len(hip) == 7
    with solar_system_ephemeris.set("builtin"):
        c = get_body("jupiter", Time(EPOCH, scale="utc"))
    ref = np.array([math.cos(c.dec.rad) * math.cos(c.ra.rad), math.cos(c.dec.rad) * math.sin(c.ra.rad),
                    math.sin(c.dec.rad)])
    jup = u[sky.PLANETS.index("jupiter")]
    assert math.degrees(math.acos(min(1.0, jup @ ref))) * 60 < 1.0
    # magnitudes in their known ranges (Jupiter -2.9..-1.6, Venus -4.9..-3.8, Neptune 7.7..8.0)
    m = dict(zip(sky.PLANETS, v_mag, strict=True))
    assert -2.95 < m["jupiter"] < -1.6 and -4.9 < m["venus"] < -3.8 and 7.6 < m["neptune"] < 8.0


def test_planets_are_imaged_without_a_hip_and_naming_one_is_wrong(catalog):
    cfg = SimConfig(planets=True, epoch=EPOCH, near_ecliptic=True)
    sim = Simulator(catalog, Camera(), cfg, seed=0)
    plain = Simulator(catalog, Camera(), SimConfig(near_ecliptic=True), seed=0)
    extra = sum(int((sim.draw(t)[4] == -1).sum()) - int((plain.draw(t)[4] == -1).sum()) for t in range(150))
    assert extra > 5
    assert score_trial(np.array([1234, 5]), np.array([-1, 5]))["n_wrong"] == 1
    with pytest.raises(ConfigError):
        SimConfig(planets=True)            # needs an epoch


def test_near_ecliptic_boresights_lie_in_the_band(catalog):
    sim = Simulator(catalog, Camera(), SimConfig(near_ecliptic=True), seed=5)
    pole = sky.ecliptic_to_icrs(0.0, math.pi / 2)[0]
    lat = [math.degrees(math.asin(sim.draw(t)[0][2] @ pole)) for t in range(100)]
    assert max(abs(x) for x in lat) <= sky.NEAR_ECLIPTIC_DEG + 1e-9
    free = Simulator(catalog, Camera(), SimConfig(), seed=5)
    assert max(abs(math.degrees(math.asin(free.draw(t)[0][2] @ pole))) for t in range(100)) > 20


def test_aberration_at_30_kms_moves_a_star_at_90_deg_by_20_6_arcsec():
    apex = np.array([0.0, 0.0, 1.0])
    u = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    out = sky.aberrate(u, 30.0, apex)
    shift = np.degrees(np.arccos(np.clip(np.sum(out * u, axis=1), -1, 1))) * 3600
    assert shift[0] == pytest.approx(20.64, abs=0.01) and shift[1] < 1e-6
    assert out[0, 2] > 0                       # towards the apex


def test_aberration_shifts_simulated_stars(catalog):
    a = Simulator(catalog, Camera(), SimConfig(), seed=1).draw(2)
    b = Simulator(catalog, Camera(), SimConfig(velocity_kms=30.0), seed=1).draw(2)
    ia, ib = np.argsort(a[4]), np.argsort(b[4])
    d = np.hypot(a[1][ia] - b[1][ib], a[2][ia] - b[2][ib])
    px = 20.64 / 3600 * math.pi / 180 * Camera().f_px          # at most v/c in px
    assert 0.01 < d.max() <= px * 1.01


def test_sky_settings_are_grid_axes_with_common_random_numbers(catalog):
    grid = Grid({"rate_deg_s": [0.0, 1.0], "velocity_kms": [0.0, 30.0], "planets": [0.0, 1.0]})
    atts = []
    for point in grid.points():
        settings = sim_settings({"epoch": 2030.0}, point)
        cfg = SimConfig(**settings)
        assert isinstance(cfg.planets, bool)
        atts.append(Simulator(catalog, Camera(), cfg, seed=9).draw(11)[0])
    assert all(np.array_equal(atts[0], a) for a in atts)


def _boresight(attitude: np.ndarray) -> dict:
    """The boresight columns as the harness computed them image by image (numpy's scalar calls) until stop 48:
    the reference its per-set computation must equal to the last bit."""
    z = attitude[2]
    return {"boresight_ra_deg": float(np.degrees(np.arctan2(z[1], z[0])) % 360.0),
            "boresight_dec_deg": float(np.degrees(np.arcsin(min(1.0, max(-1.0, z[2])))))}


def test_boresight_columns(catalog):
    from starid.harness import _boresights

    att = Simulator(catalog, Camera(), SimConfig(), seed=0).draw(0)[0]
    ra_deg, dec_deg = _boresights(att[None])
    ra, dec = math.radians(ra_deg[0]), math.radians(dec_deg[0])
    assert np.allclose([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)], att[2])


def test_epoch_forms():
    assert sky.parse_epoch(2000.0).isoformat().startswith("2000-01-01T12:00")
    assert sky.parse_epoch("2030-06-01T00:00:00Z").year == 2030
    with pytest.raises(ConfigError):
        SimConfig(epoch="yesterday")


def test_skymap_cells_are_equal_area_and_the_worst_cell_is_found():
    import pandas as pd

    from starid.report import skymap

    rng = np.random.default_rng(0)
    n = 40_000
    ra, dec = rng.uniform(0, 360, n), np.degrees(np.arcsin(rng.uniform(-1, 1, n)))
    counts = np.bincount(skymap.cell_of(ra, dec), minlength=skymap.N_DEC * skymap.N_RA)
    assert counts.min() > 0.8 * counts.mean() and counts.max() < 1.2 * counts.mean()
    bad = skymap.cell_of(ra, dec) == skymap.cell_of(50.0, 0.0)[()]
    frame = pd.DataFrame({"label": "x", "trial": np.arange(n), "boresight_ra_deg": ra, "boresight_dec_deg": dec,
                          "status": np.where(bad, "no_result", "correct")})
    figures, tables = skymap.skymap_parts(frame, "test")
    assert len(figures) == 1 and tables[0].frame.iloc[0]["ra_deg"] == "40-60"
    assert tables[0].frame.iloc[0]["id_rate"] == "0.000"
    assert skymap.skymap_parts(frame.head(100)) == ([], [])
    figures, tables = skymap.skymap_parts(frame, "flight_cubesat_wide", suffix="_flight_cubesat_wide")
    assert figures[0].name == "skymap_flight_cubesat_wide" and tables[0].name == "worst_cells_flight_cubesat_wide"
    assert "(flight_cubesat_wide)" in figures[0].title


def test_nearest_trial_finds_the_trial_of_a_given_boresight(catalog):
    sim = Simulator(catalog, Camera(), SimConfig(), seed=1)
    ra, dec = sky.boresight_radec_deg(sim.draw(37)[0])
    trial, sep = sky.nearest_trial(sim, ra, dec, 60)
    assert trial == 37 and sep < 1e-6
    assert sky.parse_radec("-10,20") == (350.0, 20.0)
    for bad in ("1,2,3", "10,95", "x,1"):
        with pytest.raises(ConfigError):
            sky.parse_radec(bad)


def test_proper_motion_moves_groombridge_1830_by_its_motion_at_2030(catalog):
    cfg = SimConfig(epoch="2030-01-01T12:00:00")
    assert sky.star_units(catalog, SimConfig()) is catalog.unit_icrs          # epoch unset: J2000 itself
    moved = sky.star_units(catalog, cfg)
    pmra, pmde = sky.proper_motions(catalog)
    i = int(np.argmax(np.hypot(pmra, pmde)))
    assert catalog.hip[i] == 57939                                           # the fastest star with V <= 8
    sep_arcsec = math.degrees(math.acos(min(1.0, moved[i] @ catalog.unit_icrs[i]))) * 3600
    dt = sky.years_since_j2000(cfg.epoch)
    assert dt == pytest.approx(30.0, abs=0.01)
    assert sep_arcsec == pytest.approx(np.hypot(pmra[i], pmde[i]) * dt / 1000, rel=1e-3)   # 211.8 arcsec
    assert 211 < sep_arcsec < 213
    # the simulator images the moved stars (same attitude, same stars, shifted centroids)
    a = Simulator(catalog, Camera(), SimConfig(), seed=0).draw(3)
    b = Simulator(catalog, Camera(), cfg, seed=0).draw(3)
    assert np.array_equal(a[0], b[0]) and not np.allclose(a[1], b[1], atol=1e-9)


def test_image_columns_are_the_per_image_values_to_the_last_bit(catalog):
    # the harness computes every image's trial, star counts and boresight once per trial set: the values each
    # row had from _boresight and the image's own arrays, bit for bit, poles and false stars included
    from starid.harness import image_columns

    trials = Simulator(catalog, Camera(), SimConfig(false_stars=2, sigma_mag=0.3), seed=5).generate(300)
    cols = image_columns(trials)
    assert cols is image_columns(trials)                    # once per set
    for i in range(len(trials)):
        obs = trials.observation(i)
        want = {"trial": int(trials.trial[i]), "n_stars": len(obs), "n_true_stars": int((obs.truth_hip >= 0).sum()),
                "n_redraws": int(trials.n_redraws[i]), **_boresight(trials.attitude[i])}
        got = {k: v[i] for k, v in cols.items()}
        assert got == want and all(type(got[k]) is type(want[k]) for k in want)
    assert sum(cols["n_true_stars"]) < sum(cols["n_stars"])    # the false stars are not counted
    from starid.harness import _boresights

    rng = np.random.default_rng(1)
    att = rng.normal(size=(2000, 3, 3))
    att[:, 2] /= np.linalg.norm(att[:, 2], axis=1)[:, None]
    att[:3, 2] = [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1e-300, -0.0, 1.0000000000000002]]   # poles, past 1
    ra, dec = _boresights(att)
    for k in range(len(att)):
        b = _boresight(att[k])
        assert (ra[k], dec[k]) == (b["boresight_ra_deg"], b["boresight_dec_deg"])
