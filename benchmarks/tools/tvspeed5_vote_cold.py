"""What makes triangle voting's ``vote`` slower right after the other plugins (issue #25, branch tvspeed5).

    python benchmarks/tools/tvspeed5_vote_cold.py SKY [N]

Table 6's images of SKY (``paper`` or ``real``; ``benchmarks/test_ratios.py``'s settings, seed 0), N (80) x 2
rounds. Per image ``vote`` is timed once after every other registered plugin identified the image (as in the
benchmark), in four ways: ``cold`` as is; ``data_warm`` after reading one byte per cache line of the database's
``records``, ``cell_start``, ``rows`` and ``features`` (the tables the scan reads: in cache, the code not);
``other_image`` after ``vote`` on the next image (code and branch predictors warm, this image's records not);
``warm`` after ``vote`` on the same image. Prints the median of each, in us.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from starid_algorithms.triangle_voting import kernels as tvk

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px
from starid.registry import get_algorithm

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from test_ratios import NAMES, TABLE6_SIM  # noqa: E402

NO = np.zeros((0, 0), dtype=np.int32)


def main(sky: str, n: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
    tr = sim.generate(n)
    obs = [tr.observation(i, truth=False) for i in range(n)]
    others = [get_algorithm(x)() for x in NAMES if x != "triangle_voting"]
    dbs = [a.build(cat, cam) for a in others]
    alg = get_algorithm("triangle_voting")()
    db = alg.build(cat, cam)
    kt, ktol, _, _ = alg._kernel_args(db, cam)

    def v_cam(o):
        order = np.lexsort((o.y_px, o.x_px, o.mag))
        order = order[o.mag[order] <= alg.mag_limit + alg.mag_margin]
        return backproject_px(o.x_px[order], o.y_px[order], cam.f_px, cam.cx_px, cam.cy_px)

    vs = [v_cam(o) for o in obs]
    for a, d in zip(others, dbs, strict=True):
        a.identify(d, obs[0])
    tvk.vote(vs[0], kt, ktol, NO, NO)
    tables = [db.records, db.cell_start, db.rows, db.features]
    res = {k: [] for k in ("cold", "data_warm", "other_image", "warm")}
    for _ in range(2):
        for k, v in enumerate(vs):
            for mode, times in res.items():
                for a, d in zip(others, dbs, strict=True):
                    a.identify(d, obs[k])
                if mode == "data_warm":
                    sum(int(t.view(np.uint8)[::64].sum()) for t in tables)
                elif mode == "other_image":
                    tvk.vote(vs[(k + 1) % len(vs)], kt, ktol, NO, NO)
                elif mode == "warm":
                    tvk.vote(v, kt, ktol, NO, NO)
                t0 = time.perf_counter_ns()
                tvk.vote(v, kt, ktol, NO, NO)
                times.append((time.perf_counter_ns() - t0) * 1e-3)
    print(sky, "vote median us:", {k: round(float(np.median(x)), 1) for k, x in res.items()})


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 80)
