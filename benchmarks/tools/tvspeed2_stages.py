"""Where triangle_voting's ``identify`` spends its time after the tvspeed2 branch (issue #25).

    python benchmarks/tools/tvspeed2_stages.py [N] [R]

Table 6's two skies at 1 px / 0.5 Mv (seed 0), N images (40), each call timed R times (5, minimum
kept), median over images in us. Stages, each called as ``identify`` calls it: ``triangles``,
``scan``, ``side_checks`` (the cut-down copies of ``vote``'s loops in ``tvspeed_stages.py``),
``vote``, ``identify_rows`` (+ selection, verification, confirmation / fallback), ``finish_cone``
(the final step, ``final.py``), ``identify_image`` (the one kernel ``identify`` calls: order,
back-projection, ``identify_rows``, ``finish_cone``) and ``identify`` (+ the Python wrapper and
the ``Identification``); tetra's ``identify`` on the same images for scale.

Since branch tvspeed3 the ``scan`` and ``side_checks`` copies read the records' columns as strided
views of the 16-byte rows and check every side exactly: they no longer describe ``vote`` (which
reads whole rows and decides most side checks from the float32 chords); the other stages do.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from starid_algorithms.triangle_voting import algorithm as tva
from starid_algorithms.triangle_voting import final
from starid_algorithms.triangle_voting import kernels as tvk

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px
from starid.registry import get_algorithm

sys.path.insert(0, str(Path(__file__).resolve().parent))
from tvspeed_stages import _best, _loops  # noqa: E402

STAGES = ("triangles", "scan", "side_checks", "vote", "identify_rows", "finish_cone", "identify_image", "identify")


def _steps(alg, db, o, repeats):
    x, y, mag = o.x_px, o.y_px, o.mag
    out = {"identify": _best(lambda: alg.identify(db, o), repeats)}
    _, ktol, fin_cam = alg._tolerances(o.camera)
    kt, fin_db = tva._kernel_tables(db), tva._finish_tables(db)
    out["identify_image"] = _best(lambda: tvk.identify_image(x, y, mag, kt, ktol, fin_db, fin_cam), repeats)
    order = np.lexsort((y, x, mag))
    order = order[mag[order] <= alg.mag_limit + alg.mag_margin][:alg.max_stars]
    if order.size < 3:
        return out
    cam = o.camera
    v_cam = backproject_px(x[order], y[order], cam.f_px, cam.cx_px, cam.cy_px)
    tol = alg._tolerance(cam)
    tb = tva._tables(db)
    args = (v_cam, tb.base, tb.height, tb.side_i, tb.side_j, tb.cell_start, tb.n_cells_b, tb.n_cells_h, tb.cell_b,
            tb.cell_h, tb.pr_chord, tb.dmin_chord, tol.n_nbr, tol.sigma_chord, tol.k_sigma, tb.main, tb.n_i, tb.n_j,
            tb.unit)
    no = np.zeros((0, 0), dtype=np.int32)
    out["triangles"] = _best(lambda: _loops(*args, 0), repeats)
    out["scan"] = _best(lambda: _loops(*args, 1), repeats)
    out["side_checks"] = _best(lambda: _loops(*args, 2), repeats)
    out["vote"] = _best(lambda: tvk.vote(v_cam, kt, ktol, no, no), repeats)
    out["identify_rows"] = _best(lambda: tvk.identify_rows(v_cam, kt, ktol, no, no), repeats)
    rows, _ = tvk.identify_rows(v_cam, kt, ktol, no, no)
    if rows.max() >= 0:
        all_rows = np.full(len(x), -1, dtype=np.int64)
        all_rows[order] = rows
        out["finish_cone"] = _best(lambda: final.finish_cone(x, y, mag, all_rows, *fin_db, *fin_cam[:11]), repeats)
    return out


def main(n: int, repeats: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    for sky in ("paper", "real"):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                        seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(n)]
        for name in ("tetra", "triangle_voting"):
            alg = get_algorithm(name)()
            db = alg.build(cat, cam)
            alg.identify(db, obs[0])
            if name == "tetra":
                rows = [{"identify": _best(lambda o=o: alg.identify(db, o), repeats)} for o in obs]  # noqa: B023
            else:
                rows = [_steps(alg, db, o, repeats) for o in obs]
            for k in STAGES:
                v = np.array([r.get(k, 0.0) for r in rows])
                if v.any():
                    print(f"{sky:5s} {name:16s} {k:14s} median {np.median(v):8.1f} us  mean {v.mean():8.1f} us",
                          flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40, int(sys.argv[2]) if len(sys.argv) > 2 else 5)
