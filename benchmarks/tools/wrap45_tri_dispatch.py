"""What numba's dispatch costs the triangle kernels' named-tuple arguments (issue #25, stop 45, branch
``wrap45-tri``): a trivial kernel called with spherical_triangle's arguments, the tolerances and camera
frame as the named tuples (``SphTol``, ``Frame``) or as one float64 array (``packed_params``).

    python benchmarks/tools/wrap45_tri_dispatch.py [CALLS] [REPEATS]

Prints per argument set the minimum over REPEATS of the mean time of CALLS calls, in microseconds (warm
caches: the same objects every call, so it reads lower than a call from the harness).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from starid_algorithms.spherical_triangle.kernels import packed_params

from starid import Camera, load_hipparcos
from starid.kernels import camera_frame
from starid.kernels.jit import kernel
from starid.registry import get_algorithm


@kernel
def _tuples(x, index, guide_unit, tol, frame):
    return tol.eps + frame.f_px + x[0] + guide_unit[0, 0] + index.area[0]


@kernel
def _array(x, index, guide_unit, params):
    return params[15] + params[0] + x[0] + guide_unit[0, 0] + index.area[0]


def main(calls: int, repeats: int) -> None:
    cat, cam = load_hipparcos(), Camera()
    alg = get_algorithm("spherical_triangle")()
    db = alg.build(cat, cam)
    tol, frame = alg.tolerances(cam, db), camera_frame(cam)
    x = np.zeros(10)
    for label, fn, args in (("SphTol + Frame", _tuples, (x, db.index, db.guide_unit, tol, frame)),
                            ("one float64 array", _array, (x, db.index, db.guide_unit, packed_params(tol, frame)))):
        fn(*args)
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter_ns()
            for _ in range(calls):
                fn(*args)
            best = min(best, (time.perf_counter_ns() - t0) / calls / 1e3)
        print(f"{label:18s} {best:6.2f} us per call (min of {repeats} x {calls})")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20000, int(sys.argv[2]) if len(sys.argv) > 2 else 7)
