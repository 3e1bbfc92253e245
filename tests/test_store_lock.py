"""Two runs into one --out (issue #26): the second is refused naming the holder; a killed run's lock is taken over."""

import json
import os
import signal
import socket
import subprocess
import sys

import pytest

from starid.cli import main
from starid.errors import ConfigError, StarIDWarning
from starid.experiment.store import HOLDER, FolderLock

# holds the lock as a run does (filelock + the holder file), without importing starid (fast)
HOLD = """
import json, os, socket, sys, time
from filelock import FileLock
out = sys.argv[1]
lock = FileLock(os.path.join(out, ".starid.lock"), timeout=0)
lock.acquire()
json.dump({"pid": os.getpid(), "host": socket.gethostname(), "started": "2026-01-01T00:00:00Z",
           "command": "starid run ptp"}, open(os.path.join(out, ".starid.lock.json"), "w"))
print("locked", flush=True)
time.sleep(600)
"""


def _hold(out):
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "locked"
    return proc


@pytest.fixture
def holder(tmp_path):
    """A process holding the lock of ``tmp_path / 'out'``."""
    out = tmp_path / "out"
    out.mkdir()
    proc = _hold(out)
    yield out, proc
    if proc.poll() is None:
        proc.kill()
    proc.wait(timeout=30)


def test_a_second_run_is_refused_naming_the_holder(holder, capsys, monkeypatch):
    from starid.experiment.executors import LocalExecutor

    ran = []   # a spy, not a clock: refused before any task reaches the executor
    monkeypatch.setattr(LocalExecutor, "run", lambda self, tasks, on_result: ran.append(len(tasks)))
    out, proc = holder
    assert main(["run", "ptp", "--trials", "100000", "--jobs", "1", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert ran == []
    assert (f"in use by another starid run: pid {proc.pid} on {socket.gethostname()}, started "
            f"2026-01-01T00:00:00Z (starid run ptp)") in err
    assert len(err.strip().splitlines()) == 1
    assert not (out / "chunks").exists() or not list((out / "chunks").iterdir())


def test_a_killed_runs_lock_is_stale_and_taken_over(holder):
    out, proc = holder
    with pytest.raises(ConfigError, match=f"pid {proc.pid}"):
        FolderLock(out).acquire()
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    assert json.loads((out / HOLDER).read_text())["pid"] == proc.pid        # left behind by the killed run
    with pytest.warns(StarIDWarning, match=f"taking over the lock of a run that is no longer running .pid {proc.pid}"):
        lock = FolderLock(out).acquire()
    assert json.loads((out / HOLDER).read_text())["pid"] == os.getpid()
    lock.release()
    assert not (out / HOLDER).exists()
    with FolderLock(out):           # released: free again, and no stale holder to report
        pass


def test_overwrite_never_clears_a_folder_another_run_is_writing(holder, capsys):
    """--overwrite checks the lock before deleting anything: the live run's chunks stay."""
    out, proc = holder
    (out / "manifest.json").write_text(json.dumps({"digest": "0" * 16, "experiment": {"name": "run"}}))
    (out / "chunks").mkdir()
    (out / "chunks" / "a.parquet").write_bytes(b"live run's chunk")
    assert main(["run", "ptp", "--trials", "10", "--jobs", "1", "--quiet", "--overwrite", "--out", str(out)]) == 2
    assert f"pid {proc.pid}" in capsys.readouterr().err
    assert (out / "chunks" / "a.parquet").read_bytes() == b"live run's chunk"
