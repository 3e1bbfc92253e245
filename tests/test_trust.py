"""Bad input never becomes a wrong number; a plugin cannot hide or clash; runs stop cleanly."""

import gzip
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from starid import Camera, ConfigError, SimConfig, Simulator
from starid.catalog import load_csv
from starid.cli import main
from starid.errors import CatalogError, ObservationError, StarIDWarning
from starid.io import read_numeric_csv


def test_trial_ids_are_exact_integers(tmp_path):
    (tmp_path / "o.csv").write_text("trial,x_px,y_px,mag\n9007199254740992,1,2,3\n9007199254740993,1,2,3\n"
                                    "9223372036854775807,1,2,3\n")
    cols, _ = read_numeric_csv(tmp_path / "o.csv", ["trial", "x_px", "y_px", "mag"], integer=("trial",))
    assert cols["trial"].tolist() == [2**53, 2**53 + 1, 2**63 - 1]
    (tmp_path / "big.csv").write_text("trial,x_px,y_px,mag\n9223372036854775808,1,2,3\n")
    with pytest.raises(ValueError, match="fits in 64 bits"):
        read_numeric_csv(tmp_path / "big.csv", ["trial", "x_px", "y_px", "mag"], integer=("trial",))
    (tmp_path / "frac.csv").write_text("trial,x_px,y_px,mag\n1.5,1,2,3\n")
    with pytest.raises(ValueError, match="line 2: trial must be a whole number"):
        read_numeric_csv(tmp_path / "frac.csv", ["trial", "x_px", "y_px", "mag"], integer=("trial",))


def test_identify_keeps_huge_trial_ids_apart(tmp_path, catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(), seed=1)
    rows = []
    for t, trial in enumerate((2**53, 2**53 + 1)):
        obs = sim.observation(t)
        rows += [f"{trial},{x:.17g},{y:.17g},{m:.17g}" for x, y, m in zip(obs.x_px, obs.y_px, obs.mag, strict=True)]
    (tmp_path / "o.csv").write_text("trial,x_px,y_px,mag\n" + "\n".join(rows) + "\n")
    assert main(["identify", "ptp", str(tmp_path / "o.csv"), "--out", str(tmp_path / "id")]) == 0
    trials = pd.read_csv(tmp_path / "id" / "trials.csv", dtype={"trial": "int64"})
    assert trials["trial"].tolist() == [2**53, 2**53 + 1]


@pytest.mark.parametrize("option", ["--resolution", "--focal-mm", "--pixel-um"])
def test_zero_camera_settings_are_refused(tmp_path, capsys, option):
    (tmp_path / "o.csv").write_text("trial,x_px,y_px,mag\n0,1,2,3\n")
    assert main(["identify", "ptp", str(tmp_path / "o.csv"), "--out", str(tmp_path / "id"), option, "0"]) == 2
    assert re.search("must be a finite number > 0|must be an integer >= 1", capsys.readouterr().err)
    assert not (tmp_path / "id").exists()


@pytest.mark.parametrize("content, message", [
    (b"\x00\x01\x02binary", "not a text CSV"),
    (gzip.compress(b"hip,ra_deg,dec_deg,vmag\n1,2,3,4\n", mtime=0), "not a text CSV"),
    (b"PK\x03\x04npz-like", "not a text CSV"),
    (b"hip,ra_deg,dec_deg,vmag\n1," + b"9" * 200_000 + b",3,4\n", "line 2"),
])
def test_non_text_and_overlong_csv_are_refused(tmp_path, content, message):
    (tmp_path / "c.csv").write_bytes(content)
    with pytest.raises(CatalogError, match=message):
        load_csv(tmp_path / "c.csv")


def test_bom_is_read(tmp_path):
    rows = "".join(f"{i + 1},{i * 7 % 360},{(i * 13) % 170 - 85},{4 + (i % 3)}\n" for i in range(30))
    (tmp_path / "c.csv").write_bytes("\ufeffhip,ra_deg,dec_deg,vmag\n".encode() + rows.encode())
    assert len(load_csv(tmp_path / "c.csv")) == 30


def test_catalog_in_radians_is_warned_about(tmp_path):
    rng = np.random.default_rng(0)
    df = pd.DataFrame({"hip": np.arange(1, 51), "ra_deg": rng.uniform(0, 2 * np.pi, 50),
                       "dec_deg": rng.uniform(-1.5, 1.5, 50), "vmag": rng.uniform(1, 6, 50)})
    df.to_csv(tmp_path / "c.csv", index=False)
    with pytest.warns(StarIDWarning, match="radians"):
        load_csv(tmp_path / "c.csv")


@pytest.mark.parametrize("args", [["--jobs", "0"], ["--jobs", "-1"], ["--trials", "0"], ["--trials", "10000000000"],
                                  ["--seed", "-1"]])
def test_bad_counts_are_refused(args, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "ptp", *args])
    assert exc.value.code == 2


def test_out_is_checked_before_any_work(tmp_path, capsys, monkeypatch):
    from starid.experiment.executors import LocalExecutor

    ran = []   # a spy, not a clock: no task may reach the executor
    monkeypatch.setattr(LocalExecutor, "run", lambda self, tasks, on_result: ran.append(len(tasks)))
    (tmp_path / "file").write_text("")
    assert main(["run", "ptp", "--trials", "100000", "--out", str(tmp_path / "file")]) == 2
    assert ran == [] and "is a file" in capsys.readouterr().err


def test_identify_without_truth_removes_a_stale_summary(tmp_path, catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(), seed=2)
    obs = sim.observation(0)
    pd.DataFrame({"trial": 0, "x_px": obs.x_px, "y_px": obs.y_px, "mag": obs.mag,
                  "truth_hip": obs.truth_hip}).to_csv(tmp_path / "t.csv", index=False)
    pd.DataFrame({"trial": 0, "x_px": obs.x_px, "y_px": obs.y_px, "mag": obs.mag}).to_csv(tmp_path / "n.csv",
                                                                                          index=False)
    assert main(["identify", "ptp", str(tmp_path / "t.csv"), "--out", str(tmp_path / "o")]) == 0
    assert (tmp_path / "o" / "summary.csv").exists()
    assert main(["identify", "ptp", str(tmp_path / "n.csv"), "--out", str(tmp_path / "o")]) == 0
    assert not (tmp_path / "o" / "summary.csv").exists()


def test_every_trial_failing_is_shown_and_exits_nonzero(capsys):
    from misbehaving import register_all, unregister_all

    register_all()
    try:
        assert main(["run", "misbehaving[mode=build_raises]", "--trials", "5", "--jobs", "1", "--quiet"]) == 1
    finally:
        unregister_all()
    out = capsys.readouterr().out
    assert "error_rate" in out and "every trial of misbehaving[mode=build_raises] failed" in out


CLASH = '''
from starid_algorithms.ptp import PTP


class Impostor(PTP):
    """Claims to be PTP."""
'''


def test_a_name_clash_is_refused_naming_both(tmp_path, monkeypatch):
    site = tmp_path / "site"
    (site / "impostor_pkg").mkdir(parents=True)
    (site / "impostor_pkg" / "__init__.py").write_text(CLASH)
    info = site / "impostor_pkg-9.9.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: impostor-pkg\nVersion: 9.9\n")
    (info / "entry_points.txt").write_text("[starid.algorithms]\nptp = impostor_pkg:Impostor\n")
    monkeypatch.syspath_prepend(str(site))
    from starid.registry import available_algorithms

    ptp = {i.name: i for i in available_algorithms()}["ptp"]
    assert ptp.status == "broken" and "impostor-pkg" in ptp.error and "starid" in ptp.error


SLOW = """
import faulthandler, signal, sys
faulthandler.register(signal.SIGUSR1, all_threads=True)    # the test's diagnosis when the run does not end
from starid.cli import main
sys.exit(main(["run", "tetra", "pvector", "--trials", "100000", "--jobs", "2", "--quiet", "--out", sys.argv[1]]))
"""


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_interrupt_stops_workers_and_exits_cleanly(tmp_path, sig, code):
    (tmp_path / "slow.py").write_text(SLOW)
    # SIGINT at its default in the run, whatever the test runner inherited: a background job of a
    # non-interactive shell starts with SIGINT ignored, and a run started so keeps ignoring it (the Unix
    # convention Python follows), which is what made this test hang when the suite ran as `cmd &`
    proc = subprocess.Popen([sys.executable, str(tmp_path / "slow.py"), str(tmp_path / "out")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    chunks = tmp_path / "out" / "chunks"
    # the first chunk comes after a cold compile of the two plugins (tetra and pvector, the quickest: ~16 CPU s).
    # Stop 38 found why this test failed now and then: the harness's scoring kernels compiled inside the first
    # image's 10 s limit, and on a loaded machine the worker was killed there and restarted, over and over
    # (harness.warm_scoring now compiles them in the warm-up; tests/test_score_kernels.py checks it)
    deadline = time.time() + 180
    while time.time() < deadline and not list(chunks.glob("*.parquet")):
        time.sleep(0.2)
    children = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
    if not children:    # say why: the run's exit code (None: still running) and what it printed
        code_then = proc.poll()
        proc.kill()
        out, err = proc.communicate(timeout=60)
        pytest.fail(f"no worker processes: run exit code {code_then}, "
                    f"{len(list(chunks.glob('*.parquet')))} chunks written; stderr: {err[-3000:]!r}")
    proc.send_signal(sig)
    try:
        out, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:       # say where it hangs: every thread's stack, and the process tree
        tree = subprocess.run(["ps", "-o", "pid,ppid,stat,etime,wchan:20,args", "--ppid", str(proc.pid), "-p",
                               str(proc.pid)], capture_output=True, text=True).stdout
        proc.send_signal(signal.SIGUSR1)
        time.sleep(2)
        proc.kill()
        out, err = proc.communicate(timeout=60)
        pytest.fail(f"the run did not end within 60 s of signal {sig}; processes:\n{tree}\nstderr:\n{err[-6000:]}")
    assert proc.returncode == code
    assert len(err.strip().splitlines()) == 1 and "run the same command again to resume" in err
    time.sleep(0.5)
    for pid in children:
        assert not os.path.exists(f"/proc/{pid}") or "zombie" in open(f"/proc/{pid}/status").read().lower()
    assert list(chunks.glob("*.parquet")), "finished chunks were lost"


def test_sigterm_is_not_swallowed_by_except_exception():
    """SIGTERM becomes ``starid.cli.Terminated`` wherever the main thread is; an ``except Exception`` on the way
    (pandas, pyarrow, a plugin's failure being recorded) must let it through, as it does KeyboardInterrupt."""
    from starid.cli import Terminated, _on_sigterm

    try:
        try:
            _on_sigterm(signal.SIGTERM, None)
        except Exception:  # noqa: BLE001 -- what library code does
            pytest.fail("Terminated was caught by except Exception")
    except Terminated:
        pass


def test_python_O_does_not_skip_conformance(tmp_path):
    code = ("from misbehaving import Misbehaving\nfrom starid.testing import check_algorithm, ConformanceError\n"
            "try:\n    check_algorithm(Misbehaving, ['noise_free_identified'])\nexcept ConformanceError as e:\n"
            "    print('refused:', e)\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.path.dirname(__file__), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-O", "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert "refused: misbehaving: check 'noise_free_identified' failed" in out.stdout, out.stderr


def test_starid_check_reports_each_check(capsys):
    assert main(["check", "ptp"]) == 0
    out = capsys.readouterr().out
    assert "random_fields" in out and "all checks passed" in out
    assert main(["check", "no-such-thing"]) == 2


# -- property-based: any input runs or is refused with a message, never a traceback ---------------

csv_text = st.text(alphabet=st.sampled_from(list("0123456789.,-+eE nai\n\r\"x\ufeff")), max_size=200)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(body=csv_text, header=st.sampled_from(["trial,x_px,y_px,mag\n", "trial,x_px,y_px,mag,truth_hip\n", ""]))
def test_observation_reader_never_crashes(tmp_path, body, header):
    from starid.cli.identify import read_observations

    path = tmp_path / "o.csv"
    path.write_text(header + body, encoding="utf-8")
    try:
        read_observations(path, Camera())
    except ObservationError as exc:
        assert str(exc)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(body=csv_text)
def test_catalog_reader_never_crashes(tmp_path, body):
    path = tmp_path / "c.csv"
    path.write_text("hip,ra_deg,dec_deg,vmag\n" + body, encoding="utf-8")
    try:
        load_csv(path)
    except CatalogError as exc:
        assert str(exc)


number = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6), st.booleans(),
                   st.none(), st.text(max_size=3))


@settings(max_examples=300, deadline=None)
@given(width=number, focal=number, pixel=number, sigma=number, mag=number, false=number)
def test_camera_and_simulator_parameters_run_or_refuse(width, focal, pixel, sigma, mag, false):
    try:
        cam = Camera(width_px=width, height_px=width, focal_mm=focal, pixel_um=pixel)
        config = SimConfig(sigma_px=sigma, sigma_mag=mag, false_stars=false, min_stars=0)
        Simulator(__import__("starid").load_hipparcos(), cam, config, seed=0).generate(1)
    except ConfigError as exc:
        assert str(exc)


KERNEL = '''
from numba import njit


@njit(cache=True)
def twice(x):
    return 2 * x
'''


def test_a_broken_numba_cache_is_named_not_scored(tmp_path):
    """A garbage cache file: the failure says which folder to clear (never a silent rate of 0)."""
    (tmp_path / "cachedmod.py").write_text(KERNEL)
    run = (f"import sys; sys.path.insert(0, {str(tmp_path)!r})\nfrom starid.jitcache import describe\n"
           "import cachedmod\ntry:\n    print('value', cachedmod.twice(21))\nexcept Exception as exc:\n"
           "    print('failed:', describe(exc))\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}    # cache beside the module
    first = subprocess.run([sys.executable, "-c", run], capture_output=True, text=True, timeout=300, env=env)
    assert "value 42" in first.stdout, first.stderr
    cache = tmp_path / "__pycache__"
    files = list(cache.glob("*.nbi")) + list(cache.glob("*.nbc"))
    assert files
    for f in files:
        f.write_bytes(b"\x80garbage" * 3)
    second = subprocess.run([sys.executable, "-c", run], capture_output=True, text=True, timeout=300, env=env)
    out = second.stdout
    assert "numba cache file is unreadable" in out and str(cache) in out, out + second.stderr
