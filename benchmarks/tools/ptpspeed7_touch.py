"""What an interleaved ptp kernel call waits for: its kernel timed right after the other registered plugins
identified the image, alone and with one thing read into the cache first, untimed (issue #25, eighth round).

    python benchmarks/tools/ptpspeed7_touch.py N SKY

Table 6's images (1 px / 0.5 Mv, seed 0), N of them in SKY (paper or real). Variants, in a shuffled order per
image, each after the other plugins: the kernel alone; after reading the kernel's machine code (the executable
mapping of ``/proc/self/maps`` that holds its entry point: numba links the callees into the kernel's module);
after reading the packed tables (both arrays), ``narrow`` alone, ``wide`` alone; and the kernel on a copy of
the packed tables in transparent huge pages (an anonymous map with ``MADV_HUGEPAGE``, 2 MB aligned: the tables
then need one TLB entry). Median µs, and the median of each variant's paired difference from the kernel alone.
"""

from __future__ import annotations

import ctypes
import mmap
import sys
import time

import numpy as np
from ptpspeed7_wrapper import setup  # benchmarks/tools
from starid_algorithms.ptp import kernels as K

HUGE = 2 << 20


def huge_copy(arrays):
    """Copies of ``arrays`` in one anonymous map advised for huge pages, from a 2 MB boundary."""
    sizes = [(a.nbytes + 63) // 64 * 64 for a in arrays]
    m = mmap.mmap(-1, sum(sizes) + HUGE, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
    m.madvise(mmap.MADV_HUGEPAGE, 0, len(m))
    buf = np.frombuffer(m, dtype=np.uint8)
    off = (-buf.ctypes.data) % HUGE
    out = []
    for a, size in zip(arrays, sizes, strict=True):
        v = buf[off:off + a.nbytes].view(a.dtype).reshape(a.shape)
        v[...] = a
        out.append(v)
        off += size
    return out, m


def code_bytes():
    """The kernel's machine code as a read-only uint8 array (its module's executable mapping)."""
    f = K.identify_kernel
    overload = f.overloads[f.signatures[0]]
    entry = overload.library.get_pointer_to_function(overload.fndesc.llvm_func_name)
    with open("/proc/self/maps") as maps:
        for line in maps:
            lo, hi = (int(v, 16) for v in line.split()[0].split("-"))
            if lo <= entry < hi:
                return np.frombuffer((ctypes.c_char * (hi - lo)).from_address(lo), dtype=np.uint8)
    raise RuntimeError("the kernel's code is in no mapping")


def main(n: int, sky: str) -> None:
    _, ptp, db, rest, obs, (_, params, (narrow, wide), _) = setup(n, sky)
    (h_narrow, h_wide), keep = huge_copy([narrow, wide])
    code = code_bytes()
    print(f"kernel module code {code.shape[0] // 1024} KB; tables {narrow.nbytes // 1024} + {wide.nbytes // 1024} KB")
    nothing = lambda: None      # noqa: E731
    variants = {
        "alone": (nothing, (narrow, wide)),
        "code read first": (lambda: code[::64].sum(), (narrow, wide)),
        "tables read first": (lambda: (narrow[::16].sum(), wide[::64].sum()), (narrow, wide)),
        "narrow read first": (lambda: narrow[::16].sum(), (narrow, wide)),
        "wide read first": (lambda: wide[::64].sum(), (narrow, wide)),
        "tables in huge pages": (nothing, (h_narrow, h_wide)),
    }
    f = K.identify_kernel
    for _, tables in variants.values():
        f(obs[0].x_px, obs[0].y_px, obs[0].mag, params, *tables)
    for a, d in rest:
        a.identify(d, obs[0])
    cold = {k: [] for k in variants}
    rng = np.random.default_rng(0)
    for o in obs:
        order = list(variants)
        rng.shuffle(order)
        for k in order:
            before, tables = variants[k]
            for a, d in rest:
                a.identify(d, o)
            before()
            t0 = time.perf_counter_ns()
            f(o.x_px, o.y_px, o.mag, params, *tables)
            cold[k].append(time.perf_counter_ns() - t0)
    print(f"{sky} sky, {n} images; the kernel after the other plugins, median µs, and paired minus 'alone'")
    for k in variants:
        d = np.array(cold[k]) - np.array(cold["alone"])
        print(f"  {k:22s} {np.median(cold[k]) / 1e3:7.1f} {np.median(d) / 1e3:+7.1f}", flush=True)
    del keep


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(int(sys.argv[1]), sys.argv[2])
