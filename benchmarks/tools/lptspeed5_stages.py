"""Where ``lpt``'s time goes in the benchmark's interleaved timing, and warm (issue #25, branch lptspeed5).

    python benchmarks/tools/lptspeed5_stages.py SKY N ROUNDS MODE

MODE ``interleaved``: as ``benchmarks/test_ratios.py`` times it, every other registered plugin identifies
the image before each timed lpt call, so lpt starts with the caches and branch history they left. Per
image three lpt calls, each after the others: ``identify`` (what the benchmark times), the kernel alone
(``identify_kernel`` with the plugin's arguments) and the kernel with the cycle counter read around its
stages (``lptspeed3_stages.timed_kernels``: a copy of the kernel, the plugin is not touched). N images
x ROUNDS; medians over all calls, and per stage the mean over all calls and over the calls at or below
the median. MODE ``warm``: the same three, each image's fastest of ROUNDS back-to-back calls.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from lptspeed3_stages import cycles_per_us, timed_kernels  # noqa: E402

from benchmarks.test_ratios import NAMES, TABLE6_SIM  # noqa: E402
from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos  # noqa: E402
from starid.registry import get_algorithm  # noqa: E402


def main(sky: str, n: int, rounds: int, mode: str) -> None:
    mod = timed_kernels()
    kernel = sys.modules[get_algorithm("lpt").__module__.rsplit(".", 1)[0] + ".kernels"].identify_kernel
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    others = [get_algorithm(x)() for x in NAMES if x != "lpt"]
    dbs = [a.build(cat, cam) for a in others]
    lpt = get_algorithm("lpt")()
    ldb = lpt.build(cat, cam)
    for a, db in zip(others, dbs, strict=True):
        a.identify(db, obs[0])
    lpt.identify(ldb, obs[0])

    def evict(o):
        if mode == "interleaved":
            for a, db in zip(others, dbs, strict=True):
                a.identify(db, o)

    def call_identify(o, trace):
        lpt.identify(ldb, o)

    def call_kernel(o, trace):
        kernel(o.x_px, o.y_px, *lpt._kernel_args(ldb, o.camera), np.zeros(7, dtype=np.int64))

    def call_timed(o, trace):
        mod.identify_kernel(o.x_px, o.y_px, *lpt._kernel_args(ldb, o.camera), trace)

    calls = (call_identify, call_kernel, call_timed)
    times = [[] for _ in calls]
    stages = []
    for _ in range(1 if mode == "warm" else rounds):
        for o in obs:
            best = [np.inf] * len(calls)
            best_trace = None
            for c, f in enumerate(calls):
                for _ in range(rounds if mode == "warm" else 1):
                    evict(o)
                    trace = np.zeros(16, dtype=np.int64)
                    trace[:4] = -1
                    t0 = time.perf_counter_ns()
                    f(o, trace)
                    dt = (time.perf_counter_ns() - t0) * 1e-3
                    if dt < best[c]:
                        best[c] = dt
                        if c == 2:
                            best_trace = trace
            for c in range(len(calls)):
                times[c].append(best[c])
            stages.append([best[2], *best_trace[4:7], *best_trace[8:15]])
    per_us = cycles_per_us(mod)
    t = [np.array(x) for x in times]
    print(f"{sky} sky, {mode}, {n} images x {rounds}: median us: identify {np.median(t[0]):.1f}, "
          f"kernel {np.median(t[1]):.1f}, timed kernel {np.median(t[2]):.1f}; "
          f"identify - kernel {np.median(t[0]) - np.median(t[1]):.1f}")
    a = np.array(stages, dtype=float)
    a[:, 4:] /= per_us
    med = np.median(a[:, 0])
    cols = {"kernel": 0, "tables": 4, "scan": 8, "image groups": 5, "db groups": 6, "sum tests": 10, "scoring": 7,
            "verification": 9, "n_patterns": 1, "n_comparisons": 2, "n_verif": 3}
    rest = a[:, 0] - a[:, 4] - a[:, 8] - a[:, 9]
    print(f"{'calls':>10s} " + " ".join(f"{c:>13s}" for c in cols) + f" {'rest':>13s}")
    for label, sel in (("all", np.ones(len(a), bool)), ("<= median", a[:, 0] <= med)):
        m = a[sel].mean(axis=0)
        print(f"{label:>10s} " + " ".join(f"{m[i]:13.1f}" for i in cols.values()) + f" {rest[sel].mean():13.1f}")


if __name__ == "__main__":
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4])
