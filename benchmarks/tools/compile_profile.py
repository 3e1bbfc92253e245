"""Where a cold compile goes, per numba dispatcher: build and warm-up identify of each named plugin
(as ``starid.harness.prepare`` does), in this process, on Table 6's camera. Run it on an empty cache:

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/compile_profile.py geometric_voting tetra

Prints per plugin one JSON line (CPU s of the whole preparation, build_s, compile_s, CPU s inside
LLVM, dispatcher compilations) and its dispatchers by exclusive compile CPU seconds (each
dispatcher's own typing, lowering, LLVM optimisation and code generation, its callees'
compilations left out). A top-level kernel's exclusive time includes re-optimising and re-emitting
every callee linked into it (numba links each callee's final module into the caller's and runs the
module passes again), so it grows with the depth of the call tree below it. Plugins named later
reuse kernels compiled for earlier ones.
"""

from __future__ import annotations

import contextlib
import json
import sys
import time
from collections import defaultdict

from numba.core import event

from starid import SimConfig, Simulator, load_hipparcos
from starid.experiment.spec import sim_settings
from starid.experiments import table6
from starid.harness import prepare
from starid.registry import algorithm_info


class _Recorder(event.Listener):
    def __init__(self):
        self.stack: list = []
        self.exclusive: dict = defaultdict(float)
        self.count: dict = defaultdict(int)
        self.llvm_s = 0.0
        self._llvm_t0 = None

    def on_start(self, ev):
        if ev.kind == "numba:compile":
            self.stack.append([ev.data["dispatcher"], time.process_time(), 0.0])
        elif ev.kind == "numba:llvm_lock":
            self._llvm_t0 = time.process_time()

    def on_end(self, ev):
        if ev.kind == "numba:compile":
            dispatcher, t0, children = self.stack.pop()
            f = dispatcher.py_func
            name = f"{f.__module__.rsplit('.', 2)[-2] if f.__module__.count('.') > 1 else f.__module__}.{f.__name__}"
            dt = time.process_time() - t0
            self.exclusive[name] += dt - children
            self.count[name] += 1
            if self.stack:
                self.stack[-1][2] += dt
        elif ev.kind == "numba:llvm_lock" and self._llvm_t0 is not None:
            self.llvm_s += time.process_time() - self._llvm_t0


def warmup_trials(n: int = 2):
    """``(catalog, trials)``: the embedded catalog and ``n`` Table 6 images (paper's sky, seed 0) with their
    warm-up image, on which every compile tool here prepares plugins."""
    exp = table6.experiment(trials=n)
    catalog = load_hipparcos()
    return catalog, Simulator(catalog, exp.make_camera(), SimConfig(**sim_settings(exp.sim, {"sky": "paper"})),
                              seed=0).generate(n)


def prepare_listening(name: str, catalog, trials, listener=None, kinds=("numba:compile",)):
    """``(prepared, cpu_s)``: plugin ``name`` built and warmed up as :func:`starid.harness.prepare` does,
    with ``listener`` installed for each numba event kind in ``kinds`` (none without one)."""
    c0 = time.process_time()
    with contextlib.ExitStack() as stack:
        for kind in kinds if listener is not None else ():
            stack.enter_context(event.install_listener(kind, listener))
        p = prepare(algorithm_info(name).cls(), catalog, trials.camera, trials.warmup, name)
    return p, time.process_time() - c0


def main(names: list[str], top: int = 15) -> None:
    catalog, trials = warmup_trials()
    for name in names:
        rec = _Recorder()
        p, cpu_s = prepare_listening(name, catalog, trials, rec, ("numba:compile", "numba:llvm_lock"))
        print(json.dumps({"plugin": name, "cpu_s": round(cpu_s, 2), "build_s": round(p.build_s, 2),
                          "compile_s": round(p.compile_s, 2), "llvm_cpu_s": round(rec.llvm_s, 1),
                          "compilations": sum(rec.count.values()), "error": p.error}), flush=True)
        for k, v in sorted(rec.exclusive.items(), key=lambda kv: -kv[1])[:top]:
            print(f"  {v:7.2f} s  x{rec.count[k]}  {k}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
