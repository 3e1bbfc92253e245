"""planets_in_view (issue #24): a controlled count of planets in the field, and per-study
trials / cameras of the realism experiment."""

import numpy as np
import pytest

from starid import sky
from starid.camera import Camera
from starid.catalog import load_hipparcos
from starid.errors import ConfigError
from starid.experiment import Experiment, Grid, Study
from starid.experiment.runner import plan
from starid.simulate import SimConfig, Simulator

EPOCH = "2030-01-01T00:00:00"


@pytest.fixture(scope="module")
def catalog():
    return load_hipparcos()


def _planets_per_field(catalog, k, **kw):
    cfg = SimConfig(planets_in_view=k, epoch=EPOCH, near_ecliptic=True, **kw)
    ts = Simulator(catalog, Camera(), cfg, seed=3).generate(12)
    return ts, np.add.reduceat((ts.truth_hip < 0).astype(int), ts.offsets[:-1])


def test_planets_in_view_puts_the_asked_number_of_planets_in_every_field(catalog):
    fields = {}
    for k in (0, 1, 3):
        ts, n = _planets_per_field(catalog, k)
        assert np.all(n == k)                     # every one detected (V < 6, no noise) and on the sensor
        fields[k] = ts
    # common random numbers: the same attitudes and stars at every count, and the k-planet field
    # holds the (k-1)-planet field's planets
    assert np.allclose(fields[0].attitude, fields[3].attitude)
    planets1 = set(np.round(fields[1].x_px[fields[1].truth_hip < 0], 6))
    planets3 = set(np.round(fields[3].x_px[fields[3].truth_hip < 0], 6))
    assert planets1 <= planets3
    mags = np.sort(fields[3].mag[fields[3].truth_hip < 0])
    assert mags.min() < -3.5                       # Venus (-4.2 at 2030-01-01) is among them


def test_planets_in_view_is_checked():
    with pytest.raises(ConfigError, match="planets_in_view needs an epoch"):
        SimConfig(planets_in_view=2)
    with pytest.raises(ConfigError, match="from 0 to 5"):
        SimConfig(planets_in_view=6, epoch=EPOCH)
    assert SimConfig(planets_in_view=2.0, epoch=EPOCH).planets_in_view == 2     # --param gives floats
    assert sky.trial_draws(SimConfig(), 0, 5)["apex"] == pytest.approx(
        sky.trial_draws(SimConfig(planets_in_view=1, epoch=EPOCH), 0, 5)["apex"])


def test_a_study_can_have_its_own_trials_and_camera(catalog):
    exp = Experiment("x", (Study("a", ("pyramid",), Grid({"sigma_px": [0.0]})),
                           Study("b", ("pyramid",), Grid({"sigma_px": [0.0]}), trials=700,
                                 camera={"preset": "cubesat_wide"})), trials=300)
    placements = plan(exp, catalog)
    by_study = {s: [p.chunk for p in placements if p.study == s] for s in ("a", "b")}
    assert sum(c.stop - c.start for c in by_study["a"]) == 300
    assert sum(c.stop - c.start for c in by_study["b"]) == 700
    assert by_study["a"][0].camera is None and by_study["b"][0].camera.width_px == 1024
    assert by_study["b"][0].camera.height_px == 512
    assert by_study["a"][0].key != by_study["b"][0].key      # another camera, another chunk
    again = Experiment.from_dict(exp.to_dict())
    assert again.digest() == exp.digest() and again.studies[1].trials == 700
    # without per-study settings the definition (and so every chunk key) is as before
    plain = Experiment("x", (Study("a", ("pyramid",), Grid({"sigma_px": [0.0]})),), trials=300)
    assert "trials" not in plain.to_dict()["studies"][0]


def test_realism_runs_every_camera_and_effect_and_its_flight_rule():
    from starid.experiments import realism

    exp = realism.experiment(40)
    names = {s.name for s in exp.studies}
    for cam in realism.CAMERAS:
        for effect in (*realism.SWEEPS, "flight"):
            assert realism.study_name(effect, cam) in names
    flight = [s for s in exp.studies if s.name.startswith("flight")]
    assert all(s.trials == realism.FLIGHT_TRIALS for s in flight)
    assert all(s.trials == 40 for s in exp.studies if not s.name.startswith("flight"))
    assert {s.trials for s in realism.experiment(40, flight_trials=100).studies if s.name.startswith("flight")} \
        == {100}
    assert {s.trials for s in realism.experiment(6000).studies if s.name.startswith("flight")} == {6000}


def test_realism_gives_the_cubesat_algorithms_the_sensors_guide_star_limit():
    from starid.experiments import realism

    exp = realism.experiment(10, flight_trials=10)
    cube = next(s for s in exp.studies if s.name == "rate_cubesat_wide")
    table4 = next(s for s in exp.studies if s.name == "rate_table4")
    params = {v.label: dict(v.params) for v in cube.variants}
    assert params["pyramid"] == {"mag_limit": 3.8}          # its default 6.0 does not follow the world
    assert params["grid"] == {}                             # grid follows the world's mag_limit
    assert all(not v.params for v in table4.variants)       # Table 4: every default
    assert [v.label for v in cube.variants] == [v.label for v in table4.variants]


def test_planets_in_view_is_a_flag_of_the_commands():
    from starid.cli import build_parser
    from starid.cli.options import sky_settings

    parser = build_parser()
    heads = {"run": ["run", "tetra"], "sweep": ["sweep", "tetra", "--param", "sigma_px=0,1", "--out", "d"],
             "simulate": ["simulate", "--out", "x.npz"], "render": ["render", "--trial", "0", "--out", "d"]}
    for command, head in heads.items():
        args = parser.parse_args(head + ["--planets-in-view", "2", "--epoch", EPOCH])
        assert sky_settings(args)["planets_in_view"] == 2, command
    off = parser.parse_args(["run", "tetra"])
    assert "planets_in_view" not in sky_settings(off)      # off: the settings (and every table) stay as they were
