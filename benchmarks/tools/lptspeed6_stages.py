"""Where ``lpt``'s kernel spends its time, warm and cold, every stage (issue #25, branch lptspeed6).

    python benchmarks/tools/lptspeed6_stages.py SKY N ROUNDS EVICT

The kernels module copied with the cycle counter read around its stages (``lptspeed3_stages.PATCHES``,
its verification slot counts each candidate once since stop 42) and around the set-up: the
parameters and ``begin_identify``, the work arrays, the reference patterns (neighbours, LPT string,
its index) and the whole call inside the kernel. Table 6's images of SKY (seed 0), N x ROUNDS; before
each call EVICT: ``none`` (warm), ``others`` (every other registered plugin identifies the image, as
``benchmarks/test_ratios.py`` times them) or a number of MiB (a walk over a buffer that large). Per
image each stage's minimum over the ROUNDS (drops preemption by other jobs); prints the medians over
the images (us) of the call from Python, the kernel from entry to return, and each stage; the call
minus the kernel is numba's dispatch of the arguments and the boxing of the results.
"""

from __future__ import annotations

import importlib.util
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from lptspeed3_stages import CYCLES, PATCHES, cycles_per_us  # noqa: E402
from lptspeed6_verify import walk  # noqa: E402

from benchmarks.test_ratios import NAMES, TABLE6_SIM  # noqa: E402
from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos  # noqa: E402
from starid.registry import get_algorithm  # noqa: E402

#: (text, its timed replacement) around the set-up, the patterns and the whole kernel; trace slots 16..19
SETUP = [
    ("    sensor = frame_at(params, np.int64(0))\n", "    k0 = cycles()\n    sensor = frame_at(params, np.int64(0))\n"),
    ("    rows, unit, usable, order = begin_identify(",
     "    k1 = cycles()\n    rows, unit, usable, order = begin_identify("),
    ("    m = search.n_sectors\n    n_guide = chars.start.shape[0] - 1\n",
     "    k2 = cycles()\n    trace[16] += k2 - k1\n    m = search.n_sectors\n    n_guide = chars.start.shape[0] - 1\n"),
    ("    for t in range(min(search.max_refs, order.shape[0])):\n",
     "    trace[17] += cycles() - k2\n    for t in range(min(search.max_refs, order.shape[0])):\n"
     "        k3 = cycles()\n"),
    ("        image = ImageString(img_sector",
     "        trace[18] += cycles() - k3\n        image = ImageString(img_sector"),
    ("    return no_match(rows)", "    trace[19] += cycles() - k0\n    return no_match(rows)"),
    ("                trace[3] = (best_sc[c] + 1023) // 1024\n",
     "                trace[3] = (best_sc[c] + 1023) // 1024\n                trace[19] += cycles() - k0\n"),
]


def stage_kernels(package: str):
    """The plugin's kernels module with the cycle reads, imported from a temporary copy."""
    src = (Path(sys.modules[f"{package}.lpt.kernels"].__file__)).read_text()
    src = src.replace("from ..lpt_improved.planar import", f"from {package}.lpt_improved.planar import")
    src = src.replace("from numba import njit\n", "from numba import njit\n" + CYCLES, 1)
    for old, new in [*PATCHES, *SETUP]:
        if old not in src:
            sys.exit(f"the kernel changed; patch not found:\n{old}")
        src = src.replace(old, new, 1)
    path = Path(tempfile.mkdtemp()) / "lpt6_stage_kernels.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location("lpt6_stage_kernels", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def main(sky: str, n: int, rounds: int, evict_mode: str) -> None:
    alg = get_algorithm("lpt")()
    package = type(alg).__module__.split(".")[0]
    importlib.import_module(f"{package}.lpt.kernels")
    mod = stage_kernels(package)
    cat, cam = load_hipparcos(), Camera()
    db = alg.build(cat, cam)
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    if evict_mode == "others":
        others = [get_algorithm(x)() for x in NAMES if x != "lpt"]
        odbs = [a.build(cat, cam) for a in others]

        def evict(o):
            for a, d in zip(others, odbs, strict=True):
                a.identify(d, o)
    elif evict_mode == "none":
        def evict(o):
            pass
    else:
        buf = np.ones(int(float(evict_mode) * 2 ** 20), dtype=np.uint8)

        def evict(o):
            walk(buf)
    evict(obs[0])
    mod.identify_kernel(obs[0].x_px, obs[0].y_px, *alg._kernel_args(db, cam), np.zeros(24, dtype=np.int64))
    low = np.full((n, 24), np.inf)
    wall = np.full(n, np.inf)
    for _ in range(rounds):
        for i, o in enumerate(obs):
            trace = np.zeros(24, dtype=np.int64)
            trace[:4] = -1
            args = alg._kernel_args(db, o.camera)
            evict(o)
            t0 = time.perf_counter_ns()
            mod.identify_kernel(o.x_px, o.y_px, *args, trace)
            wall[i] = min(wall[i], (time.perf_counter_ns() - t0) * 1e-3)
            low[i] = np.minimum(low[i], trace)
    per_us = cycles_per_us(mod)
    stages = {"kernel": 19, "begin": 16, "work arrays": 17, "patterns": 18, "tables": 8, "scan": 12,
              "- image groups": 9, "- db groups": 10, "- sum tests": 14, "- scoring": 11, "verification": 13}
    print(f"{sky} sky, evict={evict_mode}, {n} images, per image min of {rounds}, median over images (us): "
          f"call {np.median(wall):.1f}; " + ", ".join(f"{k} {np.median(low[:, c]) / per_us:.1f}"
                                                       for k, c in stages.items())
          + f"; patterns / comparisons / verifications {np.median(low[:, 4]):.0f} / {np.median(low[:, 5]):.0f} / "
          f"{np.median(low[:, 6]):.0f}")


if __name__ == "__main__":
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4])
