"""The paper's accuracy a(h) of galvizo2018 readings on images made one simulator difference at a time.

    python benchmarks/tools/galvizo_sim_variants.py N F:RHO_DEG:FIELD:ORDER:NOISE [...] -- LABEL [LABEL ...]

    e.g. ... 200 12:0:square:mag:axis 12:0:square:random:axis -- interior_angle:galvizo2018

    N        images per setting (seed 0, the simulator's trials from 0, the same attitudes in every setting)
    F        false stars; RHO_DEG the noise of Galvizo & Lim (deg)
    FIELD    square : galvizo2018's 17.7 x 17.7 deg camera (starid reproduce galvizo2018)
             cone   : a 20 x 20 deg camera, only the stars within 10 deg of the boresight (the paper's
                      field, psi = 20 deg), false stars uniform in that cone
    ORDER    mag    : the algorithms see the simulated magnitudes (brightest first)
             random : every detection gets a random magnitude, so the order the readings try stars in
                      is random (hoku shuffles its image list and has no magnitudes)
    NOISE    axis   : N(0, sigma) per axis in pixels, sigma = rho / sqrt(2) (the experiment's setting)
             arc    : each true star moved N(0, rho^2) deg along a great circle in a uniformly random
                      direction (the paper's SLERP noise); in the cone, a move leaving it is redrawn

FIELD=square ORDER=mag NOISE=axis is the experiment's own images (its first N trials). Prints one line
per label: mean a(h) +- 95 %, starid's id rate, mean stars named, and S (the share of images whose first
query's R has one member, times 2,000: the query table's S) where the reading counts its first query.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from starid import SimConfig, Simulator, load_hipparcos
from starid.experiment import Experiment, Study, Variant
from starid.experiment.spec import sim_settings
from starid.experiments import galvizo2018 as g
from starid.harness import prepare
from starid.observation import Observation
from starid.scoring import bijection_accuracy

HALF_CONE_DEG = g.PAPER_FOV_DEG / 2


def _camera(field: str):
    cam = dict(g.CAMERA, fov_deg=g.PAPER_FOV_DEG) if field == "cone" else dict(g.CAMERA)
    return Experiment(g.NAME, (Study("s", ("pyramid",)),), camera=cam).make_camera()


def _tangent(v: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Uniformly random unit directions perpendicular to each row of ``v``."""
    d = rng.normal(size=v.shape)
    d -= (d * v).sum(1)[:, None] * v
    return d / np.linalg.norm(d, axis=1)[:, None]


def _in_field(v, field, camera):
    if field == "cone":
        return v[:, 2] > math.cos(math.radians(HALF_CONE_DEG))
    x, y = camera.project(v)
    return (v[:, 2] > 0) & camera.in_image(x, y)


def images(n, false_stars, rho_deg, field, order, noise, seed=0, catalog=None):
    """The images of one setting (see the module's docstring), from ``catalog`` (all of Hipparcos when None)."""
    camera = _camera(field)
    catalog = load_hipparcos() if catalog is None else catalog
    axis_px = g.sigma_px_of(rho_deg, camera)
    direct = field == "square" and noise == "axis"
    settings = sim_settings(g.SIM, {"sigma_px": axis_px if direct else 0.0,
                                    "false_stars": false_stars if direct else 0})
    sim = Simulator(catalog, camera, SimConfig(**settings), seed=seed)
    out = []
    trial = 0
    while len(out) < n:
        obs = sim.observation(trial)
        rng = np.random.default_rng([seed, trial, 7])
        trial += 1
        x, y, mag, hip = obs.x_px, obs.y_px, obs.mag, obs.truth_hip
        if not direct:
            v = camera.backproject(x, y)
            if field == "cone":
                keep = _in_field(v, field, camera)
                v, mag, hip = v[keep], mag[keep], hip[keep]
                if hip.size < 5:
                    continue
            if rho_deg > 0 and noise == "arc":
                moved = v.copy()
                todo = np.arange(v.shape[0])
                for _ in range(100):
                    a = np.radians(rng.normal(0.0, rho_deg, todo.size))
                    cand = np.cos(a)[:, None] * v[todo] + np.sin(a)[:, None] * _tangent(v[todo], rng)
                    ok = _in_field(cand, field, camera) if field == "cone" else np.ones(todo.size, dtype=bool)
                    moved[todo[ok]] = cand[ok]
                    todo = todo[~ok]
                    if todo.size == 0:
                        break
                v = moved
            x, y = camera.project(v)
            if rho_deg > 0 and noise == "axis":
                x = x + rng.normal(0.0, axis_px, x.size)
                y = y + rng.normal(0.0, axis_px, y.size)
            inside = camera.in_image(x, y)
            x, y, mag, hip = x[inside], y[inside], mag[inside], hip[inside]
            if false_stars:
                if field == "cone":
                    cz = rng.uniform(math.cos(math.radians(HALF_CONE_DEG)), 1.0, false_stars)
                    ph = rng.uniform(0.0, 2 * math.pi, false_stars)
                    sz = np.sqrt(1 - cz * cz)
                    fx, fy = camera.project(np.stack([sz * np.cos(ph), sz * np.sin(ph), cz], axis=1))
                else:
                    fx = rng.uniform(0.0, camera.width_px, false_stars)
                    fy = rng.uniform(0.0, camera.height_px, false_stars)
                x, y = np.concatenate([x, fx]), np.concatenate([y, fy])
                mag = np.concatenate([mag, rng.uniform(mag.min(), mag.max(), false_stars)])
                hip = np.concatenate([hip, np.full(false_stars, -1, dtype=np.int64)])
        if order == "random":
            mag = rng.uniform(0.0, 6.0, hip.size)
        p = rng.permutation(hip.size)
        out.append(Observation(x[p], y[p], mag[p], camera, hip[p]))
    return camera, catalog, out


def main(n, settings, labels):
    prepared = {}
    for setting in settings:
        f, rho, field, order, noise = setting.split(":")
        false_stars, rho_deg = int(f), float(rho)
        camera, catalog, obs = images(n, false_stars, rho_deg, field, order, noise)
        for label in labels:
            if (label, field) not in prepared:
                prepared[label, field] = prepare(Variant.parse(label).make(), catalog, camera, obs[0], label)
            score(prepared[label, field], label, camera, obs, setting)


def score(p, label, camera, obs, setting):
    n_corr, n_id, ok, first_r = [], [], [], []
    for o in obs:
        ident = p.algorithm.identify(p.database, Observation(o.x_px, o.y_px, o.mag, camera))
        hip = np.asarray(ident.hip)
        first_r.append((ident.counters or {}).get("first_R", -1))
        named = hip >= 0
        right = int((named & (hip == o.truth_hip)).sum())
        n_corr.append(right)
        n_id.append(int(named.sum()))
        ok.append(right >= 3 and right == named.sum())
    acc = bijection_accuracy(n_corr, n_id)
    half = 1.96 * acc.std(ddof=1) / math.sqrt(acc.size)
    print(f"{label:34s} {setting:24s} n={len(obs)}: "
          f"a(h) {acc.mean():.3f} +-{half:.3f}  starid {np.mean(ok):.3f}  named {np.mean(n_id):.2f}"
          + (f"  S {np.mean(np.equal(first_r, 1)) * 2000:.0f} of 2000" if min(first_r) >= 0 else ""), flush=True)


if __name__ == "__main__":
    if "--" not in sys.argv[2:]:
        sys.exit(__doc__)
    cut = sys.argv.index("--")
    main(int(sys.argv[1]), sys.argv[2:cut], sys.argv[cut + 1:])
