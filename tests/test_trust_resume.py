"""Issue #26, "done when": a run killed with SIGKILL mid-way, one of its chunks then truncated, resumed, ends with
the frame of an uninterrupted run (every column but the times)."""

import contextlib
import json
import os
import signal
import subprocess
import sys
import time

import pandas as pd

from starid.experiment import runner

TIMES = ["time_us", "build_s", "compile_s"]
BLOCK, TRIALS = 20, 80          # ptp + pvector: 2 x 4 chunks (the by-hand version: BLOCK 500, --trials 2500)

# the command line of the issue, with small chunks so that a kill lands between chunks within seconds
RUN = f"""
import sys
from starid.experiment import runner
runner.BLOCK = {BLOCK}
from starid.cli import main
sys.exit(main(["run", "ptp", "pvector", "--trials", "{TRIALS}", "--jobs", "1", "--quiet", "--out", sys.argv[1]]))
"""


def _start(out):
    return subprocess.Popen([sys.executable, "-c", RUN, str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def _gone(pid):
    try:
        with open(f"/proc/{pid}/status") as fh:
            return "zombie" in fh.read().lower()
    except OSError:
        return True


def _frame(out):
    return pd.read_parquet(out / "results.parquet").drop(columns=TIMES)


def test_killed_truncated_and_resumed_equals_uninterrupted(tmp_path, monkeypatch, capsys):
    killed = tmp_path / "killed"
    proc = _start(killed)
    chunks = killed / "chunks"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None and not list(chunks.glob("*.parquet")):
        time.sleep(0.01)
    workers = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
    assert workers, "no worker process"
    os.kill(proc.pid, signal.SIGKILL)           # the run alone: no handler runs, no cleanup, the lock left behind
    try:
        proc.communicate(timeout=60)             # its workers end with it (they held its stdout/stderr open)
    except subprocess.TimeoutExpired:
        for pid in workers:
            with contextlib.suppress(ProcessLookupError):
                os.kill(int(pid), signal.SIGKILL)
        raise AssertionError("the workers of the killed run outlived it") from None
    assert proc.returncode == -signal.SIGKILL
    for _ in range(100):
        if all(_gone(pid) for pid in workers):
            break
        time.sleep(0.1)
    assert all(_gone(pid) for pid in workers), "the workers of the killed run outlived it"
    manifest = json.loads((killed / "manifest.json").read_text())
    done = sorted(chunks.glob("*.parquet"))
    assert 1 <= len(done) < len(manifest["chunks"]) == 2 * TRIALS // BLOCK, "the kill did not land mid-way"
    assert not (killed / "results.parquet").exists()
    victim = done[0]
    victim.write_bytes(victim.read_bytes()[: victim.stat().st_size // 3])      # truncated, as by a full disk

    # resumed and uninterrupted: the same command in this process, with the same chunks
    from starid.cli import main

    monkeypatch.setattr(runner, "BLOCK", BLOCK)
    argv = ["run", "ptp", "pvector", "--trials", str(TRIALS), "--jobs", "1", "--quiet", "--out"]
    assert main([*argv, str(killed)]) == 0
    err = capsys.readouterr().err
    assert f"chunk {victim.stem}" in err and "damaged" in err and "set aside" in err
    assert (chunks / f"{victim.name}.damaged").is_file()
    manifest = json.loads((killed / "manifest.json").read_text())
    assert manifest["reused_chunks"] == len(done) - 1 and manifest["finished"]
    whole = tmp_path / "whole"
    assert main([*argv, str(whole)]) == 0
    a, b = _frame(killed), _frame(whole)
    assert len(a) == 2 * TRIALS and set(a["algorithm"]) == {"ptp", "pvector"}
    pd.testing.assert_frame_equal(a, b)
