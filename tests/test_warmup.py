"""Compile scheduling (starid/experiment/warmup.py) and the one array type kernels see."""

from types import SimpleNamespace

import numpy as np
import pytest

from starid import Camera, SimConfig, Simulator
from starid.experiment import compile_weights
from starid.experiment.warmup import compile_order, compile_weight, schedule


def _task(name, k):
    return SimpleNamespace(chunk=SimpleNamespace(variant=SimpleNamespace(name=name)), k=k)


def test_first_chunk_of_each_plugin_goes_first_the_rest_in_plan_order(monkeypatch):
    monkeypatch.setattr(compile_weights, "CPU_S", {"ptp": 9.0, "grid": 5.0, "tetra": 2.0})
    plan = [_task(n, k) for n in ("ptp", "tetra", "ptp", "grid") for k in range(3)]
    out = schedule(plan)
    assert [(t.chunk.variant.name, t.k) for t in out[:3]] == [("ptp", 0), ("grid", 0), ("tetra", 0)]
    firsts = {id(t) for t in out[:3]}
    rest = [t for t in plan if id(t) not in firsts]
    assert [id(t) for t in out[3:]] == [id(t) for t in rest]     # every other chunk in plan order
    assert sorted(map(id, out)) == sorted(map(id, plan))


def test_first_chunks_go_heaviest_compile_first_and_an_unmeasured_plugin_weighs_the_median(monkeypatch):
    monkeypatch.setattr(compile_weights, "CPU_S", {"a": 1.0, "b": 7.0, "c": 3.0, "d": 5.0})
    assert compile_weight("b") == 7.0 and compile_weight("someone_elses") == 5.0
    assert compile_order(["a", "x", "b", "c", "y"]) == ["b", "x", "y", "c", "a"]    # ties keep their order
    plan = [_task(n, k) for n in ("a", "x", "b", "c") for k in range(2)]
    assert [t.chunk.variant.name for t in schedule(plan)[:4]] == ["b", "x", "c", "a"]


def test_every_registered_plugin_has_a_measured_compile_weight():
    """``benchmarks/tools/compile_weights.py`` measured every built-in plugin (rerun it for a new one)."""
    from starid.registry import available_algorithms

    builtin = {i.name for i in available_algorithms() if i.status == "ok" and
               i.cls.__module__.startswith("starid_algorithms.")}
    assert len(builtin) >= 10 and builtin <= set(compile_weights.CPU_S)
    assert all(s > 0 for s in compile_weights.CPU_S.values())


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


def _dispatch_task(name, block, sky="paper"):
    """A task as the Dispatcher sees it: variant (made from the registry), settings, block, camera."""
    from starid.experiment import Variant

    chunk = SimpleNamespace(variant=Variant(name), settings={"sigma_px": 1.0}, settings_key=sky, start=block * 10,
                            stop=block * 10 + 10)
    return SimpleNamespace(chunk=chunk, catalog_path="", camera=Camera(), seed=0, k=(name, sky, block))


def test_dispatcher_gives_first_chunks_first_then_keeps_each_worker_to_its_algorithms(monkeypatch):
    from starid.experiment.warmup import Dispatcher

    monkeypatch.setattr(compile_weights, "CPU_S", {"ptp": 9.0, "tetra": 7.0, "pvector": 5.0, "grid": 3.0})
    names = ("ptp", "tetra", "pvector", "grid")
    plan = [_dispatch_task(n, b, sky) for sky in ("paper", "real") for n in names for b in range(3)]
    d = Dispatcher(plan)
    w1, w2 = SimpleNamespace(), SimpleNamespace()
    got = {id(w1): [], id(w2): []}
    # the first chunks alternate between the workers as they come free: one compile per plugin
    for w in (w1, w2, w1, w2):
        got[id(w)].append(d.take(w).k)
    assert [k[0] for k in got[id(w1)] + got[id(w2)]] == ["ptp", "pvector", "tetra", "grid"]
    while d:
        for w in (w1, w2):
            if d:
                got[id(w)].append(d.take(w).k)
    mine = {id(w1): {"ptp", "pvector"}, id(w2): {"tetra", "grid"}}
    for w, keys in got.items():
        assert {k[0] for k in keys} == mine[w]        # no worker built another's databases
    taken = sorted(got[id(w1)] + got[id(w2)])
    assert taken == sorted(t.k for t in plan)         # every task exactly once


def test_dispatcher_lets_a_free_worker_take_what_is_left_and_puts_a_redo_first():
    from starid.experiment.warmup import Dispatcher

    plan = [_dispatch_task(n, b) for n in ("ptp", "tetra") for b in range(3)]
    d = Dispatcher(plan)
    w1, w2 = SimpleNamespace(), SimpleNamespace()
    assert d.take(w1).k == ("ptp", "paper", 0) and d.take(w2).k == ("tetra", "paper", 0)
    assert [d.take(w1).k for _ in range(2)] == [("ptp", "paper", 1), ("ptp", "paper", 2)]
    assert d.take(w1).k == ("tetra", "paper", 1)      # nothing of its own left: the first pending task
    redo = plan[0]
    d.put_back(redo)
    assert d.take(w2) is redo and len(d) == 1


def test_trial_set_images_are_the_checked_observations(catalog):
    """The harness's images (checked once per set) equal Observation's own checked ones; a set that fails the
    checks still refuses its bad image."""
    from starid.errors import ObservationError
    from starid.observation import Observation, TrialSet

    trials = Simulator(catalog, Camera.from_fov(12.0), SimConfig(sigma_px=0.5), seed=3).generate(5)
    for i in range(len(trials)):
        fast = trials.observation(i)
        a, b = trials.offsets[i], trials.offsets[i + 1]
        slow = Observation(trials.x_px[a:b], trials.y_px[a:b], trials.mag[a:b], trials.camera, trials.truth_hip[a:b])
        for o in (fast, fast.for_plugin()):
            assert not o.x_px.flags.writeable and not o.mag.flags.writeable
        assert fast.for_plugin().truth_hip is None and trials.observation(i, truth=False).truth_hip is None
        for name in ("x_px", "y_px", "mag", "truth_hip"):
            x, y = getattr(fast, name), getattr(slow, name)
            assert x.dtype == y.dtype and x.flags.c_contiguous and np.array_equal(x, y)
    x = np.array(trials.x_px)
    x[trials.offsets[2]] = np.nan
    bad = TrialSet(trials.trial, trials.offsets, x, trials.y_px, trials.mag, trials.truth_hip, trials.attitude,
                   trials.n_redraws, trials.camera)
    bad.observation(1)
    with pytest.raises(ObservationError, match="non-finite"):
        bad.observation(2)
