"""ptp's kernel (and tetra's ``identify``) timed right after itself on the same image or on other images,
without other plugins between (issue #25, eighth round): whether a warm call is fast because it repeats the
image (the branch predictors trained on its own data-dependent branches) or because its code and tables are in
the cache.

    python benchmarks/tools/ptpspeed7_repeat.py N SKY

Table 6's images (1 px / 0.5 Mv, seed 0), N of them in SKY (paper or real); median µs over the images of one
call right after: the same image; the previous image; the three previous images.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from starid_algorithms.ptp import kernels as K

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm


def main(n: int, sky: str) -> None:
    cat, cam = load_hipparcos(), Camera()
    ptp = get_algorithm("ptp")()
    db = ptp.build(cat, cam)
    tetra = get_algorithm("tetra")()
    tdb = tetra.build(cat, cam)
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                    seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(n)]
    ptp.identify(db, obs[0])
    tetra.identify(tdb, obs[0])
    _, params, (narrow, wide), _ = ptp.kept("kernel_call", (db, cam), lambda: None)

    def kernel(o):
        t0 = time.perf_counter_ns()
        K.identify_kernel(o.x_px, o.y_px, o.mag, params, narrow, wide)
        return time.perf_counter_ns() - t0

    def tetra_call(o):
        t0 = time.perf_counter_ns()
        tetra.identify(tdb, o)
        return time.perf_counter_ns() - t0

    out = {k: [] for k in ("ptp kernel, the same image before", "ptp kernel, the previous image before",
                           "ptp kernel, three other images before", "tetra identify, the same image before",
                           "tetra identify, the previous image before")}
    lists = list(out.values())
    for i, o in enumerate(obs):
        p, q, r = obs[i - 1], obs[i - 2], obs[i - 3]
        kernel(o)
        lists[0].append(kernel(o))
        kernel(p)
        lists[1].append(kernel(o))
        kernel(p)
        kernel(q)
        kernel(r)
        lists[2].append(kernel(o))
        tetra_call(o)
        lists[3].append(tetra_call(o))
        tetra_call(p)
        lists[4].append(tetra_call(o))
    print(f"{sky} sky, {n} images; median µs of one call right after")
    for k, v in out.items():
        print(f"  {k:42s} {np.median(v) / 1e3:7.1f}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), sys.argv[2])
