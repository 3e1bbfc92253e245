"""Under ``--executor dask`` every call of plugin code runs under the same limits as the local executor
(issue #26): a hang in identify or in build is ``timeout`` rows naming the phase, runaway memory a
``crashed`` row saying "memory limit", the other algorithm's rows intact, and every non-time column equal
to a local run's. Workers that cannot supervise (daemonic) are a clear error, exit 2.

These run on a cluster given by address; the LocalCluster that ``--executor dask`` starts itself runs
``tests/test_engine.py::test_dask_local_cluster_gives_the_same_frame`` (its chunks too are supervised)."""

import pytest
from misbehaving import register_all, unregister_all

from starid.experiment import Experiment, Study, Variant, run_experiment, runner
from starid.scoring import CRASHED, FAILED, TIMEOUT

distributed = pytest.importorskip("distributed")

MEASURED = ["time_us", "build_s", "compile_s"]
#: the well-behaved algorithm beside the bad one: no numba kernel, so milliseconds whatever the compile cache
GOOD = "misbehaving[mode=none]"


@pytest.fixture(autouse=True)
def misbehaving_registered():
    register_all()
    yield
    unregister_all()


def _cluster(daemon: bool):
    import dask

    with dask.config.set({"distributed.worker.daemon": daemon}):
        return distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None)


@pytest.fixture(scope="module")
def scheduler():
    """One non-daemonic worker, as ``DASK_DISTRIBUTED__WORKER__DAEMON=False dask worker ADDRESS`` starts it."""
    cluster = _cluster(daemon=False)
    yield cluster.scheduler_address
    cluster.close()


def _experiment(bad: str) -> Experiment:
    return Experiment("limits", (Study("s", (Variant.parse(bad), Variant.parse(GOOD))),), trials=6, seed=3)


def _dask_and_local(monkeypatch, bad: str, scheduler: str | None, **limits):
    """The bad and good rows of a dask run, after checking that the whole frame equals a local run's but
    for the times."""
    monkeypatch.setattr(runner, "BLOCK", 3)         # two chunks per algorithm
    frame = run_experiment(_experiment(bad), None, jobs=1, executor="dask", scheduler=scheduler, progress=False,
                           **limits)
    local = run_experiment(_experiment(bad), None, jobs=1, progress=False, **limits)
    assert list(frame.columns) == list(local.columns)
    assert frame.drop(columns=MEASURED).equals(local.drop(columns=MEASURED))
    return frame[frame["label"] == bad], frame[frame["label"] == GOOD]


def test_dask_a_hang_in_identify_is_a_timeout_row(monkeypatch, scheduler):
    # the warm-up image has 10 stars, trials 1 and 4 have 20 and 16: they hang
    bad, good = _dask_and_local(monkeypatch, "misbehaving[mode=hang,every=4]", scheduler, time_limit_s=0.5)
    assert bad["status"].tolist() == ["no_result", TIMEOUT, "no_result", "no_result", TIMEOUT, "no_result"]
    assert bad.loc[bad["status"] == TIMEOUT, "error"].eq("identify ran longer than the 0.5 s --time-limit").all()
    assert len(good) == 6 and not good["status"].isin(FAILED).any()


def test_dask_a_hang_in_build_is_timeout_rows_naming_the_phase(monkeypatch, scheduler):
    bad, good = _dask_and_local(monkeypatch, "misbehaving[mode=build_hang]", scheduler, build_time_limit_s=0.5)
    assert len(bad) == 6 and (bad["status"] == TIMEOUT).all()
    assert bad["error"].eq("preparing the chunk (derived/build) ran longer than the 0.5 s --build-time-limit").all()
    assert len(good) == 6 and not good["status"].isin(FAILED).any()


def test_dask_memory_without_bound_is_a_crashed_row(monkeypatch, scheduler):
    bad, good = _dask_and_local(monkeypatch, "misbehaving[mode=alloc,every=4]", scheduler, memory_limit_gb=6.0)
    assert bad["status"].tolist() == ["no_result", CRASHED, "no_result", "no_result", CRASHED, "no_result"]
    assert bad.loc[bad["status"] == CRASHED, "error"].str.startswith(
        "memory limit of 6 GB per worker (--memory-limit-gb) exceeded: MemoryError").all()
    assert len(good) == 6 and not good["status"].isin(FAILED).any()


def test_dask_workers_that_cannot_supervise_are_refused(capsys):
    from starid.cli import main

    cluster = _cluster(daemon=True)         # what `dask worker ADDRESS` starts by default
    try:
        assert main(["run", "misbehaving[mode=hang,every=1]", "--trials", "2", "--jobs", "1", "--executor", "dask",
                     "--scheduler", cluster.scheduler_address, "--quiet"]) == 2
    finally:
        cluster.close()
    err = capsys.readouterr().err
    assert "1 of 1 Dask workers cannot supervise plugin code" in err and "is daemonic" in err
    assert "DASK_DISTRIBUTED__WORKER__DAEMON=False" in err and "Traceback" not in err
