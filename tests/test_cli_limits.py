"""Plugin code a command calls itself runs under the engine's limits (issue #26): ``show`` (build, warm-up,
identify, explain), ``identify`` on centroid and image files, and ``check``. A call that hangs or allocates
without bound is that algorithm's ``timeout`` / ``crashed`` (panel, row, check), the others' intact."""

from dataclasses import dataclass
from typing import ClassVar

import pandas as pd
import pytest
from misbehaving import Misbehaving, register_all, unregister_all

from starid.cli import main
from starid.experiment.executors import address_space_gb
from starid.registry import register, unregister
from starid.scoring import CRASHED, TIMEOUT

GOOD = "misbehaving[mode=none]"


@dataclass(frozen=True)
class Hanging(Misbehaving):
    """Hangs in every identify (what ``starid check`` gets: a class with its defaults)."""

    name: ClassVar[str] = "misbehaving_hanging"
    mode: str = "hang"
    every: int = 1


@dataclass(frozen=True)
class BuildHanging(Misbehaving):
    """Hangs in build (what ``starid info`` builds: a class with its defaults)."""

    name: ClassVar[str] = "misbehaving_build_hanging"
    mode: str = "build_hang"


@pytest.fixture(autouse=True)
def misbehaving_registered():
    register_all()
    register(Hanging)
    register(BuildHanging)
    yield
    unregister(BuildHanging.name)
    unregister(Hanging.name)
    unregister_all()


def _show(tmp_path, capsys, bad: str, *limits: str) -> str:
    rc = main(["show", bad, GOOD, "--trial", "0", "--out", str(tmp_path / "t.png"), *limits])
    out = capsys.readouterr().out
    assert rc == 0 and (tmp_path / "t.png").is_file()      # a failed panel is drawn, as a crashing plugin's is
    assert f"{GOOD} no_result" in " ".join(out.split()), out    # the other panel as usual, explained
    return out


def test_show_explain_that_hangs_is_a_timeout_panel(tmp_path, capsys):
    out = _show(tmp_path, capsys, "misbehaving[mode=explain_hang]", "--time-limit", "1")
    assert "misbehaving[mode=explain_hang]: timeout: explain ran longer than the 1 s --time-limit" in out


def test_show_build_that_hangs_is_a_timeout_panel(tmp_path, capsys):
    out = _show(tmp_path, capsys, "misbehaving[mode=build_hang]", "--build-time-limit", "1")
    assert "misbehaving[mode=build_hang]: timeout: build ran longer than the 1 s --build-time-limit" in out


def test_show_memory_without_bound_is_a_crashed_panel(tmp_path, capsys):
    out = _show(tmp_path, capsys, "misbehaving[mode=alloc,every=1]", "--memory-limit-gb", "4")
    assert "misbehaving[mode=alloc,every=1]: crashed: memory limit of 4 GB" in out


@pytest.fixture
def obs_csv(tmp_path):
    """Four images of 3, 4, 5, 6 centroids: ``every=4`` hits image 1 alone (the warm-up is image 0)."""
    lines = ["trial,x_px,y_px,mag"]
    for t in range(4):
        lines += [f"{t},{100 + 50 * j},{200 + 30 * j},{j + 0.5}" for j in range(t + 3)]
    path = tmp_path / "obs.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def _identify(tmp_path, items, *limits):
    rc = main(["identify", *items, "--out", str(tmp_path / "ids"), "--quiet", *limits])
    assert rc == 0
    return pd.read_csv(tmp_path / "ids" / "trials.csv", keep_default_na=False)


def test_identify_an_image_that_hangs_is_its_timeout_row(tmp_path, obs_csv):
    bad = "misbehaving[mode=hang,every=4]"
    frame = _identify(tmp_path, [bad, GOOD, str(obs_csv)], "--time-limit", "1")
    rows = frame[frame["label"] == bad].set_index("trial")
    assert rows.loc[1, "status"] == TIMEOUT
    assert rows.loc[1, "error"] == "identify ran longer than the 1 s --time-limit"
    assert (rows.drop(index=1)["status"] == "no_result").all()       # the images after it go on
    assert (frame[frame["label"] == GOOD]["status"] == "no_result").all() and len(frame) == 8


def test_identify_a_build_that_hangs_is_every_image_timeout(tmp_path, obs_csv):
    bad = "misbehaving[mode=build_hang]"
    frame = _identify(tmp_path, [bad, GOOD, str(obs_csv)], "--build-time-limit", "1")
    rows = frame[frame["label"] == bad]
    assert len(rows) == 4 and (rows["status"] == TIMEOUT).all()
    assert rows["error"].eq("derived/build ran longer than the 1 s --build-time-limit").all()
    assert (frame[frame["label"] == GOOD]["status"] == "no_result").all()


def test_identify_memory_without_bound_is_a_crashed_row(tmp_path, obs_csv):
    bad = "misbehaving[mode=alloc,every=4]"
    frame = _identify(tmp_path, [bad, GOOD, str(obs_csv)], "--memory-limit-gb", "4")
    rows = frame[frame["label"] == bad].set_index("trial")
    assert rows.loc[1, "status"] == CRASHED
    assert rows.loc[1, "error"].startswith("memory limit of 4 GB per worker (--memory-limit-gb) exceeded: MemoryError")
    assert (rows.drop(index=1)["status"] == "no_result").all()


@pytest.mark.skipif(address_space_gb() == 0.0, reason="no /proc/self/statm: the limit caps the whole address space")
def test_identify_memory_a_plugin_leaked_does_not_count_against_the_next_image(tmp_path, obs_csv):
    # images of 4 and 6 centroids leak 1.5 GB and run out of the 4 GB limit; those of 3 and 5 need 3 GB: image 2
    # (5 centroids) comes after a leak and passes, as it would alone
    bad = "misbehaving[mode=leak,every=2,gb=3.0]"
    frame = _identify(tmp_path, [bad, GOOD, str(obs_csv)], "--memory-limit-gb", "4")
    rows = frame[frame["label"] == bad].set_index("trial")
    assert (rows.loc[[1, 3], "status"] == CRASHED).all()
    assert rows.loc[[1, 3], "error"].str.startswith("memory limit of 4 GB per worker (--memory-limit-gb) exceeded: "
                                                    "MemoryError").all()
    assert (rows.loc[[0, 2], "status"] == "no_result").all()


def test_identify_image_file_that_hangs_is_its_timeout_row(tmp_path):
    pytest.importorskip("PIL")
    image = tmp_path / "t0.png"
    assert main(["render", "--trial", "0", "--size", "256x256", "--fov-deg", "10", "--bits", "8",
                 "--out", str(image)]) == 0
    bad = "misbehaving[mode=hang,every=1]"
    assert main(["identify", bad, GOOD, str(image), "--fov-deg", "10", "--out", str(tmp_path / "ids"),
                 "--time-limit", "1"]) == 0
    att = pd.read_csv(tmp_path / "ids" / "attitudes.csv").set_index("algorithm")
    assert att.loc[bad, "status"] == TIMEOUT and att.loc[GOOD, "status"] == "not solved"


def test_check_that_hangs_fails_each_check_and_ends(capsys):
    rc = main(["check", Hanging.name, "--build-time-limit", "0.5"])
    out = capsys.readouterr().out
    assert rc == 1
    assert "FAILED (timeout)  check 'deterministic' ran longer than the 0.5 s --build-time-limit" in out
    assert "default_constructible    ok" in out          # the checks that call no identify still pass


def test_info_build_that_hangs_says_so_and_ends(capsys):
    assert main(["info", BuildHanging.name, "--build-time-limit", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "derived defaults and database size not known: timeout: build ran longer than the 0.5 s " \
           "--build-time-limit" in out
    assert "mode   str" in out                  # the parameter table still printed


@pytest.mark.parametrize("command", ["identify", "show", "check"])
def test_bad_limit_is_refused_before_any_work(tmp_path, obs_csv, capsys, command):
    flag = "--time-limit" if command != "check" else "--build-time-limit"
    argv = {"identify": ["identify", GOOD, str(obs_csv), "--out", str(tmp_path / "ids")],
            "show": ["show", GOOD, "--trial", "0", "--out", str(tmp_path / "t.png")],
            "check": ["check", GOOD.split("[")[0]]}[command]
    assert main([*argv, flag, "0"]) == 2
    assert f"{flag} must be a number of seconds > 0, got 0.0" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [obs_csv]
