"""triangle_voting's database on 4 KB pages against the same arrays on 2 MB pages, interleaved (issue #25, tvspeed7).

    python benchmarks/tools/tvspeed7_huge.py [N] [R] [SKIES]

Two triangle_voting instances with the same database values: one with ordinary copies of every array (``np.array``,
each below numpy's 4 MB threshold for huge pages: on 4 KB pages), one with the arrays in one 2 MB-aligned block
advised ``MADV_HUGEPAGE`` (what ``build`` gives since tvspeed7's ``on_huge_pages``; made here by :func:`packed`
with ``ctypes``, so the tool also measures a base checkout's database). ``tvspeed5_ab.py``'s loop: Table 6's images
(seed 0), N (150) x R (2) per sky of SKIES (``paper,real``); per image every other plugin identifies it, then one
variant is timed; the others again, then the other variant (order alternating). Prints the medians, huge / small,
whether the ids agree, and the block's ``AnonHugePages`` (0 kB: the system gave no huge pages, the comparison means
nothing).
"""

from __future__ import annotations

import ctypes
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks.test_ratios import NAMES, TABLE6_SIM  # noqa: E402
from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos  # noqa: E402
from starid.registry import get_algorithm  # noqa: E402

HUGE = 2 << 20
MADV_HUGEPAGE = 14  # Linux


def packed(arrays: list[np.ndarray]) -> tuple[list[np.ndarray], np.ndarray]:
    """Copies of ``arrays`` in one 2 MB-aligned buffer of at least 4 MB (numpy's threshold for huge pages)."""
    sizes = [(a.nbytes + 63) // 64 * 64 for a in arrays]
    buf = np.empty(max(sum(sizes), 4 << 20) + HUGE, dtype=np.uint8)
    off = (-buf.ctypes.data) % HUGE
    span = (sum(sizes) + HUGE - 1) // HUGE * HUGE
    ctypes.CDLL(None).madvise(ctypes.c_void_p(buf.ctypes.data + off), ctypes.c_size_t(span), MADV_HUGEPAGE)
    out = []
    for a, s in zip(arrays, sizes, strict=True):
        v = np.ndarray(a.shape, a.dtype, buffer=buf, offset=off)
        v[...] = a
        out.append(v)
        off += s
    return out, buf


def huge_kb(buf: np.ndarray) -> int:
    """``AnonHugePages`` (kB) of the mappings overlapping ``buf``."""
    a0, a1 = buf.ctypes.data, buf.ctypes.data + buf.nbytes
    kb, inside = 0, False
    for line in Path("/proc/self/smaps").read_text().splitlines():
        head = line.split()[0]
        if "-" in head and not head.endswith(":"):
            lo, hi = (int(x, 16) for x in head.split("-"))
            inside = lo < a1 and hi > a0
        elif inside and head == "AnonHugePages:":
            kb += int(line.split()[1])
    return kb


NAMES_DB = ["features", "records", "rows", "cell_start", "unit_icrs", "hip", "sky_start", "deep_v_mag", "deep_index"]


def huge_db(db):
    arrays = [getattr(db, k) for k in NAMES_DB] + [db.deep.unit, db.deep.hip]
    copies, buf = packed(arrays)
    deep = type(db.deep)(copies[-2], copies[-1])
    return dataclasses.replace(db, **dict(zip(NAMES_DB, copies[:-2], strict=True)), deep=deep), buf


def small_db(db):
    deep = type(db.deep)(np.array(db.deep.unit), np.array(db.deep.hip))
    return dataclasses.replace(db, **{k: np.array(getattr(db, k)) for k in NAMES_DB}, deep=deep)


def _t(f) -> float:
    t0 = time.perf_counter_ns()
    f()
    return (time.perf_counter_ns() - t0) * 1e-3


def main(n: int, rounds: int, skies: list[str]) -> None:
    cat, cam = load_hipparcos(), Camera()
    variants = [get_algorithm("triangle_voting")(), get_algorithm("triangle_voting")()]
    others = [get_algorithm(x)() for x in NAMES if x != "triangle_voting"]
    k_te = [x for x in NAMES if x != "triangle_voting"].index("tetra")
    small = small_db(variants[0].build(cat, cam))
    huge, buf = huge_db(variants[1].build(cat, cam))
    vdbs = [small, huge]
    for sky in skies:
        sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(len(trials))]
        dbs = [a.build(cat, cam) for a in others]
        for a, d in zip(others + variants, dbs + vdbs, strict=True):
            a.identify(d, obs[0])
        same = all(np.array_equal(variants[0].identify(small, o).hip, variants[1].identify(huge, o).hip) for o in obs)
        t = np.zeros((2, rounds * n))
        tetra = []
        for r in range(rounds):
            for i, o in enumerate(obs):
                for v in ((0, 1) if (i + r) % 2 == 0 else (1, 0)):
                    for j, (a, d) in enumerate(zip(others, dbs, strict=True)):
                        dt = _t(lambda a=a, d=d, o=o: a.identify(d, o))
                        if j == k_te:
                            tetra.append(dt)
                    a, d = variants[v], vdbs[v]
                    t[v, r * n + i] = _t(lambda a=a, d=d, o=o: a.identify(d, o))
        te = float(np.median(tetra))
        ms, mh = float(np.median(t[0])), float(np.median(t[1]))
        print(f"{sky:5s} {n}x{rounds} interleaved: tetra {te:6.1f} us | small pages {ms:6.1f} ({ms / te:4.2f}x) | "
              f"huge pages {mh:6.1f} ({mh / te:4.2f}x) | huge/small {mh / ms:5.3f} (per image "
              f"{np.median(t[1] / t[0]):5.3f}) | same ids {same} | AnonHugePages {huge_kb(buf)} kB", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 150, int(sys.argv[2]) if len(sys.argv) > 2 else 2,
         (sys.argv[3] if len(sys.argv) > 3 else "paper,real").split(","))
