"""Where chunks run: supervised local worker processes, or a Dask cluster.

A *task* is one chunk (grid point x algorithm variant x block of trials, see
:mod:`starid.experiment.runner`) plus the images to skip. :func:`execute_task` computes it
anywhere; each worker process keeps the databases it built and the trials it simulated, so a
database is built once per variant and worker, not once per chunk.

:class:`LocalExecutor` (``--executor local``, the default) runs ``jobs`` worker processes (never
more than the machine's cores, so measured times are not oversubscribed) and supervises them:
before every image a worker writes which image it is on; an image that runs past the time limit
gets its worker killed and is recorded as ``timeout``, a worker that dies (a segfault,
``os._exit``) gets its image recorded as ``crashed`` against that algorithm, and in both cases a
fresh worker redoes the chunk with that image skipped. Ctrl-C or SIGTERM stop every worker;
finished chunks are already in the results folder.

:class:`DaskExecutor` (``--executor dask [--scheduler ADDRESS]``, the ``starid[dask]`` extra)
submits the same tasks to a Dask cluster (a ``LocalCluster`` without an address). A Dask worker
runs each task under the same supervision (:func:`run_supervised`: a :class:`LocalExecutor` of one
worker kept per worker thread), so the same limits hold and record the same rows; its process must
not be daemonic (``distributed.worker.daemon = False``, which starid sets for its LocalCluster and
checks on a cluster given by address).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
import threading
import time
import uuid
from collections import OrderedDict, deque
from dataclasses import dataclass, field
from multiprocessing.connection import wait

import pandas as pd

from ..catalog import Catalog, load_csv, load_hipparcos
from ..errors import ConfigError
from ..harness import constant_columns, database_key, failed_row, param_columns, prepare, rows_to_frame, trial_row
from ..provenance import versions
from ..registry import algorithm_info
from ..scoring import CRASHED, TIMEOUT, SuccessRule
from ..simulate import SimConfig, Simulator
from .store import release_in_child
from .warmup import TRIALS_KEPT, Dispatcher, schedule

DEFAULT_TIME_LIMIT_S = 10.0
#: ``--build-time-limit``: seconds a worker may spend preparing a chunk (simulating its trials,
#: ``derived`` + ``build``) before that algorithm's images become ``timeout`` rows
BUILD_TIME_LIMIT_S = 600.0
#: the ``--memory-limit-gb`` default is never below this (address space, not resident memory: a plugin's
#: first frames and threads reserve arenas it never touches)
MIN_MEMORY_GB = 4.0


def fair_share_gb(jobs: int) -> float:
    """The per-worker ``--memory-limit-gb`` default: physical memory / ``jobs`` in GB, at least
    :data:`MIN_MEMORY_GB`."""
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return float("inf")
    return max(MIN_MEMORY_GB, round(total / 1e9 / max(jobs, 1), 1))


#: this process's --memory-limit-gb (None: unlimited); ``retire``: a plugin ran out of it in this chunk
_MEMORY = {"limit_gb": None, "retire": False}


def address_space_gb() -> float:
    """This process's address space (``VmSize``) in GB, 0.0 where ``/proc`` does not say (not Linux)."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[0])
        return pages * os.sysconf("SC_PAGE_SIZE") / 1e9
    except (OSError, ValueError, IndexError):
        return 0.0


def _limit_memory(limit_gb: float | None) -> None:
    """Hold this (worker) process to ``--memory-limit-gb``: an allocation beyond it fails (``MemoryError``)
    instead of taking the machine down. The limit is headroom, set by :func:`memory_headroom`."""
    _MEMORY["limit_gb"] = limit_gb
    memory_headroom()


def memory_headroom() -> None:
    """Cap this process's address space (RLIMIT_AS) at what it holds now plus ``--memory-limit-gb``.

    Called when the process starts and again before each phase of plugin code (a chunk's preparation,
    then its images), so that a phase may add the limit to the address space whatever the phases before
    it left there: the databases and compiled code of earlier chunks in the same worker, the allocator's
    reserved arenas (pyarrow's pool reserves 1 GiB on the first frame a worker builds). An image's status
    is then the same whichever chunks ran before it in its worker, hence for any ``--jobs``. Where the
    address space cannot be read (not Linux) the cap is the limit itself."""
    limit_gb = _MEMORY["limit_gb"]
    if limit_gb is None or limit_gb == float("inf"):
        return
    import resource

    limit = int((address_space_gb() + limit_gb) * 1e9)
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))


def memory_error(error: str, limit_gb: float | None) -> str:
    """``error`` said as the memory limit's when it is a ``MemoryError`` under a limit, else ``""``."""
    if limit_gb is None or "MemoryError" not in (error or ""):
        return ""
    return f"memory limit of {limit_gb:g} GB per worker (--memory-limit-gb) exceeded: {error}"


def _memory_row(row: dict) -> dict:
    """A row whose error is a ``MemoryError`` under the worker's limit is ``crashed``, saying so."""
    error = memory_error(row.get("error", ""), _MEMORY["limit_gb"])
    if error:
        row = {**row, "status": CRASHED, "error": error}
    return row


def _image_row(prepared, trials, i: int, catalog, rule) -> dict:
    """Image ``i``'s trial row under the memory limit.

    An image that runs out of the limit is ``crashed``, saying so, and the images after it get the limit again
    as headroom over what the worker then holds: numba does not free what a compiled kernel allocated before it
    raised ``MemoryError``, and without the reset those leaks added up until every later image (and the row's
    own bookkeeping, and the chunk's frame) failed, a worker died, or the run ended. The worker then ends after
    this chunk (``_MEMORY["retire"]``), taking the leaked memory with it."""
    try:
        row = _memory_row(trial_row(prepared, trials, i, catalog, rule))
    except MemoryError as exc:      # not even the row's own bookkeeping fitted (the plugin's error was caught)
        memory_headroom()
        error = f"MemoryError: {exc}" if str(exc) else "MemoryError"
        row = failed_row(trials, i, CRASHED, memory_error(error, _MEMORY["limit_gb"]) or error)
    if after_memory_error(row.get("error", "")):
        _MEMORY["retire"] = True
    return row


def after_memory_error(error: str) -> bool:
    """After an image whose ``error`` is a ``MemoryError``: this process takes the limit again as headroom over
    what it now holds (what a numba kernel leaked on running out is not the next image's), and says so."""
    if "MemoryError" not in (error or ""):
        return False
    memory_headroom()
    return True


def overran_error(phase: str, limit_s: float, build: bool) -> str:
    """The ``timeout`` error of a ``phase`` that ran past its limit."""
    return f"{phase} ran longer than the {limit_s:g} s {'--build-time-limit' if build else '--time-limit'}"


def died_error(exitcode, phase: str, memory_limit_gb: float | None) -> str:
    """The ``crashed`` error of a supervised process that died inside ``phase``."""
    error = f"the worker process died (exit code {exitcode}) inside {phase}"
    if exitcode in (-6, -9, -11) and memory_limit_gb is not None:  # abort / killed / segfault: often an allocation
        error += f" (memory limit {memory_limit_gb:g} GB per worker, --memory-limit-gb)"
    return error


#: beat positions: preparing (simulate, derived, build) / the warm-up identify / between images
_BUILD, _WARMUP, _IDLE = -1.0, -3.0, -2.0


@dataclass(frozen=True)
class Task:
    """One chunk to compute; ``skip`` maps image positions to ``(status, error)`` already decided."""

    index: int
    chunk: object
    catalog_path: str
    camera: object
    seed: int
    min_correct: int
    skip: dict = field(default_factory=dict)


# ---- what a worker process computes (also called by Dask workers) -------------------------------

_CACHE: dict = {"catalog": {}, "trials": OrderedDict(), "sims": OrderedDict(), "prepared": {}, "databases": {}}
_CACHE["info"] = {}     # (plugin name, class) -> AlgorithmInfo: 24 ms of entry-point metadata per call


def _catalog(path: str) -> Catalog:
    cache = _CACHE["catalog"]
    if path not in cache:
        cache[path] = load_csv(path) if path else load_hipparcos()
    return cache[path]


def _trials(task: Task, catalog: Catalog):
    chunk = task.chunk
    key = (task.catalog_path, task.camera, task.seed, chunk.settings_key, chunk.start, chunk.stop)
    cache = _CACHE["trials"]
    if key in cache:
        cache.move_to_end(key)
    else:
        sims = _CACHE["sims"]      # one simulator per grid point (its catalog subset and k-d tree), not per block
        sim_key = key[:4]
        sim = sims.get(sim_key)
        if sim is None:
            sim = sims[sim_key] = Simulator(catalog, task.camera, SimConfig(**chunk.settings), seed=task.seed)
            while len(sims) > 4:
                sims.popitem(last=False)
        else:
            sims.move_to_end(sim_key)
        if sim.config.pipeline == "image":
            from ..render import image_trials

            trials, stats = image_trials(sim, chunk.stop - chunk.start, chunk.start)
            cache[key] = (sim, trials, stats.add_prefix("img_").rename(columns={"img_trial": "trial"}))
        else:
            cache[key] = (sim, sim.generate(chunk.stop - chunk.start, chunk.start), None)
        while len(cache) > TRIALS_KEPT:
            cache.popitem(last=False)
    return cache[key]


def execute_task(task: Task, beat=None) -> pd.DataFrame:
    """The trial rows of one chunk. ``beat`` (a shared array) hears which image is running."""
    _MEMORY["retire"] = False
    memory_headroom()           # this chunk's preparation, beyond what earlier chunks left in this worker
    catalog = _catalog(task.catalog_path)
    sim, trials, image_stats = _trials(task, catalog)
    chunk = task.chunk
    if beat is not None:   # the time first: the parent never pairs a new position with an old start
        beat[2], beat[0], beat[1] = time.monotonic(), task.index, _BUILD
    try:
        algorithm = chunk.variant.make().resolved(sim.config)
        info = _CACHE["info"].get((chunk.variant.name, type(algorithm)))   # entry points: read once per worker
        if info is None:
            info = _CACHE["info"][(chunk.variant.name, type(algorithm))] = algorithm_info(chunk.variant.name)
        key = (chunk.variant.name, repr(sorted(algorithm.params().items())), task.catalog_path, trials.camera)
        prepared = _CACHE["prepared"].get(key)
        skipped = len(task.skip) >= len(trials) and all(i in task.skip for i in range(len(trials)))
        if prepared is None and skipped:    # every image already decided (a build that hung): no new call
            from ..harness import Prepared

            prepared = Prepared(algorithm, chunk.variant.label, None, 0.0, 0.0, task.skip[0][1])
        elif prepared is None:
            def on_phase(phase: str) -> None:
                if beat is not None:
                    beat[2], beat[1] = time.monotonic(), _WARMUP if phase == "warmup" else _BUILD

            # a database built at another noise level serves when only query_only parameters differ
            same_db = database_key(algorithm, task.catalog_path, trials.camera)
            prepared = prepare(algorithm, catalog, trials.camera, trials.warmup, chunk.variant.label, on_phase,
                               built=_CACHE["databases"].get(same_db))
            _CACHE["prepared"][key] = prepared
            if prepared.database is not None:
                _CACHE["databases"].setdefault(same_db, prepared)
        elif prepared.label != chunk.variant.label:
            prepared = type(prepared)(prepared.algorithm, chunk.variant.label, prepared.database, prepared.build_s,
                                      prepared.compile_s, prepared.error)
        dist, dist_version = info.dist or "in process", info.dist_version
    except Exception as exc:  # an algorithm that cannot even be made is that algorithm's failure
        from ..harness import Prepared

        prepared = Prepared(_Unmade(chunk.variant.name), chunk.variant.label, None, 0.0, 0.0,
                            f"cannot make {chunk.variant.label}: {type(exc).__name__}: {exc}")
        algorithm, dist, dist_version = None, "", ""
    rule = SuccessRule(task.min_correct)
    rows = []
    memory_headroom()           # the images' own headroom, whether this chunk built the database or not
    for i in range(len(trials)):
        if i in task.skip:
            status, error = task.skip[i]
            rows.append(failed_row(trials, i, status, error))
            continue
        if beat is not None:
            beat[2], beat[1] = time.monotonic(), float(i)
        rows.append(_image_row(prepared, trials, i, catalog, rule))
    if beat is not None:
        beat[1] = _IDLE
    df = rows_to_frame(prepared, rows)
    if image_stats is not None:     # what render -> extract did to each image
        df = df.merge(image_stats, on="trial", how="left")
    params = prepared.algorithm.params() if algorithm is not None else dict(chunk.variant.params)
    tail = {"plugin_dist": dist, "plugin_version": dist_version, **param_columns(params), **versions()}
    return pd.concat([df, constant_columns(tail, df.index)], axis=1)


class _Unmade:
    """Stands in for an algorithm that could not be constructed (its rows carry the error)."""

    def __init__(self, name):
        self.name = name


# ---- local supervised workers ------------------------------------------------------------------

#: the parent's ends of the pipes of this process's live workers: a forked worker inherits them and
#: closes its copies (:func:`_die_with_parent`)
_PARENT_ENDS: set = set()


def _die_with_parent(parent_pid: int) -> None:
    """In a forked worker: end with the run that started it, even when that run is killed (SIGKILL: no
    ``finally`` stops the workers). Without this a worker outlives it -- computing, compiling, holding the
    run's stdout/stderr open, waiting forever on a pipe whose other end it inherited itself.

    The inherited copies of the parent's pipe ends are closed (so the parent's death is an end of file
    or a broken pipe here), and on Linux the kernel kills the worker when its parent dies
    (``PR_SET_PDEATHSIG``)."""
    for end in list(_PARENT_ENDS):
        try:
            end.close()
        except OSError:
            pass
    _PARENT_ENDS.clear()
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)     # PR_SET_PDEATHSIG = 1
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent_pid:      # the parent died before the line above
        os._exit(1)


def _child_setup(memory_limit_gb, parent_pid) -> None:
    """What every supervised process does first: die with its parent, hold no folder lock, take its memory
    limit, leave Ctrl-C to the parent."""
    if parent_pid is not None:
        _die_with_parent(parent_pid)
    release_in_child()          # a worker outliving a killed run must not keep its folder locked
    _limit_memory(memory_limit_gb)
    signal.signal(signal.SIGINT, signal.SIG_IGN)      # the parent alone handles Ctrl-C
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _worker_main(conn, beat, memory_limit_gb=None, parent_pid=None):
    _child_setup(memory_limit_gb, parent_pid)
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):     # the parent is gone
            return
        if task is None:
            return
        try:
            frame = execute_task(task, beat)
        except Exception as exc:   # a harness bug, not a plugin's: report it, keep the worker
            conn.send(("fail", task.index, f"{type(exc).__name__}: {exc}"))
            continue
        if _MEMORY["retire"]:       # a plugin ran out of memory: end, with what numba leaked (_image_row)
            conn.send(("last", task.index, frame))
            return
        conn.send(("ok", task.index, frame))


class _Worker:
    def __init__(self, ctx, memory_limit_gb=None):
        self.beat = ctx.Array("d", [-1.0, -2.0, 0.0], lock=False)
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_main, args=(child, self.beat, memory_limit_gb, os.getpid()),
                                daemon=True)
        _PARENT_ENDS.add(self.conn)     # before the fork: the child closes its copy
        self.proc.start()
        child.close()
        self.task: Task | None = None

    def stop(self, kill: bool = False):
        if kill:
            self.proc.kill()
        else:
            try:
                self.conn.send(None)
            except (OSError, BrokenPipeError):
                self.proc.kill()
        self.proc.join(timeout=5)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()
        _PARENT_ENDS.discard(self.conn)


def check_jobs(jobs: int) -> int:
    """``jobs`` if it is a whole number from 1 to the number of cores, else a clear error."""
    cores = os.cpu_count() or 1
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ConfigError(f"--jobs must be a whole number >= 1, got {jobs!r}")
    if jobs > cores:
        raise ConfigError(f"--jobs {jobs} exceeds the {cores} cores of this machine; timings would be "
                          f"oversubscribed (use at most {cores})")
    return jobs


def check_limits(jobs: int, time_limit_s: float, build_time_limit_s: float,
                 memory_limit_gb: float | None) -> tuple[float, float, float]:
    """``(time_limit_s, build_time_limit_s, memory_limit_gb)`` as floats, or a clear error naming the flag;
    ``memory_limit_gb`` None is the fair share of this machine for ``jobs`` workers."""
    if memory_limit_gb is None:
        memory_limit_gb = fair_share_gb(jobs)
    if isinstance(memory_limit_gb, bool) or not (isinstance(memory_limit_gb, (int, float)) and memory_limit_gb > 0):
        raise ConfigError(f"--memory-limit-gb must be a number of GB > 0, got {memory_limit_gb!r}")
    for flag, value in (("--time-limit", time_limit_s), ("--build-time-limit", build_time_limit_s)):
        if isinstance(value, bool) or not (isinstance(value, (int, float)) and 0 < value < float("inf")):
            raise ConfigError(f"{flag} must be a number of seconds > 0, got {value!r}")
    return float(time_limit_s), float(build_time_limit_s), float(memory_limit_gb)


def known_failure(task: Task, failed: dict) -> Task:
    """``task`` with every image decided when preparing its algorithm already hung or died in another
    chunk (``failed``: prepare key -> (status, error)); it is not called again."""
    failure = failed.get(prepare_key(task))
    if failure is None or task.skip:
        return task
    n = task.chunk.stop - task.chunk.start
    return Task(task.index, task.chunk, task.catalog_path, task.camera, task.seed, task.min_correct,
                {i: failure for i in range(n)})


def prepare_key(task: Task):
    """What a prepared algorithm depends on: variant, settings, catalog, camera."""
    return (task.chunk.variant, task.chunk.settings_key, task.catalog_path, task.camera)


class LocalExecutor:
    """Supervised worker processes on this machine (see the module docstring).

    ``keep_workers``: the workers outlive :meth:`run` (and the databases they built), until
    :meth:`close` or a run that fails; the Dask executor supervises each chunk with one of these.
    """

    def __init__(self, jobs: int | None = None, time_limit_s: float = DEFAULT_TIME_LIMIT_S,
                 build_time_limit_s: float = BUILD_TIME_LIMIT_S, memory_limit_gb: float | None = None,
                 keep_workers: bool = False):
        self.jobs = check_jobs(jobs if jobs is not None else (os.cpu_count() or 1))
        self.time_limit_s, self.build_time_limit_s, self.memory_limit_gb = check_limits(
            self.jobs, time_limit_s, build_time_limit_s, memory_limit_gb)
        self.keep_workers = keep_workers
        self._workers: list[_Worker] = []
        # (variant, settings, catalog, camera) -> (status, error) of a prepare that hung or died
        self._failed: dict = {}

    def close(self) -> None:
        """Stop the workers (kept ones included)."""
        for w in self._workers:
            w.stop(kill=w.task is not None)
        self._workers.clear()

    def run(self, tasks: list[Task], on_result) -> None:
        ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
        pending = Dispatcher(tasks)   # each plugin's first chunk first (one compile each), then each worker its own
        workers = self._workers
        while len(workers) < min(self.jobs, len(tasks)):
            workers.append(_Worker(ctx, self.memory_limit_gb))
        finished = False
        try:
            while pending or any(w.task is not None for w in workers):
                for w in workers:
                    if w.task is None and pending:
                        w.task = self._known_failure(pending.take(w))
                        w.conn.send(w.task)
                busy = [w for w in workers if w.task is not None]
                ready = wait([w.conn for w in busy], timeout=0.1)
                for w in busy:
                    if w.conn in ready:
                        try:
                            kind, index, payload = w.conn.recv()
                        except (EOFError, OSError):
                            continue            # it died; handled below
                        if kind == "fail":
                            raise RuntimeError(f"starid internal error in a worker: {payload}")
                        task, w.task = w.task, None
                        on_result(task, payload)
                        if kind == "last":      # it ended after this chunk (a plugin ran out of memory)
                            w.stop()
                            workers[workers.index(w)] = _Worker(ctx, self.memory_limit_gb)
                for k, w in enumerate(workers):
                    if w.task is None:
                        continue
                    replacement = self._check(w)
                    if replacement is not None:
                        w.stop(kill=True)
                        workers[k] = _Worker(ctx, self.memory_limit_gb)
                        pending.put_back(replacement)
            finished = True
        finally:
            if not (self.keep_workers and finished):
                self.close()

    def _known_failure(self, task: Task) -> Task:
        return known_failure(task, self._failed)

    def _check(self, w: _Worker) -> Task | None:
        """A task to redo when ``w`` died or overran, else ``None``."""
        task = w.task
        position, since = w.beat[1], w.beat[2]
        alive = w.proc.is_alive()
        elapsed = time.monotonic() - since
        image = position >= 0
        # the warm-up identify compiles the plugin's kernels (tens of seconds on a cold cache), so it is part of
        # preparing and runs under the build limit, not the per-image one
        limit = {_BUILD: self.build_time_limit_s, _WARMUP: self.build_time_limit_s}.get(position, self.time_limit_s)
        if alive and not ((image or position in (_BUILD, _WARMUP)) and elapsed > limit):
            return None
        phase = "identify" if image else "the warm-up identify" if position == _WARMUP else \
            "preparing the chunk (derived/build)"
        if alive:
            status = TIMEOUT
            error = overran_error(phase, limit, position in (_BUILD, _WARMUP))
        else:
            w.proc.join()
            status = CRASHED
            error = died_error(w.proc.exitcode, phase, self.memory_limit_gb)
        skip = dict(task.skip)
        if image and int(w.beat[0]) == task.index:
            skip[int(position)] = (status, error)
        else:       # hung or died while preparing: every image of the chunk fails the same way
            n = task.chunk.stop - task.chunk.start
            skip = {i: (status, error) for i in range(n)}
            self._failed[prepare_key(task)] = (status, error)
        w.task = None
        return Task(task.index, task.chunk, task.catalog_path, task.camera, task.seed, task.min_correct, skip)


# ---- one command's plugin calls (show, identify, check) -----------------------------------------

@dataclass(frozen=True)
class Limits:
    """``--time-limit``, ``--build-time-limit`` and ``--memory-limit-gb`` of a command that calls plugin code
    itself (``show``, ``identify``, ``check``): checked by :func:`check_limits`, memory None being this
    machine's fair share for one process."""

    time_limit_s: float = DEFAULT_TIME_LIMIT_S
    build_time_limit_s: float = BUILD_TIME_LIMIT_S
    memory_limit_gb: float | None = None

    def checked(self) -> Limits:
        return Limits(*check_limits(1, self.time_limit_s, self.build_time_limit_s, self.memory_limit_gb))

    @classmethod
    def from_args(cls, args) -> Limits:
        return cls(args.time_limit, args.build_time_limit, args.memory_limit_gb).checked()


@dataclass(frozen=True)
class Outcome:
    """What :func:`call_supervised` got back: ``fn``'s value (None when it never returned), what it emitted
    before, and, when a call overran or the process died, ``status`` (``timeout`` / ``crashed``) and ``error``
    naming the call (``phase``)."""

    value: object
    emitted: list
    status: str = ""
    error: str = ""
    phase: str = ""
    build: bool = False     # the call that failed was held to --build-time-limit (derived, build, warm-up)


class _Control:
    """What ``fn`` of :func:`call_supervised` gets: ``phase(name, build=False)`` before each plugin call (held
    to ``--build-time-limit`` when ``build``, else to ``--time-limit``) and ``emit(item)`` for a result that
    must survive a later call's overrun."""

    def __init__(self, conn):
        self._conn = conn
        self._build = True

    def phase(self, name: str, build: bool = False) -> None:
        if self._build and not build:       # the images' own memory headroom, as a chunk's in the engine
            memory_headroom()
        self._build = build
        self._conn.send(("phase", name, build))

    def emit(self, item) -> None:
        self._conn.send(("emit", item))


def _call_main(conn, fn, memory_limit_gb, parent_pid):
    _child_setup(memory_limit_gb, parent_pid)
    try:
        value = fn(_Control(conn))
    except BaseException as exc:  # noqa: BLE001 -- a starid error (ConfigError...) is raised in the parent
        try:
            conn.send(("raise", exc))
        except Exception:  # noqa: BLE001 -- an exception that does not pickle
            conn.send(("raise", RuntimeError(f"{type(exc).__name__}: {exc}")))
        return
    conn.send(("ok", value))


def call_supervised(fn, limits: Limits, on_emit=None) -> Outcome:
    """``fn(control)`` run in a forked child process under ``limits``, as :class:`LocalExecutor`'s workers run
    chunks: the same memory limit (RLIMIT_AS), the child dying with this process, each call that
    ``control.phase`` announces held to its time limit (the child killed when it overruns) and a child that
    dies reported, not raised. The value of ``fn`` and what it ``emit`` ted come back over a pipe (pickled);
    ``on_emit(item)`` hears each item as it comes (a progress bar).

    An exception ``fn`` raises is raised here. Without ``fork`` (not Linux/macOS) ``fn`` runs in this
    process, unsupervised."""
    if "fork" not in mp.get_all_start_methods():
        emitted: list = []

        class _Here:
            def phase(self, name, build=False):
                pass

            def emit(self, item):
                emitted.append(item)
                if on_emit is not None:
                    on_emit(item)

        return Outcome(fn(_Here()), emitted)
    ctx = mp.get_context("fork")
    conn, child = ctx.Pipe()
    proc = ctx.Process(target=_call_main, args=(child, fn, limits.memory_limit_gb, os.getpid()), daemon=True)
    _PARENT_ENDS.add(conn)      # before the fork: the child closes its copy
    emitted = []
    phase, build, since = "starting the process", True, time.monotonic()
    try:
        proc.start()
        child.close()
        while True:
            limit = limits.build_time_limit_s if build else limits.time_limit_s
            if not conn.poll(max(0.0, since + limit - time.monotonic())):
                return Outcome(None, emitted, TIMEOUT, overran_error(phase, limit, build), phase, build)
            try:
                message = conn.recv()
            except (EOFError, OSError):
                proc.join()
                return Outcome(None, emitted, CRASHED, died_error(proc.exitcode, phase, limits.memory_limit_gb),
                               phase, build)
            kind = message[0]
            if kind == "phase":
                phase, build, since = message[1], message[2], time.monotonic()
            elif kind == "emit":
                emitted.append(message[1])
                if on_emit is not None:
                    on_emit(message[1])
            elif kind == "ok":
                return Outcome(message[1], emitted)
            else:
                raise message[1]
    finally:
        if proc.is_alive():
            proc.kill()
        if proc.pid is not None:
            proc.join()
        _PARENT_ENDS.discard(conn)
        conn.close()


def call_per_item(fn, n: int, limits: Limits, on_item=None, build_fails_rest: bool = True) -> dict:
    """Items ``0..n-1`` computed by ``fn(control, start)`` (items ``start..n-1``, each announced with
    ``control.phase`` and sent with ``control.emit((k, item))``; ``k = -1`` for what the items share, e.g. a
    prepared algorithm's sizes) in supervised processes (:func:`call_supervised`).

    Returns ``{k: item}`` with an :class:`Outcome` for each item that overran or died: as the engine does, a
    fresh process goes on after it; a failure while preparing (``build``) is every remaining item's, the
    plugin not called again (unless not ``build_fails_rest``: items that each prepare their own, such as the
    conformance checks). ``on_item(k, item)`` hears each item as it comes."""
    items: dict = {}
    start = 0

    def heard(message):
        k, item = message
        items[k] = item
        if on_item is not None:
            on_item(k, item)

    while start < n:
        outcome = call_supervised(lambda control, start=start: fn(control, start), limits, heard)
        if not outcome.status:
            break
        done = max([k for k in items if k >= start], default=start - 1)
        if outcome.build and build_fails_rest:
            for k in range(done + 1, n):
                heard((k, outcome))
            break
        heard((done + 1, outcome))
        start = done + 2
    return items


# ---- Dask ---------------------------------------------------------------------------------------

#: how to start Dask workers that can supervise (said by the error when they cannot)
WORKER_HOWTO = ("start the workers with DASK_DISTRIBUTED__WORKER__DAEMON=False in their environment "
                "(dask worker ADDRESS, the nanny then starts them as non-daemonic processes), or with "
                "dask worker --no-nanny ADDRESS")

#: ``--scheduler``: how long a run waits for the cluster's first worker
WAIT_FOR_WORKERS_S = 60.0


#: in a Dask worker process: thread -> (run id, the LocalExecutor(1) supervising the chunks it runs)
_SUPERVISORS: dict = {}


def cannot_supervise() -> str:
    """Why this (Dask worker) process cannot start the supervised process a chunk runs in, or ``""``."""
    proc = mp.current_process()
    if proc.daemon:
        return (f"the Dask worker process {proc.name!r} (pid {os.getpid()}) is daemonic, and a daemonic process "
                f"cannot start the supervised process that holds plugin code to --time-limit, --build-time-limit "
                f"and --memory-limit-gb")
    return ""


def run_supervised(task: Task, run_id: str, limits: tuple, registrations: tuple = ()) -> tuple[pd.DataFrame, dict]:
    """In a Dask worker: ``task``'s rows, computed in a supervised child process exactly as
    :class:`LocalExecutor` computes them (same limits, same ``timeout``/``crashed`` rows), and what this
    worker knows of prepares that hung or died (prepare key -> (status, error)).

    ``limits`` is ``(time_limit_s, build_time_limit_s, memory_limit_gb)``, memory None meaning this
    machine's memory / its cores. ``registrations``: the client's in-process algorithm registrations
    (classes), made here too, as a forked local worker inherits them. Each worker thread keeps its child
    (and the databases it built) for the later chunks of run ``run_id``; a chunk of another run stops it."""
    from .. import registry

    for cls in registrations:
        if registry._registered.get(cls.name) is not cls:
            registry.register(cls)
    thread = threading.get_ident()
    held = _SUPERVISORS.get(thread)
    if held is not None and held[0] != run_id:     # left by an earlier run
        held[1].close()
        del _SUPERVISORS[thread]
        held = None
    if held is None:
        reason = cannot_supervise()
        if reason:
            raise ConfigError(f"{reason}; {WORKER_HOWTO}")
        # what the parent of local workers has done before forking them (planning loads every entry point):
        # the child then inherits the imports, and a plugin's imports are not counted in its build time
        registry.available_algorithms()
        time_limit_s, build_time_limit_s, memory_limit_gb = limits
        if memory_limit_gb is None:
            memory_limit_gb = fair_share_gb(os.cpu_count() or 1)
        held = _SUPERVISORS[thread] = (run_id, LocalExecutor(1, time_limit_s, build_time_limit_s, memory_limit_gb,
                                                             keep_workers=True))
    supervisor = held[1]
    out = []
    supervisor.run([task], lambda _, frame: out.append(frame))
    return out[0], dict(supervisor._failed)


def close_supervisors(run_id: str | None = None) -> None:
    """Stop this Dask worker's supervised children (of run ``run_id`` only, when given) that are not
    computing (a chunk still running after its run was interrupted finishes first)."""
    for thread, (rid, supervisor) in list(_SUPERVISORS.items()):
        busy = any(w.task is not None for w in supervisor._workers)
        if (run_id is None or rid == run_id) and not busy:
            supervisor.close()
            del _SUPERVISORS[thread]


class DaskExecutor:
    """The same tasks on a Dask cluster (``scheduler`` address, or a LocalCluster of ``jobs`` workers),
    each chunk under the same limits as :class:`LocalExecutor`: a Dask worker runs it in a supervised
    child process (:func:`run_supervised`), which its process must be allowed to start (not daemonic;
    starid starts its LocalCluster so, and checks a cluster it is given)."""

    def __init__(self, jobs: int | None = None, scheduler: str | None = None,
                 time_limit_s: float = DEFAULT_TIME_LIMIT_S, build_time_limit_s: float = BUILD_TIME_LIMIT_S,
                 memory_limit_gb: float | None = None):
        try:
            import distributed  # noqa: F401
        except ImportError:
            raise ConfigError("--executor dask needs the dask extra: pip install 'starid[dask]'") from None
        self.jobs = check_jobs(jobs if jobs is not None else (os.cpu_count() or 1))
        self.scheduler = scheduler
        # a LocalCluster's workers share this machine: each gets the local executor's fair share; the
        # workers of a cluster given by address each take their own machine's (memory / cores)
        self.time_limit_s, self.build_time_limit_s, memory_gb = check_limits(
            self.jobs, time_limit_s, build_time_limit_s, memory_limit_gb)
        self.memory_limit_gb = None if memory_limit_gb is None and scheduler else memory_gb

    def run(self, tasks: list[Task], on_result) -> None:
        import dask
        from distributed import Client, LocalCluster, as_completed

        from .. import registry

        limits = (self.time_limit_s, self.build_time_limit_s, self.memory_limit_gb)
        run_id = uuid.uuid4().hex
        registrations = tuple(registry._registered.values())
        cluster = None
        # the nanny reads this when it (re)starts a worker process: for the whole run
        with dask.config.set({"distributed.worker.daemon": False}):
            if self.scheduler:
                try:
                    client = Client(self.scheduler)
                except (OSError, TimeoutError) as exc:
                    raise ConfigError(f"--scheduler {self.scheduler}: cannot reach the Dask scheduler: "
                                      f"{exc}") from None
            else:
                cluster = LocalCluster(n_workers=self.jobs, threads_per_worker=1, processes=True,
                                       dashboard_address=None)
                client = Client(cluster)
            try:
                if self.scheduler:
                    self._check_workers(client)
                self._submit_all(client, as_completed(), tasks, run_id, limits, registrations, on_result)
            finally:
                if self.scheduler:      # the cluster lives on: its workers' children of this run end now
                    try:
                        client.run(close_supervisors, run_id)
                    except Exception:  # noqa: BLE001 -- a worker gone; its children die with it
                        pass
                client.close()
                if cluster is not None:
                    cluster.close()

    def _check_workers(self, client) -> None:
        """A clear error (exit 2) unless the cluster at ``self.scheduler`` has workers and each can
        supervise a chunk."""
        try:
            client.wait_for_workers(1, timeout=WAIT_FOR_WORKERS_S)
        except TimeoutError:
            raise ConfigError(f"--scheduler {self.scheduler}: the Dask scheduler has no workers "
                              f"(waited {WAIT_FOR_WORKERS_S:g} s)") from None
        reasons = {addr: why for addr, why in client.run(cannot_supervise).items() if why}
        if reasons:
            addr, why = next(iter(reasons.items()))
            raise ConfigError(f"--scheduler {self.scheduler}: {len(reasons)} of {len(client.nthreads())} Dask "
                              f"workers cannot supervise plugin code ({addr}: {why}); {WORKER_HOWTO}")

    @staticmethod
    def _submit_all(client, completed, tasks, run_id, limits, registrations, on_result) -> None:
        """Each plugin's first chunk first (:func:`schedule`), at most two per worker thread in flight, so a
        chunk whose prepare hung or died elsewhere is sent with its images decided, not called again."""
        pending = deque(schedule(tasks))
        failed: dict = {}
        futures: dict = {}

        def submit() -> None:
            window = max(1, 2 * sum(client.nthreads().values()))
            while pending and len(futures) < window:
                task = known_failure(pending.popleft(), failed)
                future = client.submit(run_supervised, task, run_id, limits, registrations, pure=False)
                futures[future] = task
                completed.add(future)

        submit()
        for future in completed:
            task = futures.pop(future)
            frame, learned = future.result()
            failed.update(learned)
            on_result(task, frame)
            submit()


def make_executor(name: str, jobs: int | None, scheduler: str | None = None,
                  time_limit_s: float = DEFAULT_TIME_LIMIT_S, build_time_limit_s: float = BUILD_TIME_LIMIT_S,
                  memory_limit_gb: float | None = None):
    """``local`` or ``dask``."""
    if name == "local":
        if scheduler:
            raise ConfigError("--scheduler goes with --executor dask")
        return LocalExecutor(jobs, time_limit_s, build_time_limit_s, memory_limit_gb)
    if name == "dask":
        return DaskExecutor(jobs, scheduler, time_limit_s, build_time_limit_s, memory_limit_gb)
    raise ConfigError(f"unknown executor {name!r}; use 'local' or 'dask'")


__all__ = ["DaskExecutor", "Limits", "LocalExecutor", "Outcome", "Task", "call_per_item", "call_supervised",
           "check_jobs", "check_limits", "execute_task", "make_executor", "memory_error", "run_supervised"]
