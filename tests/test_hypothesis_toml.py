"""Property tests (issue #26): any experiment definition either loads or is refused with a starid error naming the
key, before any work -- never a traceback, never an unbounded grid."""

import copy

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from starid.errors import ConfigError
from starid.experiment import Experiment
from starid.experiment.spec import sim_settings

BASE = {"name": "fuzz", "trials": 10, "seed": 1, "sim": {"sigma_px": 0.5},
        "studies": [{"name": "s", "algorithms": ["ptp"], "grid": {"sigma_px": [0.1, 0.2]}}]}

junk = st.one_of(st.none(), st.booleans(), st.integers(-5, 10**12), st.floats(allow_nan=True),
                 st.text(max_size=4), st.lists(st.integers(0, 3), max_size=3),
                 st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))
# where a wrong value goes: a path into BASE
PATHS = [("name",), ("trials",), ("seed",), ("sim",), ("sim", "sigma_px"), ("studies",), ("studies", 0),
         ("studies", 0, "name"), ("studies", 0, "algorithms"), ("studies", 0, "algorithms", 0), ("studies", 0, "grid"),
         ("studies", 0, "grid", "sigma_px"), ("studies", 0, "trials"), ("camera",)]


def _set(d, path, value):
    for p in path[:-1]:
        d = d[p]
    d[path[-1]] = value


def _load(d):
    """Load and expand the grid: what a run does before any work."""
    exp = Experiment.from_dict(d)
    for study in exp.studies:
        for point in study.grid.points():
            sim_settings(exp.sim, point)
        for variant in study.variants:
            variant.make()
    exp.make_camera()
    return exp


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(path=st.sampled_from(PATHS), value=junk)
def test_a_wrong_value_anywhere_is_a_config_error(path, value):
    d = copy.deepcopy(BASE)
    _set(d, path, value)
    try:
        _load(d)
    except ConfigError as exc:
        assert str(exc)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(where=st.sampled_from([(), ("studies", 0), ("sim",)]), key=st.text("abcxyz_", min_size=1, max_size=8))
def test_an_unknown_key_is_refused_by_name(where, key):
    d = copy.deepcopy(BASE)
    target = d
    for p in where:
        target = target[p]
    if key in target or (where == () and key in ("name", "trials", "seed", "camera", "sim", "description")):
        return
    target[key] = 1
    try:
        _load(d)
    except ConfigError as exc:
        assert repr(key) in str(exc) or key in str(exc)
    else:
        raise AssertionError(f"unknown key {key!r} in {where or 'the top level'} was accepted")


def test_empty_and_huge_grids_are_refused_naming_the_axis():
    d = copy.deepcopy(BASE)
    d["studies"][0]["grid"] = {"sigma_px": []}
    try:
        _load(d)
    except ConfigError as exc:
        assert "sigma_px" in str(exc)
    else:
        raise AssertionError("an empty grid axis was accepted")
    d["studies"][0]["grid"] = {name: list(range(1, 40)) for name in ("sigma_px", "sigma_mag", "false_stars",
                                                                     "min_stars", "lost_stars")}
    try:
        _load(d)
    except ConfigError as exc:
        assert "grid" in str(exc) and "points" in str(exc)
    else:
        raise AssertionError("a grid of 39**5 = 90 million points was accepted")
