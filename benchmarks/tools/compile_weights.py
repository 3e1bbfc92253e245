"""Measure every registered plugin's cold preparation and write :mod:`starid.experiment.compile_weights`.

Each plugin is prepared (database build + warm-up identify, :func:`starid.harness.prepare`) in a
process of its own with an empty numba cache (``benchmarks/tools/cold_compile.py``), so each is charged
the shared kernels it compiles; the CPU seconds are the weights :func:`starid.experiment.warmup.schedule`
orders the first chunks by (heaviest first). Run it on an idle machine after a change that moves a
plugin's compile time by more than a second or two:

    python benchmarks/tools/compile_weights.py            # every registered plugin, ~2 min
    python benchmarks/tools/compile_weights.py --print    # measure and print, write nothing

Only the order in which workers compile changes with the weights, never a result.
"""

from __future__ import annotations

import datetime
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
TARGET = REPO / "starid" / "experiment" / "compile_weights.py"


def measure(name: str) -> float:
    """CPU seconds of ``name``'s preparation on an empty numba cache, in a new process."""
    with tempfile.TemporaryDirectory() as cache:
        out = subprocess.run([sys.executable, str(REPO / "benchmarks" / "tools" / "cold_compile.py"), name],
                             env={**os.environ, "NUMBA_CACHE_DIR": cache}, capture_output=True, text=True,
                             check=True).stdout
    record = [json.loads(line) for line in out.splitlines() if '"plugin"' in line][0]
    if record["error"]:
        raise SystemExit(f"{name}: {record['error']}")
    return float(record["cpu_s"])


def render(cpu_s: dict[str, float], commit: str) -> str:
    rows = "\n".join(f'    "{name}": {s:.1f},' for name, s in sorted(cpu_s.items(), key=lambda kv: -kv[1]))
    return f'''"""Measured cold-preparation CPU seconds per plugin: the order workers compile in (heaviest first).

Written by ``python benchmarks/tools/compile_weights.py`` (each plugin alone in a process, empty numba
cache, database build + warm-up identify) at commit {commit}, {datetime.date.today().isoformat()}, on issue #25's
2-core machine. :func:`starid.experiment.warmup.schedule` deals the first chunk of each plugin (the one
that compiles) heaviest first, so that two workers finish compiling at about the same time; a plugin
not listed (a third party's) weighs the median. Only the order of computation depends on these numbers.
"""

CPU_S: dict[str, float] = {{
{rows}
}}
'''


def main(argv: list[str]) -> None:
    from starid.registry import available_algorithms

    names = sorted(i.name for i in available_algorithms() if i.status == "ok")
    cpu_s = {}
    for name in names:
        cpu_s[name] = measure(name)
        print(f"{name:20s} {cpu_s[name]:6.1f} CPU s", flush=True)
    if "--print" in argv:
        return
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                            text=True).stdout.strip() or "unknown"
    tmp = TARGET.with_suffix(".tmp")
    tmp.write_text(render(cpu_s, commit))
    os.replace(tmp, TARGET)
    print(f"wrote {TARGET.relative_to(REPO)}")


if __name__ == "__main__":
    main(sys.argv[1:])
