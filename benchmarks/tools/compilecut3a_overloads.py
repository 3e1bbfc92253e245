"""Every numba compilation of a cold preparation of one plugin, with its signature, its exclusive CPU s and
the kernel whose typing asked for it: which numpy overloads (``np.impl``, ``np.<lambda>``) a plugin compiles,
for which argument types, and from where. Run on an empty cache:

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/compilecut3a_overloads.py planar_triangle [MIN_S]

Prints one line per compilation of at least MIN_S exclusive CPU s (default 0.04), largest first.
"""

from __future__ import annotations

import sys
import time

from compile_profile import prepare_listening, warmup_trials  # benchmarks/tools
from numba.core import event


def _name(dispatcher) -> str:
    f = dispatcher.py_func
    return f"{f.__module__}.{f.__qualname__}"


class _Recorder(event.Listener):
    def __init__(self):
        self.rows = []
        self.stack = [["<root>", "", 0.0, 0.0]]  # name, signature, t0, children's time

    def on_start(self, ev):
        self.stack.append([_name(ev.data["dispatcher"]), str(ev.data.get("args")), time.process_time(), 0.0])

    def on_end(self, ev):
        name, sig, t0, kids = self.stack.pop()
        incl = time.process_time() - t0
        self.stack[-1][3] += incl
        self.rows.append((incl - kids, name, sig, self.stack[-1][0]))


def main(name: str, min_s: float) -> None:
    catalog, trials = warmup_trials()
    rec = _Recorder()
    p, cpu_s = prepare_listening(name, catalog, trials, rec)
    print(f"{name}: cpu_s {cpu_s:.2f} build_s {p.build_s:.2f} compilations {len(rec.rows)} "
          f"error {p.error!r}")
    for excl, fn, sig, parent in sorted(rec.rows, reverse=True):
        if excl >= min_s:
            print(f"{excl:6.2f}  {fn}{sig[:160]}  <- {parent.rsplit('.', 1)[-1]}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1], float(sys.argv[2]) if len(sys.argv) > 2 else 0.04)
