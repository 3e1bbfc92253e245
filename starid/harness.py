"""The scoring harness: every algorithm on the same trials, timed and scored the same way.

For each algorithm: build the database once (``build_s``), warm the JIT up on a separate
trial that is not scored (``compile_s``) -- :func:`prepare` -- then time ``identify`` per
trial with ``time.perf_counter_ns`` around the call alone -- :func:`score`; :func:`run` does
both for several algorithms on the same trials. An exception inside one trial is recorded as
that trial's failure (``status == "error"`` with the error text) and the run goes on.

Success rule (:class:`SuccessRule`, defaults): a trial is **correct** when at least
``min_correct = 3`` observed stars get their true id and none gets a wrong one;
**misidentified** when any reported id is wrong (a false star given an id is wrong);
otherwise **no_result**.
"""

from __future__ import annotations

import json
import math
import multiprocessing as mp
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np
import pandas as pd

from .attitude import rotation_angle_rad, solve_wahba
from .catalog import Catalog
from .observation import TrialSet
from .plugin import Algorithm, check_identification
from .simulate import Simulator

RAD_TO_ARCSEC = 180.0 / math.pi * 3600.0

SUMMARY_COLUMNS = [
    "algorithm", "trials", "id_rate", "id_rate_lo", "id_rate_hi", "misid_rate", "no_result_rate",
    "star_recall", "star_precision", "time_median_us", "time_mean_us", "time_p95_us", "db_mb",
    "build_s", "compile_s", "error_rate", "attitude_err_median_arcsec",
]


@dataclass(frozen=True)
class SuccessRule:
    """When an image counts as correctly identified."""

    min_correct: int = 3

    def classify(self, n_correct: int, n_wrong: int) -> str:
        if n_wrong > 0:
            return "misidentified"
        if n_correct >= self.min_correct:
            return "correct"
        return "no_result"


def versions() -> dict:
    from . import __version__

    return {"starid_version": __version__, "numpy_version": np.__version__,
            "numba_version": numba.__version__, "python_version": platform.python_version()}


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion (95 % by default)."""
    if n == 0:
        return (float("nan"), float("nan"))
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return (max(0.0, centre - half), min(1.0, centre + half))


def score_trial(hip: np.ndarray, truth: np.ndarray, rule: SuccessRule) -> dict:
    reported = hip != -1
    correct = reported & (hip == truth)
    n_correct = int(correct.sum())
    n_wrong = int(reported.sum()) - n_correct
    return {"n_identified": int(reported.sum()), "n_correct": n_correct, "n_wrong": n_wrong,
            "status": rule.classify(n_correct, n_wrong)}


def attitude_error_arcsec(hip, obs, catalog: Catalog, attitude_true) -> float:
    """Error of the Wahba (SVD) attitude from the identified stars, NaN if fewer than two."""
    reported = np.flatnonzero(hip != -1)
    if reported.size < 2:
        return float("nan")
    rows = catalog.index_of(hip[reported])
    b_cam = obs.camera.backproject(obs.x_px[reported], obs.y_px[reported])
    A = solve_wahba(b_cam, catalog.unit_icrs[rows])
    return rotation_angle_rad(A, attitude_true) * RAD_TO_ARCSEC


def warmup_observation(simulator: Simulator):
    """A trial outside every scored range (index 2**62), used only to warm the JIT up."""
    return simulator.observation(2**62)


@dataclass(frozen=True, eq=False)
class Prepared:
    """An algorithm with its database built (``build_s``) and its JIT warmed up (``compile_s``)."""

    algorithm: Algorithm
    database: object
    build_s: float
    compile_s: float


def prepare(algorithm: Algorithm, catalog: Catalog, camera, warmup) -> Prepared:
    """Build the database once and warm the JIT up on ``warmup``, an observation never scored."""
    t0 = time.perf_counter()
    database = algorithm.build(catalog, camera)
    build_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        algorithm.identify(database, warmup)
        algorithm.identify(database, warmup.permuted(np.arange(len(warmup))[::-1]))
    except Exception:  # a failing warm-up shows up again, per image, in the scored runs
        pass
    return Prepared(algorithm, database, build_s, time.perf_counter() - t0)


def timed_identify(algorithm: Algorithm, database, obs, catalog_hip: np.ndarray) -> tuple[np.ndarray, int, str]:
    """One ``identify`` call timed with ``perf_counter_ns`` around the call alone.

    Returns ``(hip, elapsed_ns, error)``: on an exception or a broken plugin contract the ids
    are all -1 and ``error`` says what happened.
    """
    t0 = time.perf_counter_ns()
    try:
        result = algorithm.identify(database, obs)
        elapsed_ns = time.perf_counter_ns() - t0
        check_identification(result, len(obs), catalog_hip)
    except Exception as exc:
        return np.full(len(obs), -1, dtype=np.int64), time.perf_counter_ns() - t0, f"{type(exc).__name__}: {exc}"
    return np.asarray(result.hip, dtype=np.int64), elapsed_ns, ""


def score(prepared: Prepared, trials: TrialSet, catalog: Catalog, simulator: Simulator,
          rule: SuccessRule = SuccessRule(), progress: bool = False) -> pd.DataFrame:
    """Time and score a prepared algorithm on ``trials``; one row per trial."""
    algorithm, database = prepared.algorithm, prepared.database
    rows = []
    iterator = range(len(trials))
    if progress:
        from tqdm.auto import tqdm

        iterator = tqdm(iterator, desc=algorithm.name, unit="img", leave=False)
    for i in iterator:
        obs = trials.observation(i)
        hip, elapsed_ns, error = timed_identify(algorithm, database, obs, catalog.hip)
        row = {"trial": int(trials.trial[i]), "n_stars": len(obs), "n_true_stars": int((obs.truth_hip >= 0).sum()),
               "error": error}
        row.update(score_trial(hip, obs.truth_hip, rule))
        row["time_us"] = elapsed_ns / 1e3
        if error:
            row["status"] = "error"
            row["attitude_err_arcsec"] = float("nan")
        else:
            row["attitude_err_arcsec"] = attitude_error_arcsec(hip, obs, catalog, trials.attitude[i])
        rows.append(row)
    df = pd.DataFrame(rows, columns=["trial", "n_stars", "n_true_stars", "status", "error", "n_identified",
                                     "n_correct", "n_wrong", "time_us", "attitude_err_arcsec"])
    df.insert(0, "algorithm", algorithm.name)
    df["n_redraws"] = trials.n_redraws
    df["db_mb"] = database.nbytes / 1e6
    df["build_s"] = prepared.build_s
    df["compile_s"] = prepared.compile_s
    df["algorithm_params"] = json.dumps(algorithm.params(), sort_keys=True, default=str)
    df["success_min_correct"] = rule.min_correct
    for key, value in {**simulator.params(), **versions()}.items():
        df[key] = value
    return df


# State handed to forked worker processes (set just before the pool forks, read in the children).
_FORKED: dict = {}


def _score_chunk(positions: np.ndarray) -> list[pd.DataFrame]:
    st = _FORKED
    trials = st["trials"].select(positions)
    return [score(p, trials, st["catalog"], st["simulator"], st["rule"]) for p in st["prepared"]]


def run(algorithms: list[Algorithm], trials: TrialSet, catalog: Catalog, simulator: Simulator,
        rule: SuccessRule = SuccessRule(), progress: bool = False, jobs: int = 1) -> pd.DataFrame:
    """Score every algorithm on the same trials; a tidy frame, one row per (algorithm, trial).

    Databases are built and the JIT warmed up once, in this process. With ``jobs > 1`` the
    trials are split into contiguous chunks scored by forked worker processes (each runs every
    algorithm on its chunk, so all algorithms are timed under the same load); everything but
    the measured times is identical for any ``jobs``.
    """
    warmup = warmup_observation(simulator)
    prepared = [prepare(a, catalog, simulator.camera, warmup) for a in algorithms]
    jobs = max(1, min(int(jobs), len(trials)))
    if jobs == 1 or "fork" not in mp.get_all_start_methods():
        frames = [score(p, trials, catalog, simulator, rule, progress) for p in prepared]
        return pd.concat(frames, ignore_index=True)
    chunks = np.array_split(np.arange(len(trials)), 4 * jobs)
    chunks = [c for c in chunks if c.size]
    _FORKED.update(prepared=prepared, trials=trials, catalog=catalog, simulator=simulator, rule=rule)
    try:
        with ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context("fork")) as pool:
            results = pool.map(_score_chunk, chunks)
            if progress:
                from tqdm.auto import tqdm

                results = tqdm(results, total=len(chunks), desc="chunks", leave=False)
            per_chunk = list(results)
    finally:
        _FORKED.clear()
    frames = [pd.concat([chunk[k] for chunk in per_chunk], ignore_index=True) for k in range(len(prepared))]
    return pd.concat(frames, ignore_index=True)


def summarize(df: pd.DataFrame) -> pd.DataFrame:
    """One row per algorithm (in order of first appearance) with the summary columns."""
    out = []
    for name, g in df.groupby("algorithm", sort=False):
        n = len(g)
        n_ok = int((g["status"] == "correct").sum())
        lo, hi = wilson_interval(n_ok, n)
        reported = g["n_identified"].sum()
        t = g["time_us"].to_numpy()
        out.append({
            "algorithm": name, "trials": n, "id_rate": n_ok / n if n else float("nan"),
            "id_rate_lo": lo, "id_rate_hi": hi,
            "misid_rate": float((g["status"] == "misidentified").mean()),
            "no_result_rate": float((g["status"] == "no_result").mean()),
            "star_recall": g["n_correct"].sum() / max(g["n_true_stars"].sum(), 1),
            "star_precision": g["n_correct"].sum() / reported if reported else float("nan"),
            "time_median_us": float(np.median(t)), "time_mean_us": float(np.mean(t)),
            "time_p95_us": float(np.percentile(t, 95)),
            "db_mb": float(g["db_mb"].iloc[0]), "build_s": float(g["build_s"].iloc[0]),
            "compile_s": float(g["compile_s"].iloc[0]),
            "error_rate": float((g["status"] == "error").mean()),
            "attitude_err_median_arcsec": float(np.nanmedian(g["attitude_err_arcsec"]))
            if g["attitude_err_arcsec"].notna().any() else float("nan"),
        })
    return pd.DataFrame(out, columns=SUMMARY_COLUMNS)
