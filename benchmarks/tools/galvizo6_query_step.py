"""The query table's f and S counted hoku's way for all six methods of Galvizo & Lim (2018): per-seed detail.

Galvizo & Lim's query table (f = the share of 2,000 query steps whose candidate set R holds the right
catalog set, S = the number with |R| = 1, no noise) comes from hoku's separate query experiment, not
from the identifications. ``starid.experiments.hoku_query`` does that step for the six methods (each
with its own features, table and the paper's windows, on hoku's cone fields; its docstring gives the
hoku files and commits read) and ``starid reproduce galvizo2018`` prints it for one seed; this script
prints it per seed, pooled, by longest side, and with two extras:

* ``S_hoku`` for SPH and PLN: ``e_query`` returns a one-element list when nothing matches, so hoku's
  ``r.size()`` is 1 for an empty R as well (counted separately: ``S_hoku`` against ``S``);
* for PYR, the misses of f split by which set difference removed a true star;
* ``PYR-JOIN`` (not hoku's, for comparison, on the same trios as PYR): the three pair windows joined
  into catalog triangles, the form of ``pyramid:galvizo2018``'s triad query.

f and S are reported with a 95 % interval (normal approximation on the count of 2,000; the pooled
line over every seed of the run scales its interval to 2,000 as well).

    python benchmarks/tools/galvizo6_query_step.py QUERIES [CATALOG_STARS] [--seeds 5,6,7] [--methods ANG,PYR,...]

``--methods`` (default: the six, ANG,INT,SPH,PLN,COM,PYR) may add PYR-JOIN.

CATALOG_STARS (default: every star with V < 6, 5,022 in starid's catalog) keeps only the brightest
that many for the tables and the fields (the paper's catalog has 4,560 stars with m < 6).
The "tables" time is K2 and K3-bar; K3 is enumerated (not stored) in each triangle method's time.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from starid.catalog import load_hipparcos
from starid.experiments import hoku_query as hq

METHODS = ("ANG", "INT", "SPH", "PLN", "COM", "PYR", "PYR-JOIN")
TRIANGLE = {"SPH": "spherical", "PLN": "planar", "COM": "planar"}
PRINTED = {  # doc/include/floats/query-table.tex at 0cb340ec: (f, S); COM's own S (commented row) 1,991
    "ANG": (1.0, 32), "INT": (1.0, 1440), "PLN": (1.0, 1994), "COM": (1.0, 1994), "SPH": (1.0, 1984),
    "PYR": (0.99, 1501), "PYR-JOIN": (0.99, 1501),
}


def pyramid_join(pairs: hq.PairTable, u: np.ndarray, s: np.ndarray) -> tuple[int, int, int, int]:
    """Not hoku's: the same three pair windows joined into catalog triangles (x, y, z) with xy in the
    ij window, xz in ik and yz in jk (the form ``pyramid:galvizo2018``'s triad query takes), for comparison."""
    def oriented(p: int, q: int) -> dict[int, set[int]]:
        w = pairs.window(float(hq.angle_deg(u[s[p]], u[s[q]])))
        out: dict[int, set[int]] = {}
        for a, b in zip(pairs.a[w].tolist(), pairs.b[w].tolist(), strict=True):
            out.setdefault(a, set()).add(b)
            out.setdefault(b, set()).add(a)
        return out
    ij, ik, jk = oriented(0, 1), oriented(0, 2), oriented(1, 2)
    r = [(x, y, z) for x in ij.keys() & ik.keys() for y in ij[x] for z in ik[x] if z in jk.get(y, ())]
    has = int(tuple(int(x) for x in s) in set(r))
    return len(r), len({tuple(sorted(t)) for t in r}), has, 0


def run(tables: hq.HokuTables, m: str, n_q: int, seeds: list[int]) -> list[np.ndarray]:
    """Per seed, one row per query: rows, sets, in_R, removed, longest side (deg)."""
    u = tables.u
    stars = [hq.draw_queries(u, m.replace("-JOIN", ""), n_q, seed) for seed in seeds]
    if m == "PYR-JOIN":
        out = []
        for st in stars:
            r = np.array([pyramid_join(tables.pairs, u, s) for s in st], dtype=np.float64)
            out.append(np.column_stack([r, hq.longest_side_deg(u, st)]))
        return out
    if m in TRIANGLE:   # every seed in one pass over K3
        kind = TRIANGLE[m]
        rows, has = tables.triangle_search(**{kind: np.concatenate(stars)})[kind]
        side = hq.longest_side_deg(u, np.concatenate(stars))
        r = np.column_stack([rows, rows, has, np.zeros_like(rows), side])
        return np.split(r, len(seeds))
    cols = ["rows", "sets", "in_R", "removed", "longest_side_deg"]
    return [hq.query_results(tables, m, st)[cols].to_numpy(np.float64) for st in stars]


def main() -> None:
    argv = sys.argv[1:]
    seeds, methods = [5, 6, 7], [m for m in METHODS if m != "PYR-JOIN"]
    if "--seeds" in argv:
        k = argv.index("--seeds")
        seeds = [int(x) for x in argv[k + 1].split(",")]
        del argv[k:k + 2]
    if "--methods" in argv:
        k = argv.index("--methods")
        methods = [m.strip().upper() for m in argv[k + 1].split(",")]
        del argv[k:k + 2]
    n_q = int(argv[0])
    rows, u = hq.bright_stars(load_hipparcos(), int(argv[1]) if len(argv) > 1 else None)
    t0 = time.process_time()
    tables = hq.HokuTables(u)
    if "INT" in methods:
        tables.trios   # noqa: B018 (built here, so that its time counts with the tables)
    t_tables = time.process_time() - t0
    results, cpu = {}, {}
    for m in methods:
        t1 = time.process_time()
        results[m] = run(tables, m, n_q, seeds)
        cpu[m] = time.process_time() - t1
    k3 = tables.k3_counts
    print(f"catalog: {len(rows)} stars with V < 6; K2 {tables.pairs.t.size} pairs"
          + (f"; K3 {k3['trios']} trios" if k3 else "")
          + (f" (planar rows {k3['planar']})" if "planar" in k3 else "")
          + (f" (spherical rows {k3['spherical']})" if "spherical" in k3 else "")
          + f"; tables {t_tables:.1f} CPU s")
    for m in methods:
        for seed, r in zip(seeds, results[m], strict=True):
            report(m, f"seed {seed}", r)
        if len(seeds) > 1:
            report(m, "pooled", np.concatenate(results[m]))
        print(f"  ({cpu[m]:.1f} CPU s)")


def report(m: str, label: str, r: np.ndarray) -> None:
    n = len(r)
    one = int((r[:, 0] == 1).sum())
    empty = int((r[:, 0] == 0).sum())
    one_sets = int((r[:, 1] == 1).sum())
    s, ds = hq.interval(one, n, 2000)
    f, df = hq.interval(int(r[:, 2].sum()), n)
    pf, ps = PRINTED[m]
    extra = ""
    if m in ("SPH", "PLN"):   # e_query: an empty R is logged as r.size() = 1
        sh, dsh = hq.interval(one + empty, n, 2000)
        extra = f"; S_hoku (empty R logged as 1) {sh:.0f} +-{dsh:.0f}"
    print(f"{m} {label:8s} n={n}: S = {s:.0f} +-{ds:.0f} (rows; sets {2000 * one_sets / n:.0f}) [printed {ps}]; "
          f"f = {f:.4f} +-{df:.4f} [printed {pf}]; |R| = 0 in {empty}, >1 in {int((r[:, 0] > 1).sum())}, "
          f"mean |R| {r[:, 0].mean():.2f}{extra}")
    if label == "pooled":
        if m == "PYR":
            miss = r[:, 2] == 0
            print(f"      misses of f: {int(miss.sum())}; a true star removed by a set difference: J in T_i "
                  f"{int((miss & (r[:, 3] == 1)).sum())}, K in T_i or T_j {int((miss & (r[:, 3] == 2)).sum())}")
        for lo, hi in ((0, 2), (2, 5), (5, 10), (10, 20)):
            k = (r[:, 4] >= lo) & (r[:, 4] < hi)
            if k.any():
                print(f"      longest side {lo:2d}-{hi:2d} deg: {int(k.sum()):5d} queries, |R| = 1 in "
                      f"{(r[k, 0] == 1).mean():.3f}, |R| = 0 in {(r[k, 0] == 0).mean():.3f}, f {r[k, 2].mean():.3f}")


if __name__ == "__main__":
    main()
