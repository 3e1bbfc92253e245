"""Where ptp's and pvector's per-image time goes (issue #25): the whole ``identify``, the kernel call alone,
the ``Identification`` built, and, inside ptp's kernel, the share of each stage (measured by switching the
later stages off on the same images; an estimate, the stages' work is input-dependent).

Superseded: it calls ``identify_kernel`` with the tuple arguments ptp had before stop 42 (branch
ptpspeed5 passes one parameter array) and runs on that code only (``git checkout ab5f4bd``);
``ptpspeed5_split.py`` profiles ptp's current kernel.

    python benchmarks/tools/ptp_pvector_profile.py N R

Table 6's two skies at 1 px / 0.5 Mv (seed 0), N images each identified R times; medians over images of
the per-image minimum, in microseconds.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.plugin import Identification
from starid.registry import get_algorithm


def _min_us(fn, obs, repeats):
    out = np.empty(len(obs))
    for i, o in enumerate(obs):
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter_ns()
            fn(o)
            best = min(best, time.perf_counter_ns() - t0)
        out[i] = best / 1e3
    return out


def main(n: int, repeats: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    for sky in ("paper", "real"):
        _one_sky(sky, cat, cam, n, repeats)


def _one_sky(sky, cat, cam, n, repeats) -> None:
    from starid_algorithms.ptp.algorithm import _view
    from starid_algorithms.ptp.kernels import identify_kernel, plain

    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                    seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(n)]
    rows = {}
    ptp = get_algorithm("ptp")()
    db = ptp.build(cat, cam)
    ptp.identify(db, obs[0])
    view = _view(cam)[1]
    rows["ptp identify"] = _min_us(lambda o: ptp.identify(db, o), obs, repeats)
    tol = ptp.tolerances(db)
    narrow, wide = db.packed    # the kernel takes the tables packed (ptp speed round 4)
    rows["ptp kernel"] = _min_us(lambda o: identify_kernel(o.x_px, o.y_px, o.mag, view, narrow, wide, plain(tol)),
                                 obs, repeats)
    hip = np.full(10, -1, dtype=np.int64)
    rows["Identification"] = _min_us(lambda o: Identification(hip, counters={"a": 1, "b": 2, "c": 3, "d": 4}),
                                     obs, repeats)
    stages = [("searches + side checks", dict(max_candidates=0, hypotheses=0)),
              ("+ validation", dict(verify=False, confirm_fraction=0.0, nearest_check=False, hypotheses=0)),
              ("+ verify, confirm, nearest", dict(hypotheses=0))]
    for label, change in stages:
        t = plain(tol._replace(**change))
        identify_kernel(obs[0].x_px, obs[0].y_px, obs[0].mag, view, narrow, wide, t)
        rows["ptp kernel: " + label] = _min_us(
            lambda o, t=t: identify_kernel(o.x_px, o.y_px, o.mag, view, narrow, wide, t), obs, repeats)
    pv = get_algorithm("pvector")()
    pdb = pv.build(cat, cam)
    pv.identify(pdb, obs[0])
    rows["pvector identify"] = _min_us(lambda o: pv.identify(pdb, o), obs, repeats)
    rows["pvector kernel"] = _min_us(lambda o: pv._run(pdb, o), obs, repeats)
    tet = get_algorithm("tetra")()
    tdb = tet.build(cat, cam)
    tet.identify(tdb, obs[0])
    rows["tetra identify"] = _min_us(lambda o: tet.identify(tdb, o), obs, repeats)
    for k, v in rows.items():
        print(f"{sky:5s}  {k:40s} median {np.median(v):8.1f}  p95 {np.percentile(v, 95):8.1f}", flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), int(sys.argv[2]))
