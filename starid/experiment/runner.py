"""Plan an experiment into chunks, compute the missing ones, assemble the tidy frame.

A chunk is (grid point settings, algorithm variant, block of ``BLOCK`` trials). Its key hashes
everything that decides its rows -- settings, variant, seed, catalog, and the source code of
starid and of the plugin -- so chunks shared by two studies (Table 6's condition is also a
point of the noise sweeps) are computed once, a resumed run computes only missing keys, and a
changed experiment only the chunks it changes.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..catalog import load_csv, load_hipparcos
from ..harness import constant_columns
from ..params import integer_columns, keep_integers
from ..provenance import now, versions
from ..registry import algorithm_info
from ..scoring import SuccessRule
from ..simulate import SimConfig
from .executors import BUILD_TIME_LIMIT_S, DEFAULT_TIME_LIMIT_S, Task, make_executor
from .spec import Experiment, Variant, sim_settings
from .store import Store

#: Trials per chunk: the unit of parallel work, of resuming and of progress.
BLOCK = 500


@dataclass(frozen=True)
class Chunk:
    key: str
    settings: dict
    settings_key: str
    variant: Variant
    start: int
    stop: int
    #: the study's own camera (:attr:`Study.camera`); None = the experiment's
    camera: object = None


@dataclass(frozen=True)
class Placement:
    """Where a chunk's rows go in the frame: study, point and that point's grid values."""

    study: str
    point: int
    grid_values: dict
    chunk: Chunk


def _hash(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:20]


def source_fingerprint(module_name: str) -> str:
    """A hash of the Python sources of a module's package (its folder, tests left out).

    Part of every chunk key, so results computed by other code are never reused: an edited
    plugin or simulator recomputes, even when its version number did not change.
    """
    module = importlib.import_module(module_name)
    if getattr(module, "__file__", None) is None:     # defined interactively: no source to hash
        return "interactive"
    path = Path(module.__file__)
    files = sorted(p for p in path.parent.rglob("*.py") if "tests" not in p.relative_to(path.parent).parts) \
        if path.name == "__init__.py" else [path]
    h = hashlib.sha256()
    for f in files:
        h.update(str(f.relative_to(path.parent)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def catalog_identity(catalog) -> str:
    """A content hash of a catalog (ids, positions, magnitudes)."""
    h = hashlib.sha256()
    for arr in (catalog.hip, catalog.ra_deg, catalog.dec_deg, catalog.v_mag):
        h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()[:16]


def plan(experiment: Experiment, catalog, rule: SuccessRule | None = None) -> list[Placement]:
    """Every chunk of the experiment, in frame order (study, point, variant, block)."""
    rule = rule or SuccessRule()
    base_camera = experiment.make_camera()
    common = {"camera": base_camera.as_dict(), "seed": experiment.seed, "catalog": catalog_identity(catalog),
              "rule": rule.min_correct, "starid": versions()["starid_version"], "core": source_fingerprint("starid")}
    plugin_code: dict[str, str] = {}
    out = []
    for study in experiment.studies:
        own = None if study.camera is None else experiment.study_camera(study)
        if own is not None:
            common = {**common, "camera": own.as_dict()}
        elif common["camera"] != base_camera.as_dict():
            common = {**common, "camera": base_camera.as_dict()}
        trials = experiment.study_trials(study)
        for p, point in enumerate(study.grid.points()):
            settings = sim_settings(experiment.sim, point)
            settings_key = _hash(settings)
            for variant in study.variants:
                info = algorithm_info(variant.name)
                variant.make()          # bad parameters are refused here, before any work
                if variant.name not in plugin_code:
                    plugin_code[variant.name] = source_fingerprint(info.cls.__module__.rpartition(".")[0]
                                                                   or info.cls.__module__)
                for start in range(0, trials, BLOCK):
                    stop = min(start + BLOCK, trials)
                    key = _hash({**common, "settings": settings, "algorithm": variant.name,
                                 "params": [list(kv) for kv in variant.params], "label": variant.label,
                                 "plugin": [info.dist, info.dist_version, plugin_code[variant.name]],
                                 "start": start, "stop": stop})
                    out.append(Placement(study.name, p, point, Chunk(key, settings, settings_key, variant, start,
                                                                     stop, own)))
    return out


def _progress_bar(total: int, enabled: bool):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    # the first chunks of each worker build the databases and compile the kernels (numba, ~20 s
    # on a first run): say so until the first chunk is back
    return tqdm(total=total, desc="building databases, compiling kernels", unit="chunk", leave=False)


def run_experiment(experiment: Experiment, out: str | Path | None = None, jobs: int | None = None,
                   executor: str = "local", scheduler: str | None = None, catalog_path: str = "",
                   time_limit_s: float = DEFAULT_TIME_LIMIT_S, progress: bool | None = None,
                   rule: SuccessRule | None = None, build_time_limit_s: float = BUILD_TIME_LIMIT_S,
                   memory_limit_gb: float | None = None) -> pd.DataFrame:
    """Run (or resume) ``experiment``; the tidy frame, one row per (study, point, variant, trial).

    With ``out`` the results folder (:mod:`.store`) keeps every chunk as it finishes, so an
    interrupted run resumes where it stopped; without it nothing is written. Both executors hold
    every call of plugin code to a limit: ``time_limit_s`` per image (and the warm-up image),
    ``build_time_limit_s`` for ``derived``/``build``; ``memory_limit_gb`` what a worker's address space may
    add in a chunk's preparation and again in its images (:func:`.executors.memory_headroom`; None: the
    machine's memory / workers; on a Dask cluster given by ``scheduler``, each worker machine's memory /
    its cores).
    """
    rule = rule or SuccessRule()
    catalog = load_csv(catalog_path) if catalog_path else load_hipparcos()
    placements = plan(experiment, catalog, rule)
    chunks = {pl.chunk.key: pl.chunk for pl in placements}
    keys = list(chunks)
    store = Store(out, experiment) if out is not None else None
    lock = store.lock() if store is not None else None      # one run per folder (exit 2 naming the holder)
    try:
        ex = make_executor(executor, jobs, scheduler, time_limit_s, build_time_limit_s, memory_limit_gb)
        return _run(experiment, placements, chunks, keys, store, ex, catalog_path, progress, rule)
    finally:
        if lock is not None:
            lock.release()


def _run(experiment, placements, chunks, keys, store, ex, catalog_path, progress, rule) -> pd.DataFrame:
    started = now()
    # a chunk file that is damaged (checksum, unreadable) is reported, set aside and recomputed
    todo = [chunks[k] for k in keys if store is None or not store.usable(k)]
    if store is not None:
        store.write_manifest(keys, started, None)
    done: dict[str, pd.DataFrame] = {}
    camera = experiment.make_camera()
    tasks = [Task(i, c, catalog_path, camera if c.camera is None else c.camera, experiment.seed, rule.min_correct)
             for i, c in enumerate(todo)]
    bar = _progress_bar(len(tasks), sys.stderr.isatty() if progress is None else progress)

    def on_result(task: Task, frame: pd.DataFrame) -> None:
        if store is not None:
            store.write(task.chunk.key, frame)
        else:
            done[task.chunk.key] = frame
        if bar is not None:
            bar.set_description("chunks", refresh=False)
            bar.update(1)

    try:
        if tasks:
            ex.run(tasks, on_result)
    finally:
        if bar is not None:
            bar.close()
    frame = assemble(placements, experiment, lambda k: done[k] if store is None else store.read(k))
    if store is not None:
        store.write_results(frame)
        store.write_manifest(keys, started, now(), {"computed_chunks": len(tasks), "reused_chunks":
                                                    len(keys) - len(tasks)})
    return frame


#: threads reading a results folder's chunk files
READ_THREADS = 4


def assemble(placements: list[Placement], experiment: Experiment, read) -> pd.DataFrame:
    """The chunks' rows in plan order, with study, point, grid values and settings as columns."""
    camera = experiment.make_camera()
    with ThreadPoolExecutor(READ_THREADS) as pool:     # Parquet decoding releases the GIL: 1.8 -> 1.3 s (#25)
        frames = list(pool.map(read, [pl.chunk.key for pl in placements]))
    lead, tail = [], []
    for pl in placements:
        lead.append({"study": pl.study, "point": pl.point, **{f"grid_{k}": v for k, v in pl.grid_values.items()}})
        tail.append({"seed": experiment.seed,
                     **{f"sim_{k}": v for k, v in SimConfig(**pl.chunk.settings).as_dict().items()},
                     **(camera if pl.chunk.camera is None else pl.chunk.camera).columns()})
    out = keep_integers(_with_constants(frames, lead, tail), integer_columns(frames))   # 8, not 8.0 (#27)
    # one block per dtype: the chunks' column-wise joins leave ~175 blocks, and an experiment's tables adding a
    # column to such a frame made pandas warn that it is highly fragmented
    return _uniform_types(out).copy()


def _with_constants(frames: list[pd.DataFrame], lead: list[dict], tail: list[dict]) -> pd.DataFrame:
    """Every chunk's rows between its ``lead`` and ``tail`` constant columns, the chunks one under the other.

    The frame :func:`_join_each` makes (the columns in the order they first appear, each column's type what
    concatenating the chunks' pieces gives), built as one concatenation of the chunks' own rows beside each
    distinct set of constants once, repeated: Table 6's 560 chunks assemble in 4.1-4.6 s instead of 7.0-8.5."""
    consts = [{**a, **b} for a, b in zip(lead, tail, strict=True)]
    own = set().union(*(df.columns for df in frames)) if frames else set()
    if not frames or any(len(df) == 0 for df in frames) or own & set().union(*consts):
        return _join_each(frames, lead, tail)     # an empty chunk's pieces count otherwise; a clash of names
    order = list(dict.fromkeys(col for df, a, b in zip(frames, lead, tail, strict=True)
                               for col in (*a, *df.columns, *b)))
    # chunks of one grid point share their constants: each distinct set once (typed, so 1, 1.0 and True differ)
    distinct: dict = {}
    which = [distinct.setdefault(tuple((k, type(v), repr(v)) for k, v in c.items()), (len(distinct), c))[0]
             for c in consts]
    one = pd.concat([constant_columns(c, pd.RangeIndex(1)) for _, c in distinct.values()], ignore_index=True)
    rows = np.repeat(np.asarray(which, dtype=np.int64), [len(df) for df in frames])
    body = pd.concat(frames, ignore_index=True)
    return pd.concat([one.take(rows).reset_index(drop=True), body], axis=1)[order]


def _join_each(frames: list[pd.DataFrame], lead: list[dict], tail: list[dict]) -> pd.DataFrame:
    """Each chunk joined to its constant columns, the joined chunks concatenated (what
    :func:`_with_constants` builds faster)."""
    return pd.concat([pd.concat([constant_columns(a, df.index), df, constant_columns(b, df.index)], axis=1)
                      for df, a, b in zip(frames, lead, tail, strict=True)], ignore_index=True)


def _uniform_types(df: pd.DataFrame) -> pd.DataFrame:
    """Columns mixing types across algorithms (a parameter that is a bool here, a float there) as text,
    so the frame can be written to Parquet."""
    mixed = [col for col in df.columns if df[col].dtype == object and len({type(v) for v in df[col].dropna()}) > 1]
    if not mixed:
        return df
    text = {col: df[col].map(lambda v: None if v is None or (isinstance(v, float) and np.isnan(v)) else str(v))
            for col in mixed}
    return pd.concat([df.drop(columns=mixed), pd.DataFrame(text, index=df.index)], axis=1)[df.columns]
