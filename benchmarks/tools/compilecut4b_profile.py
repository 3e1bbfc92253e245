"""Where a cold compile goes, per dispatcher and per numba pass (compilecut4b): build and warm-up
identify of each named plugin (as ``starid.harness.prepare`` does), in this process, on an empty cache:

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/compilecut4b_profile.py planar_triangle

Prints per plugin the CPU s of the preparation, then each dispatcher's exclusive compile CPU s (its
callees' compilations left out), the part of it inside LLVM, its module and name; then numba's
compiler-pass seconds summed over every dispatcher compiled (``get_metadata()['pipeline_times']``:
typing, lowering, ...; wall seconds, callees' compiles included in the caller's passes).
"""

from __future__ import annotations

import json
import sys
import time
from collections import defaultdict

from compile_profile import prepare_listening, warmup_trials  # benchmarks/tools
from numba.core import event


class _Recorder(event.Listener):
    def __init__(self):
        self.stack: list = []
        self.exclusive: dict = defaultdict(float)
        self.llvm: dict = defaultdict(float)
        self.count: dict = defaultdict(int)
        self.dispatchers: list = []
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
            name = f"{f.__module__}.{f.__qualname__}"
            dt = time.process_time() - t0
            self.exclusive[name] += dt - children
            self.count[name] += 1
            self.dispatchers.append(dispatcher)
            if self.stack:
                self.stack[-1][2] += dt
        elif ev.kind == "numba:llvm_lock" and self._llvm_t0 is not None:
            dt = time.process_time() - self._llvm_t0
            if self.stack:
                f = self.stack[-1][0].py_func
                self.llvm[f"{f.__module__}.{f.__qualname__}"] += dt


def main(names: list[str], top: int = 40) -> None:
    catalog, trials = warmup_trials()
    for name in names:
        rec = _Recorder()
        p, cpu_s = prepare_listening(name, catalog, trials, rec, ("numba:compile", "numba:llvm_lock"))
        print(json.dumps({"plugin": name, "cpu_s": round(cpu_s, 2), "build_s": round(p.build_s, 2),
                          "compile_s": round(p.compile_s, 2), "llvm_cpu_s": round(sum(rec.llvm.values()), 1),
                          "compilations": sum(rec.count.values()), "error": p.error}), flush=True)
        for k, v in sorted(rec.exclusive.items(), key=lambda kv: -kv[1])[:top]:
            print(f"  {v:7.2f} s  llvm {rec.llvm[k]:5.2f}  x{rec.count[k]}  {k}", flush=True)
        passes: dict = defaultdict(float)
        seen = set()
        for d in rec.dispatchers:
            if id(d) in seen:
                continue
            seen.add(id(d))
            for sig in d.signatures:
                try:
                    times = d.get_metadata(sig)["pipeline_times"]
                except Exception:  # noqa: BLE001 -- an overload without metadata
                    continue
                for pipeline in times.values():
                    for pname, t in pipeline.items():
                        passes[pname.split("_", 1)[-1] if pname[0].isdigit() else pname] += t.run
        print("  passes (wall s, summed over dispatchers, callees inside callers):")
        for k, v in sorted(passes.items(), key=lambda kv: -kv[1])[:15]:
            print(f"    {v:7.2f}  {k}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
