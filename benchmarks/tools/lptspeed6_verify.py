"""Base against branch ``lpt`` kernel stage by stage, every call cold (issue #25, branch lptspeed6).

    python benchmarks/tools/lptspeed6_verify.py BASE SKY N ROUNDS EVICT

BASE: a directory holding the base commit's ``starid_algorithms`` (``git archive BASE algorithms``
unpacked, ``algorithms`` renamed). Both kernels modules (the base's and this checkout's) are copied
with the cycle counter read around their stages (``lptspeed3_stages.PATCHES``) and imported in one
process; each runs with its own plugin class, database and kernel arguments. Table 6's images of SKY
(seed 0), N x ROUNDS; before every timed call EVICT: ``others`` (every other registered plugin
identifies the image, as ``benchmarks/test_ratios.py`` times them) or a number of MiB (a walk over a
buffer that large, one read per cache line), the base and branch calls alternating in order per image.
Per image and variant each stage's minimum over the ROUNDS (every one cold) is kept, which drops
preemption by other jobs; prints the medians over the images of the kernel time, the per-reference
tables, the scan and the verification (``confirm_near`` / ``confirm_seed``, with the seed attitudes),
the verifications per image, the verification's us per verification, the branch / base ratios, and
whether both found the same trace (reference star, guide, score, counters).
"""

from __future__ import annotations

import importlib
import importlib.util
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from lptspeed3_stages import CYCLES, PATCHES, cycles_per_us  # noqa: E402
from numba import njit  # noqa: E402

from benchmarks.test_ratios import NAMES, TABLE6_SIM  # noqa: E402
from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos  # noqa: E402
from starid.registry import get_algorithm  # noqa: E402


def timed_copy(kernels_py: Path, package: str, name: str):
    """``kernels_py`` with the cycle reads, imported as ``name`` (its relative imports from ``package``)."""
    src = kernels_py.read_text()
    src = src.replace("from ..lpt_improved.planar import", f"from {package}.lpt_improved.planar import")
    src = src.replace("from numba import njit\n", "from numba import njit\n" + CYCLES, 1)
    for old, new in PATCHES:
        if old not in src:
            sys.exit(f"{kernels_py}: patch not found:\n{old}")
        src = src.replace(old, new, 1)
    path = Path(tempfile.mkdtemp()) / f"{name}.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod



@njit(cache=True)
def walk(buf):
    s = 0
    for i in range(0, buf.shape[0], 64):
        s += buf[i]
    return s


def main(base: str, sky: str, n: int, rounds: int, evict_mode: str) -> None:
    dst = Path(base.rstrip("/") + "_ab6")
    if not (dst / "ab6_base_algorithms").exists():
        shutil.copytree(Path(base) / "starid_algorithms", dst / "ab6_base_algorithms",
                        ignore=shutil.ignore_patterns("__pycache__", "tests"))
    sys.path.insert(0, str(dst))
    base_alg = importlib.import_module("ab6_base_algorithms.lpt.algorithm").LPT()
    alg = get_algorithm("lpt")()
    here = Path(sys.modules[type(alg).__module__].__file__).parent / "kernels.py"
    pkg = type(alg).__module__.split(".")[0]
    mods = [timed_copy(dst / "ab6_base_algorithms" / "lpt" / "kernels.py", "ab6_base_algorithms", "lpt6_base_timed"),
            timed_copy(here, pkg, "lpt6_branch_timed")]
    algs = [base_alg, alg]
    cat, cam = load_hipparcos(), Camera()
    dbs = [a.build(cat, cam) for a in algs]
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    if evict_mode == "others":
        others = [get_algorithm(x)() for x in NAMES if x != "lpt"]
        odbs = [a.build(cat, cam) for a in others]

        def evict(o):
            for a, d in zip(others, odbs, strict=True):
                a.identify(d, o)
    else:
        buf = np.ones(int(float(evict_mode) * 2 ** 20), dtype=np.uint8)

        def evict(o):
            walk(buf)
    evict(obs[0])
    for v in range(2):
        trace = np.zeros(16, dtype=np.int64)
        mods[v].identify_kernel(obs[0].x_px, obs[0].y_px, *algs[v]._kernel_args(dbs[v], cam), trace)
    rec = np.zeros((2, rounds * n, 5))   # kernel us, scan cycles, verification cycles, n_verif, tables cycles
    same = True
    for r in range(rounds):
        for i, o in enumerate(obs):
            traces = [None, None]
            for v in ((0, 1) if (i + r) % 2 == 0 else (1, 0)):
                args = algs[v]._kernel_args(dbs[v], o.camera)
                trace = np.zeros(16, dtype=np.int64)
                trace[:4] = -1
                evict(o)
                t0 = time.perf_counter_ns()
                mods[v].identify_kernel(o.x_px, o.y_px, *args, trace)
                rec[v, r * n + i] = ((time.perf_counter_ns() - t0) * 1e-3, trace[12], trace[13], trace[6], trace[8])
                traces[v] = trace
            same &= bool(np.array_equal(traces[0][:7], traces[1][:7]))
    per_us = cycles_per_us(mods[0])
    # per image, each column's minimum over the rounds (every round cold): preemption by other jobs dropped
    low = rec.reshape(2, rounds, n, 5).min(axis=1)
    low[:, :, 1:3] /= per_us
    low[:, :, 4] /= per_us
    for v, label in enumerate(("base", "branch")):
        a = low[v]
        print(f"{sky} {label:6s} evict={evict_mode}, per image min of {rounds}, median over images: kernel "
              f"{np.median(a[:, 0]):7.1f} us, tables {np.median(a[:, 4]):6.1f}, scan {np.median(a[:, 1]):6.1f}, "
              f"verification {np.median(a[:, 2]):6.1f} us ({np.median(a[:, 3]):.0f} verifications; "
              f"{a[:, 2].sum() / max(a[:, 3].sum(), 1):.2f} us each over all images)")
    print(f"branch/base, medians: kernel {np.median(low[1, :, 0]) / np.median(low[0, :, 0]):.3f}, verification "
          f"{np.median(low[1, :, 2]) / np.median(low[0, :, 2]):.3f} (median of per-image ratios "
          f"{np.median(low[1, :, 2] / np.maximum(low[0, :, 2], 1e-9)):.3f}), scan "
          f"{np.median(low[1, :, 1]) / np.median(low[0, :, 1]):.3f}; same traces: {same}")

if __name__ == "__main__":
    if len(sys.argv) != 6:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5])
