"""Geometric voting's stages on the real sky's tail images (issue #25, branch tailspeed2).

    python benchmarks/tools/tailspeed2_gvstages.py N R

Table 6's real sky (1 px / 0.5 Mv, seed 0, N images). The slowest 10 % by ``identify`` (minimum of R)
are replayed stage by stage with ``gvspeed_profile.image_stages`` (each stage's minimum of R, summed
over the image's rounds, each paying a numba dispatch the kernel does not); prints the sums over
those images and over the rest.
"""

import sys
import time
from pathlib import Path

import numpy as np
from starid_algorithms.geometric_voting.algorithm import _bundles, _saturates, _vote_window

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm

sys.path.insert(0, str(Path(__file__).resolve().parent))
from gvspeed_profile import STAGES, image_stages  # noqa: E402


def main(n, repeats):
    cat, cam = load_hipparcos(), Camera()
    alg = get_algorithm("geometric_voting")()
    db = alg.build(cat, cam)
    bundles = _bundles(alg, cam, db.c_max, db.d_min_deg, _saturates(db), _vote_window(db))
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES["real"]),
                    seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(n)]
    alg.identify(db, obs[0])
    t = np.full(n, np.inf)
    for _ in range(repeats):
        for k, o in enumerate(obs):
            t0 = time.perf_counter_ns()
            alg.identify(db, o)
            t[k] = min(t[k], time.perf_counter_ns() - t0)
    order = np.argsort(-t)
    tail, rest = order[: n // 10], order[n // 10:]
    rows = {k: image_stages(alg, db, obs[k], bundles, repeats) for k in order}
    for r in rows.values():
        r["confirmation"] -= r["ranking"] + r["choice"] + r["verification"]
    print(f"real sky, {n} images, min of {repeats}: tail = slowest {len(tail)}: {sorted(tail.tolist())}")
    print(f"  {'stage':14s} {'tail sum ms':>12s} {'rest sum ms':>12s}")
    for s in STAGES:
        print(f"  {s:14s} {sum(rows[k][s] for k in tail) / 1e3:12.2f} {sum(rows[k][s] for k in rest) / 1e3:12.2f}")


if __name__ == "__main__":
    main(int(sys.argv[1]), int(sys.argv[2]))
