"""The tail images of a few plugins: per-image identify time and work counters (issue #25, branch tailspeed).

    python benchmarks/tools/tailspeed_tails.py angle,spherical_triangle,pyramid 200 3 [real|paper]

Table 6's sky (default real) at 1 px / 0.5 Mv, seed 0, N images (test_ratios' images), each plugin's
``identify`` timed image by image, the minimum of R rounds per image. Prints per plugin the median,
p95 and p95 / median, then the slowest 10 % of the images: trial, time, whether any star was named,
and the plugin's work counters (``Identification.counters``); and the mean counters of the
other 90 % for comparison.
"""

import sys
import time

import numpy as np

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm

TABLE6_SIM = {"sigma_px": 1.0, "sigma_mag": 0.5, "mag_limit": 6.0, "min_stars": 6}


def main(names, n, rounds, sky):
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    for name in names:
        a = get_algorithm(name)()
        db = a.build(cat, cam)
        a.identify(db, obs[0])
        t = np.full(n, np.inf)
        ids = [None] * n
        for _ in range(rounds):
            for k, o in enumerate(obs):
                t0 = time.perf_counter_ns()
                ids[k] = a.identify(db, o)
                t[k] = min(t[k], (time.perf_counter_ns() - t0) * 1e-9)
        med, p95 = np.median(t), np.percentile(t, 95)
        print(f"{sky} {name}: median {med * 1e6:.1f} us, p95 {p95 * 1e6:.1f} us, p95/median {p95 / med:.2f}, "
              f"mean {t.mean() * 1e6:.1f} us, total {t.sum() * 1e3:.1f} ms")
        order = np.argsort(-t)
        tail = order[: max(1, n // 10)]
        keys = list((ids[0].counters or {}).keys())
        print("  trial   time_us  named  " + " ".join(f"{k:>10s}" for k in keys))
        for k in tail:
            c = ids[k].counters or {}
            named = int((ids[k].hip >= 0).sum())
            print(f"  {k:5d} {t[k] * 1e6:9.1f} {named:6d}  " + " ".join(f"{c.get(x, 0):10d}" for x in keys))
        rest = order[max(1, n // 10):]
        means = [np.mean([(ids[k].counters or {}).get(x, 0) for k in rest]) for x in keys]
        print(f"  rest mean {t[rest].mean() * 1e6:9.1f}        " + " ".join(f"{v:10.1f}" for v in means))
        print(f"  tail share of total time: {t[tail].sum() / t.sum():.2f}")


if __name__ == "__main__":
    if len(sys.argv) not in (4, 5):
        sys.exit(__doc__)
    main(sys.argv[1].split(","), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4] if len(sys.argv) == 5 else "real")
