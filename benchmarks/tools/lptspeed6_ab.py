"""Base against branch ``lpt`` in one process, interleaved as the benchmark times (issue #25, branch lptspeed6).

    python benchmarks/tools/lptspeed6_ab.py BASE SKY N ROUNDS

BASE: a directory holding the base commit's ``starid_algorithms`` (``git archive BASE algorithms``
unpacked, ``algorithms`` renamed); it is copied once to ``BASE_ab6/ab6_base_algorithms`` and imported
from there. Unlike ``lptspeed5_ab.py`` the base runs with its own plugin class, database and kernel
arguments (the two kernels take different arguments). Table 6's images of SKY (seed 0), N x ROUNDS:
for each image every other registered plugin identifies it (as in ``benchmarks/test_ratios.py``, so
each timed call starts with the caches they left), then one lpt's ``identify`` is timed, the others
again, then the other lpt's, the order alternating per image. Prints the medians (us), the ratio of
the medians, the median of the per-image ratios, tetra's median ``identify`` from the same calls
and each lpt median's ratio to it, and whether every identification (ids, attitude) is the same.
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


def base_plugin(base: str):
    dst = Path(base.rstrip("/") + "_ab6")
    if not (dst / "ab6_base_algorithms").exists():
        shutil.copytree(Path(base) / "starid_algorithms", dst / "ab6_base_algorithms",
                        ignore=shutil.ignore_patterns("__pycache__", "tests"))
    sys.path.insert(0, str(dst))
    return importlib.import_module("ab6_base_algorithms.lpt.algorithm").LPT()


def main(base: str, sky: str, n: int, rounds: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    lpts = [base_plugin(base), get_algorithm("lpt")()]
    ldbs = [a.build(cat, cam) for a in lpts]
    others = [(x, get_algorithm(x)()) for x in NAMES if x != "lpt"]
    dbs = [a.build(cat, cam) for _, a in others]
    for (_, a), d in zip(others, dbs, strict=True):
        a.identify(d, obs[0])
    same = True
    for a, d in zip(lpts, ldbs, strict=True):
        a.identify(d, obs[0])
    t = np.zeros((2, rounds * n))
    tetra = []
    for r in range(rounds):
        for i, o in enumerate(obs):
            out = [None, None]
            for v in ((0, 1) if (i + r) % 2 == 0 else (1, 0)):
                for (name, a), d in zip(others, dbs, strict=True):
                    t0 = time.perf_counter_ns()
                    a.identify(d, o)
                    if name == "tetra":
                        tetra.append(time.perf_counter_ns() - t0)
                t0 = time.perf_counter_ns()
                out[v] = lpts[v].identify(ldbs[v], o)
                t[v, r * n + i] = (time.perf_counter_ns() - t0) * 1e-3
            same &= bool(np.array_equal(out[0].hip, out[1].hip))
            same &= (out[0].attitude is None) == (out[1].attitude is None)
            if out[0].attitude is not None and out[1].attitude is not None:
                same &= bool(np.array_equal(np.asarray(out[0].attitude), np.asarray(out[1].attitude)))
    ma, mb, mt = np.median(t[0]), np.median(t[1]), np.median(tetra) * 1e-3
    print(f"lpt {sky} sky, {n} images x {rounds}, interleaved identify: median base {ma:.1f} us "
          f"({ma / mt:.2f}x tetra), "
          f"branch {mb:.1f} us ({mb / mt:.2f}x tetra), branch/base {mb / ma:.3f} (median per-call ratio "
          f"{np.median(t[1] / t[0]):.3f}); tetra median {mt:.1f} us; identical results: {same}")


if __name__ == "__main__":
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
