"""Where planar_triangle's identify time goes when the caches are cold, as in the benchmark.

    python benchmarks/tools/plnspeed3_profile.py 100 3

Table 6's skies (1 px / 0.5 Mv, seed 0), N images, R rounds; each image is identified by tetra and
then by planar_triangle's ``identify`` sequence with a clock between the steps ("cold": as
``benchmarks/test_ratios.py`` interleaves plugins), then the same sequence again at once ("warm").
Prints the medians over images x rounds in us, and ``identify`` timed whole after a second tetra call
(the image's third visit, so partly warm: a check that the steps add up, not the benchmark's number).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from starid_algorithms.planar_triangle import kernels as ptk

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.plugin import Identification
from starid.registry import get_algorithm

T = time.perf_counter_ns
STEPS = ("prepare (held + choose_stars)", "identify_subsets", "rows + counters", "finish", "Identification")


def _sequence(alg, db, o):
    """``identify``'s steps (the default parameters' path) with a clock between them."""
    t = [T()]
    cam = o.camera
    held = alg._held(db, cam)
    order, v_cam, rank = ptk.choose_stars(o.x_px, o.y_px, o.mag, held[4], held[5], cam.f_px, cam.cx_px, cam.cy_px)
    stages = held[6].get(order.size)
    if stages is None:
        stages = held[6][order.size] = alg._stages(order.size)
    t.append(T())
    rows, chain, stage, work = ptk.identify_subsets(v_cam, rank, held[2], held[3], stages)
    t.append(T())
    all_rows = np.full(len(o), -1, dtype=np.int64)
    all_rows[order] = rows
    counts = work.tolist()
    counters = dict(zip(ptk.WORK_COUNTERS, counts, strict=True))
    t.append(T())
    if stage >= 0:
        small = stage == held[7]
        hip, att, ok = ptk.finish(o.x_px, o.y_px, o.mag, all_rows, db.guide_unit, db.guide_hip, db.deep,
                                  db.deep_v_mag, held[8], held[10] if small else held[9])
    else:
        hip, att, ok = np.full(len(o), -1, dtype=np.int64), None, False
    t.append(T())
    Identification(hip, att if ok else None, counters=counters)
    t.append(T())
    return np.diff(t) / 1e3


def main(n: int, rounds: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    tetra, alg = get_algorithm("tetra")(), get_algorithm("planar_triangle")()
    tdb, db = tetra.build(cat, cam), alg.build(cat, cam)
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(n)]
        tetra.identify(tdb, obs[0])
        alg.identify(db, obs[0])
        cold, warm, whole, t_tetra = [], [], [], []
        for _ in range(rounds):
            for o in obs:
                t0 = T()
                tetra.identify(tdb, o)
                t_tetra.append((T() - t0) / 1e3)
                cold.append(_sequence(alg, db, o))
                warm.append(_sequence(alg, db, o))
                tetra.identify(tdb, o)
                t0 = T()
                alg.identify(db, o)
                whole.append((T() - t0) / 1e3)
        cold, warm = np.array(cold), np.array(warm)
        print(f"{sky} sky, {n} images x {rounds}: median us (cold / warm); tetra {np.median(t_tetra):.1f}")
        for k, name in enumerate(STEPS):
            print(f"  {name:32s} {np.median(cold[:, k]):8.1f} {np.median(warm[:, k]):8.1f}")
        print(f"  {'sum of the steps':32s} {np.median(cold.sum(1)):8.1f} {np.median(warm.sum(1)):8.1f}")
        print(f"  {'identify whole, 3rd visit':32s} {np.median(whole):8.1f}   p95 {np.percentile(whole, 95):8.1f}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]))
