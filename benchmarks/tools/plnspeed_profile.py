"""Where planar_triangle's identify time goes, and why its steps cost more inside ``identify`` than alone.

    python benchmarks/tools/plnspeed_profile.py 30 7

Table 6's sky (1 px / 0.5 Mv, seed 0), paper then real, N images, minimum of R repeats per image; prints
medians over images in us. "alone": each step repeated on its own (its data stay in cache between
repeats), as ``ptspeed_profile.py`` times them; "in identify": ``identify``'s own sequence with a clock
between the steps (``_run``: star choice, back-projection and the subset kernel; the ``Finish`` rules and
camera frame; ``finish``; the ``Identification``). Also the kernel's parts: the image triangles and their
area k-vector searches, and per image triangle the moment filter (``_moment_list``) and a hash table of
all its candidates' star pairs (``_fill_hash``), for every image triangle of the image.
"""

# ruff: noqa: B023  (each lambda is called at once, inside its loop iteration)
from __future__ import annotations

import math
import sys
import time

import numpy as np
from numba import njit
from starid_algorithms.planar_triangle import kernels as ptk

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import camera_frame
from starid.plugin import Identification
from starid.registry import get_algorithm

T = time.perf_counter_ns


def _best(fn, repeats):
    b = np.inf
    for _ in range(repeats):
        t0 = T()
        fn()
        b = min(b, T() - t0)
    return b / 1e3


@njit
def _parts(v, db, tol, with_hash):
    img = ptk.image_triangles(v, db, tol)
    cache = ptk.new_cache(img, db.unit.shape[0])
    n = 0
    for t in range(img.tri.shape[0]):
        cand = ptk._moment_list(t, img, db, tol, cache)
        n += cand.shape[0]
        if with_hash:
            size = ptk._hash_size(cand.shape[0])
            ptk._fill_hash(cand, cand.shape[0], db.stars, np.empty(size, np.uint64))
    return n, img.tri.shape[0]


def main(n: int, repeats: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    alg = get_algorithm("planar_triangle")()
    db = alg.build(cat, cam)
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(n)]
        alg.identify(db, obs[0])
        res: dict[str, list[float]] = {}
        for o in obs:
            x, y, mag = o.x_px, o.y_px, o.mag
            usable = np.flatnonzero(mag <= db.mag_limit + alg.mag_margin)
            usable = usable[np.lexsort((y[usable], x[usable], mag[usable]))[:alg._n_chosen()]]
            order = usable[np.lexsort((mag[usable], y[usable], x[usable]))]
            v = o.camera.backproject(x[order], y[order])
            tol, tables = alg._tolerance(o.camera), db.tables()
            rank, stages = np.lexsort((y[order], x[order], mag[order])), alg._stages(order.size)
            all_rows, _, stage, counters = alg._run(db, o)
            frame = camera_frame(o.camera)
            rules = ptk.Finish(tol.beta * math.sqrt(2.0) * tol.sigma_rad, float(alg.mag_margin), float(db.mag_limit),
                               float(alg.coverage_mag_margin), float(alg.max_missed_fraction), True)
            d = {"identify": _best(lambda: alg.identify(db, o), repeats),
                 "alone: _run": _best(lambda: alg._run(db, o), repeats),
                 "alone: identify_subsets": _best(lambda: ptk.identify_subsets(v, rank, tables, tol, stages), repeats),
                 "alone: finish": _best(lambda: ptk.finish(x, y, mag, all_rows, db.guide_unit, db.guide_hip, db.deep,
                                                           db.deep_v_mag, frame, rules), repeats),
                 "parts: image_triangles + moment lists": _best(lambda: _parts(v, tables, tol, False), repeats),
                 "parts: + all hash tables": _best(lambda: _parts(v, tables, tol, True), repeats)}
            cnt, m = _parts(v, tables, tol, False)
            d["image triangles"], d["moment candidates per triangle"] = m, cnt / max(m, 1)
            d["candidates (counter)"], d["pivots (counter)"] = counters["candidates"], counters["pivots"]
            seq = np.full(4, np.inf)
            for _ in range(repeats):  # identify's sequence, a clock between its steps
                t = [T()]
                rows, _, stage, counters = alg._run(db, o)
                t.append(T())
                tol = alg._tolerance(o.camera)
                small = alg.small_subset_size is not None and stage == len(alg._stages(1)) - 1 and stage > 0
                fr = ptk.Finish(tol.beta * math.sqrt(2.0) * tol.sigma_rad, float(alg.mag_margin),
                                float(db.mag_limit), float(alg.coverage_mag_margin), float(alg.max_missed_fraction),
                                bool(alg.assign_all or small))
                frame = camera_frame(o.camera)
                t.append(T())
                hip, att, acc = ptk.finish(x, y, mag, rows, db.guide_unit, db.guide_hip, db.deep, db.deep_v_mag,
                                           frame, fr)
                t.append(T())
                Identification(hip, att if acc else None, counters=counters)
                t.append(T())
                seq = np.minimum(seq, np.diff(t) / 1e3)
            for k, val in zip(("in identify: _run", "in identify: rules + frame", "in identify: finish",
                               "in identify: Identification"), seq, strict=True):
                d[k] = val
            for k, val in d.items():
                res.setdefault(k, []).append(val)
        for k, val in res.items():
            print(f"{sky:5s} {k:40s} median {np.median(val):9.1f}  mean {np.mean(val):9.1f}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]))
