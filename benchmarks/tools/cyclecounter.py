"""The CPU cycle counter inside numba kernels, for the stage profilers of benchmarks/tools.

``cycles()`` (a numba intrinsic: ``llvm.readcyclecounter``) is called between the stages of a profiler's copy of
a kernel; ``cycles_per_us()`` converts its ticks to microseconds against ``time.perf_counter`` over 0.2 s. Used by
``profile45_tetra.py``, ``profile45_angle.py`` and ``profile45_triangles.py``; older stage tools keep their own copy.
"""

from __future__ import annotations

import time

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic


@intrinsic
def cycles(typingctx):
    def codegen(context, builder, sig, args):
        fnty = ir.FunctionType(ir.IntType(64), [])
        fn = builder.module.declare_intrinsic("llvm.readcyclecounter", fnty=fnty)
        return builder.call(fn, [])

    return types.int64(), codegen


@njit
def cyc():
    """:func:`cycles` from Python."""
    return cycles()


def cycles_per_us() -> float:
    """Cycle-counter ticks per µs, against ``perf_counter`` over 0.2 s."""
    cyc()
    t0 = time.perf_counter()
    c0 = cyc()
    time.sleep(0.2)
    c1 = cyc()
    t1 = time.perf_counter()
    return (c1 - c0) / (t1 - t0) / 1e6
