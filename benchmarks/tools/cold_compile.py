"""Compile time per plugin in this process: build and warm-up identify (as ``starid.harness.prepare``
does) of each named plugin, on Table 6's camera. Run it with an empty numba cache to measure cold:

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/cold_compile.py ptp pvector tetra

Prints one JSON line per plugin: build_s and compile_s as the harness records them, and the wall and
CPU seconds of the whole preparation. Plugins named later reuse shared kernels compiled for earlier
ones, so the order matters; run one plugin per process to charge each its shared kernels.
"""

from __future__ import annotations

import json
import os
import sys
import time

from compile_profile import warmup_trials  # benchmarks/tools

from starid.harness import prepare
from starid.registry import algorithm_info


def main(names: list[str]) -> None:
    catalog, trials = warmup_trials()
    print(json.dumps({"numba_cache_dir": os.environ.get("NUMBA_CACHE_DIR")}), flush=True)
    for name in names:
        algorithm = algorithm_info(name).cls()
        t0, c0 = time.perf_counter(), time.process_time()
        p = prepare(algorithm, catalog, trials.camera, trials.warmup, name)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        print(json.dumps({"plugin": name, "build_s": round(p.build_s, 2), "compile_s": round(p.compile_s, 2),
                          "wall_s": round(wall, 2), "cpu_s": round(cpu, 2), "error": p.error}), flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
