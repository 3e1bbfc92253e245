"""The harness's compiled checks and scoring (:mod:`starid.kernels.score`) give its numpy reference's
results to the last bit: the same errors for the same ids, the same attitude error in every row."""

import numpy as np
import pytest

from starid.attitude import random_attitude
from starid.errors import PluginError
from starid.kernels.score import ID_NOT_IN_CATALOG, ID_TWICE, IDS_OK, check_ids, score_terms
from starid.plugin import Identification, check_identification
from starid.scoring import attitude_error_arcsec, attitude_from_ids, score_trial


class _Cat:
    """The two catalog fields the reference reads, and its ``index_of``."""

    def __init__(self, hip, unit_icrs):
        self.hip, self.unit_icrs = hip, unit_icrs

    def index_of(self, hip):
        return np.searchsorted(self.hip, hip)


def _reference_check(hip, catalog_hip):
    """The numpy checks ``check_identification`` made before the kernel: (code, id)."""
    reported = hip[hip != -1]
    if reported.size:
        pos = np.minimum(np.searchsorted(catalog_hip, reported), catalog_hip.size - 1)
        bad = reported[catalog_hip[pos] != reported]
        if bad.size:
            return ID_NOT_IN_CATALOG, int(bad[0])
        ordered = np.sort(reported)
        twice = ordered[1:][ordered[1:] == ordered[:-1]]
        if twice.size:
            return ID_TWICE, int(twice[0])
    return IDS_OK, 0


@pytest.fixture(scope="module")
def sky():
    rng = np.random.default_rng(7)
    hip = np.sort(rng.choice(120_000, 4_000, replace=False)).astype(np.int64)
    unit = rng.normal(size=(hip.size, 3))
    return hip, unit / np.linalg.norm(unit, axis=1)[:, None]


def test_check_ids_matches_the_numpy_checks(sky):
    cat_hip, _ = sky
    rng = np.random.default_rng(1)
    codes = set()
    for _ in range(3_000):
        n = int(rng.integers(0, 25))
        hip = cat_hip[rng.integers(0, cat_hip.size, n)]           # repeats happen
        hip[rng.random(n) < 0.3] = -1
        if rng.random() < 0.2 and n:
            hip[rng.integers(0, n)] = rng.choice([0, 5, 119_999, 10**9, -7])   # rarely in the catalog
        got = check_ids(hip, cat_hip)
        ref = _reference_check(hip, cat_hip)
        assert (int(got[0]), int(got[1])) == ref, (hip, got, ref)
        codes.add(ref[0])
    assert codes == {IDS_OK, ID_NOT_IN_CATALOG, ID_TWICE}


@pytest.mark.parametrize("hip, message", [([1, -1, 99], "id 99, which is neither"), ([7, 3, 7, 3], "gave id 3 to"),
                                          ([-1, -1], None)])
def test_check_identification_messages(hip, message):
    cat_hip = np.array([1, 3, 7], dtype=np.int64)
    result = Identification(np.array(hip, dtype=np.int32))     # any integer dtype is accepted
    if message is None:
        assert check_identification(result, len(hip), cat_hip) is result
    else:
        with pytest.raises(PluginError, match=message):
            check_identification(result, len(hip), cat_hip)


def test_attitude_error_matches_the_numpy_solution_bit_for_bit(sky):
    cat_hip, unit = sky
    cat = _Cat(cat_hip, unit)
    rng = np.random.default_rng(2)
    compared = flipped = 0
    for k in range(3_000):
        n = int(rng.integers(0, 16))
        rows = rng.choice(cat_hip.size, n, replace=False)
        hip = cat_hip[rows].copy()
        hip[rng.random(n) < 0.25] = -1
        truth = random_attitude(rng)
        v = unit[rows] @ truth.T + rng.normal(scale=10 ** rng.uniform(-6, -1), size=(n, 3))
        if k % 5 == 0 and n >= 3:                                  # wrong matches: large angles, det U det V < 0
            v = v[rng.permutation(n)]
        if k % 7 == 0 and n >= 2:                                  # collinear: a degenerate B
            v[:] = v[0]
        v = np.ascontiguousarray(v / np.maximum(np.linalg.norm(v, axis=1), 1e-300)[:, None]).reshape(-1, 3)
        truth_hip = np.where(rng.random(n) < 0.2, -1, np.where(rng.random(n) < 0.2, cat_hip[0], hip))
        truth_hip.flags.writeable = False                          # as the trial set's truth ids
        ref = attitude_error_arcsec(attitude_from_ids(hip, v, cat), truth)
        # the harness's row: score_terms' counts and terms, numpy's arctan2 of the terms
        n_identified, n_correct, y, x = score_terms(hip, truth_hip, cat_hip, v, unit, truth)
        got = float(np.arctan2(y, x)) * (180.0 / np.pi * 3600.0)
        assert (np.isnan(ref) and np.isnan(got)) or ref == got, (k, ref, got)
        scored = score_trial(hip, truth_hip)
        assert (n_identified, n_correct) == (scored["n_identified"], scored["n_correct"]), k
        compared += not np.isnan(ref)
        flipped += not np.isnan(ref) and ref > 3600
    assert compared > 1_500 and flipped > 100



_PREPARE_THEN_ROW = """
import importlib, pkgutil
import numpy as np
from numba.core.registry import CPUDispatcher
import starid.kernels
from starid import Camera, SimConfig, Simulator, load_hipparcos
from starid.harness import prepare, trial_row
from starid.kernels.score import check_ids, score_terms
from starid.plugin import Identification
from starid.scoring import SuccessRule

cat = load_hipparcos()


class Named:
    name = "named"

    def derived(self, catalog, camera):
        return self

    def build(self, catalog, camera):
        return None

    def identify(self, database, observation):      # valid, distinct (wrong) ids
        return Identification(np.array(cat.hip[: len(observation)], dtype=np.int64))


trials = Simulator(cat, Camera(), SimConfig(), seed=3).generate(2)
prepared = prepare(Named(), cat, trials.camera, trials.warmup)
kernels = [v for info in pkgutil.walk_packages(starid.kernels.__path__, "starid.kernels.")
           for v in vars(importlib.import_module(info.name)).values() if isinstance(v, CPUDispatcher)]
count = lambda: sum(len(k.signatures) for k in kernels)
before = (len(check_ids.signatures), len(score_terms.signatures))
n_before = count()
row = trial_row(prepared, trials, 0, cat, SuccessRule())
after = (len(check_ids.signatures), len(score_terms.signatures))
print(before, after, count() - n_before, row["error"] == "" and row["attitude_err_arcsec"] > 0)
"""


def test_prepare_compiles_what_trial_row_calls():
    """The scoring kernels compile in the warm-up (under the build time limit), never in an image's time
    limit: in a new process (no signature yet), a trial row after ``prepare`` adds none to them or to any
    kernel of ``starid.kernels`` (the back-projection of the read-only image arrays included)."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _PREPARE_THEN_ROW], capture_output=True, text=True, timeout=600)
    assert out.stdout.strip() == "(1, 1) (1, 1) 0 True", out.stdout + out.stderr
