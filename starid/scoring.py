"""The success rule and the status words every result row uses.

A trial's status is one of :data:`STATUSES`:

* ``correct`` -- at least ``min_correct`` (3) observed stars got their true id and none a wrong one;
* ``misidentified`` -- any reported id is wrong (a false star given an id is wrong);
* ``no_result`` -- otherwise;
* ``error`` -- the plugin raised or broke its contract (the row's ``error`` says how);
* ``timeout`` -- ``identify`` took longer than the per-image time limit;
* ``crashed`` -- the worker process died inside ``identify`` (a segfault, ``os._exit``).

Without truth (your own centroids), the same rule with the truth unknown gives ``identified``
(at least ``min_correct`` stars got an id) or ``no_result``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .attitude import rotation_angle_rad, solve_wahba

CORRECT, MISIDENTIFIED, NO_RESULT = "correct", "misidentified", "no_result"
ERROR, TIMEOUT, CRASHED, IDENTIFIED = "error", "timeout", "crashed", "identified"
STATUSES = (CORRECT, MISIDENTIFIED, NO_RESULT, ERROR, TIMEOUT, CRASHED)
FAILED = (ERROR, TIMEOUT, CRASHED)

RAD_TO_ARCSEC = 180.0 / math.pi * 3600.0


@dataclass(frozen=True)
class SuccessRule:
    """When an image counts as correctly identified."""

    min_correct: int = 3

    def classify(self, n_correct: int, n_wrong: int) -> str:
        if n_wrong > 0:
            return MISIDENTIFIED
        if n_correct >= self.min_correct:
            return CORRECT
        return NO_RESULT


def score_trial(hip: np.ndarray, truth: np.ndarray | None, rule: SuccessRule = SuccessRule()) -> dict:
    """Counts and status of one image's ids against its truth (``None``: truth unknown)."""
    reported = hip != -1
    n_identified = int(reported.sum())
    if truth is None:
        status = IDENTIFIED if n_identified >= rule.min_correct else NO_RESULT
        return {"n_identified": n_identified, "n_correct": -1, "n_wrong": -1, "status": status}
    n_correct = int((reported & (hip == truth)).sum())
    n_wrong = n_identified - n_correct
    return {"n_identified": n_identified, "n_correct": n_correct, "n_wrong": n_wrong,
            "status": rule.classify(n_correct, n_wrong)}


def attitude_from_ids(hip: np.ndarray, v_cam: np.ndarray, catalog) -> np.ndarray | None:
    """Wahba (SVD) attitude from the identified stars; ``None`` with fewer than two."""
    reported = np.flatnonzero(hip != -1)
    if reported.size < 2:
        return None
    rows = catalog.index_of(hip[reported])
    return solve_wahba(v_cam[reported], catalog.unit_icrs[rows])


def attitude_error_arcsec(attitude: np.ndarray | None, attitude_true: np.ndarray) -> float:
    """Angle between an estimated and the true attitude, NaN when there is no estimate."""
    if attitude is None:
        return float("nan")
    return rotation_angle_rad(attitude, attitude_true) * RAD_TO_ARCSEC


def bijection_accuracy(n_correct, n_identified) -> np.ndarray:
    """Per image, the share of the reported ids that are right, 0 where nothing was reported (or
    the trial failed: NaN counts): Galvizo & Lim's (2018) accuracy a(h) of the returned map h
    (their images score only the stars the map names; an empty map scores 0). Averaged over
    images it is their printed accuracy; it does not ask for ``min_correct`` stars as :class:`SuccessRule`."""
    correct = np.nan_to_num(np.asarray(n_correct, dtype=np.float64), nan=0.0).clip(min=0)
    named = np.nan_to_num(np.asarray(n_identified, dtype=np.float64), nan=0.0).clip(min=0)
    return np.divide(correct, named, out=np.zeros_like(correct), where=named > 0)
