"""triangle_voting's final step split into stages, interleaved as the benchmark times it (issue #25, tvspeed7).

    python benchmarks/tools/tvspeed7_stages.py [N] [R]

``tvspeed4_profile.py``'s loop (every other plugin identifies the image first, untimed; one stage timed once,
"cold"; and the minimum of 3 back-to-back calls, "warm"). Stages: ``+fallback`` (``identify_rows``' whole work,
``tvspeed6_stages.upto``), then cumulative stages of ``finish_cone`` through one kernel of this tool (``fin_upto``,
the same code for every stage, on the guide rows ``identify_rows`` gave, computed untimed beforehand):
``attitude`` (back-projection of every star, ``wahba_rows``), ``+assign`` (``_assign_all``: the field's cone search
and reprojection), ``+deep_mag`` (V of each newly assigned star), ``+coverage`` (the coverage check's cone search),
``+rivals`` (the close-pair search per identified star: the whole final step); then ``identify_flat``,
``identify`` and tetra's ``identify``. N images (100), R rounds (1), both skies.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
from numba import njit
from starid_algorithms.triangle_voting import algorithm as tva
from starid_algorithms.triangle_voting import final as fin
from starid_algorithms.triangle_voting import kernels as tvk

from starid.kernels import backproject_px, wahba_rows

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tvspeed4_profile  # noqa: E402
import tvspeed6_stages  # noqa: E402

STAGES = ("+fallback", "attitude", "+assign", "+deep_mag", "+coverage", "+rivals", "identify_flat", "identify",
          "tetra")


@njit(cache=True, no_cfunc_wrapper=True)
def fin_upto(x_px, y_px, mag, rows, guide_unit, guide_hip, deep_unit, deep_index, deep_hip, deep_mag, f_px, cx_px,
             cy_px, width_px, height_px, eps_chord, mag_margin, mag_limit, coverage_mag_margin, stage):
    """``finish_cone``'s steps up to ``stage`` (0 attitude ... 4 rivals); returns a number of the last one."""
    n = rows.shape[0]
    hip = np.full(n, -1, dtype=np.int64)
    for i in range(n):
        if rows[i] >= 0:
            hip[i] = guide_hip[rows[i]]
    ranges = np.empty((fin.MAX_RANGES, 2), dtype=np.int64)
    v_cam = backproject_px(x_px, y_px, f_px, cx_px, cy_px)
    attitude = wahba_rows(v_cam, rows, guide_unit)
    if stage == 0:
        return attitude[0, 0]
    assigned = hip.copy()
    fin._assign_all(attitude, v_cam, deep_unit, deep_index, deep_hip, eps_chord, assigned, ranges, f_px, cx_px, cy_px,
                    width_px, height_px)
    if stage == 1:
        return float(assigned[0])
    hip_all = hip.copy()
    r_icrs = np.empty(3)
    for i in range(n):
        if rows[i] >= 0 or assigned[i] < 0:
            continue
        for a in range(3):
            r_icrs[a] = attitude[0, a] * v_cam[i, 0] + attitude[1, a] * v_cam[i, 1] + attitude[2, a] * v_cam[i, 2]
        if fin._deep_mag_of(deep_unit, deep_index, deep_hip, deep_mag, r_icrs, eps_chord, assigned[i],
                            ranges) <= mag[i] + mag_margin:
            hip_all[i] = assigned[i]
    if stage == 2:
        return float(hip_all[0])
    faintest_mag = mag[0]
    for i in range(1, n):
        if mag[i] > faintest_mag or math.isnan(mag[i]):
            faintest_mag = mag[i]
    predicted, missed = fin._coverage(attitude, deep_unit, deep_index, deep_hip, deep_mag,
                                      min(mag_limit, faintest_mag) - coverage_mag_margin, hip_all, ranges, f_px,
                                      cx_px, cy_px, width_px, height_px)
    if stage == 3:
        return float(predicted + missed)
    count = 0
    for i in range(n):
        if rows[i] < 0:
            continue
        for a in range(3):
            r_icrs[a] = attitude[0, a] * v_cam[i, 0] + attitude[1, a] * v_cam[i, 1] + attitude[2, a] * v_cam[i, 2]
        count += fin._rivals(deep_unit, deep_index, deep_mag, r_icrs, eps_chord, mag[i] + mag_margin, ranges)
    return float(count)


def _calls(alg, db, tetra, tetra_db, o):
    out = tvspeed6_stages._calls(alg, db, tetra, tetra_db, o)
    out = {k: v for k, v in out.items() if k in STAGES}
    x, y, mag = o.x_px, o.y_px, o.mag
    cam = o.camera
    _, ktol, fin_db, fin_cam = alg._kernel_args(db, cam)
    order = np.lexsort((y, x, mag))
    order = order[mag[order] <= alg.mag_limit + alg.mag_margin][:alg.max_stars]
    if order.size < 3:
        return out
    v_cam = backproject_px(x[order], y[order], cam.f_px, cam.cx_px, cam.cy_px)
    rows, _ = tvk.identify_rows(v_cam, tva._kernel_tables(db), ktol, tvspeed6_stages.NO, tvspeed6_stages.NO)
    if (rows >= 0).sum() < 2:
        return out
    all_rows = np.full(x.size, -1, dtype=np.int64)
    all_rows[order] = rows
    f_px, cx_px, cy_px, width_px, height_px, eps_chord, mag_margin, mag_limit, cov_margin = fin_cam[:9]
    for k, s in enumerate(STAGES[1:6]):
        out[s] = lambda k=k: fin_upto(x, y, mag, all_rows, *fin_db, f_px, cx_px, cy_px, width_px, height_px, eps_chord,
                                      mag_margin, mag_limit, cov_margin, np.int64(k))
    return out


if __name__ == "__main__":
    import starid.registry  # noqa: F401
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100
    r = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    tvspeed4_profile.main(n, r, calls_of=_calls, stages=STAGES)
