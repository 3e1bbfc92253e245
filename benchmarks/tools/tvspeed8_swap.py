"""``tvspeed5_ab.py`` both ways, so that its slot bias cancels (issue #25, tvspeed8).

    python benchmarks/tools/tvspeed8_swap.py BASE_DIR [N] [R]

``tvspeed5_ab.py`` favours its *branch* slot: a checkout of main against an unchanged copy of main gave branch /
base 0.927 (paper) and 0.960 (real) at 300 x 3. This runs it forward (this checkout in the branch slot, BASE_DIR the
base) and swapped (BASE_DIR's own ``tvspeed5_ab.py``, run in BASE_DIR, with a temporary copy of this checkout's
``algorithms/triangle_voting`` as its base), and prints per sky both ratios and ``sqrt(forward / swapped)``, this
checkout's own ratio to BASE_DIR with the bias cancelled (medians; per-image medians in brackets). BASE_DIR: a
checkout (e.g. a detached worktree) that has ``benchmarks/tools/tvspeed5_ab.py``.

Numba caches ``identify_flat`` keyed on ``kernels.py`` alone: after editing ``final.py`` remove
``algorithms/triangle_voting/__pycache__`` first, or the old compiled code is timed.
"""

from __future__ import annotations

import math
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TOOL = Path("benchmarks") / "tools" / "tvspeed5_ab.py"
LINE = re.compile(r"^(\w+)\s.*branch/base ([0-9.]+) \(per image ([0-9.]+)\)", re.M)


def ratios(cwd: Path, base: Path, n: str, r: str) -> dict[str, tuple[float, float]]:
    out = subprocess.run([sys.executable, str(TOOL), str(base), n, r], cwd=cwd, check=True, capture_output=True,
                         text=True).stdout
    print(out, end="")
    return {m[1]: (float(m[2]), float(m[3])) for m in LINE.finditer(out)}


def main() -> None:
    base = Path(sys.argv[1]).resolve()
    n = sys.argv[2] if len(sys.argv) > 2 else "300"
    r = sys.argv[3] if len(sys.argv) > 3 else "3"
    print("forward:")
    fwd = ratios(ROOT, base, n, r)
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / "branch"
        shutil.copytree(ROOT / "algorithms" / "triangle_voting", copy / "algorithms" / "triangle_voting",
                        ignore=shutil.ignore_patterns("__pycache__", "tests"))
        print("swapped:")
        swp = ratios(base, copy, n, r)
    for sky in fwd:
        (f, fi), (s, si) = fwd[sky], swp[sky]
        print(f"{sky}: forward {f:.3f} ({fi:.3f}) swapped {s:.3f} ({si:.3f}) -> this / base "
              f"{math.sqrt(f / s):.3f} ({math.sqrt(fi / si):.3f})")


if __name__ == "__main__":
    main()
