"""The compile a plugin's database build adds to its identify's, on an empty numba cache (issue #25).

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/buildcut_split.py grid tetra

Per plugin, in one process: a subprocess (its own empty cache) builds the database and pickles it;
this process then warms identify up on it (as ``starid.harness.prepare`` does: every kernel identify
needs compiles here), then builds the database itself twice. The first build compiles only what
identify did not need (the build-only kernels); the second is warm. Prints one JSON line per plugin
(CPU s: ``identify_cold``, ``build_cold``, ``build_warm``, ``build_only_compile`` = their
difference) and the dispatchers the first build compiled, by exclusive compile CPU s. Plugins named
later reuse kernels compiled for earlier ones: name one plugin per process to charge each its own.

    python benchmarks/tools/buildcut_split.py --arrays NAME OUT.npz

writes every array (and scalar) of NAME's database on Table 6's camera to ``OUT.npz``, to compare two
versions of a build bit for bit.

    python benchmarks/tools/buildcut_split.py --warm grid tetra

builds each named plugin's database five times in this process and prints the CPU s of the first and
the least of the other four (the warm build; run it once first to fill the cache).
"""

from __future__ import annotations

import dataclasses
import json
import os
import pickle
import subprocess
import sys
import tempfile
import time

import numpy as np
from numba.core import event

from starid import SimConfig, Simulator, load_hipparcos
from starid.experiment.spec import sim_settings
from starid.experiments import table6
from starid.harness import warm_scoring
from starid.registry import algorithm_info


class _Recorder(event.Listener):
    def __init__(self):
        self.stack: list = []
        self.exclusive: dict = {}

    def on_start(self, ev):
        self.stack.append([ev.data["dispatcher"], time.process_time(), 0.0])

    def on_end(self, ev):
        dispatcher, t0, children = self.stack.pop()
        f = dispatcher.py_func
        name = f"{f.__module__}.{f.__name__}"
        dt = time.process_time() - t0
        self.exclusive[name] = self.exclusive.get(name, 0.0) + dt - children
        if self.stack:
            self.stack[-1][2] += dt


def _setup():
    exp = table6.experiment(trials=2)
    catalog = load_hipparcos()
    trials = Simulator(catalog, exp.make_camera(), SimConfig(**sim_settings(exp.sim, {"sky": "paper"})),
                       seed=0).generate(2)
    return catalog, trials.camera.pinhole_frame, trials.warmup


def _build(name, catalog, camera):
    algorithm = algorithm_info(name).cls().derived(catalog, camera)
    return algorithm, algorithm.build(catalog, camera)


def _flatten(prefix, value, out):
    if isinstance(value, np.ndarray):
        out[prefix] = value
    elif dataclasses.is_dataclass(value):
        for f in dataclasses.fields(value):
            _flatten(f"{prefix}.{f.name}", getattr(value, f.name), out)
    elif isinstance(value, tuple):
        for i, v in enumerate(value):
            _flatten(f"{prefix}.{getattr(value, '_fields', range(len(value)))[i]}", v, out)
    elif isinstance(value, dict):
        for k, v in value.items():
            _flatten(f"{prefix}.{k}", v, out)
    elif isinstance(value, (int, float, bool, np.generic, str)) or value is None:
        out[prefix] = np.asarray(repr(value) if isinstance(value, float) else value)


def arrays(name: str, path: str) -> None:
    catalog, camera, _ = _setup()
    _, db = _build(name, catalog, camera)
    out: dict = {}
    _flatten("db", db, out)
    np.savez(path, **out)
    print(json.dumps({"plugin": name, "arrays": len(out), "nbytes": int(sum(a.nbytes for a in out.values()))}))


def split(name: str) -> None:
    catalog, camera, warmup = _setup()
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NUMBA_CACHE_DIR=tmp)
        subprocess.run([sys.executable, __file__, "--pickle", name, f"{tmp}/db.pkl"], env=env, check=True)
        with open(f"{tmp}/db.pkl", "rb") as fh:
            db = pickle.load(fh)
    algorithm = algorithm_info(name).cls().derived(catalog, camera)
    warm_scoring(catalog)
    warmup.unit_cam()
    view = warmup.for_plugin()
    c0 = time.process_time()
    algorithm.identify(db, view)
    algorithm.identify(db, view.permuted(np.arange(len(warmup))[::-1]))
    identify_cold = time.process_time() - c0
    rec = _Recorder()
    c0 = time.process_time()
    with event.install_listener("numba:compile", rec):
        _build(name, catalog, camera)
    build_cold = time.process_time() - c0
    c0 = time.process_time()
    _build(name, catalog, camera)
    build_warm = time.process_time() - c0
    print(json.dumps({"plugin": name, "identify_cold": round(identify_cold, 2), "build_cold": round(build_cold, 2),
                      "build_warm": round(build_warm, 2), "build_only_compile": round(build_cold - build_warm, 2)}),
          flush=True)
    for k, v in sorted(rec.exclusive.items(), key=lambda kv: -kv[1]):
        print(f"  {v:6.2f} s  {k}", flush=True)


def warm(names: list[str]) -> None:
    catalog, camera, _ = _setup()
    for name in names:
        times = []
        for _ in range(5):
            algorithm = algorithm_info(name).cls().derived(catalog, camera)
            c0 = time.process_time()
            algorithm.build(catalog, camera)
            times.append(time.process_time() - c0)
        print(json.dumps({"plugin": name, "first_build": round(times[0], 3), "warm_build": round(min(times[1:]), 3)}),
              flush=True)


def main(argv: list[str]) -> None:
    if len(argv) == 3 and argv[0] == "--pickle":
        catalog, camera, _ = _setup()
        with open(argv[2], "wb") as fh:
            pickle.dump(_build(argv[1], catalog, camera)[1], fh)
    elif len(argv) == 3 and argv[0] == "--arrays":
        arrays(argv[1], argv[2])
    elif len(argv) >= 2 and argv[0] == "--warm":
        warm(argv[1:])
    elif argv and not argv[0].startswith("-"):
        for name in argv:
            split(name)
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv[1:])
