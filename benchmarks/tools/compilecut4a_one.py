"""Exclusive compile CPU seconds of one kernel: its callees compiled first, then a fresh copy of it.

    python benchmarks/tools/compilecut4a_one.py pvector pvector.kernels.identify_rows [REPEATS] [--profile]

Prepares the plugin (build and warm-up identify, as ``starid.harness.prepare``; a warm cache is fine),
then compiles a new, uncached ``njit`` copy of the named kernel for its signature REPEATS times
(default 3) and prints the CPU seconds of each: the kernel's own typing, lowering and LLVM work (its
final module links and re-optimises its callees, as in a cold compile) without its callees' own
compilations. ``--profile`` prints cProfile's top functions of one more compile.
"""

from __future__ import annotations

import cProfile
import importlib
import pstats
import sys
import time

from numba import njit
from numba.core import event

from starid import SimConfig, Simulator, load_hipparcos
from starid.experiment.spec import sim_settings
from starid.experiments import table6
from starid.harness import prepare
from starid.registry import algorithm_info


class _Llvm(event.Listener):
    def __init__(self):
        self.s = 0.0
        self._t0 = 0.0

    def on_start(self, ev):
        self._t0 = time.process_time()

    def on_end(self, ev):
        self.s += time.process_time() - self._t0


def main(plugin: str, target: str, repeats: int, profile: bool) -> None:
    exp = table6.experiment(trials=2)
    catalog = load_hipparcos()
    trials = Simulator(catalog, exp.make_camera(), SimConfig(**sim_settings(exp.sim, {"sky": "paper"})),
                       seed=0).generate(2)
    prepare(algorithm_info(plugin).cls(), catalog, trials.camera, trials.warmup, plugin)
    mod, name = target.rsplit(".", 1)
    disp = getattr(importlib.import_module("starid_algorithms." + mod), name)
    sig = disp.signatures[0]
    out = []
    for _ in range(repeats):
        fresh = njit(**{k: v for k, v in disp.targetoptions.items() if k not in ("cache", "nopython")})(disp.py_func)
        rec = _Llvm()
        c0 = time.process_time()
        with event.install_listener("numba:llvm_lock", rec):
            fresh.compile(sig)
        out.append((time.process_time() - c0, rec.s))
    print(f"{target}: " + ", ".join(f"{c:.2f} CPU s (LLVM {llvm:.2f})" for c, llvm in out))
    if repeats:
        times = fresh.get_metadata(sig)["pipeline_times"]["nopython"]
        rows = sorted(((v.init + v.run + v.finalize, k) for k, v in times.items()), reverse=True)
        print("  last compile, numba passes (wall s): " + ", ".join(f"{k} {t:.2f}" for t, k in rows[:8]))
    if profile:
        fresh = njit(**{k: v for k, v in disp.targetoptions.items() if k not in ("cache", "nopython")})(disp.py_func)
        pr = cProfile.Profile()
        pr.enable()
        fresh.compile(sig)
        pr.disable()
        st = pstats.Stats(pr)
        st.sort_stats("tottime").print_stats(25)
        st.sort_stats("cumulative").print_stats(60)
        st.print_callers("targetconfig.py:200|add_error|get_call_type")


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--profile"]
    if len(args) < 2:
        sys.exit(__doc__)
    main(args[0], args[1], int(args[2]) if len(args) > 2 else 3, "--profile" in sys.argv)
