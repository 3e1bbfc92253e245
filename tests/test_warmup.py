"""Compile scheduling (starid/experiment/warmup.py) and the one array type kernels see."""

from types import SimpleNamespace

import numpy as np
import pytest

from starid import Camera, SimConfig, Simulator
from starid.experiment.warmup import schedule


def _task(name, k):
    return SimpleNamespace(chunk=SimpleNamespace(variant=SimpleNamespace(name=name)), k=k)


def test_first_chunk_of_each_plugin_goes_first_the_rest_in_plan_order():
    plan = [_task(n, k) for n in ("ptp", "tetra", "ptp", "grid") for k in range(3)]
    out = schedule(plan)
    assert [(t.chunk.variant.name, t.k) for t in out[:3]] == [("ptp", 0), ("tetra", 0), ("grid", 0)]
    firsts = {id(t) for t in out[:3]}
    rest = [t for t in plan if id(t) not in firsts]
    assert [id(t) for t in out[3:]] == [id(t) for t in rest]     # every other chunk in plan order
    assert sorted(map(id, out)) == sorted(map(id, plan))


def test_observation_arrays_are_read_only(catalog):
    """Every Observation hands numba one array type (read-only), so a kernel compiles once."""
    obs = Simulator(catalog, Camera.from_fov(12.0), SimConfig(sigma_px=0.5), seed=3).observation(0)
    for o in (obs, obs.permuted(np.arange(len(obs))[::-1])):
        assert not o.x_px.flags.writeable and not o.y_px.flags.writeable
        with pytest.raises(ValueError):
            o.x_px[0] = 0.0
