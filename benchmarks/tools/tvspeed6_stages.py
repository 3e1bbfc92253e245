"""triangle_voting's ``identify_rows`` split into stages, interleaved as the benchmark times it (issue #25, tvspeed6).

    python benchmarks/tools/tvspeed6_stages.py [N] [R]

``tvspeed4_profile.py``'s loop (every registered plugin identifies the image first, untimed; then one stage is timed
once, "cold"; and the minimum of 3 back-to-back calls, "warm") over cumulative stages of one kernel of this tool
(``upto``, compiled once: the same code for every stage, it returns after stage ``s``): ``vote``, ``+select``
(``select_candidates``), ``+verify`` (``verify_pairwise``), ``+confirm`` (``confirm``: consistent set and
reprojection), ``+fallback`` (``best_hypothesis`` when nothing was confirmed: ``identify_rows``' whole work); then
``identify_flat`` (+ order, back-projection, the final step, its entry) and ``identify`` (+ the Python wrapper),
and tetra's ``identify``. N images (100), R rounds (1), both skies.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from numba import njit
from starid_algorithms.triangle_voting import algorithm as tva
from starid_algorithms.triangle_voting import kernels as tvk

from starid.kernels import backproject_px, verify_pairwise

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tvspeed4_profile  # noqa: E402

STAGES = ("vote", "+select", "+verify", "+confirm", "+fallback", "identify_flat", "identify", "tetra")
NO = np.zeros((0, 0), dtype=np.int32)


@njit(cache=True, no_cfunc_wrapper=True)
def upto(v_cam, db, tol, stage):
    """``identify_rows``' stages up to ``stage`` (0 vote ... 4 fallback); returns a number of the last one."""
    cand, cand_votes, hyp, score, work = tvk.vote(v_cam, db, tol, NO, NO)
    if stage == 0:
        return cand[0, 0]
    cat_unit, eps_chord = db[tvk.DB_UNIT], tol[tvk.TOL_EPS_CHORD]
    chosen, chosen_votes = tvk.select_candidates(v_cam, cand, cand_votes, cat_unit, eps_chord)
    if stage == 1:
        return chosen[0]
    verified = verify_pairwise(v_cam, chosen, cat_unit, eps_chord, tol[tvk.TOL_MIN_SUPPORT])
    for i in range(chosen.shape[0]):
        if not verified[i]:
            chosen[i] = -1
    if stage == 2:
        return chosen[0]
    rows = tvk.confirm(v_cam, chosen, chosen_votes, db, tol, tol[tvk.TOL_MIN_STARS])
    if stage == 3:
        return rows[0]
    if not tvk._any_row(rows) and tol[tvk.TOL_MAX_HYPOTHESES] > 0:
        rows = tvk.best_hypothesis(v_cam, hyp, score, db, tol, tol[tvk.TOL_MIN_STARS] + 1)
    return rows[0]


def _calls(alg, db, tetra, tetra_db, o):
    x, y, mag = o.x_px, o.y_px, o.mag
    _, ktol, _ = alg._tolerances(o.camera)
    kt = tva._kernel_tables(db)
    flat = alg._flat_args(db, o.camera)
    out = {"identify": lambda: alg.identify(db, o),
           "tetra": lambda: tetra.identify(tetra_db, o),
           "identify_flat": lambda: tvk.identify_flat(x, y, mag, *flat)}
    order = np.lexsort((y, x, mag))
    order = order[mag[order] <= alg.mag_limit + alg.mag_margin][:alg.max_stars]
    if order.size >= 3:
        cam = o.camera
        v_cam = backproject_px(x[order], y[order], cam.f_px, cam.cx_px, cam.cy_px)
        for k, s in enumerate(STAGES[:5]):
            out[s] = lambda k=k: upto(v_cam, kt, ktol, np.int64(k))
    return out


if __name__ == "__main__":
    import starid.registry  # noqa: F401
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100
    r = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    tvspeed4_profile.main(n, r, calls_of=_calls, stages=STAGES)
