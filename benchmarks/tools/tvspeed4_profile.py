"""Where triangle_voting's ``identify`` spends its time, interleaved as the benchmark times it and warm (issue #25).

    python benchmarks/tools/tvspeed4_profile.py [N] [R]

Table 6's two skies (``benchmarks/test_ratios.py``'s settings: 1 px / 0.5 Mv, V <= 6, more than five stars,
seed 0), N images (200), R rounds (2). Every registered plugin is built and warmed up as in the benchmark. Then,
per image and per stage, the other plugins identify the image first (untimed: they evict triangle_voting's data
and code from the caches as in the benchmark's interleaved timing) and the stage is timed once ("cold"); and per
image each stage is timed 3 times back to back, minimum kept ("warm"). Stages, each called as ``identify`` calls
it: ``vote``, ``identify_rows`` (+ selection, verification, confirmation / fallback), ``identify_image`` (the one
kernel: order, back-projection, ``identify_rows``, the final step) and ``identify`` (+ the Python wrapper and the
``Identification``); tetra's ``identify`` is timed the same way for scale. Prints the median over images and
rounds per stage, in us.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from starid_algorithms.triangle_voting import algorithm as tva
from starid_algorithms.triangle_voting import kernels as tvk

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px
from starid.registry import get_algorithm

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from test_ratios import NAMES, TABLE6_SIM  # noqa: E402

STAGES = ("vote", "identify_rows", "identify_image", "identify", "tetra")
NO = np.zeros((0, 0), dtype=np.int32)


def _calls(alg, db, tetra, tetra_db, o):
    """The stages of one image as argument-free callables."""
    x, y, mag = o.x_px, o.y_px, o.mag
    _, ktol, fin_cam = alg._tolerances(o.camera)
    kt, fin_db = tva._kernel_tables(db), tva._finish_tables(db)
    out = {"identify": lambda: alg.identify(db, o),
           "identify_image": lambda: tvk.identify_image(x, y, mag, kt, ktol, fin_db, fin_cam),
           "tetra": lambda: tetra.identify(tetra_db, o)}
    order = np.lexsort((y, x, mag))
    order = order[mag[order] <= alg.mag_limit + alg.mag_margin][:alg.max_stars]
    if order.size >= 3:
        cam = o.camera
        v_cam = backproject_px(x[order], y[order], cam.f_px, cam.cx_px, cam.cy_px)
        out["vote"] = lambda: tvk.vote(v_cam, kt, ktol, NO, NO)
        out["identify_rows"] = lambda: tvk.identify_rows(v_cam, kt, ktol, NO, NO)
    return out


def _time(f) -> float:
    t0 = time.perf_counter_ns()
    f()
    return (time.perf_counter_ns() - t0) * 1e-3


def main(n: int, rounds: int, calls_of=None, stages=STAGES) -> None:
    """Print the table; ``calls_of`` (default :func:`_calls`) and ``stages`` let tvspeed5_profile.py add stages."""
    calls_of = calls_of or _calls
    cat, cam = load_hipparcos(), Camera()
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(len(trials))]
        plugins = [get_algorithm(name)() for name in NAMES]
        dbs = [a.build(cat, cam) for a in plugins]
        for a, db in zip(plugins, dbs, strict=True):
            a.identify(db, obs[0])
        k_tv, k_te = NAMES.index("triangle_voting"), NAMES.index("tetra")
        others = [(a, db) for j, (a, db) in enumerate(zip(plugins, dbs, strict=True)) if j not in (k_tv, k_te)]
        alg, db = plugins[k_tv], dbs[k_tv]
        calls = [calls_of(alg, db, plugins[k_te], dbs[k_te], o) for o in obs]
        for c in calls:  # compile every stage
            for f in c.values():
                f()
        cold = {s: [] for s in stages}
        warm = {s: [] for s in stages}
        for _ in range(rounds):
            for o, c in zip(obs, calls, strict=True):
                for s in stages:
                    if s not in c:
                        continue
                    for a, d in others:
                        a.identify(d, o)
                    cold[s].append(_time(c[s]))
        for c in calls:
            for s in stages:
                if s in c:
                    warm[s].append(min(_time(c[s]) for _ in range(3)))
        print(f"{sky} sky, {n} images x {rounds}: median us, cold (after {len(others)} other plugins) / warm")
        for s in stages:
            print(f"  {s:15s} {np.median(cold[s]):8.1f} {np.median(warm[s]):8.1f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200, int(sys.argv[2]) if len(sys.argv) > 2 else 2)
