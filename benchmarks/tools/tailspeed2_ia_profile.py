"""Where interior_angle's tail goes: trio queries, confirmations, the rest (issue #25, branch tailspeed2).

    python benchmarks/tools/tailspeed2_ia_profile.py N R

Table 6's real sky (1 px / 0.5 Mv, seed 0, N images). The slowest 10 % by ``identify`` (minimum of R)
are replayed from Python: each central star's ``trio_query`` and each returned trio's
``confirm_pattern`` timed alone (minimum of R each; every call pays a numba dispatch the kernel does
not, and ``trio_query`` here allocates its own mark array), in the kernel's order up to its answer.
Prints the sums over those images: ``identify``, the queries, the confirmations (and how many of them
repeat a star -> row pairing already confirmed in the same image), and the rest.
"""

import sys
import time
from functools import partial

import numpy as np
from starid_algorithms.angle.kernels import confirm_pattern
from starid_algorithms.interior_angle import kernels as K
from starid_algorithms.interior_angle.algorithm import camera_frame
from starid_algorithms.pyramid.kernels import select_stars

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px
from starid.registry import get_algorithm


def _best(fn, repeats):
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        out = fn()
        best = min(best, time.perf_counter_ns() - t0)
    return best * 1e-9, out


def main(n, repeats):
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES["real"]),
                    seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(n)]
    a = get_algorithm("interior_angle")()
    db = a.build(cat, cam)
    a.identify(db, obs[0])
    t = np.array([_best(partial(a.identify, db, o), repeats)[0] for o in obs])
    tail = np.argsort(-t)[: n // 10]
    t_q = t_c = 0.0
    n_q = n_c = n_rep = 0
    for k in tail:
        o = obs[k]
        tol, fr = a.tolerances(o.camera, db), camera_frame(o.camera)
        v = backproject_px(o.x_px, o.y_px, fr.f_px, fr.cx_px, fr.cy_px)
        sel = select_stars(o.x_px, o.y_px, o.mag, v, tol.d_min, tol.max_stars)
        out = np.empty((max(tol.max_candidates, 1), 3), dtype=np.int64)
        rows = np.empty(len(o.x_px), dtype=np.int64)
        seen, done = set(), False
        for c in range(min(len(sel), tol.max_centres)):
            k1, k2 = K.nearest_two(v, sel, c)
            dt, cnt = _best(partial(K.trio_query, v, sel[c], sel[k1], sel[k2], db.kv, db.pairs, db.nbr, db.nbr_chord,
                                    db.nbr_start, db.guide_unit, tol, out), repeats)
            t_q += dt
            n_q += 1
            if cnt <= 0 or cnt > tol.max_candidates or (tol.unique and cnt != 1):
                continue
            star = np.array([sel[c], sel[k1], sel[k2]])
            for r in range(cnt):
                row = out[r].copy()
                key = frozenset(zip(star.tolist(), row.tolist(), strict=True))
                n_rep += key in seen
                seen.add(key)
                dt, ok = _best(partial(confirm_pattern, v, star, row, db.guide_unit, tol.c_fov, tol.eps, tol.widen,
                                       fr, tol.min_extra, tol.confirm_fraction, rows), repeats)
                t_c += dt
                n_c += 1
                if ok:
                    done = True
                    break
            if done:
                break
    total = t[tail].sum()
    print(f"real sky, {n} images, min of {repeats}; the slowest {len(tail)}: identify {total * 1e3:.2f} ms, "
          f"{n_q} queries {t_q * 1e3:.2f} ms, {n_c} confirmations {t_c * 1e3:.2f} ms ({n_rep} repeat a pairing), "
          f"rest {(total - t_q - t_c) * 1e3:.2f} ms")


if __name__ == "__main__":
    main(int(sys.argv[1]), int(sys.argv[2]))
