"""Where an interleaved ptp call's time goes, with a cache-evicting buffer walk between calls (issue #25,
sixth speed round). Cheaper than ``ptpspeed4_split.py`` (which runs the 13 other plugins before each call).

    python benchmarks/tools/ptpspeed5_split.py N SKY [WALK_MB] [others]

Table 6's images (1 px / 0.5 Mv, seed 0), N of them in the sky SKY (paper or real). Before every timed call
a walk over a WALK_MB buffer (default 16: four times the 4 MB L2) evicts the caches, or, with ``others``,
every other registered plugin identifies the image first (as ``benchmarks/test_ratios.py``). Median over
the images, µs, of: tetra's ``identify``; ptp's ``identify`` (wrapper included); ``identify_kernel`` with
the plugin's tolerances, without the steps after validation, with ``max_candidates=0`` (no records), with
no windows (``d_max`` of one unit); the full kernel with the packed tables read (untimed) just before, and
with the kernel run on another image just before (its code and objects warm, most rows cold); a numba kernel
that returns at once with ptp's six arguments, and
with one small array. The counters' medians (detections, windows) are printed too.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from numba import njit
from starid_algorithms.ptp import kernels as K
from starid_algorithms.ptp.algorithm import _view

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import available_algorithms, get_algorithm


@njit
def _noop6(x_px, y_px, mag, params, narrow, wide):
    return np.zeros(1, dtype=np.int64)


@njit
def _noop1(x_px):
    return np.zeros(1, dtype=np.int64)


def _kernel_call(params, narrow, wide):
    return lambda o: K.identify_kernel(o.x_px, o.y_px, o.mag, params, narrow, wide)


def main(n: int, sky: str, walk_mb: float, others: bool) -> None:
    cat, cam = load_hipparcos(), Camera()
    ptp = get_algorithm("ptp")()
    db = ptp.build(cat, cam)
    tetra = get_algorithm("tetra")()
    tdb = tetra.build(cat, cam)
    rest = []
    if others:
        names = sorted(i.name for i in available_algorithms() if i.status == "ok")
        rest = [(a, a.build(cat, cam)) for a in (get_algorithm(nm)() for nm in names if nm not in ("ptp", "tetra"))]
    narrow, wide = db.packed
    view = _view(cam)
    tol = ptp.tolerances(db)
    post_off = {"verify": False, "confirm_fraction": 0.0, "nearest_check": False, "hypotheses": 0}
    tols = {"full": K.params_of(view, tol), "no post": K.params_of(view, tol._replace(**post_off)),
            "no records": K.params_of(view, tol._replace(max_candidates=0, **post_off)),
            "no windows": K.params_of(view, tol._replace(d_max=1.0, **post_off))}
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                    seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(n)]
    buf = np.ones(int(walk_mb * 2**20) // 8)

    def evict(o):
        if others:
            for a, d in rest:
                a.identify(d, o)
        else:
            buf[::8] += 1.0           # one write per 64-byte line

    calls = {
        "tetra identify": lambda o: tetra.identify(tdb, o),
        "ptp identify": lambda o: ptp.identify(db, o),
        **{f"kernel {k}": _kernel_call(t, narrow, wide) for k, t in tols.items()},
        "noop kernel, ptp's 6 args": lambda o: _noop6(o.x_px, o.y_px, o.mag, tols["full"], narrow, wide),
        "noop kernel, 1 arg": lambda o: _noop1(o.x_px),
    }
    for f in calls.values():
        f(obs[0])
    for a, d in rest:
        a.identify(d, obs[0])
    prev = {"o": obs[-1]}

    def touched(o):                   # untimed before the call: the packed tables read into the cache
        return lambda: (narrow.sum(), wide.sum())

    def other_image(o):               # untimed: the full kernel on another image (its code and objects)
        return lambda: K.identify_kernel(prev["o"].x_px, prev["o"].y_px, prev["o"].mag, tols["full"], narrow, wide)

    pre = {"kernel full, tables touched first": touched, "kernel full, another image first": other_image}
    for k in pre:
        calls[k] = calls["kernel full"]
    cold = {k: [] for k in calls}
    warm = {k: [] for k in calls}
    n_det, n_win = [], []
    for o in obs:
        ident = ptp.identify(db, o)
        n_det.append(len(o.x_px))
        n_win.append(ident.counters["searches"])
        for k, f in calls.items():
            evict(o)
            if k in pre:
                pre[k](o)()
            t0 = time.perf_counter_ns()
            f(o)
            cold[k].append(time.perf_counter_ns() - t0)
            best = np.inf
            for _ in range(3):
                t0 = time.perf_counter_ns()
                f(o)
                best = min(best, time.perf_counter_ns() - t0)
            warm[k].append(best)
        prev["o"] = o
    how = "the other plugins" if others else f"a {walk_mb:g} MB walk"
    print(f"{sky} sky, {n} images (median detections {np.median(n_det):.0f}, windows {np.median(n_win):.0f}); "
          f"median µs: cold (after {how}) / warm (min of 3)")
    for k in calls:
        print(f"  {k:28s} {np.median(cold[k]) / 1e3:7.1f} {np.median(warm[k]) / 1e3:7.1f}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4, 5):
        sys.exit(__doc__)
    main(int(sys.argv[1]), sys.argv[2], float(sys.argv[3]) if len(sys.argv) >= 4 else 16.0,
         len(sys.argv) == 5 and sys.argv[4] == "others")
