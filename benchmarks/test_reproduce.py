"""Issue #25's target for a whole published comparison: ``starid reproduce zhou2015 --trials 2000``
within :data:`ZHOU2015_WALL_S` seconds on the project's 2-core machine.

Measured as a user runs it: ``python -m starid`` of this environment, every core, a new results
folder, the numba cache as it is (warm after the first command; run ``benchmarks/test_compile.py``
for the cold compile). A wall-time target stated by the issue for its 2-core machine, so it belongs
here and never in ``tests/``; it only means something on an otherwise idle machine (``uptime`` load
< 1). It takes minutes: ``STARID_BENCH_ZHOU2015=0`` skips it.

Run: ``python -m pytest benchmarks/test_reproduce.py -s``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

ZHOU2015_WALL_S = 240.0
TRIALS = 2000


@pytest.mark.skipif(os.environ.get("STARID_BENCH_ZHOU2015") == "0", reason="STARID_BENCH_ZHOU2015=0")
def test_reproduce_zhou2015_wall(tmp_path):
    out = tmp_path / "zhou2015"
    t0 = time.perf_counter()
    command = [sys.executable, "-m", "starid", "reproduce", "zhou2015", "--trials", str(TRIALS), "--quiet",
               "--out", str(out)]
    subprocess.run(command, check=True)
    wall_s = time.perf_counter() - t0
    print(f"\nstarid reproduce zhou2015 --trials {TRIALS}: {wall_s:.0f} s wall, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.1f}")
    assert (out / "zhou2015.md").exists()
    assert wall_s <= ZHOU2015_WALL_S, f"zhou2015 took {wall_s:.0f} s (target {ZHOU2015_WALL_S:g} s)"
