"""Per-image identify time of a few plugins, minimum over rounds (issue #25, branch lptspeed2).

    python benchmarks/tools/lptspeed2_time.py tetra,lpt 60 5 [SKY ...]

Table 6's images (1 px / 0.5 Mv, seed 0), N per sky, each plugin's ``identify`` timed image by image
in turn, R rounds; per image the minimum over the rounds is kept; prints per sky and plugin the
median, p95 and mean of those minima (us) and the median's ratio to the first name's.
"""

import sys
import time

import numpy as np

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm


def main(names, n, rounds, skies):
    cat, cam = load_hipparcos(), Camera()
    plugins = [get_algorithm(x)() for x in names]
    dbs = [a.build(cat, cam) for a in plugins]
    for sky in skies:
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(len(trials))]
        for a, db in zip(plugins, dbs, strict=True):
            a.identify(db, obs[0])
        t = np.full((len(names), len(obs)), np.inf)
        for _ in range(rounds):
            for k, o in enumerate(obs):
                for j, (a, db) in enumerate(zip(plugins, dbs, strict=True)):
                    t0 = time.perf_counter_ns()
                    a.identify(db, o)
                    t[j, k] = min(t[j, k], (time.perf_counter_ns() - t0) * 1e-3)
        ref = np.median(t[0])
        for j, x in enumerate(names):
            med = np.median(t[j])
            print(f"{sky:5s} {x:12s} median {med:8.1f} p95 {np.percentile(t[j], 95):8.1f} mean {t[j].mean():8.1f} us"
                  f"  {med / ref:6.2f}x {names[0]}  p95/median {np.percentile(t[j], 95) / med:5.2f}")


if __name__ == "__main__":
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    main(sys.argv[1].split(","), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4:] or ["paper", "real"])
