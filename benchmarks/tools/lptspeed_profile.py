"""Where the per-image time of lpt, lpt_improved and grid goes: wrapper, kernel, Identification.

    python benchmarks/tools/lptspeed_profile.py lpt,lpt_improved,grid,tetra 60 5

Table 6's two skies at 1 px / 0.5 Mv (seed 0), N images, each step timed R times (minimum kept);
per sky and plugin the median over images of: the whole ``identify``; the kernel call alone
(``identify_kernel`` with the arguments ``_run`` builds); ``_run`` (the Python that builds the
kernel's arguments + the kernel); so wrapper = run - kernel and Identification = identify - run.
Also the median of each work counter.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm


def _min_ns(f, repeats):
    best = None
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        f()
        dt = time.perf_counter_ns() - t0
        best = dt if best is None else min(best, dt)
    return best / 1e3


def kernel_call(alg, db, o):
    """A zero-argument callable running the plugin's kernel alone, arguments prebuilt (or None)."""
    import importlib
    import inspect
    if not hasattr(alg, "_run"):
        return None
    mod = importlib.import_module(type(alg).__module__.rsplit(".", 1)[0] + ".kernels")
    captured = {}
    real = mod.identify_kernel

    class Spy:
        def __call__(self, *args):
            captured["args"] = args
            return real(*args)

    alg_mod = inspect.getmodule(type(alg))
    alg_mod.identify_kernel = Spy()
    try:
        alg._run(db, o)
    finally:
        alg_mod.identify_kernel = real
    args = captured["args"]
    return lambda: real(*args)


def main(names, n, repeats):
    cat, cam = load_hipparcos(), Camera()
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(n)]
        for name in names:
            alg = get_algorithm(name)()
            db = alg.build(cat, cam)
            alg.identify(db, obs[0])
            t_id, t_run, t_k, counters = [], [], [], []
            for o in obs:
                t_id.append(_min_ns(lambda o=o, alg=alg, db=db: alg.identify(db, o), repeats))
                if hasattr(alg, "_run"):
                    t_run.append(_min_ns(lambda o=o, alg=alg, db=db: alg._run(db, o), repeats))
                    k = kernel_call(alg, db, o)
                    t_k.append(_min_ns(k, repeats))
                c = alg.identify(db, o).counters
                if c:
                    counters.append(c)
            line = f"{sky:5s} {name:14s} identify {np.median(t_id):8.1f} p95 {np.percentile(t_id, 95):8.1f}"
            if t_k:
                line += (f" | kernel {np.median(t_k):8.1f} wrapper {np.median(np.subtract(t_run, t_k)):6.1f}"
                         f" Identification {np.median(np.subtract(t_id, t_run)):6.1f}")
            if counters:
                line += " | " + " ".join(f"{k} {np.median([c[k] for c in counters]):.0f}" for k in counters[0])
            print(line, flush=True)


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(sys.argv[1].split(","), int(sys.argv[2]), int(sys.argv[3]))
