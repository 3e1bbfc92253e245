"""Per-pass compile seconds of chosen dispatchers (numba's ``pipeline_times``), after a cold prepare.

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/compilecut4a_passes.py pvector pvector.kernels.identify_rows

Prepares the plugin (build and warm-up identify, as ``starid.harness.prepare``) on Table 6's camera, then
prints for each named dispatcher (module path under ``starid_algorithms.`` + function) the seconds of each numba
compiler pass of its compilation, largest first, and the seconds inside LLVM while it was the innermost
compiling dispatcher (its final module: linking, optimisation, code generation).
"""

from __future__ import annotations

import importlib
import sys
import time
from collections import defaultdict

from compile_profile import prepare_listening, warmup_trials  # benchmarks/tools
from numba.core import event


class _Llvm(event.Listener):
    def __init__(self):
        self.stack: list = []
        self.llvm: dict = defaultdict(float)
        self._t0 = None

    def on_start(self, ev):
        if ev.kind == "numba:compile":
            self.stack.append(ev.data["dispatcher"].py_func.__qualname__)
        elif ev.kind == "numba:llvm_lock":
            self._t0 = time.process_time()

    def on_end(self, ev):
        if ev.kind == "numba:compile":
            self.stack.pop()
        elif ev.kind == "numba:llvm_lock" and self._t0 is not None and self.stack:
            self.llvm[self.stack[-1]] += time.process_time() - self._t0


def main(plugin: str, targets: list[str]) -> None:
    catalog, trials = warmup_trials()
    rec = _Llvm()
    _, cpu_s = prepare_listening(plugin, catalog, trials, rec, ("numba:compile", "numba:llvm_lock"))
    print(f"{plugin}: {cpu_s:.2f} CPU s")
    for target in targets:
        mod, name = target.rsplit(".", 1)
        disp = getattr(importlib.import_module("starid_algorithms." + mod), name)
        for sig in disp.signatures:
            times = disp.get_metadata(sig)["pipeline_times"]["nopython"]
            rows = sorted(((v.init + v.run + v.finalize, k) for k, v in times.items()), reverse=True)
            total = sum(t for t, _ in rows)
            print(f"{target}: passes {total:.2f} s, LLVM while innermost {rec.llvm[disp.py_func.__qualname__]:.2f} s")
            for t, k in rows[:8]:
                print(f"  {t:6.2f}  {k}")


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2:])
