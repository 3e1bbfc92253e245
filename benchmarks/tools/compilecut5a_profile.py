"""Every numba compilation of one plugin's cold preparation with its argument types, exclusive CPU s and
the kernel whose typing asked for it (compilecut5a: which numpy specialisations a plugin compiles and
who asks for them). Run on an empty cache:

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/compilecut5a_profile.py planar_triangle [FILTER]

Prints the preparation's CPU s, then one line per compilation (exclusive CPU s, caller, dispatcher,
argument types), those whose dispatcher name contains FILTER only (default: all).
"""

from __future__ import annotations

import sys
import time

from compile_profile import prepare_listening, warmup_trials  # benchmarks/tools
from numba.core import event


def _name(dispatcher) -> str:
    f = dispatcher.py_func
    return f"{f.__module__.rsplit('.', 1)[-1]}.{f.__qualname__}"


class _Recorder(event.Listener):
    def __init__(self):
        self.stack, self.rows = [], []

    def on_start(self, ev):
        d = ev.data["dispatcher"]
        if d.py_func.__module__.startswith("numba.") and self.stack:
            flags = self.stack[-1][4]  # numba's own implementations compile with their caller's flags
        else:
            flags = "inner" if d.targetoptions.get("no_cpython_wrapper") else "top"
        self.stack.append([d, ev.data.get("args"), time.process_time(), 0.0, flags])

    def on_end(self, ev):
        dispatcher, args, t0, children, flags = self.stack.pop()
        dt = time.process_time() - t0
        caller = _name(self.stack[-1][0]) if self.stack else "-"
        self.rows.append((dt - children, caller, f"{_name(dispatcher)} [{flags}]", str(args)))
        if self.stack:
            self.stack[-1][3] += dt


def main(name: str, needle: str = "") -> None:
    catalog, trials = warmup_trials()
    rec = _Recorder()
    p, cpu_s = prepare_listening(name, catalog, trials, rec)
    print(f"{name}: cpu_s {cpu_s:.2f} build_s {p.build_s:.2f} compilations {len(rec.rows)}")
    total = 0.0
    for excl, caller, disp, args in sorted(rec.rows, key=lambda r: -r[0]):
        if needle in disp and needle != "-":
            total += excl
            print(f"  {excl:6.3f}  {caller:40s} {disp:45s} {args[:150]}")
    print(f"  {total:6.3f}  in all")
    seen: dict = {}
    for excl, _, disp, args in rec.rows:
        seen.setdefault((disp.split(" [")[0], args), []).append((disp.split(" [")[1][:-1], excl))
    twice = {k: v for k, v in seen.items() if len(v) > 1}
    print(f"compiled more than once (both flag sets): {sum(e for v in twice.values() for _, e in v):.3f} s")
    for (disp, args), v in sorted(twice.items(), key=lambda kv: -sum(e for _, e in kv[1])):
        print(f"  {' '.join(f'{f} {e:.3f}' for f, e in v):30s} {disp:45s} {args[:100]}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(*sys.argv[1:])
