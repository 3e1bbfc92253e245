"""Which of triangle_voting's bytes make its interleaved ("cold") time (issue #25, tvspeed7).

    python benchmarks/tools/tvspeed7_warm.py [N] [R] [SKIES]

Table 6's images (``benchmarks/test_ratios.py``'s settings, seed 0), N images (60) x R rounds (2) per sky of SKIES
(``paper,real``). Per image and variant: every other registered plugin identifies the image (as in the benchmark),
then the variant's arrays are read once (one byte of every 64, outside the timing), then triangle_voting's
``identify`` is timed. Variants: ``none`` (the benchmark's cold call), ``records`` (the compact records),
``+cells`` (and ``cell_start``), ``+rows`` (and the guide rows and float32 features), ``db`` (every array
``identify_flat`` reads: the guide and deep-sky tables too), ``code`` (the executable mapping of
``identify_flat``'s machine code, read as data), ``code_pf`` (a prefetch hint for every line of that mapping,
issued inside the timed call, before ``identify``), ``heap`` (scratch arrays of ``vote``'s sizes allocated,
written and freed: their memory cached for the call's own), ``lapack`` (``wahba_rows`` on three stars: its LAPACK
code), ``entry`` (``identify_flat`` on three stars too faint to use: the call's entry and return),
``call`` (``identify`` of the same image once before:
code, scratch memory and data warm), ``other`` (``identify`` of the next image once before: code and scratch
memory warm, this image's records not). Prints per variant the median us and its difference to ``none``.
"""

from __future__ import annotations

import ctypes
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

from starid.kernels import wahba_rows
from starid.kernels.prefetch import prefetch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from starid_algorithms.triangle_voting.kernels import identify_flat  # noqa: E402

from benchmarks.test_ratios import NAMES, TABLE6_SIM  # noqa: E402
from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos  # noqa: E402
from starid.registry import get_algorithm  # noqa: E402


@njit(cache=True)
def _touch(a):
    """Sum of one byte of every 64 of the bytes of ``a`` (a flat uint8 view): brings its lines in."""
    s = 0
    for k in range(0, a.size, 64):
        s += a[k]
    return s


@njit(cache=True)
def _prefetch_all(a):
    """A prefetch hint for every 64th byte of ``a`` (no load waits for it)."""
    for k in range(0, a.size, 64):
        prefetch(a, k)


@njit(cache=True)
def _heap(n):
    """Allocate, write and free scratch arrays of the sizes ``vote`` allocates for ``n`` stars (in its order), so
    that the allocator hands their (now cached) memory to the next call's arrays."""
    cap = n * 21
    a = np.zeros(1024)
    b = np.zeros(1024)
    c = np.zeros(1024)
    d = np.zeros(2048)
    e = np.zeros(2048)
    f = np.zeros(256)
    g = np.zeros((256, 6))
    h = np.zeros((cap, 3))
    i = np.zeros((cap, 4))
    j = np.zeros((cap, 5))
    k = np.zeros(256)
    m = np.zeros(256)
    return a[0] + b[0] + c[0] + d[0] + e[0] + f[0] + g[0, 0] + h[0, 0] + i[0, 0] + j[0, 0] + k[0] + m[0]


@njit(cache=True)
def _lapack(v, rows, unit):
    """``wahba_rows`` (its LAPACK SVD) on a few stars: the code the final step and ``confirm`` run."""
    return wahba_rows(v, rows, unit)[0, 0]


def _bytes(arr: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(arr).reshape(-1).view(np.uint8)


def _code_bytes() -> np.ndarray:
    """The executable mapping holding ``identify_flat``'s machine code, as uint8 (read, never written)."""
    from starid_algorithms.triangle_voting.kernels import identify_flat
    cres = identify_flat.overloads[identify_flat.signatures[0]]
    addr = cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name)
    for line in Path("/proc/self/maps").read_text().splitlines():
        lo, hi = (int(x, 16) for x in line.split()[0].split("-"))
        if lo <= addr < hi:
            return np.ctypeslib.as_array((ctypes.c_uint8 * (hi - lo)).from_address(lo))
    raise RuntimeError("identify_flat's code not found")


def main(n: int, rounds: int, skies: list[str]) -> None:
    tv = get_algorithm("triangle_voting")()
    cat, cam = load_hipparcos(), Camera()
    others = [get_algorithm(x)() for x in NAMES if x != "triangle_voting"]
    for sky in skies:
        sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(len(trials))]
        dbs = [a.build(cat, cam) for a in others]
        db = tv.build(cat, cam)
        for a, d in zip(others, dbs, strict=True):
            a.identify(d, obs[0])
        tv.identify(db, obs[0])
        flat = [x for x in tv._flat_args(db, cam) if isinstance(x, np.ndarray)]
        sets = {"none": [], "records": [db.records], "+cells": [db.records, db.cell_start],
                "+rows": [db.records, db.cell_start, db.rows, db.features], "db": flat}
        sets = {k: [_bytes(a) for a in v] for k, v in sets.items()}
        code = _code_bytes()
        sets["code"] = [code]
        _prefetch_all(code)
        names = [*sets, "code_pf", "heap", "lapack", "entry", "other", "call"]
        lap = (np.eye(3), np.arange(3, dtype=np.int64), np.ascontiguousarray(db.unit_icrs[:3], dtype=np.float64))
        _lapack(*lap)
        flat_args = tv._flat_args(db, cam)
        dim = (np.zeros(3), np.zeros(3), np.full(3, 99.0))  # three stars fainter than the cut: status 0 at once
        identify_flat(*dim, *flat_args)
        t = np.zeros((len(names), rounds * n))
        for r in range(rounds):
            for i, o in enumerate(obs):
                for v in np.roll(np.arange(len(names)), i + r):
                    for a, d in zip(others, dbs, strict=True):
                        a.identify(d, o)
                    if names[v] == "call":
                        tv.identify(db, o)
                    elif names[v] == "code_pf":
                        pass
                    elif names[v] == "lapack":
                        _lapack(*lap)
                    elif names[v] == "entry":
                        identify_flat(*dim, *flat_args)
                    elif names[v] == "heap":
                        _heap(max(o.x_px.size, 3))
                    elif names[v] == "other":
                        tv.identify(db, obs[(i + 1) % n])
                    else:
                        for b in sets[names[v]]:
                            _touch(b)
                    t0 = time.perf_counter_ns()
                    if names[v] == "code_pf":
                        _prefetch_all(code)
                    tv.identify(db, o)
                    t[v, r * n + i] = (time.perf_counter_ns() - t0) * 1e-3
        med = np.median(t, axis=1)
        print(f"{sky:5s} {n}x{rounds}: " + " | ".join(
            f"{k} {m:6.1f} ({m - med[0]:+6.1f})" for k, m in zip(names, med, strict=True)), flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 60, int(sys.argv[2]) if len(sys.argv) > 2 else 2,
         (sys.argv[3] if len(sys.argv) > 3 else "paper,real").split(","))
