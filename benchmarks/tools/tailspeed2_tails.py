"""Tail images of pvector, interior_angle and geometric_voting, and what variants cost on them
(issue #25, branch tailspeed2).

    python benchmarks/tools/tailspeed2_tails.py REF VARIANT[;VARIANT...] N R [real|paper]

Table 6's sky (default real) at 1 px / 0.5 Mv, seed 0, N images (test_ratios' images). Each variant
(``NAME``, ``NAME[KEY=VALUE,...]`` or ``NAME:SOURCE``, separated by ``;``) identifies every image R
times, interleaved image by image; each image's time is the minimum of the R. The tail is the
slowest 10 % of the images under REF (a variant spec). Prints per variant the median, p95, p95 /
median, the summed time of the tail images and of all images, and whether its hip arrays equal
REF's on every image (a variant that changes a parameter need not).
"""

import sys
import time

import numpy as np

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.experiment.spec import Variant

TABLE6_SIM = {"sigma_px": 1.0, "sigma_mag": 0.5, "mag_limit": 6.0, "min_stars": 6}


def main(ref, specs, n, rounds, sky):
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    specs = [ref] + [s for s in specs if s != ref]
    algs = [Variant.parse(s).make() for s in specs]
    dbs = [a.build(cat, cam) for a in algs]
    for a, db in zip(algs, dbs, strict=True):
        a.identify(db, obs[0])
    t = np.full((len(algs), n), np.inf)
    hips = [[None] * n for _ in algs]
    for _ in range(rounds):
        for k, o in enumerate(obs):
            for j, (a, db) in enumerate(zip(algs, dbs, strict=True)):
                t0 = time.perf_counter_ns()
                r = a.identify(db, o)
                t[j, k] = min(t[j, k], (time.perf_counter_ns() - t0) * 1e-9)
                hips[j][k] = r.hip
    tail = np.argsort(-t[0])[: max(1, n // 10)]
    print(f"{sky} sky, {n} images, min of {rounds}; tail = slowest 10 % under {ref}: {sorted(tail.tolist())}")
    for j, s in enumerate(specs):
        med, p95 = np.median(t[j]), np.percentile(t[j], 95)
        same = all(np.array_equal(hips[j][k], hips[0][k]) for k in range(n))
        print(f"  {s:50s} median {med * 1e6:7.1f} us  p95 {p95 * 1e6:7.1f} us  p95/med {p95 / med:5.2f}  "
              f"tail {t[j, tail].sum() * 1e3:7.2f} ms  all {t[j].sum() * 1e3:7.2f} ms  same hips {same}")


if __name__ == "__main__":
    if len(sys.argv) not in (5, 6):
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2].split(";"), int(sys.argv[3]), int(sys.argv[4]),
         sys.argv[5] if len(sys.argv) == 6 else "real")
