"""angle's and interior_angle's ``identify`` against the wrapper they had before stop 45's savings (issue #25).

    python benchmarks/tools/wrap45_angle.py N R

Until stop 45 both plugins' ``identify`` rebuilt the tolerances and the camera frame for every image,
called the search kernel, then took the catalog ids (``hip_of``) and the attitude (``backproject_px`` and
``wahba_rows`` from Python) after it. Now the two are kept per (database, camera) and one numba call
(``identify_kernel``) returns the ids and the attitude too. This tool runs, on Table 6's images (1 px /
0.5 Mv, seed 0, N per sky, the minimum of R per image, tetra's identify before each), the plugin's
``identify`` and ``old``, that wrapper rebuilt here on the plugins' ``angle_kernel`` / ``interior_kernel``
(the search's rows, pair or trio and counters, from ``identify_kernel``), and asserts the same ``hip`` (and
dtype), counters and attitude (bit for bit) on every repeat: the ids and the attitude computed in the kernel
against the Python arithmetic they replace. Nothing here changes a plugin. ``old``'s times are not the
pre-stop-45 plugin's (its kernel now computes the ids and the attitude too, and ``angle_kernel`` wraps
``identify_kernel``): for before / after times run ``benchmarks/tools/min_time.py`` on the two commits.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from starid_algorithms.angle.kernels import WORK_NAMES as ANGLE_WORK
from starid_algorithms.angle.kernels import angle_kernel
from starid_algorithms.interior_angle.kernels import WORK_NAMES as INTERIOR_WORK
from starid_algorithms.interior_angle.kernels import interior_kernel
from starid_algorithms.pyramid.algorithm import hip_of

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, camera_frame, wahba_rows
from starid.plugin import Identification
from starid.registry import get_algorithm

TABLE6_SIM = {"sigma_px": 1.0, "sigma_mag": 0.5, "mag_limit": 6.0, "min_stars": 6}
KERNELS = {"angle": (angle_kernel, ANGLE_WORK), "interior_angle": (interior_kernel, INTERIOR_WORK)}


def old_identify(alg, search, work_names):
    """The wrapper before stop 45 (both plugins had this one), on the plugin's search kernel."""
    def identify(db, o):
        rows, _, work = search(o.x_px, o.y_px, o.mag, db.kv, db.pairs, db.nbr, db.nbr_chord, db.nbr_start,
                               db.guide_unit, alg.tolerances(o.camera, db), camera_frame(o.camera))
        hip = hip_of(db, rows)
        counters = dict(zip(work_names, work.tolist(), strict=True))
        if not (rows >= 0).any():
            return Identification(hip, None, counters=counters)
        cam = o.camera
        v = backproject_px(o.x_px, o.y_px, cam.f_px, cam.cx_px, cam.cy_px)
        return Identification(hip, wahba_rows(v, rows, db.guide_unit), counters=counters)
    return identify


def same(a, b):
    if a.hip.dtype != b.hip.dtype or not (a.hip == b.hip).all() or a.counters != b.counters:
        return False
    if a.attitude is None or b.attitude is None:
        return a.attitude is None and b.attitude is None
    return bool((a.attitude == b.attitude).all())


def main(n: int, rounds: int, names=("angle", "angle:paper", "interior_angle", "interior_angle:paper")) -> None:
    cat, cam = load_hipparcos(), Camera()
    tetra = get_algorithm("tetra")()
    tdb = tetra.build(cat, cam)
    runs = {}
    for name in names:
        base, _, reading = name.partition(":")
        cls = get_algorithm(base)
        alg = cls(**cls.published_readings[reading]) if reading == "galvizo2018" else \
            cls(**cls.published) if reading == "paper" else cls()
        search, work_names = KERNELS[base]
        runs[name] = (alg, alg.build(cat, cam), old_identify(alg, search, work_names))
    for sky in ("paper", "real"):
        trials = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0).generate(n)
        obs = [trials.observation(i, truth=False) for i in range(len(trials))]
        tetra.identify(tdb, obs[0])
        print(f"{sky} sky, {len(obs)} images, min of {rounds}: median µs (x tetra's median), mean")
        for name, (alg, db, old) in runs.items():
            alg.identify(db, obs[0])
            old(db, obs[0])                                     # compile apart
            best = {k: np.full(len(obs), np.inf) for k in ("tetra", "old", "new")}
            for i, o in enumerate(obs):
                for _ in range(rounds):
                    out = {}
                    for label, f in (("old", old), ("new", alg.identify)):
                        t0 = time.perf_counter_ns()
                        tetra.identify(tdb, o)
                        t1 = time.perf_counter_ns()
                        out[label] = f(db, o)
                        t2 = time.perf_counter_ns()
                        best["tetra"][i] = min(best["tetra"][i], t1 - t0)
                        best[label][i] = min(best[label][i], t2 - t1)
                    assert same(out["old"], out["new"]), (sky, name, i)
            t_ref = np.median(best["tetra"])
            line = "  ".join(f"{k} {np.median(v) / 1e3:6.1f} ({np.median(v) / t_ref:4.2f}x) mean {v.mean() / 1e3:6.1f}"
                             for k, v in best.items())
            print(f"  {name:22s} {line}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]))
