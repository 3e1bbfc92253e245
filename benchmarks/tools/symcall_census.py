"""How often each compiled kernel is optimised again inside its callers: the upper bound of what calling it
through a registered symbol (instead of linking it) could save on a cold compile. Run it on an empty cache:

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/symcall_census.py angle tetra pyramid ...

Builds and warms up each named plugin in this process (as ``starid.harness.prepare`` does), listening
to numba's compile and LLVM events. numba links each callee's final module into its caller's module
and runs the module pass pipeline and code generation on the whole again
(``numba/core/codegen.py``, ``CPUCodeLibrary.finalize``), so a compiled kernel K is optimised and
emitted once for itself and once more for every library whose link closure holds it. Per K (one line
per compiled signature) it prints: ``linkers``, the number of other libraries compiled in this
process whose link closure holds K; ``llvm_s``, the LLVM CPU seconds of K's own compile (its callees'
compilations left out, but the re-optimisation of its linked callees in); ``insts``, the LLVM
instructions of K's optimised module; and ``est_s = linkers * llvm_s``, a rough estimate of the LLVM
seconds K costs inside its callers (rough: re-optimising optimised IR is not the same work as the
first time, and a caller's optimiser drops what it inlines and never calls). The total LLVM and
compile CPU seconds of the whole run are printed first.

What it led to (issue #25, symcall branch, commits 81cf085..49ec0b1, reverted): the four kernels on top
of its list (``wahba_rows``, ``reproject_assign``, ``verify_pairwise``, ``sort_rows``; ~10 LLVM s
estimated) compiled as ``numba.cfunc(cache=True)`` C functions bound to ``starid_*`` symbols at import
and called through ``ExternalFunction`` shims. Same rows; the 14 plugins in one cold process -7 CPU s
(-2 to -13 over four back-to-back pairs), but every cold ``import starid`` +5.5 CPU s (the C functions
compile eagerly, ~1 s more than the kernels they wrap), so a one-plugin process got 3 CPU s slower
and the two-process benchmark stayed at 55 s wall. Callers save ~5 s per process; the C functions cost
~5 s per process.
"""

from __future__ import annotations

import json
import sys
import time
from collections import defaultdict

from compile_profile import prepare_listening, warmup_trials  # benchmarks/tools
from numba.core import event


def _name(dispatcher) -> str:
    f = dispatcher.py_func
    mod = f.__module__
    return f"{mod.rsplit('.', 2)[-2] if mod.count('.') > 1 else mod}.{f.__name__}"


class _Census(event.Listener):
    def __init__(self):
        self.stack: list = []        # [dispatcher, t0, children_s, llvm_excl_s]
        self.libs: dict = {}          # library -> dict(name, sig, excl_s, llvm_s)
        self.llvm_total = 0.0
        self._llvm_t0 = None

    def on_start(self, ev):
        if ev.kind == "numba:compile":
            d = ev.data["dispatcher"]
            self.stack.append([d, time.process_time(), 0.0, 0.0, set(map(id, self._libraries(d)))])
        elif ev.kind == "numba:llvm_lock":
            self._llvm_t0 = time.process_time()

    def on_end(self, ev):
        if ev.kind == "numba:compile":
            d, t0, children, llvm_s, before = self.stack.pop()
            dt = time.process_time() - t0
            new = [lib for lib in self._libraries(d) if id(lib) not in before]
            for lib in new:
                self.libs[lib] = {"name": _name(d), "sig": self._sig(d, lib), "excl_s": (dt - children) / len(new),
                                  "llvm_s": llvm_s / len(new)}
            if self.stack:
                self.stack[-1][2] += dt
        elif ev.kind == "numba:llvm_lock" and self._llvm_t0 is not None:
            dt = time.process_time() - self._llvm_t0
            self.llvm_total += dt
            if self.stack:
                self.stack[-1][3] += dt
            self._llvm_t0 = None

    @staticmethod
    def _libraries(d):
        return [getattr(cres, "library", None) for cres in list(d.overloads.values()) if getattr(cres, "library", None)]

    @staticmethod
    def _sig(d, lib):
        for sig, cres in d.overloads.items():
            if getattr(cres, "library", None) is lib:
                return ", ".join(str(t) for t in sig)
        return "?"


def _closure(lib, memo):
    """Every library linked into ``lib``'s final module, directly or through its callees' modules."""
    if id(lib) in memo:
        return memo[id(lib)]
    out = set()
    for sub in getattr(lib, "_linking_libraries", ()):
        out.add(sub)
        out |= _closure(sub, memo)
    memo[id(lib)] = out
    return out


def _insts(lib) -> int:
    try:
        return sum(1 for fn in lib._final_module.functions for b in fn.blocks for _ in b.instructions)
    except Exception:   # noqa: BLE001 -- a library without a module
        return -1


def census_of(names: list[str]) -> tuple[_Census, float]:
    """``(census, cpu_s)``: the plugins ``names`` built and warmed up in this process in turn, numba's
    compile and LLVM events recorded (also used by ``compile_census.py``)."""
    catalog, trials = warmup_trials()
    census = _Census()
    total_cpu = 0.0
    for name in names:
        _, cpu_s = prepare_listening(name, catalog, trials, census, ("numba:compile", "numba:llvm_lock"))
        total_cpu += cpu_s
    return census, total_cpu


def main(names: list[str], top: int = 40, prefix: str = "") -> None:
    census, total_cpu = census_of(names)
    memo: dict = {}
    linkers: dict = defaultdict(int)
    for lib in census.libs:
        for sub in _closure(lib, memo):
            linkers[id(sub)] += 1
    print(json.dumps({"plugins": names, "cpu_s": round(total_cpu, 2), "llvm_cpu_s": round(census.llvm_total, 2),
                      "libraries": len(census.libs)}), flush=True)
    rows = []
    for lib, info in census.libs.items():
        n = linkers[id(lib)]
        rows.append((n * info["llvm_s"], n, info, _insts(lib)))
    rows.sort(key=lambda r: -r[0])
    print(f"{'est_s':>7} {'linkers':>7} {'llvm_s':>7} {'excl_s':>7} {'insts':>7}  kernel (signature)")
    for est, n, info, insts in [r for r in rows if r[2]["name"].startswith(prefix)][:top]:
        print(f"{est:7.2f} {n:7d} {info['llvm_s']:7.3f} {info['excl_s']:7.3f} {insts:7d}  {info['name']}"
              f" ({info['sig'][:90]})", flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
