"""Every call of plugin code under a limit (issue #26): a build or warm-up that hangs, or memory without
bound, is that algorithm's ``timeout`` / ``crashed`` rows, the others' rows intact."""

import pytest
from misbehaving import register_all, unregister_all

from starid.errors import ConfigError
from starid.experiment import Experiment, Study, Variant, run_experiment, runner
from starid.experiment.executors import LocalExecutor, address_space_gb
from starid.scoring import CRASHED, FAILED, TIMEOUT


@pytest.fixture(autouse=True)
def misbehaving_registered():
    register_all()
    yield
    unregister_all()


#: the algorithm whose rows must stay intact beside the bad one: a double with no numba kernel, so its
#: build and warm-up take milliseconds whatever the state of the compile cache (ptp's cold compile
#: takes longer than these tests' sub-second limits)
GOOD = "misbehaving[mode=none]"


def _run(monkeypatch, bad: str, trials: int = 6, **limits):
    monkeypatch.setattr(runner, "BLOCK", 3)         # two chunks per algorithm
    exp = Experiment("limits", (Study("s", (Variant.parse(bad), Variant.parse(GOOD))),), trials=trials, seed=3)
    frame = run_experiment(exp, None, jobs=1, progress=False, **limits)
    return frame[frame["label"] == bad], frame[frame["label"] == GOOD]


def test_a_build_that_hangs_is_timeout_rows_and_is_not_called_again(monkeypatch):
    bad, good = _run(monkeypatch, "misbehaving[mode=build_hang]", time_limit_s=5.0, build_time_limit_s=0.5)
    assert len(bad) == 6 and (bad["status"] == TIMEOUT).all()
    assert bad["error"].eq("preparing the chunk (derived/build) ran longer than the 0.5 s --build-time-limit").all()
    assert len(good) == 6 and not good["status"].isin(FAILED).any()


def test_a_warm_up_that_hangs_is_timeout_rows(monkeypatch):
    # the warm-up compiles, so it runs under the build limit (a cold compile can exceed the per-image one)
    bad, good = _run(monkeypatch, "misbehaving[mode=hang,every=1]", trials=3, time_limit_s=5.0, build_time_limit_s=0.5)
    assert len(bad) == 3 and (bad["status"] == TIMEOUT).all()
    assert bad["error"].eq("the warm-up identify ran longer than the 0.5 s --build-time-limit").all()
    assert len(good) == 3 and not good["status"].isin(FAILED).any()


def test_memory_without_bound_is_a_crashed_row(monkeypatch):
    bad, good = _run(monkeypatch, "misbehaving[mode=alloc,every=1]", trials=3, memory_limit_gb=6.0)
    assert len(bad) == 3 and (bad["status"] == CRASHED).all()
    assert bad["error"].str.startswith("memory limit of 6 GB per worker (--memory-limit-gb) exceeded: "
                                       "MemoryError").all()
    assert len(good) == 3 and not good["status"].isin(FAILED).any()


@pytest.mark.skipif(address_space_gb() == 0.0, reason="no /proc/self/statm: the limit caps the whole address space")
def test_an_images_memory_status_does_not_depend_on_what_ran_before_it_in_its_worker():
    # the limit is headroom over what the worker holds when a chunk starts (and again when its images start):
    # a chunk that left 2 GB in the worker (as a database does) leaves the next plugin's 2 GB per image as
    # possible as in a fresh worker, and 6 GB per image is beyond the limit in both
    def run(gb, before=()):
        variants = tuple(Variant.parse(v) for v in (*before, f"misbehaving[mode=need,every=1,gb={gb}]"))
        exp = Experiment("headroom", (Study("s", variants),), trials=2, seed=3)
        frame = run_experiment(exp, None, jobs=1, progress=False, memory_limit_gb=4.0)
        return frame[frame["label"].str.contains("leave")], frame[frame["label"].str.contains("need")]

    left, need = run(2.0, ("misbehaving[mode=leave,gb=2.0]",))
    assert len(left) == 2 and not left["status"].isin(FAILED).any()         # it did leave its 2 GB
    assert len(need) == 2 and not need["status"].isin(FAILED).any()
    assert not run(2.0)[1]["status"].isin(FAILED).any()
    assert (run(6.0)[1]["status"] == CRASHED).all()
    assert (run(6.0, ("misbehaving[mode=leave,gb=2.0]",))[1]["status"] == CRASHED).all()


@pytest.mark.parametrize("kwargs, flag", [({"build_time_limit_s": 0}, "--build-time-limit"),
                                          ({"build_time_limit_s": float("nan")}, "--build-time-limit"),
                                          ({"memory_limit_gb": -1}, "--memory-limit-gb")])
def test_bad_limits_are_refused(kwargs, flag):
    with pytest.raises(ConfigError, match=flag):
        LocalExecutor(1, **kwargs)


@pytest.mark.skipif(address_space_gb() == 0.0, reason="no /proc/self/statm: the limit caps the whole address space")
def test_memory_a_plugin_leaked_on_running_out_does_not_count_against_the_next_images(monkeypatch):
    # images with an even number of stars leak 1.5 GB (as a numba kernel does when it raises MemoryError) and
    # fail beyond the 4 GB limit; the others need 3 GB. Each image is judged on its own need: the odd ones pass
    # however many leaks came before them, and the worker that leaked ends after its chunk.
    monkeypatch.setattr(runner, "BLOCK", 10)
    bad = "misbehaving[mode=leak,every=2,gb=3.0]"
    exp = Experiment("leak", (Study("s", (Variant.parse(bad),)),), trials=20, seed=3)
    frame = run_experiment(exp, None, jobs=1, progress=False, memory_limit_gb=4.0)
    even = frame["n_stars"] % 2 == 0
    first = frame.index[even][0]
    assert even.sum() >= 3 and (~even[first:]).sum() >= 3          # leaks before several odd images
    assert (frame.loc[even, "status"] == CRASHED).all()
    assert frame.loc[even, "error"].str.startswith("memory limit of 4 GB per worker (--memory-limit-gb) exceeded: "
                                                   "MemoryError").all()
    assert not frame.loc[~even, "status"].isin(FAILED).any()
    odd = frame[~even]
    pids = odd.groupby(odd.index // 10)["n_pid"].unique()      # the worker of each chunk of 10 images
    assert first < 10 and len(pids) == 2 and pids.map(len).eq(1).all()
    assert pids.iloc[0][0] != pids.iloc[1][0]                   # the first chunk's worker leaked and ended
