"""The scoring harness: one algorithm over a :class:`~starid.observation.TrialSet` -> trial rows.

For one algorithm: build the database once (``build_s``) and warm the JIT up on the trial set's
``warmup`` image, which is never scored (``compile_s``) -- :func:`prepare`; then time
``identify`` per image with ``time.perf_counter_ns`` around the call alone and score it against
the truth -- :func:`score`. Every algorithm is timed and scored this same way, on the same images.

An algorithm gets each image through :meth:`Observation.for_plugin` (read-only arrays, no
truth); the harness alone holds the truth. An exception (``SystemExit`` included) or a broken
contract inside one image is that image's ``error`` row, and the run goes on; a database that
fails to build makes every image of that algorithm an ``error`` row. Time limits and crashes
are the executors' business (:mod:`starid.experiment.executors`), which run this code in
supervised worker processes.

The success rule and status words are :mod:`starid.scoring`'s; summaries are :mod:`starid.stats`'.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .catalog import Catalog
from .jitcache import describe
from .kernels.score import check_ids, score_terms
from .observation import Observation, TrialSet
from .plugin import Algorithm, check_identification
from .provenance import versions
from .scoring import ERROR, RAD_TO_ARCSEC, SuccessRule, score_trial

#: The success rule when none is given (frozen, so one instance serves every call).
DEFAULT_RULE = SuccessRule()

#: The trial-row schema: every result row of ``run``, ``table6``, ``identify`` and the engine
#: starts with these columns (the engine then adds the grid point's settings, the algorithm's
#: parameters as ``param_<key>`` columns, the seed and the versions).
TRIAL_COLUMNS = ["algorithm", "label", "trial", "n_stars", "n_true_stars", "status", "error", "n_identified",
                 "n_correct", "n_wrong", "time_us", "attitude_err_arcsec", "n_redraws", "db_mb", "build_s",
                 "compile_s", "boresight_ra_deg", "boresight_dec_deg"]


@dataclass(frozen=True, eq=False)
class Prepared:
    """An algorithm with its database built (``build_s``) and its JIT warmed up (``compile_s``).

    ``error`` is set (and ``database`` is ``None``) when ``build`` failed.
    """

    algorithm: Algorithm
    label: str
    database: object
    build_s: float
    compile_s: float
    error: str = ""


def build_key(algorithm: Algorithm) -> tuple:
    """What an algorithm's database depends on: its class and every parameter but its
    :attr:`~starid.plugin.Algorithm.query_only` ones (two algorithms with equal keys build the same
    database on the same catalog and camera; the conformance check ``query_only`` holds plugins to it)."""
    skip = set(getattr(type(algorithm), "query_only", ()) or ())
    return type(algorithm), repr(sorted((k, v) for k, v in algorithm.params().items() if k not in skip))


def database_key(algorithm: Algorithm, catalog_path: str, camera) -> tuple:
    """What a built database depends on: :func:`build_key`, the catalog and the camera the algorithm
    assumes. A worker builds one database per key (``executors.execute_task``), and the dispatcher keeps
    each worker to the keys it holds (``warmup.Dispatcher``): both take it from here."""
    return (*build_key(algorithm), catalog_path, camera)


def warm_scoring(catalog: Catalog) -> None:
    """Compile the harness's scoring kernels (:mod:`starid.kernels.score`) for the types :func:`trial_row`
    passes them. :func:`prepare` calls it in the warm-up, which runs under the build time limit and is not
    the plugin's ``compile_s``: on a cold cache their compile (~4.5 CPU s, much longer on a loaded machine)
    would otherwise fall inside the first image's time limit, and a worker killed there compiles again."""
    cat_hip = np.ascontiguousarray(catalog.hip, dtype=np.int64)
    hip = np.array(cat_hip[:3], dtype=np.int64)
    check_ids(hip, cat_hip)
    truth = np.eye(3)
    truth.flags.writeable = False           # trial_row's true attitudes are read-only views of the trial set
    truth_hip = hip.copy()
    truth_hip.flags.writeable = False       # and its truth ids
    score_terms(hip, truth_hip, catalog.hip, np.array(catalog.unit_icrs[:3], dtype=np.float64), catalog.unit_icrs,
                truth)


def _describe(exc: BaseException) -> str:
    return describe(exc)


def prepare(algorithm: Algorithm, catalog: Catalog, camera, warmup: Observation | None,
            label: str | None = None, on_phase: Callable[[str], None] | None = None,
            built: Prepared | None = None) -> Prepared:
    """Derive the sensor-dependent parameters, build the database once and warm the JIT up on
    ``warmup`` (never scored). The prepared algorithm is the derived one (:meth:`Algorithm.derived`).

    ``built``: the same algorithm prepared on the same catalog and camera with parameters that differ
    only in its :attr:`~starid.plugin.Algorithm.query_only` ones (:func:`build_key`): its database is
    the one this would build, so it is used as it is and ``build_s`` is its build's.

    ``on_phase`` hears ``"build"`` before ``derived``/``build`` and ``"warmup"`` before the warm-up
    ``identify``: the supervising executor holds each phase to its limit (``--build-time-limit``,
    ``--time-limit``), so that a plugin hanging there is that algorithm's ``timeout``."""
    label = label or algorithm.name
    camera = camera.pinhole_frame    # a distorted camera: plugins work in its undistorted frame
    if on_phase is not None:
        on_phase("build")
    t0 = time.perf_counter()
    try:
        algorithm = algorithm.derived(catalog, camera)
        database = algorithm.build(catalog, camera) if built is None else built.database
    except (Exception, SystemExit) as exc:
        return Prepared(algorithm, label, None, time.perf_counter() - t0, 0.0, f"build failed: {_describe(exc)}")
    build_s = time.perf_counter() - t0 if built is None else built.build_s
    t0 = time.perf_counter()
    if warmup is not None:
        if on_phase is not None:
            on_phase("warmup")
        warm_scoring(catalog)
        warmup.unit_cam()       # trial_row's back-projection of the read-only image arrays (a kernel signature)
        t0 = time.perf_counter()
        plugin_view = warmup.for_plugin()
        try:
            algorithm.identify(database, plugin_view)
            algorithm.identify(database, plugin_view.permuted(np.arange(len(warmup))[::-1]))
        except (Exception, SystemExit):  # a failing warm-up shows up again, per image, in the scored runs
            pass
    return Prepared(algorithm, label, database, build_s, time.perf_counter() - t0)


def counter_columns(counters: dict | None) -> dict:
    """An :class:`~starid.plugin.Identification`'s work counters as trial-row columns ``n_<name>``
    (none when the plugin reports none); a name whose column the schema already has is skipped."""
    if not counters:
        return {}
    return {f"n_{k}": int(v) for k, v in counters.items() if f"n_{k}" not in TRIAL_COLUMNS}


def timed_identify(prepared: Prepared, obs: Observation, catalog_hip: np.ndarray, counters: dict | None = None):
    """One ``identify`` call on ``obs.for_plugin()``, timed around the call alone.

    Returns ``(hip, elapsed_ns, error)``: on an exception or a broken contract the ids are all
    -1 and ``error`` says what happened. ``counters``, when given, is filled with the
    identification's work counters (:attr:`~starid.plugin.Identification.counters`), if any.
    """
    view = obs.for_plugin()
    if prepared.error:
        return np.full(len(obs), -1, dtype=np.int64), 0, prepared.error
    t0 = time.perf_counter_ns()
    try:
        result = prepared.algorithm.identify(prepared.database, view)
        elapsed_ns = time.perf_counter_ns() - t0
        check_identification(result, len(obs), catalog_hip)
    except (Exception, SystemExit) as exc:
        return np.full(len(obs), -1, dtype=np.int64), time.perf_counter_ns() - t0, _describe(exc)
    if counters is not None and result.counters:
        counters.update(result.counters)
    return np.array(result.hip, dtype=np.int64), elapsed_ns, ""   # a writable copy: one kernel signature


def _image_fields(trials: TrialSet, i: int) -> dict:
    """The columns every row of image ``i`` has, whatever the algorithm did (:func:`image_columns`)."""
    return {k: v[i] for k, v in image_columns(trials).items()}


def image_columns(trials: TrialSet) -> dict:
    """The columns every row has, for every image of ``trials`` at once, as lists of Python numbers (trial,
    n_stars, n_true_stars, n_redraws, boresight_ra_deg, boresight_dec_deg: :func:`_boresights`, to the last bit
    what numpy's scalar calls gave per image). Computed once per trial set (each algorithm of a chunk scores
    the same set): ~5 us of numpy calls per row before (#25)."""
    cols = trials.__dict__.get("_image_columns")
    if cols is None:
        true = np.concatenate(([0], np.cumsum(trials.truth_hip >= 0)))
        ra_deg, dec_deg = _boresights(trials.attitude)
        cols = {"trial": trials.trial.tolist(), "n_stars": np.diff(trials.offsets).tolist(),
                "n_true_stars": (true[trials.offsets[1:]] - true[trials.offsets[:-1]]).tolist(),
                "n_redraws": trials.n_redraws.tolist(), "boresight_ra_deg": ra_deg.tolist(),
                "boresight_dec_deg": dec_deg.tolist()}
        object.__setattr__(trials, "_image_columns", cols)
    return cols


def _boresights(attitude: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``boresight_ra_deg`` / ``boresight_dec_deg`` of every attitude ``(t, 3, 3)``: where the camera's z axis
    (the attitude's third row, ICRS) points."""
    z = attitude[:, 2, :]
    return np.degrees(np.arctan2(z[:, 1], z[:, 0])) % 360.0, np.degrees(np.arcsin(np.clip(z[:, 2], -1.0, 1.0)))


def constant_columns(values: dict, index: pd.Index) -> pd.DataFrame:
    """One column per item of ``values``, the value repeated on every row of ``index`` (one block,
    not one insertion per column)."""
    return pd.DataFrame({k: pd.Series([v] * len(index), index=index, dtype=object if v is None else None)
                         for k, v in values.items()}, index=index)


def param_columns(params: dict) -> dict:
    """An algorithm's parameters as ``param_<key>`` columns (scalars as they are, anything else as text)."""
    return {f"param_{k}": v if isinstance(v, (bool, int, float, str, type(None))) else repr(v)
            for k, v in params.items()}


def trial_row(prepared: Prepared, trials: TrialSet, i: int, catalog: Catalog, rule: SuccessRule,
              keep_ids: bool = False) -> dict:
    """Run, time and score image ``i`` of ``trials``: one trial row."""
    obs = trials.observation(i)
    counters: dict = {}
    hip, elapsed_ns, error = timed_identify(prepared, obs, catalog.hip, counters)
    row = _image_fields(trials, i)
    row["error"] = error
    if error:
        row.update(score_trial(hip, obs.truth_hip, rule))
        row["status"] = ERROR
        row["attitude_err_arcsec"] = float("nan")
    else:
        # score_trial's counts and attitude_error_arcsec(attitude_from_ids(...)) in one compiled call, to the last
        # bit (numpy's arctan2 of its terms: starid.kernels.score.attitude_error_terms)
        n_identified, n_correct, y, x = score_terms(hip, obs.truth_hip, catalog.hip, obs.unit_cam(), catalog.unit_icrs,
                                                    np.ascontiguousarray(trials.attitude[i]))
        row["n_identified"], row["n_correct"], row["n_wrong"] = n_identified, n_correct, n_identified - n_correct
        row["status"] = rule.classify(n_correct, n_identified - n_correct)
        row["attitude_err_arcsec"] = float(np.arctan2(y, x)) * RAD_TO_ARCSEC
    row["time_us"] = elapsed_ns / 1e3
    row.update(counter_columns(counters))
    if keep_ids:
        row["ids"] = hip.tolist()
        row["truth_ids"] = obs.truth_hip.tolist()
    return row


def failed_row(trials: TrialSet, i: int, status: str, error: str) -> dict:
    """The row of image ``i`` when its ``identify`` never returned (timeout, crash)."""
    return {**_image_fields(trials, i), "error": error, "n_identified": 0, "n_correct": 0,
            "n_wrong": 0, "status": status, "time_us": float("nan"), "attitude_err_arcsec": float("nan")}


def rows_to_frame(prepared: Prepared, rows: list[dict]) -> pd.DataFrame:
    """Trial rows of one prepared algorithm as a frame in the :data:`TRIAL_COLUMNS` order."""
    df = pd.DataFrame(rows)
    df.insert(0, "algorithm", prepared.algorithm.name)
    df.insert(1, "label", prepared.label)
    df["db_mb"] = prepared.database.nbytes / 1e6 if prepared.database is not None else float("nan")
    df["build_s"] = prepared.build_s
    df["compile_s"] = prepared.compile_s
    extra = [c for c in df.columns if c not in TRIAL_COLUMNS]
    return df.reindex(columns=TRIAL_COLUMNS + extra)


def score(prepared: Prepared, trials: TrialSet, catalog: Catalog, rule: SuccessRule = DEFAULT_RULE,
          keep_ids: bool = False, on_trial: Callable[[int], None] | None = None) -> pd.DataFrame:
    """Time and score a prepared algorithm on every image of ``trials``; one row per image.

    ``on_trial(i)`` is called before image ``i`` (the executors' heartbeat).
    """
    rows = []
    for i in range(len(trials)):
        if on_trial is not None:
            on_trial(i)
        rows.append(trial_row(prepared, trials, i, catalog, rule, keep_ids))
    return rows_to_frame(prepared, rows)


def run(algorithms, trials: TrialSet, catalog: Catalog, simulator=None, rule: SuccessRule = DEFAULT_RULE,
        keep_ids: bool = False, progress: bool = False) -> pd.DataFrame:
    """Score several algorithms on the same trials, in this process: the notebook entry point.

    ``algorithms`` are instances (or ``(label, instance)`` pairs). With a ``simulator`` its
    settings fill the algorithms' ``follows`` parameters and become columns. One row per
    (algorithm, trial); for sweeps, parallel runs and time limits use :mod:`starid.experiment`.
    """
    frames = []
    items = [a if isinstance(a, tuple) else (None, a) for a in algorithms]
    labels = [label or a.name for label, a in items]
    dup = {x for x in labels if labels.count(x) > 1}
    if dup:
        from .errors import ConfigError

        raise ConfigError(f"algorithm label(s) {sorted(dup)} given twice; give each variant its own label")
    for (_, algorithm), label in zip(items, labels, strict=True):
        if simulator is not None:
            algorithm = algorithm.resolved(simulator.config)
        prepared = prepare(algorithm, catalog, trials.camera, trials.warmup, label)
        iterator = range(len(trials))
        if progress:
            from tqdm.auto import tqdm

            iterator = tqdm(iterator, desc=label, unit="img", leave=False)
        rows = [trial_row(prepared, trials, i, catalog, rule, keep_ids) for i in iterator]
        df = rows_to_frame(prepared, rows)
        frames.append(pd.concat([df, constant_columns(param_columns(prepared.algorithm.params()), df.index)], axis=1))
    from .params import integer_columns, keep_integers

    out = keep_integers(pd.concat(frames, ignore_index=True), integer_columns(frames))   # 8, not 8.0 (#27)
    tail = {**(simulator.params() if simulator is not None else {}), **versions()}
    return pd.concat([out, constant_columns(tail, out.index)], axis=1)

