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


def _chunk_task(name, block, sky="paper"):
    chunk = SimpleNamespace(variant=SimpleNamespace(name=name), settings_key=sky, start=block * 10,
                            stop=block * 10 + 10)
    return SimpleNamespace(chunk=chunk, catalog_path="", camera=None, seed=0, k=(name, sky, block))


def test_later_chunks_run_block_by_block_so_workers_reuse_simulated_images():
    """Plan order is plugin-major; after the first chunks, every plugin's chunk of a block comes
    before the next block, so a worker's simulated-trials cache hits."""
    plan = [_chunk_task(n, b, sky) for sky in ("paper", "real") for n in ("ptp", "tetra") for b in range(3)]
    out = [t.k for t in schedule(plan)]
    assert out[:2] == [("ptp", "paper", 0), ("tetra", "paper", 0)]
    assert out[2:] == [("ptp", "paper", 1), ("tetra", "paper", 1), ("ptp", "paper", 2), ("tetra", "paper", 2),
                       ("ptp", "real", 0), ("tetra", "real", 0), ("ptp", "real", 1), ("tetra", "real", 1),
                       ("ptp", "real", 2), ("tetra", "real", 2)]
    assert sorted(out) == sorted(t.k for t in plan)
