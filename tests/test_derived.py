"""Sensor-derived defaults (``Algorithm.derived``): recorded as used, held to the contract by conformance."""

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from starid import Camera, SimConfig, Simulator, load_hipparcos
from starid.experiment import Experiment, Grid, Study, run_experiment
from starid.harness import run
from starid.plugin import Algorithm, Database, Identification
from starid.registry import register, unregister
from starid.testing import ConformanceError, check_algorithm


@dataclass(frozen=True, eq=False)
class _DB(Database):
    hip: np.ndarray


@dataclass(frozen=True)
class FieldSized(Algorithm):
    """Test double: ``radius_deg`` None = half the camera's field; ``mode`` breaks the contract one way."""

    name: ClassVar[str] = "field_sized"
    radius_deg: float | None = None
    mode: str = "ok"

    def derived(self, catalog, camera):
        if self.mode == "overrides":
            return dataclasses.replace(self, radius_deg=1.0)
        if self.mode == "drifts":
            return dataclasses.replace(self, radius_deg=(self.radius_deg or camera.fov_x_deg) / 2)
        if self.mode == "other_class":
            return Plain()
        if self.radius_deg is not None:
            return self
        return dataclasses.replace(self, radius_deg=camera.fov_x_deg / 2)

    def build(self, catalog, camera):
        return _DB(catalog.hip[:4].copy())

    def identify(self, database, observation):
        return Identification.none(len(observation))


@dataclass(frozen=True)
class Plain(Algorithm):
    """Test double with nothing to derive."""

    name: ClassVar[str] = "plain"

    def build(self, catalog, camera):
        return _DB(catalog.hip[:4].copy())

    def identify(self, database, observation):
        return Identification.none(len(observation))


def test_rows_record_the_derived_value_not_none():
    catalog, camera = load_hipparcos(), Camera.from_fov(20.0, 1024)
    sim = Simulator(catalog, camera, SimConfig(), seed=1)
    frame = run([FieldSized(), ("pinned", FieldSized(radius_deg=3.0))], sim.generate(3), catalog, sim)
    by_label = frame.groupby("label")["param_radius_deg"].unique()
    assert list(by_label["field_sized"]) == [pytest.approx(10.0)]
    assert list(by_label["pinned"]) == [3.0]


def test_the_engine_records_the_derived_value():
    register(FieldSized)
    try:
        exp = Experiment("derived", (Study("s", ("field_sized", "field_sized[radius_deg=2.0]"),
                                           Grid({"sigma_px": [0.0]})),),
                         trials=3, seed=1, camera={"fov_deg": 20.0, "resolution_px": 1024})
        frame = run_experiment(exp, None, jobs=1, progress=False)
    finally:
        unregister("field_sized")
    values = dict(zip(frame["label"], frame["param_radius_deg"], strict=True))
    assert values == {"field_sized": pytest.approx(10.0), "field_sized[radius_deg=2.0]": 2.0}


@dataclass(frozen=True)
class Overrides(FieldSized):
    """Test double: derives a value over a pinned one."""

    radius_deg: float | None = 4.0
    mode: str = "overrides"


@dataclass(frozen=True)
class Drifts(FieldSized):
    """Test double: deriving again changes the value."""

    mode: str = "drifts"


@dataclass(frozen=True)
class OtherClass(FieldSized):
    """Test double: derives an instance of another class."""

    mode: str = "other_class"


@pytest.mark.parametrize("cls, message", [(Overrides, "changed pinned parameter"), (Drifts, "not idempotent"),
                                          (OtherClass, "must return a OtherClass")])
def test_conformance_holds_derived_to_its_contract(cls, message):
    with pytest.raises(ConformanceError, match=message):
        check_algorithm(cls, checks=["derived"])


def test_conformance_passes_a_plugin_that_derives_nothing_and_one_that_derives_right():
    assert check_algorithm(Plain, checks=["derived"]) == ["derived"]
    assert check_algorithm(FieldSized, checks=["derived"]) == ["derived"]


def test_info_names_the_derived_value_on_the_default_camera(capsys):
    from starid.cli import main

    assert main(["info", "ptp", "--no-build"]) == 0
    lines = {line.split()[0]: line for line in capsys.readouterr().out.splitlines() if line.startswith("  d_min_deg")
             or line.startswith("  sigma_px")}
    assert "(None: derived from the camera; 0.05 on the default one)" in lines["d_min_deg"]
    assert "(None: follows the simulator sigma_px)" in lines["sigma_px"]


def test_info_prints_a_derived_flag_as_a_flag(capsys):
    from starid.cli import main

    assert main(["info", "geometric_voting", "--no-build"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("  saturate_votes"))
    assert "(None: derived from the camera; False on the default one)" in line
