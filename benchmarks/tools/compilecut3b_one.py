"""One kernel's own cold compile, its callees loaded from a warm cache: the preparation of a plugin (as
``starid.harness.prepare`` does) after deleting only the named kernels' cache files, so the CPU seconds
measured are those kernels' typing, lowering and LLVM (their linked callees re-optimised and re-emitted
in their modules included), steadier than a whole cold compile for before/after pairs:

    export NUMBA_CACHE_DIR=$(mktemp -d)
    python benchmarks/tools/compilecut3b_one.py pvector identify_rows          # fills the cache
    python benchmarks/tools/compilecut3b_one.py pvector identify_rows [REPEATS]
    python benchmarks/tools/compilecut3b_one.py pvector @plugins [REPEATS]   # every plugin kernel cold

Prints the CPU s of each preparation with the named kernels' cache files deleted first, and per kernel
numba's pass times (wall s) of the last one: type inference, lowering (with LLVM) and the rest.
"""

from __future__ import annotations

import glob
import json
import os
import shutil
import subprocess
import sys
import time


def _patch_stages() -> dict:
    """CPU s in numba's type inference, lowering and LLVM finalisation (optimisation + code generation;
    it runs inside lowering, whose time includes it), outermost calls only (a nested compile's time
    counts in the stage that triggered it)."""
    from numba.core import codegen, typed_passes

    stages = {"typing_cpu_s": 0.0, "lowering_cpu_s": 0.0, "llvm_finalize_cpu_s": 0.0}
    depth = {"compile": [0], "llvm": [0]}

    def wrap(owner, attr, key, group):
        orig = getattr(owner, attr)
        d = depth[group]

        def run(*a, **k):
            if d[0]:
                return orig(*a, **k)
            d[0] += 1
            t0 = time.process_time()
            try:
                return orig(*a, **k)
            finally:
                stages[key] += time.process_time() - t0
                d[0] -= 1
        setattr(owner, attr, run)

    wrap(typed_passes.NopythonTypeInference, "run_pass", "typing_cpu_s", "compile")
    wrap(typed_passes.NativeLowering, "run_pass", "lowering_cpu_s", "compile")
    wrap(codegen.CPUCodeLibrary, "finalize", "llvm_finalize_cpu_s", "llvm")
    return stages


def _once(name: str, kernels: list[str]) -> None:
    from starid import SimConfig, Simulator, load_hipparcos
    from starid.experiment.spec import sim_settings
    from starid.experiments import table6
    from starid.harness import prepare
    from starid.registry import algorithm_info

    exp = table6.experiment(trials=2)
    catalog = load_hipparcos()
    trials = Simulator(catalog, exp.make_camera(), SimConfig(**sim_settings(exp.sim, {"sky": "paper"})),
                       seed=0).generate(2)
    cls = algorithm_info(name).cls
    stages = _patch_stages()
    c0 = time.process_time()
    p = prepare(cls(), catalog, trials.camera, trials.warmup, name)
    out = {"plugin": name, "cpu_s": round(time.process_time() - c0, 3), "error": p.error}
    out.update({k: round(v, 3) for k, v in stages.items()})
    mod = sys.modules[cls.__module__.rsplit(".", 1)[0] + ".kernels"]
    for k in kernels:
        d = getattr(mod, k, None)
        for cr in (d.overloads.values() if d is not None else ()):
            pt = (cr.metadata or {}).get("pipeline_times", {}).get("nopython", {})
            ti = sum(v.run for n, v in pt.items() if "type_inference" in n)
            lo = sum(v.run for n, v in pt.items() if "native_lowering" in n)
            rest = sum(v.run for v in pt.values()) - ti - lo
            out[k] = {"typing_s": round(ti, 3), "lowering_llvm_s": round(lo, 3), "rest_s": round(rest, 3)}
    print(json.dumps(out), flush=True)


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--once":
        _once(sys.argv[2], sys.argv[3].split(","))
        return
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    name, kernels = sys.argv[1], sys.argv[2].split(",")
    repeats = int(sys.argv[3]) if len(sys.argv) > 3 else 1
    cache = os.environ.get("NUMBA_CACHE_DIR")
    if not cache:
        sys.exit("set NUMBA_CACHE_DIR to a directory of its own")
    for _ in range(repeats):
        if kernels == ["@plugins"]:     # every plugin's kernels cold, the core's (starid/) warm
            for d in glob.glob(os.path.join(cache, "*")):
                if not os.path.basename(d).startswith(("kernels_", "starid_")):
                    shutil.rmtree(d)
        for k in kernels:
            for f in glob.glob(os.path.join(cache, "**", f"*.{k}-*.nb[ic]"), recursive=True):
                os.remove(f)
        subprocess.run([sys.executable, __file__, "--once", name, ",".join(kernels)], check=True)


if __name__ == "__main__":
    main()
