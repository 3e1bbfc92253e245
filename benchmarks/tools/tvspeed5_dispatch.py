"""The cost of entering a numba kernel with triangle voting's arguments, cold and warm (issue #25, tvspeed5).

    python benchmarks/tools/tvspeed5_dispatch.py [N]

Four kernels that return at once, called with: ``d7`` identify_image's seven arguments (the stars' x, y, mag and
four plain tuples: 13 arrays, 35 Python numbers); ``d_arr`` x, y, mag, 11 of those arrays and one float64 array of
the numbers; ``d_tup`` the same with the 11 arrays in one tuple; ``d3`` x, y, mag alone. Table 6's paper-sky
images (seed 0), N (60) x 2 rounds: per image and kernel, every other registered plugin identifies the image, then
one timed call ("cold"), then the minimum of 3 back-to-back calls ("warm"). Prints the medians, in us.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from test_ratios import NAMES, TABLE6_SIM  # noqa: E402


@njit(cache=True)
def d7(x, y, mag, db, tol, fin_db, fin_cam):
    return x.shape[0] + db[4] + tol[4] + fin_db[1].shape[0] + fin_cam[-1]


@njit(cache=True)
def d_arr(x, y, mag, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, params):
    return x.shape[0] + params[0]


@njit(cache=True)
def d_tup(x, y, mag, arrs, params):
    return x.shape[0] + params[0] + arrs[0].shape[0]


@njit(cache=True)
def d3(x, y, mag):
    return x.shape[0]


def main(n: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES["paper"]}), seed=0)
    tr = sim.generate(n)
    obs = [tr.observation(i, truth=False) for i in range(n)]
    others = [get_algorithm(x)() for x in NAMES if x != "triangle_voting"]
    dbs = [a.build(cat, cam) for a in others]
    alg = get_algorithm("triangle_voting")()
    db = alg.build(cat, cam)
    kt, ktol, fin_db, fin_cam = alg._kernel_args(db, cam)
    arrs = [a for a in kt + fin_db if isinstance(a, np.ndarray)][:11]
    params = np.array([float(v) for v in ktol + fin_cam + tuple(v for v in kt if not isinstance(v, np.ndarray))])
    atup = tuple(arrs)
    calls = {"d7": lambda o: d7(o.x_px, o.y_px, o.mag, kt, ktol, fin_db, fin_cam),
             "d_arr": lambda o: d_arr(o.x_px, o.y_px, o.mag, *arrs, params),
             "d_tup": lambda o: d_tup(o.x_px, o.y_px, o.mag, atup, params),
             "d3": lambda o: d3(o.x_px, o.y_px, o.mag)}
    for a, d in zip(others, dbs, strict=True):
        a.identify(d, obs[0])
    for f in calls.values():
        f(obs[0])
    cold = {k: [] for k in calls}
    warm = {k: [] for k in calls}
    for _ in range(2):
        for o in obs:
            for k, f in calls.items():
                for a, d in zip(others, dbs, strict=True):
                    a.identify(d, o)
                t0 = time.perf_counter_ns()
                f(o)
                cold[k].append((time.perf_counter_ns() - t0) * 1e-3)
                w = []
                for _ in range(3):
                    t0 = time.perf_counter_ns()
                    f(o)
                    w.append((time.perf_counter_ns() - t0) * 1e-3)
                warm[k].append(min(w))
    for k in calls:
        print(f"{k:6s} cold {np.median(cold[k]):6.1f} us  warm {np.median(warm[k]):6.1f} us")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 60)
