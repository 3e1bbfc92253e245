"""Property tests (issue #26): camera files and the observation CSV reader take any input and
either give finite, usable values or a starid error naming what is wrong -- never a traceback."""

import json
import math

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from starid.camera import Camera
from starid.cameras import OPTIONAL, REQUIRED, load_camera
from starid.cli.identify import read_observations
from starid.errors import ConfigError, ObservationError

FAST = settings(max_examples=150, deadline=None, derandomize=True,
                suppress_health_check=list(HealthCheck))

# TOML scalars of every kind a hand-written file may hold (nan and inf are valid TOML floats)
SCALARS = st.one_of(
    st.integers(-10**12, 10**12), st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, 1, -1, 1024, 12.0, 0.0, -0.0, 1e-300, 1e300]),
    st.text(max_size=8), st.booleans())
VALUES = st.one_of(SCALARS, st.lists(SCALARS, max_size=6))


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)
    return "[" + ", ".join(toml_value(x) for x in v) + "]"


GOOD = {"width_px": 1024, "height_px": 768, "pixel_um": 5.5, "focal_mm": 25.0}


FLOAT = st.floats(allow_nan=True, allow_infinity=True)
FIVE = st.one_of(st.lists(FLOAT, min_size=5, max_size=5),
                 st.lists(st.one_of(FLOAT, SCALARS), min_size=5, max_size=5))
#: a field and a value for it: the distortion mostly five entries, so that each entry's check is reached
CHANGE = st.sampled_from(REQUIRED + OPTIONAL + ("fov_deg", "k1")).flatmap(
    lambda k: st.tuples(st.just(k), FIVE if k == "distortion" else VALUES))


@FAST
@example(change=("distortion", [math.nan, 0.0, 0.0, 0.0, 0.0]), more={}, drop=set(), alone=True)
@example(change=("distortion", [0.0, 0.0, 0.0, 0.0, -math.inf]), more={}, drop=set(), alone=True)
@example(change=("cx_px", math.inf), more={}, drop=set(), alone=True)
@example(change=("exposure_s", math.nan), more={}, drop=set(), alone=True)
@example(change=("width_px", True), more={}, drop=set(), alone=True)
@given(change=CHANGE, more=st.dictionaries(st.sampled_from(REQUIRED + OPTIONAL), VALUES, max_size=2),
       drop=st.sets(st.sampled_from(REQUIRED), max_size=1), alone=st.booleans())
def test_any_camera_file_loads_or_names_its_fault(tmp_path_factory, change, more, drop, alone):
    key, value = change
    # half the examples change one field of a good camera (so each field's own check is reached)
    changes = {key: value} if alone else {**more, key: value}
    table = {k: v for k, v in {**GOOD, **changes}.items() if k not in drop or alone}
    path = tmp_path_factory.mktemp("cam") / "camera.toml"
    path.write_text("[camera]\n" + "".join(f"{k} = {toml_value(v)}\n" for k, v in table.items()))
    try:
        cam = load_camera(path)
    except ConfigError as exc:
        # the message names the file and a field (or the TOML fault)
        assert str(path) in str(exc) or "camera" in str(exc)
        return
    assert isinstance(cam, Camera)
    for name in ("width_px", "height_px", "pixel_um", "focal_mm", "cx_px", "cy_px"):
        value = getattr(cam, name)
        assert math.isfinite(value) and not isinstance(value, bool), name
    assert all(math.isfinite(v) for v in cam.distortion)
    assert cam.width_px >= 1 and cam.height_px >= 1 and cam.pixel_um > 0 and cam.focal_mm > 0


CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["nan", "NaN", "inf", "-inf", "Infinity", "-Infinity", "1e999", "-1e999", "", " ", "1_0",
                     "0x10", "1,5", "  3.5 ", "+4", "1e-400", "\u0663", "\u00bd", "None", "true"]),
    st.integers(-10**20, 10**20).map(str), st.text(max_size=6))


def good(lo, hi, whole=False):
    return (st.integers(lo, hi) if whole else st.floats(lo, hi)).map(repr)


# each cell a valid value or any text, so that rows with one bad cell among good ones are common
ROW = st.tuples(st.one_of(good(0, 3, True), CELLS), st.one_of(good(0, 1023), CELLS),
                st.one_of(good(0, 767), CELLS), st.one_of(good(-1, 8), CELLS))


@FAST
@example(rows=[("0", "10.0", "20.0", "nan")])
@example(rows=[("0", "inf", "20.0", "5.0")])
@example(rows=[("0", "10.0", "20.0", "5.0"), ("1", "10.0", "-Infinity", "5.0")])
@example(rows=[("0", "10.0", "20.0", "1e999")])
@given(rows=st.lists(ROW, min_size=1, max_size=6))
def test_observation_csv_gives_finite_values_or_names_the_line(tmp_path_factory, rows):
    path = tmp_path_factory.mktemp("obs") / "obs.csv"
    lines = ["trial,x_px,y_px,mag"] + [",".join(c.replace(",", ";").replace("\n", " ") for c in row)
                                       for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    try:
        trials, observations, _ = read_observations(path, Camera())
    except ObservationError as exc:
        assert str(path) in str(exc)
        return
    for obs in observations:
        for arr in (obs.x_px, obs.y_px, obs.mag):
            assert np.all(np.isfinite(arr))
    assert len(trials) == len(observations) >= 1
