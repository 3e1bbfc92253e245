"""What angle's Python side would cost with two exact changes, measured, not made (issue #25, stop 45).

    python benchmarks/tools/profile45_angle_wrapper.py N R

``benchmarks/tools/profile45_angle.py`` finds half of ``Angle.identify``'s median time outside the kernel's
work: ``tolerances()`` and ``camera_frame()`` rebuilt for every image, ``hip_of`` and the attitude
(``backproject_px`` and ``wahba_rows``, each a numba call from Python) after the kernel. This tool times, on
Table 6's images (1 px / 0.5 Mv, seed 0, N per sky, the minimum of R per image, tetra's identify before
each), the plugin's ``identify`` against two functions of this tool that do the same thing:

* ``kept``: the tolerances and the camera frame kept per (database, camera) with ``Algorithm.kept``, as ptp's
  wrapper keeps its arguments;
* ``kept + in kernel``: the same, and the catalog ids and the attitude computed in a numba function that calls
  ``angle_kernel`` and then the same ``backproject_px`` / ``wahba_rows`` on its rows.

Each image's results must be the plugin's exactly: the same ``hip`` (and dtype), counters and attitude (bit for
bit; asserted on every repeat). Nothing here changes the plugin.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from numba import njit
from starid_algorithms.angle.kernels import WORK_NAMES, angle_kernel
from starid_algorithms.pyramid.algorithm import hip_of

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, camera_frame, wahba_rows
from starid.plugin import Identification
from starid.registry import get_algorithm

TABLE6_SIM = {"sigma_px": 1.0, "sigma_mag": 0.5, "mag_limit": 6.0, "min_stars": 6}


@njit
def kernel_hip_attitude(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, cam, guide_hip):
    """``angle_kernel``, then the catalog ids and the attitude the wrapper computes from its rows."""
    rows, _, work = angle_kernel(x_px, y_px, mag, kv, pairs, nbr, nbr_chord, nbr_start, guide_unit, tol, cam)
    n = rows.shape[0]
    hip = np.full(n, -1, dtype=np.int64)
    found = False
    for s in range(n):
        if rows[s] >= 0:
            hip[s] = guide_hip[rows[s]]
            found = True
    if found:
        v = backproject_px(x_px, y_px, cam.f_px, cam.cx_px, cam.cy_px)
        return hip, wahba_rows(v, rows, guide_unit), True, work
    return hip, np.zeros((3, 3)), False, work


def make_variants(alg):
    def kept_args(db, camera):
        return alg.kept("profile45", (db, camera), lambda: (alg.tolerances(camera, db), camera_frame(camera)))

    def identify_kept(db, o):
        camera = o.camera
        tol, frame = kept_args(db, camera)
        rows, _, work = angle_kernel(o.x_px, o.y_px, o.mag, db.kv, db.pairs, db.nbr, db.nbr_chord, db.nbr_start,
                                     db.guide_unit, tol, frame)
        hip = hip_of(db, rows)
        counters = dict(zip(WORK_NAMES, work.tolist(), strict=True))
        if not (rows >= 0).any():
            return Identification(hip, None, counters=counters)
        v = backproject_px(o.x_px, o.y_px, camera.f_px, camera.cx_px, camera.cy_px)
        return Identification(hip, wahba_rows(v, rows, db.guide_unit), counters=counters)

    def identify_in_kernel(db, o):
        tol, frame = kept_args(db, o.camera)
        hip, attitude, found, work = kernel_hip_attitude(o.x_px, o.y_px, o.mag, db.kv, db.pairs, db.nbr,
                                                         db.nbr_chord, db.nbr_start, db.guide_unit, tol, frame,
                                                         db.guide_hip)
        return Identification(hip, attitude if found else None,
                              counters=dict(zip(WORK_NAMES, work.tolist(), strict=True)))

    return {"angle identify (the plugin's)": alg.identify, "kept": identify_kept,
            "kept + in kernel": identify_in_kernel}


def same(a, b):
    if a.hip.dtype != b.hip.dtype or not (a.hip == b.hip).all() or a.counters != b.counters:
        return False
    if a.attitude is None or b.attitude is None:
        return a.attitude is None and b.attitude is None
    return bool((a.attitude == b.attitude).all())


def main(n: int, rounds: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    alg = get_algorithm("angle")()
    db = alg.build(cat, cam)
    tetra = get_algorithm("tetra")()
    tdb = tetra.build(cat, cam)
    variants = make_variants(alg)
    for sky in ("paper", "real"):
        trials = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0).generate(n)
        obs = [trials.observation(i, truth=False) for i in range(len(trials))]
        for f in variants.values():
            f(db, obs[0])                                       # compile apart
        tetra.identify(tdb, obs[0])
        best = {k: np.full(len(obs), np.inf) for k in ("tetra identify", *variants)}
        for i, o in enumerate(obs):
            for _ in range(rounds):
                out = {}
                for label, f in variants.items():
                    t0 = time.perf_counter_ns()
                    tetra.identify(tdb, o)
                    t1 = time.perf_counter_ns()
                    out[label] = f(db, o)
                    t2 = time.perf_counter_ns()
                    best["tetra identify"][i] = min(best["tetra identify"][i], t1 - t0)
                    best[label][i] = min(best[label][i], t2 - t1)
                ref = out["angle identify (the plugin's)"]
                assert all(same(ref, v) for v in out.values()), (sky, i)
        t_ref = np.median(best["tetra identify"])
        print(f"{sky} sky, {len(obs)} images, min of {rounds}: median µs (x tetra's median), mean")
        for label, v in best.items():
            print(f"  {label:32s} {np.median(v) / 1e3:8.1f} ({np.median(v) / t_ref:4.2f}x) {v.mean() / 1e3:8.1f}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]))
