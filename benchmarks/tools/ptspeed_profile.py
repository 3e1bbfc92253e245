"""Where planar_triangle's and triangle_voting's per-image time goes (issue #25 profile tables).

Since branch tvspeed2 triangle_voting's deep sky is ordered for cone searches, not by z, so its
``finish`` line here no longer times what identify runs; ``tvspeed2_stages.py`` does.

    python benchmarks/tools/ptspeed_profile.py 60 5

Table 6's two skies at 1 px / 0.5 Mv (seed 0), N images, each step timed R times (minimum kept, as
``min_time.py``). Steps are called exactly as ``identify`` calls them: for planar_triangle the image
triangles and their area k-vector searches (``image_triangles``), the whole subset kernel
(``identify_subsets``: searches, candidate checks, pivots, recovery, extension, pairwise check),
``finish`` (attitude, assignment, coverage, rivals) and the whole ``identify``; the Python wrapper and
the ``Identification`` are what ``identify`` costs beyond its kernels. Likewise for triangle_voting:
``vote`` (grid searches and candidate checks), ``identify_rows`` (vote + selection + verification +
confirmation/fallback), ``finish`` and ``identify``. Prints median and mean over images, in us.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from starid_algorithms.planar_triangle import kernels as ptk
from starid_algorithms.triangle_voting import algorithm as tva
from starid_algorithms.triangle_voting import kernels as tvk

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px, camera_frame
from starid.registry import get_algorithm


def _best(fn, repeats):
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        fn()
        best = min(best, time.perf_counter_ns() - t0)
    return best / 1e3


def _pt_steps(alg, db, o, repeats):
    """Per-step times of one planar_triangle image (the kernel arguments rebuilt as ``_run`` does)."""
    x, y, mag = o.x_px, o.y_px, o.mag
    usable = np.flatnonzero(mag <= db.mag_limit + alg.mag_margin)
    n_chosen = alg._n_chosen()
    if n_chosen is not None and usable.size > n_chosen:
        usable = usable[np.lexsort((y[usable], x[usable], mag[usable]))[:n_chosen]]
    out = {"identify": _best(lambda: alg.identify(db, o), repeats)}
    if usable.size < 3:
        return out
    order = usable[np.lexsort((mag[usable], y[usable], x[usable]))]
    v_cam = o.camera.backproject(x[order], y[order])
    tol = alg._tolerance(o.camera)
    tables = db.tables()
    rank = np.lexsort((y[order], x[order], mag[order]))
    stages = alg._stages(order.size)
    out["image_triangles"] = _best(lambda: ptk.image_triangles(v_cam, tables, tol), repeats)
    out["kernel"] = _best(lambda: ptk.identify_subsets(v_cam, rank, tables, tol, stages), repeats)
    all_rows, _, stage, _ = alg._run(db, o)
    if np.any(all_rows >= 0):
        small = alg.small_subset_size is not None and stage == len(alg._stages(1)) - 1 and stage > 0
        rules = ptk.Finish(tol.beta * np.sqrt(2.0) * tol.sigma_rad, float(alg.mag_margin), float(db.mag_limit),
                           float(alg.coverage_mag_margin), float(alg.max_missed_fraction),
                           bool(alg.assign_all or small))
        frame = camera_frame(o.camera)
        out["finish"] = _best(lambda: ptk.finish(x, y, mag, all_rows, db.guide_unit, db.guide_hip, db.deep,
                                                 db.deep_v_mag, frame, rules), repeats)
    return out


def _tv_steps(alg, db, o, repeats):
    x, y, mag = o.x_px, o.y_px, o.mag
    out = {"identify": _best(lambda: alg.identify(db, o), repeats)}
    order = np.lexsort((y, x, mag))
    order = order[mag[order] <= alg.mag_limit + alg.mag_margin][:alg.max_stars]
    if order.size < 3:
        return out
    cam = o.camera
    v_cam = backproject_px(x[order], y[order], cam.f_px, cam.cx_px, cam.cy_px)
    tol_nt = alg._tolerance(cam)
    tol = tuple(tol_nt)       # plain tuples, as identify passes them (one kernel signature)
    tables = tuple(db.tables())
    votes, mark = tva._scratch(db, order.size)
    out["vote"] = _best(lambda: tvk.vote(v_cam, tables, tol, votes, mark), repeats)
    out["kernel"] = _best(lambda: tvk.identify_rows(v_cam, tables, tol, votes, mark), repeats)
    rows, _ = tvk.identify_rows(v_cam, tables, tol, votes, mark)
    if rows.max() >= 0:
        all_rows = np.full(len(x), -1, dtype=np.int64)
        all_rows[order] = rows
        rules = ptk.Finish(tol_nt.eps_chord, float(alg.mag_margin), float(alg.mag_limit),
                           float(alg.coverage_mag_margin), float(alg.max_missed_fraction), bool(alg.assign_all))
        frame = camera_frame(cam)
        unit = getattr(tva, "_unit_f64", lambda d: d.unit_icrs)(db)
        out["finish"] = _best(lambda: ptk.finish(x, y, mag, all_rows, unit, db.hip, db.deep, db.deep_v_mag,
                                                 frame, rules), repeats)
    return out


def main(n: int, repeats: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(n)]
        for name, steps in (("tetra", None), ("planar_triangle", _pt_steps), ("triangle_voting", _tv_steps)):
            alg = get_algorithm(name)()
            db = alg.build(cat, cam)
            alg.identify(db, obs[0])
            rows = []
            for o in obs:
                if steps is None:
                    rows.append({"identify": _best(lambda o=o, a=alg, d=db: a.identify(d, o), repeats)})
                else:
                    rows.append(steps(alg, db, o, repeats))
            keys = sorted({k for r in rows for k in r})
            for k in keys:
                v = np.array([r.get(k, 0.0) for r in rows])
                print(f"{sky:5s} {name:16s} {k:16s} median {np.median(v):9.1f} us  mean {v.mean():9.1f} us  "
                      f"p95 {np.percentile(v, 95):9.1f} us", flush=True)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]))
