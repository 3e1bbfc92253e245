"""Per-image identify time at 1 px / 0.5 Mv with F false stars (zhou2015's false-star sweep), robust to
load: the minimum over R repeats of each image.

    python benchmarks/tools/false_star_time.py planar_triangle 40 3 5      # NAME N R F

Table 6's camera and simulation (seed 0), both skies; prints per sky the median, mean and p95 over
images of the per-image minimum, in microseconds (see min_time.py for the caveat of the minimum).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from starid import SimConfig, Simulator, load_hipparcos
from starid.experiment.spec import sim_settings
from starid.experiments import table6
from starid.harness import prepare
from starid.registry import algorithm_info


def main(name: str, n: int, repeats: int, false_stars: int) -> None:
    exp = table6.experiment(trials=2)
    camera, catalog = exp.make_camera(), load_hipparcos()
    for sky in ("paper", "real"):
        settings = sim_settings(exp.sim, {"sky": sky, "sigma_px": 1.0, "sigma_mag": 0.5, "false_stars": false_stars})
        trials = Simulator(catalog, camera, SimConfig(**settings), seed=0).generate(n)
        p = prepare(algorithm_info(name).cls(), catalog, trials.camera, trials.warmup, name)
        times = []
        for i in range(n):
            obs = trials.observation(i, truth=False)
            best = np.inf
            for _ in range(repeats):
                t0 = time.perf_counter()
                p.algorithm.identify(p.database, obs)
                best = min(best, time.perf_counter() - t0)
            times.append(best * 1e6)
        t = np.array(times)
        print(f"{sky:5s} {name} false_stars={false_stars} n={n} min of {repeats}: median {np.median(t):10.1f} us  "
              f"mean {t.mean():10.1f} us  p95 {np.percentile(t, 95):10.1f} us", flush=True)


if __name__ == "__main__":
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]))
