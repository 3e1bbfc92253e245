"""INT's query-table S: hoku's form of the query step against the first query of ``interior_angle:galvizo2018``.

Galvizo & Lim print S = 1,440 of 2,000 for the Interior Angle method (the query steps whose candidate
set R has one member, no noise); the reading's first query (the brightest star as the central star,
its two nearest stars) gets S = 1,880 on ``starid reproduce galvizo2018``'s images. This script
searches the paper's table K3-bar (every ordered trio (i, j, c) of catalog stars within 20 deg of
each other with theta(c, i) < theta(c, j), i.e. each set three times, once per central star c) by
brute force on starid's catalog, with hoku's features and windows (the table and the query are
``starid.experiments.hoku_query``'s ``TrioTable`` and ``int_query``):

* theta_1 = theta(c, i), theta_2 = theta(c, j) (deg), swapped when theta_1 > theta_2;
* phi = the angle at c between the chords i - c and j - c (deg; hoku's ``Trio::dot_angle`` takes
  the angle between the normalised vectors i - c and j - c, not the great-circle angle);
* every feature within 3 sigma = 0.03 deg of the query's (sigma_theta = sigma_phi = 1e-2 deg);
* |R| counted as rows (hoku's ``r.size()``) and as distinct catalog sets.

Read in ``glennga/hoku`` (stored versions; none is held at the paper's commit 0cb340ec):
``lib/identification/dot-angle.cpp`` at b7d2ff1b9dd1 (``Dot::generate_table``, ``Dot::query``),
``lib/experiment/experiment.cpp`` at e6f6c8afb4e7 (``Query::generate_n_stars``) and
``include/experiment/experiment.h`` at 2a2c1ca156b4 (``Query::trial``). No hoku code is used here.

It counts |R| for several ways of choosing the query trio, on the same fields:

* ``hoku``: hoku's ``Experiment::Query``: three random stars of the field (``generate_n_stars``
  shuffles the field's stars and takes the first three), the third the central star;
* ``nearest``: the same random central star with its two nearest stars of the field (Liebe's
  choice, the reading's);
* ``brightest``: the field's brightest star with its two nearest (the reading's first query).

Two sets of fields:

* ``exp``: the images of ``starid reproduce galvizo2018`` at its 0 point (seed 0, 0 false stars,
  no noise, the 17.7 deg square; the stars' catalog vectors from ``truth_hip``; brightest by the
  simulated magnitude). ``brightest`` here re-counts the reading's own first query (S = 1,880);
* ``cone``: hoku's generator: a uniformly random centre, every catalog star with V < 6 within 10 deg
  of it (the paper's psi / 2), at least three; no rotation (the features do not depend on it).

    python benchmarks/tools/galvizo5_int_query.py EXP_IMAGES CONE_FIELDS [CATALOG_STARS] [--plugin] [--seed S]

``--plugin`` also runs ``interior_angle:galvizo2018`` on the ``exp`` images and compares its
first-query counter ``first_R`` with ``brightest``'s rows image by image (the plugin's phi is the
great-circle angle and its windows are on chords, so a few trios at a window's edge may differ).

CATALOG_STARS (default: every star with V < 6, 5,022 in starid's catalog) keeps only the brightest
that many for the table and the cone fields (the paper's catalog has 4,560 stars with m < 6).
``--seed S`` (default 5) seeds the cone fields and the random trios (the ``exp`` images stay seed 0).
"""

from __future__ import annotations

import sys

import numpy as np
import scipy.sparse as sp

from starid import SimConfig, Simulator
from starid.catalog import load_hipparcos
from starid.experiment import Variant
from starid.experiment.spec import sim_settings
from starid.experiments import galvizo2018 as g
from starid.experiments.hoku_query import FOV_DEG, TrioTable
from starid.experiments.hoku_query import WINDOW_INT_DEG as EPS_DEG  # 3 sigma_theta = 3 sigma_phi
from starid.experiments.hoku_query import int_query as count


def n_sets(table: TrioTable) -> int:
    """Unordered trios with every pair within 20 deg (K3; K3-bar holds three rows for each)."""
    n = len(table.u)
    adj = sp.csr_matrix((np.ones(table.a.size), (table.a, table.b)), shape=(n, n))
    return int(round(adj.multiply(adj @ adj).sum() / 6))


def nearest_two(u: np.ndarray, field: np.ndarray, c: int) -> tuple[int, int]:
    others = field[field != c]
    d = u[others] @ u[c]
    o = np.argsort(-d, kind="stable")
    return int(others[o[0]]), int(others[o[1]])


def summarise(name: str, res: list[tuple[int, int, int, float]]) -> None:
    r = np.array(res, dtype=np.float64)
    n = len(r)
    one_rows = int((r[:, 0] == 1).sum())
    one_sets = int((r[:, 1] == 1).sum())
    print(f"  {name:10s} S = {2000 * one_rows / n:6.0f} (rows) / {2000 * one_sets / n:6.0f} (sets) of 2,000; "
          f"|R| = 1 in {one_rows} of {n}, 0 in {int((r[:, 0] == 0).sum())}, >1 in {int((r[:, 0] > 1).sum())}; "
          f"f = {r[:, 2].mean():.3f}; mean |R| rows {r[:, 0].mean():.2f}; longer side median "
          f"{np.median(r[:, 3]):.1f} deg")
    for lo, hi in ((0, 2), (2, 5), (5, 10), (10, 20)):
        m = (r[:, 3] >= lo) & (r[:, 3] < hi)
        if m.any():
            print(f"      longer side {lo:2d}-{hi:2d} deg: {int(m.sum()):4d} queries, |R| = 1 in "
                  f"{(r[m, 0] == 1).mean():.3f}")


def main() -> None:
    argv = sys.argv[1:]
    plugin = "--plugin" in argv
    seed = 5
    if "--seed" in argv:
        k = argv.index("--seed")
        seed = int(argv[k + 1])
        del argv[k:k + 2]
    args = [a for a in argv if a != "--plugin"]
    n_exp, n_cone = int(args[0]), int(args[1])
    catalog = load_hipparcos()
    bright = np.nonzero(catalog.v_mag < 6.0)[0]
    if len(args) > 2:
        bright = bright[np.argsort(catalog.v_mag[bright], kind="stable")[:int(args[2])]]
        bright.sort()
    u = np.asarray(catalog.unit_icrs, dtype=np.float64)[bright]
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    table = TrioTable(u)
    n_sets_ = n_sets(table)
    print(f"table: {len(bright)} stars, {table.t.size // 2} pairs within {FOV_DEG:g} deg, {n_sets_} trios "
          f"({3 * n_sets_} rows of K3-bar); windows +-{EPS_DEG} deg")
    rng = np.random.default_rng([seed, 0])

    if n_exp:
        exp = g.experiment(trials=n_exp, seed=0)
        camera = exp.make_camera()
        config = SimConfig(**sim_settings(exp.sim, {"false_stars": 0, "sigma_px": 0.0}))
        images = Simulator(catalog, camera, config, seed=0).generate(n_exp, 0)
        pos_of = np.full(len(catalog.hip), -1, dtype=np.int64)
        pos_of[bright] = np.arange(len(bright))
        res = {"hoku": [], "nearest": [], "brightest": []}
        missing = 0
        first_r = []
        if plugin:
            algo = Variant.as_reading("interior_angle", "galvizo2018").make().resolved(config)
            db = algo.build(catalog, camera)
        for t in range(n_exp):
            obs = images.observation(t)
            rows = catalog.index_of(obs.truth_hip)
            field = pos_of[rows]
            missing += int((field < 0).sum())
            mag = np.asarray(obs.mag)[field >= 0]
            field = field[field >= 0]
            s = rng.permutation(field)[:3]
            res["hoku"].append(count(table, int(s[2]), int(s[0]), int(s[1])))
            i, j = nearest_two(u, field, int(s[2]))
            res["nearest"].append(count(table, int(s[2]), i, j))
            c = int(field[np.argmin(mag)])
            i, j = nearest_two(u, field, c)
            res["brightest"].append(count(table, c, i, j))
            if plugin:
                first_r.append(int(algo.identify(db, obs).counters["first_R"]))
        print(f"exp: {n_exp} images of starid reproduce galvizo2018's 0 point (seed 0), "
              f"{missing} detections not in the table")
        for name, r in res.items():
            summarise(name, r)
        if plugin:
            ours = np.array([r[0] for r in res["brightest"]])
            first_r = np.array(first_r)
            print(f"  plugin first_R: |R| = 1 in {int((first_r == 1).sum())} of {n_exp} (S = "
                  f"{2000 * (first_r == 1).mean():.0f}); images where it differs from brightest's rows: "
                  f"{int((first_r != ours).sum())}")

    if n_cone:
        cmin = np.cos(np.radians(FOV_DEG / 2))
        rng = np.random.default_rng([seed, 1])   # the cone fields do not depend on EXP_IMAGES
        res = {"hoku": [], "nearest": [], "brightest": []}
        vmag = catalog.v_mag[bright]
        sizes = []
        while len(res["hoku"]) < n_cone:
            centre = rng.normal(size=3)
            centre /= np.linalg.norm(centre)
            field = np.nonzero(u @ centre > cmin)[0]
            if field.size < 3:
                continue
            sizes.append(field.size)
            s = rng.permutation(field)[:3]
            res["hoku"].append(count(table, int(s[2]), int(s[0]), int(s[1])))
            i, j = nearest_two(u, field, int(s[2]))
            res["nearest"].append(count(table, int(s[2]), i, j))
            c = int(field[np.argmin(vmag[field])])
            i, j = nearest_two(u, field, c)
            res["brightest"].append(count(table, c, i, j))
        print(f"cone: {n_cone} fields of hoku's generator (seed {seed}), {np.mean(sizes):.1f} stars per field")
        for name, r in res.items():
            summarise(name, r)


if __name__ == "__main__":
    main()
