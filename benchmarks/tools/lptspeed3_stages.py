"""Where ``lpt``'s kernel spends its time, stage by stage (issue #25, branch lptspeed3).

    python benchmarks/tools/lptspeed3_stages.py SKY N R

A copy of ``starid_algorithms/lpt/kernels.py`` with the CPU cycle counter (``llvm.readcyclecounter``)
read around its stages is written to a temporary directory and imported (the plugin itself is not
touched); the kernel is called with the arguments the plugin builds. Table 6's images (1 px /
0.5 Mv, seed 0), N of them, each R times; per image the call with the least wall time is kept.
Prints, for all images, those at or below the median and those at or above the p95 (by kernel
time), the mean per image in us of: the kernel call, the per-reference tables (``window_counts``,
``shift_tables_of``, ``level_set_masks``), the scan of the strings (all below), within it the
image-side groups (``image_groups_at``), the database-side groups (``reaches_groups``), the exact
sum tests (``reaches_budget`` / ``reaches_tables_at``) and the scoring (``best_shift`` /
``shift_scores``), and the verification of the candidates (``confirm``). Cycle reads cost a little
themselves (a few hundred per string that reaches the groups), so the stages add up to more than
the kernel time of the plugin.
"""

import importlib.util
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import starid_algorithms.lpt.kernels as LK
from numba import njit

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm

CYCLES = '''
from llvmlite import ir as _ir
from numba.core import types as _nt
from numba.extending import intrinsic as _intrinsic


@_intrinsic
def cycles(typingctx):
    def codegen(context, builder, signature, args):
        fn = builder.module.declare_intrinsic("llvm.readcyclecounter", fnty=_ir.FunctionType(_ir.IntType(64), []))
        return builder.call(fn, [])
    return _nt.int64(), codegen
'''

# (text in the summed scan path, its timed replacement); each is replaced at its first occurrence
PATCHES = [
    ("        if fast:\n            window_counts(image, search, most)",
     "        c0 = cycles()\n        if fast:\n            window_counts(image, search, most)"),
    ("            level_set_masks(image, search, most, set_masks, most_masks)\n",
     "            level_set_masks(image, search, most, set_masks, most_masks)\n"
     "        c1 = cycles()\n        trace[8] += c1 - c0\n"),
    ("                        if not image_groups_at(chars, g, image, by_level_x, nz - need, pattern2, valid, xs, "
     "groups):\n                            continue\n",
     "                        ca = cycles()\n"
     "                        ok_ = image_groups_at(chars, g, image, by_level_x, nz - need, pattern2, valid, xs, "
     "groups)\n                        trace[9] += cycles() - ca\n"
     "                        if not ok_:\n                            continue\n"),
    ("                        matched, sh = best_shift(xs, nz, sets.shape[1], planes, cand)\n",
     "                        ca = cycles()\n"
     "                        matched, sh = best_shift(xs, nz, sets.shape[1], planes, cand)\n"
     "                        trace[11] += cycles() - ca\n"),
    ("                    elif not reaches_groups(chars, g, total - need, most, tables, valid, groups):\n"
     "                        continue\n"
     "                    elif total - need <= BUDGET_MAX:\n"
     "                        if not reaches_budget(chars, g, total - need, most, tables, valid, at_most):\n"
     "                            continue\n"
     "                    elif not reaches_tables_at(chars, g, need, most, tables, sum_planes):\n"
     "                        continue\n",
     "                    else:\n"
     "                        ca = cycles()\n"
     "                        ok_ = reaches_groups(chars, g, total - need, most, tables, valid, groups)\n"
     "                        cb = cycles()\n                        trace[10] += cb - ca\n"
     "                        if not ok_:\n                            continue\n"
     "                        if total - need <= BUDGET_MAX:\n"
     "                            ok_ = reaches_budget(chars, g, total - need, most, tables, valid, at_most)\n"
     "                        else:\n"
     "                            ok_ = reaches_tables_at(chars, g, need, most, tables, sum_planes)\n"
     "                        trace[14] += cycles() - cb\n"
     "                        if not ok_:\n                            continue\n"),
    ("                    matched, sh = shift_scores(chars, g, image, search, sets, planes)\n",
     "                    ca = cycles()\n"
     "                    matched, sh = shift_scores(chars, g, image, search, sets, planes)\n"
     "                    trace[11] += cycles() - ca\n"),
    ("        for c in range(found):\n            g = scan_guide",
     "        c2 = cycles()\n        trace[12] += c2 - c1\n        for c in range(found):\n            g = scan_guide"),
    ("            count_work(trace, 2, 1)\n            if ok:",
     # each candidate's own time (stop 42: this slot used to add the time since the first candidate after every
     # candidate, so candidate k counted k times and the verification read several times too high)
     "            count_work(trace, 2, 1)\n            c3 = cycles()\n            trace[13] += c3 - c2\n"
     "            c2 = c3\n            if ok:"),
]


def timed_kernels():
    """The plugin's kernels module with the cycle reads, imported from a temporary copy."""
    src = Path(LK.__file__).read_text()
    src = src.replace("from ..lpt_improved.planar import", "from starid_algorithms.lpt_improved.planar import")
    src = src.replace("from numba import njit\n", "from numba import njit\n" + CYCLES, 1)
    for old, new in PATCHES:
        if old not in src:
            sys.exit(f"the kernel changed; patch not found:\n{old}")
        src = src.replace(old, new, 1)
    path = Path(tempfile.mkdtemp()) / "lpt_timed_kernels.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location("lpt_timed_kernels", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def cycles_per_us(mod) -> float:
    read = njit(lambda: mod.cycles())
    read()
    c0, t0 = read(), time.perf_counter()
    while time.perf_counter() - t0 < 0.2:
        pass
    return (read() - c0) / ((time.perf_counter() - t0) * 1e6)


def main(sky: str, n: int, repeats: int) -> None:
    mod = timed_kernels()
    cat, cam = load_hipparcos(), Camera()
    alg = get_algorithm("lpt")()
    db = alg.build(cat, cam)
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                    seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    rows = []
    for o in obs:
        args = alg._kernel_args(db, o.camera)
        best = None
        for _ in range(repeats + 1):            # the first call of the first image compiles
            trace = np.zeros(16, dtype=np.int64)
            trace[:4] = -1
            t0 = time.perf_counter_ns()
            mod.identify_kernel(o.x_px, o.y_px, *args, trace)
            dt = (time.perf_counter_ns() - t0) * 1e-3
            if best is None or dt < best[0]:
                best = (dt, trace.copy())
        rows.append([best[0], *best[1][4:7], *best[1][8:15]])
    a = np.array(rows, dtype=float)
    per_us = cycles_per_us(mod)
    a[:, 4:] /= per_us
    med, p95 = np.median(a[:, 0]), np.percentile(a[:, 0], 95)
    print(f"{sky}: {len(a)} images, min of {repeats}: kernel median {med:.1f} us, p95 {p95:.1f} us "
          f"({per_us:.0f} cycles per us)")
    cols = {"kernel": 0, "tables": 4, "scan": 8, "image groups": 5, "db groups": 6, "sum tests": 10, "scoring": 7,
            "verification": 9, "n_patterns": 1, "n_comparisons": 2, "n_verifications": 3}
    print(f"{'images':>10s} " + " ".join(f"{c:>15s}" for c in cols))
    for label, sel in (("all", np.ones(len(a), bool)), ("<= median", a[:, 0] <= med), (">= p95", a[:, 0] >= p95)):
        m = a[sel].mean(axis=0)
        print(f"{label:>10s} " + " ".join(f"{m[i]:15.1f}" for i in cols.values()))


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
