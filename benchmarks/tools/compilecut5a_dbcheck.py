"""planar_triangle's database, array by array, saved or compared (compilecut5a: the build rewritten
in numpy must give the same bytes). On the Table 6 camera and two others:

    python benchmarks/tools/compilecut5a_dbcheck.py save DIR     # on the base commit
    python benchmarks/tools/compilecut5a_dbcheck.py check DIR    # after: prints differing arrays
"""

from __future__ import annotations

import sys
import time

import numpy as np

from starid import Camera, load_hipparcos
from starid.registry import get_algorithm

CASES = {"table6": {}, "paper": {"mag_limit": 6.0}, "fov20": {"fov_db_deg": 20.0, "mag_limit": 5.0}}


def arrays(db) -> dict:
    return {"tri_stars": db.tri_stars, "area": db.tri_area.values, "kv": db.tri_area.k,
            "kvmq": np.array([db.tri_area.m, db.tri_area.q], dtype=np.float64),
            "moment": db.tri_moment, "perm": db.tri_moment_perm, "guide_hip": db.guide_hip,
            "guide_unit": db.guide_unit, "nbr_ptr": db.nbr_ptr, "nbr_idx": db.nbr_idx,
            "rules": np.array(db.rules, dtype=np.float64)}


def main(mode: str, out: str) -> None:
    cat, cam = load_hipparcos(), Camera()
    bad = 0
    for case, params in CASES.items():
        alg = get_algorithm("planar_triangle")(**params)
        c0 = time.process_time()
        db = alg.build(cat, cam)
        got = arrays(db)
        print(case, f"build {time.process_time() - c0:.2f} CPU s", len(db.tri_stars), "triangles", flush=True)
        if mode == "save":
            np.savez(f"{out}/{case}.npz", **got)
            continue
        want = np.load(f"{out}/{case}.npz")
        for k, v in got.items():
            same = v.dtype == want[k].dtype and v.shape == want[k].shape and v.tobytes() == want[k].tobytes()
            if not same:
                bad += 1
                print("  DIFFERS", k, v.dtype, want[k].dtype, v.shape, want[k].shape)
    print("differing arrays:", bad)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
