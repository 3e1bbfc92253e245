"""Base against branch kernel in one process, interleaved as the benchmark times (issue #25, branch lptspeed5).

    python benchmarks/tools/lptspeed5_ab.py BASE PLUGIN SKY N ROUNDS

BASE: a directory holding the base commit's ``starid_algorithms`` (e.g. ``git archive BASE algorithms``
unpacked and renamed); it is copied once to ``BASE_ab/ab_base_algorithms`` and imported from there
(its numba cache stays there). PLUGIN: lpt, lpt_improved or grid. Table 6's images of SKY (seed 0),
N x ROUNDS: for each image every other registered plugin identifies it (as in
``benchmarks/test_ratios.py``, so each timed call starts with the caches they left), then the base's
``identify_kernel`` is timed, the others again, then the branch's, in alternating order per image,
both with the plugin's kernel arguments. A machine busy with other jobs slows both alike. Prints the
medians (us), the branch / base ratio of the medians and the median of the per-image ratios, and
tetra's median ``identify`` from the same calls.
"""

from __future__ import annotations

import importlib
import shutil
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks.test_ratios import NAMES, TABLE6_SIM  # noqa: E402
from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos  # noqa: E402
from starid.registry import get_algorithm  # noqa: E402


def base_kernels(base: str, plugin: str):
    dst = Path(base.rstrip("/") + "_ab")
    if not (dst / "ab_base_algorithms").exists():
        shutil.copytree(Path(base) / "starid_algorithms", dst / "ab_base_algorithms",
                        ignore=shutil.ignore_patterns("__pycache__", "tests"))
    sys.path.insert(0, str(dst))
    return importlib.import_module(f"ab_base_algorithms.{plugin}.kernels")


def main(base: str, plugin: str, sky: str, n: int, rounds: int) -> None:
    kb = base_kernels(base, plugin)
    alg = get_algorithm(plugin)()
    kn = importlib.import_module(type(alg).__module__.rsplit(".", 1)[0] + ".kernels")
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    others = [(x, get_algorithm(x)()) for x in NAMES if x != plugin]
    dbs = [a.build(cat, cam) for _, a in others]
    db = alg.build(cat, cam)
    trace0 = alg._run(db, obs[0])[3]
    kernels = (kb.identify_kernel, kn.identify_kernel)
    for (_, a), d in zip(others, dbs, strict=True):
        a.identify(d, obs[0])
    for k in kernels:
        k(obs[0].x_px, obs[0].y_px, *alg._kernel_args(db, obs[0].camera), trace0.copy())
    t = np.zeros((2, rounds * n))
    tetra = []
    for r in range(rounds):
        for i, o in enumerate(obs):
            order = (0, 1) if (i + r) % 2 == 0 else (1, 0)
            for v in order:
                for (name, a), d in zip(others, dbs, strict=True):
                    t0 = time.perf_counter_ns()
                    a.identify(d, o)
                    if name == "tetra":
                        tetra.append(time.perf_counter_ns() - t0)
                args = alg._kernel_args(db, o.camera)
                trace = trace0.copy()
                t0 = time.perf_counter_ns()
                kernels[v](o.x_px, o.y_px, *args, trace)
                t[v, r * n + i] = (time.perf_counter_ns() - t0) * 1e-3
    ma, mb = np.median(t[0]), np.median(t[1])
    print(f"{plugin} {sky} sky, {n} images x {rounds}, interleaved: kernel median base {ma:.1f} us, "
          f"branch {mb:.1f} us, branch/base {mb / ma:.3f} (median per-call ratio {np.median(t[1] / t[0]):.3f}); "
          f"tetra identify median {np.median(tetra) * 1e-3:.1f} us")


if __name__ == "__main__":
    if len(sys.argv) != 6:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5]))
