"""triangle_voting base against branch in one process, interleaved as the benchmark times it (issue #25, tvspeed5).

    python benchmarks/tools/tvspeed5_ab.py BASE_DIR [N] [R] [SKIES]

BASE_DIR: a checkout of the base commit (its ``algorithms/triangle_voting`` is copied once to
``BASE_DIR/../tv5_ab/ab_base_tv`` and imported from there as a package of its own, its numba cache kept there).
Table 6's images (``benchmarks/test_ratios.py``'s settings, seed 0) of each sky in SKIES (``paper,real``), N
images (100) x R rounds (2): per image, every other registered plugin identifies it (as in the benchmark, so the
timed call starts with the caches they left: tetra's ``identify`` is timed there), then one triangle_voting
variant's ``identify`` is timed; the others again, then the other variant; the variants' order alternates per
image. Then the warm time: per image each variant's ``identify`` 3 times back to back, the minimum. Prints per sky
the medians (us) of tetra, base and branch, the ratios to tetra, branch / base, and the warm medians.
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


def base_class(base: str):
    dst = Path(base).resolve().parent / "tv5_ab"
    if not (dst / "ab_base_tv").exists():
        shutil.copytree(Path(base) / "algorithms" / "triangle_voting", dst / "ab_base_tv",
                        ignore=shutil.ignore_patterns("__pycache__", "tests"))
    sys.path.insert(0, str(dst))
    return importlib.import_module("ab_base_tv.algorithm").TriangleVoting


def _t(f) -> float:
    t0 = time.perf_counter_ns()
    f()
    return (time.perf_counter_ns() - t0) * 1e-3


def main(base: str, n: int, rounds: int, skies: list[str]) -> None:
    variants = [base_class(base)(), get_algorithm("triangle_voting")()]
    cat, cam = load_hipparcos(), Camera()
    others = [get_algorithm(x)() for x in NAMES if x != "triangle_voting"]
    k_te = [x for x in NAMES if x != "triangle_voting"].index("tetra")
    for sky in skies:
        sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(len(trials))]
        dbs = [a.build(cat, cam) for a in others]
        vdbs = [a.build(cat, cam) for a in variants]
        for a, d in zip(others + variants, dbs + vdbs, strict=True):
            a.identify(d, obs[0])
        t = np.zeros((2, rounds * n))
        tetra = []
        for r in range(rounds):
            for i, o in enumerate(obs):
                for v in ((0, 1) if (i + r) % 2 == 0 else (1, 0)):
                    for j, (a, d) in enumerate(zip(others, dbs, strict=True)):
                        dt = _t(lambda a=a, d=d, o=o: a.identify(d, o))
                        if j == k_te:
                            tetra.append(dt)
                    a, d = variants[v], vdbs[v]
                    t[v, r * n + i] = _t(lambda a=a, d=d, o=o: a.identify(d, o))
        warm = np.array([[min(_t(lambda a=a, d=d, o=o: a.identify(d, o)) for _ in range(3)) for o in obs]
                         for a, d in zip(variants, vdbs, strict=True)])
        te = float(np.median(tetra))
        mb, mn = float(np.median(t[0])), float(np.median(t[1]))
        print(f"{sky:5s} {n}x{rounds} interleaved: tetra {te:6.1f} us | base {mb:6.1f} ({mb / te:4.2f}x) | "
              f"branch {mn:6.1f} ({mn / te:4.2f}x) | branch/base {mn / mb:5.3f} "
              f"(per image {np.median(t[1] / t[0]):5.3f})"
              f" | warm min of 3: base {np.median(warm[0]):6.1f} branch {np.median(warm[1]):6.1f} us", flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 100, int(sys.argv[3]) if len(sys.argv) > 3 else 2,
         (sys.argv[4] if len(sys.argv) > 4 else "paper,real").split(","))
