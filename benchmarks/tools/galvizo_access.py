"""hoku's catalog-access counts of galvizo2018 readings on images made one difference at a time.

    python benchmarks/tools/galvizo_access.py N F:RHO_DEG:FIELD:ORDER:NOISE:CATALOG [...] -- LABEL [LABEL ...]

    e.g. ... 500 0:0:square:mag:axis:all 0:0:cone:random:arc:4560 -- angle:galvizo2018

F, RHO_DEG, FIELD, ORDER, NOISE as in ``galvizo_sim_variants.py`` (its images, seed 0); CATALOG ``all``
(every Hipparcos star, starid's sky: 5,022 with V < 6) or a number K: only the K brightest stars with
V < 6 exist (the sky the images are made of and the catalog the database is built from; the paper's
catalog has 4,560). Prints per label the counts of ``starid reproduce galvizo2018``'s table
"galvizo_access" (``starid.experiments.galvizo2018.access_frame``): accesses to a map h (where the plugin
counts them), to r, and to r over the images that needed more than one (with their number per 2,000),
each capped at 501 as hoku logs them.
"""

from __future__ import annotations

import math
import sys

import numpy as np
from galvizo_sim_variants import images

from starid import load_hipparcos
from starid.experiment import Variant
from starid.experiments import galvizo2018 as g
from starid.harness import prepare
from starid.observation import Observation


def _catalog(spec: str):
    catalog = load_hipparcos()
    if spec == "all":
        return catalog
    bright = np.flatnonzero(catalog.v_mag < g.SIM["mag_limit"])
    keep = bright[np.argsort(catalog.v_mag[bright], kind="stable")[:int(spec)]]
    return catalog.subset(np.sort(keep), name=f"brightest {spec}")


def _pm(x: np.ndarray) -> str:
    if x.size == 0:
        return "-"
    half = 1.96 * x.std(ddof=1) / math.sqrt(x.size) if x.size > 1 else float("nan")
    return f"{x.mean():7.2f} +-{half:5.2f}"


def main(n, settings, labels):
    cap = g.ACCESS_LIMIT + 1
    for setting in settings:
        f, rho, field, order, noise, cat = setting.split(":")
        catalog = _catalog(cat)
        camera, catalog, obs = images(n, int(f), float(rho), field, order, noise, catalog=catalog)
        for label in labels:
            p = prepare(Variant.parse(label).make(), catalog, camera, obs[0], label)
            name = label.split(":")[0]
            h, r = [], []
            for o in obs:
                c = p.algorithm.identify(p.database, Observation(o.x_px, o.y_px, o.mag, camera)).counters or {}
                h.append(c.get(g.ACCESS_H.get(name, "")[2:], -1))
                r.append(c.get("to_r", -1))
            h = np.minimum(np.asarray(h, dtype=float), cap)
            r = np.minimum(np.asarray(r, dtype=float), cap)
            more = r[r > 1]
            print(f"{label:32s} {setting:30s} n={len(obs)}: h {_pm(h[h >= 0])}  r {_pm(r[r >= 0])}  "
                  f"r>1 {_pm(more)} in {more.size / max(len(obs), 1) * 2000:.0f} of 2000", flush=True)


if __name__ == "__main__":
    if "--" not in sys.argv[2:]:
        sys.exit(__doc__)
    cut = sys.argv.index("--")
    main(int(sys.argv[1]), sys.argv[2:cut], sys.argv[cut + 1:])
