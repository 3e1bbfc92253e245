"""The teaching walk-through runs as a script (its cells end with their own checks) and draws its pictures."""

import os
import subprocess
import sys
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "teaching.py"


def test_teaching_example_runs(tmp_path):
    env = {**os.environ, "STARID_EXAMPLE_OUT": str(tmp_path), "STARID_EXAMPLE_TRIALS": "8", "MPLBACKEND": "Agg"}
    done = subprocess.run([sys.executable, str(EXAMPLE)], env=env, cwd=tmp_path, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    for name in ("time.png", "rates.png", "failure.png"):
        assert (tmp_path / name).read_bytes()[:4] == b"\x89PNG"
    assert "planar_triangle" in done.stdout and "triangle_voting" in done.stdout


def test_teaching_example_is_percent_cell_format():
    text = EXAMPLE.read_text()
    assert text.count("\n# %%") >= 8 and text.startswith("# %% [markdown]")
