"""The indexed cone search against the binary-search one: the same row ranges (issue #25, tvspeed4).

    python benchmarks/tools/tvspeed4_cone_check.py [N]

On triangle_voting's deep sky (every catalog star, in ``final.band_order``) ``final.cone_ranges_indexed`` (starting
from the database's ``deep_index``) and ``final.cone_ranges`` (binary searches over the whole deep sky) are asked
for N random directions (5000) at each of the chords 1e-4, 1e-3, 3e-3, 0.05, 0.2, 0.5, plus the poles and right
ascension 0 and just below 2 pi; prints the number of searches and of those whose ranges differ (exit 1 if any).
"""

from __future__ import annotations

import sys

import numpy as np
from starid_algorithms.triangle_voting import final

from starid import Camera, load_hipparcos
from starid.registry import get_algorithm


def main(n: int) -> int:
    db = get_algorithm("triangle_voting")().build(load_hipparcos(), Camera())
    unit, index = db.deep.unit, db.deep_index
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(n, 3))
    special = [(0, 0, 1), (0, 0, -1), (1, 0, 0), (1, -1e-9, 0), (1, 1e-9, 0), (0.6, -1e-7, 0.8)]
    dirs = np.vstack([dirs, np.array(special, dtype=float)])
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    a = np.empty((final.MAX_RANGES, 2), dtype=np.int64)
    b = np.empty((final.MAX_RANGES, 2), dtype=np.int64)
    searches = differ = 0
    for c in (1e-4, 1e-3, 3e-3, 0.05, 0.2, 0.5):
        for d in dirs:
            na = final.cone_ranges(unit, d[0], d[1], d[2], c, a)
            nb = final.cone_ranges_indexed(unit, index, d[0], d[1], d[2], c, b)
            searches += 1
            if na != nb or not np.array_equal(a[:na], b[:nb]):
                differ += 1
    print(f"cone searches: {searches}; ranges differing: {differ}")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 5000))
