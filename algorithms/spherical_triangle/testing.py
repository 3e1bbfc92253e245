"""Test helpers shared by the ``spherical_triangle`` and ``composite_pyramid`` test files (one copy).

Not part of the algorithm: a Python recount of what the kernels' ``to_r`` counter counts.
"""

from __future__ import annotations

import numpy as np
from starid_algorithms.pyramid.kernels import select_stars

from starid.kernels import backproject_px
from starid.kernels import triangles as T


def first_single_query(algo, db, obs, order):
    """1-based position, in ``order`` (trios of selected-star positions), of the first trio whose
    (area, moment) query returns exactly one catalog triangle; 0 when none does (Python recount with
    the shared query kernel)."""
    cam = obs.camera
    tol = algo.tolerances(cam, db)
    v = backproject_px(obs.x_px, obs.y_px, cam.f_px, cam.cx_px, cam.cy_px)
    sel = select_stars(obs.x_px, obs.y_px, obs.mag, v, tol.d_min, tol.max_stars)
    cand = np.empty(tol.max_candidates, dtype=np.int64)
    for q, (i, j, k) in enumerate(order(len(sel))):
        if i >= len(sel) or k >= len(sel):
            continue
        nc = T.trio_query(v, sel[i], sel[j], sel[k], db.index, tol.kind, tol.depth, tol.sigma_rad, tol.beta,
                          tol.fixed_area, tol.fixed_moment, tol.chord_max, tol.max_hits, tol.truncate,
                          db.guide_unit, tol.eps_side, cand)
        if nc == 1:
            return q + 1
    return 0
