"""Check triangle voting's cone-search final step against planar_triangle's ``finish`` (issue #25, tvspeed2).

    python benchmarks/tools/tvspeed2_finish_check.py [N] [R]

1. Cone searches (``final.cone_ranges``) on the deep sky of the default database: R random directions
   (and the poles and right ascension 0) at chords from 1e-4 to 0.5, each compared with a brute-force
   scan: every row within the chord must be in the ranges.
2. Table 6's two skies at 1 px / 0.5 Mv (seed 0), N images each, and the real sky with 3 false stars:
   the guide rows ``identify_rows`` gives, with every guide row of the image's true stars also tried,
   passed to ``final.finish_cone`` (the database's deep sky, band order) and to planar_triangle's
   ``finish`` (the same stars sorted by z, as ``starid.kernels.deep_sky`` makes them); hip, attitude and
   acceptance must be the same. Prints the counts; exit 1 on any difference.
"""

from __future__ import annotations

import sys

import numpy as np
from starid_algorithms.planar_triangle import kernels as ptk
from starid_algorithms.triangle_voting import algorithm as tva
from starid_algorithms.triangle_voting import final
from starid_algorithms.triangle_voting import kernels as tvk

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import DeepSky, backproject_px, camera_frame


def cone_check(unit: np.ndarray, repeats: int, rng) -> int:
    bad = 0
    ranges = np.empty((final.MAX_RANGES, 2), dtype=np.int64)
    u64 = unit.astype(np.float64)
    dirs = [np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0]), np.array([1.0, 0.0, 0.0]),
            np.array([1.0, -1e-12, 0.3])]
    dirs += list(rng.normal(size=(repeats, 3)))
    for d in dirs:
        d = d / np.linalg.norm(d)
        for rho in (1e-4, 7e-4, 1.5e-3, 0.05, 0.13, 0.5):
            inside = np.flatnonzero(np.sqrt(((u64 - d) ** 2).sum(1)) <= rho)
            count = final.cone_ranges(unit, d[0], d[1], d[2], rho, ranges)
            got = np.concatenate([np.arange(a, b) for a, b in ranges[:count]] or [np.zeros(0, dtype=np.int64)])
            if not np.isin(inside, got).all():
                bad += 1
    print(f"cone searches: {len(dirs) * 6} checked, {bad} missed a row")
    return bad


def main(n: int, repeats: int) -> int:
    cat, cam = load_hipparcos(), Camera()
    alg = tva.TriangleVoting()
    db = alg.build(cat, cam)
    bad = cone_check(db.deep.unit, repeats, np.random.default_rng(1))
    z_order = np.lexsort((db.deep.hip, db.deep.unit[:, 2]))
    deep_z = DeepSky(np.ascontiguousarray(db.deep.unit[z_order]), np.ascontiguousarray(db.deep.hip[z_order]))
    mag_z = np.ascontiguousarray(db.deep_v_mag[z_order])
    frame = camera_frame(cam)
    unit64 = tva._unit_f64(db)
    tol = alg._tolerance(cam)
    row_of = {int(h): r for r, h in enumerate(db.hip)}
    compared = 0
    differing = 0
    for sky, false_stars in (("paper", 0), ("real", 0), ("real", 3)):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6,
                                            false_stars=false_stars, **SKIES[sky]), seed=0)
        trials = sim.generate(n)
        for k in range(n):
            o = trials.observation(k, truth=True)
            x, y, mag = o.x_px, o.y_px, o.mag
            order = np.lexsort((y, x, mag))
            order = order[mag[order] <= alg.mag_limit + alg.mag_margin]
            tries = []
            if order.size >= 3:
                v_cam = backproject_px(x[order], y[order], cam.f_px, cam.cx_px, cam.cy_px)
                rows, _ = tvk.identify_rows(v_cam, tva._kernel_tables(db), tuple(tol), *tva._scratch(db, order.size))
                all_rows = np.full(x.size, -1, dtype=np.int64)
                all_rows[order] = rows
                tries.append(all_rows)
            truth = np.array([row_of.get(int(h), -1) for h in o.truth_hip], dtype=np.int64)
            tries.append(truth)
            for rows in tries:
                for assign_all, missed in ((True, 1.0 / 3.0), (False, 1.0 / 3.0), (True, 1.0)):
                    a = final.finish_cone(x, y, mag, rows, unit64, db.hip, db.deep.unit, db.deep_index, db.deep.hip,
                                          db.deep_v_mag,
                                          *frame, tol.eps_chord, 1.0, 6.5, 0.75, missed, assign_all)
                    b = ptk.finish(x, y, mag, rows, unit64, db.hip, deep_z, mag_z, frame,
                                   ptk.Finish(tol.eps_chord, 1.0, 6.5, 0.75, missed, assign_all))
                    compared += 1
                    if not (np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]) and a[2] == b[2]):
                        differing += 1
                        print("differs:", sky, false_stars, k, assign_all, missed)
    print(f"final steps compared: {compared}, differing: {differing}")
    return 1 if bad or differing else 0


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 300, int(sys.argv[2]) if len(sys.argv) > 2 else 200))
