"""The cold-compile benchmark (``benchmarks/test_compile.py``'s ``cold_compile``: 2 processes, one empty
shared numba cache, each taking the next plugin when free) with the plugins in a given order, to weigh
the order against the code:

    python benchmarks/tools/compile_order_ab.py ptp,pvector,planar_triangle,... LABEL
    PYTHONPATH=<a copy of another commit> python benchmarks/tools/compile_order_ab.py ORDER LABEL

(``PYTHONPATH``: a directory with ``starid`` and ``starid_algorithms`` linked to the other commit's
``starid`` and ``algorithms``; the processes inherit it). Prints one JSON line: wall seconds, CPU
seconds per process, and each plugin's CPU seconds.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import test_compile  # noqa: E402  benchmarks/test_compile.py


def main(order: list[str], label: str) -> None:
    test_compile._names = lambda: list(order)
    with tempfile.TemporaryDirectory() as cache:
        wall, records = test_compile.cold_compile(Path(cache), 2)
    cpu = [round(sum(r["cpu_s"] for r in records if r["process"] == k), 1) for k in range(2)]
    print(json.dumps({"label": label, "wall_s": round(wall, 1), "cpu_s": cpu, "total": round(sum(cpu), 1),
                      "errors": [r["error"] for r in records if r["error"]],
                      "per": {r["plugin"]: round(r["cpu_s"], 1) for r in records}}), flush=True)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1].split(","), sys.argv[2])
