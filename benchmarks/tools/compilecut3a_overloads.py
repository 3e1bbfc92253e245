"""Every numba compilation of a cold preparation of one plugin, with its signature, its exclusive CPU s and
the kernel whose typing asked for it: which numpy overloads (``np.impl``, ``np.<lambda>``) a plugin compiles,
for which argument types, and from where. Run on an empty cache:

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/compilecut3a_overloads.py planar_triangle [MIN_S]

Prints one line per compilation of at least MIN_S exclusive CPU s (default 0.04), largest first.
"""

from __future__ import annotations

import sys
import time

from numba.core import event

from starid import SimConfig, Simulator, load_hipparcos
from starid.experiment.spec import sim_settings
from starid.experiments import table6
from starid.harness import prepare
from starid.registry import algorithm_info


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
    exp = table6.experiment(trials=2)
    catalog = load_hipparcos()
    trials = Simulator(catalog, exp.make_camera(), SimConfig(**sim_settings(exp.sim, {"sky": "paper"})),
                       seed=0).generate(2)
    rec = _Recorder()
    c0 = time.process_time()
    with event.install_listener("numba:compile", rec):
        p = prepare(algorithm_info(name).cls(), catalog, trials.camera, trials.warmup, name)
    print(f"{name}: cpu_s {time.process_time() - c0:.2f} build_s {p.build_s:.2f} compilations {len(rec.rows)} "
          f"error {p.error!r}")
    for excl, fn, sig, parent in sorted(rec.rows, reverse=True):
        if excl >= min_s:
            print(f"{excl:6.2f}  {fn}{sig[:160]}  <- {parent.rsplit('.', 1)[-1]}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1], float(sys.argv[2]) if len(sys.argv) > 2 else 0.04)
