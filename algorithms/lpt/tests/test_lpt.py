"""LPT-specific tests: database layout, shift voting against brute force, Luo's set-up, explain, parameters.

Conformance (random fields, coincident stars, ids beyond 2^31, explain's type, determinism, order
invariance) runs for every plugin in tests/test_conformance.py and is not repeated here.
"""

import numpy as np
import pytest

from starid import Camera, ConfigError, SimConfig, Simulator
from starid_algorithms.lpt import LPT
from starid_algorithms.lpt.kernels import StringSearch, shift_scores


@pytest.fixture(scope="module")
def db(catalog, camera):
    return LPT().build(catalog, camera)


def test_database_layout(db):
    assert db.strings.dtype == np.uint8 and db.strings.shape == (db.guide_hip.size, 100)
    assert db.strings.max() <= 16
    assert np.all(np.diff(db.guide_unit[:, 2]) >= 0)
    assert (db.strings > 0).sum(axis=1).mean() > 3


def _brute_force(row, img, m, level_tol, sector_tol):
    """Oracle: compare the image string with every circular shift of the database string."""
    scores = []
    for s in range(m):
        count = 0
        for k in np.flatnonzero(img):
            js = [(k + s + d) % m for d in range(-sector_tol, sector_tol + 1)]
            count += any(row[j] and abs(int(row[j]) - int(img[k])) <= level_tol for j in js)
        scores.append(count)
    return max(scores), int(np.argmax(scores))


@pytest.mark.parametrize("sector_tol", [0, 1])
def test_shift_scores_equal_brute_force_circular_match(sector_tol):
    rng = np.random.default_rng(1)
    m = 60
    search = StringSearch(m, 16, 0.0, 1.0, 0.0, 1, sector_tol, 1, 1, 1, 0.0)
    mark = np.zeros((m, m), dtype=np.int64)
    score = np.zeros(m, dtype=np.int64)
    for stamp in range(1, 30):
        row = np.zeros(m, dtype=np.uint8)
        row[rng.choice(m, 8, replace=False)] = rng.integers(1, 17, 8)
        img = np.roll(row, -int(rng.integers(m))).astype(np.int64)
        img[rng.choice(m, 3, replace=False)] = rng.integers(0, 17, 3)
        sec = np.flatnonzero(img)
        best, shift, n_chars = shift_scores(row, sec, img[sec], sec.size, search, mark, stamp, score)
        assert (best, shift) == _brute_force(row, img, m, 1, sector_tol)
        assert n_chars == np.count_nonzero(row)


def test_luo_setup(catalog):
    camera = Camera.from_fov(20.0, 1024)
    alg = LPT(mag_limit=6.5, sigma_px=0.5, max_refs=3)
    db = alg.build(catalog, camera)
    assert db.radius_deg == pytest.approx(6.0)
    sim = Simulator(catalog.brighter_than(6.5), camera, SimConfig(sigma_px=0.5, mag_limit=6.5, min_stars=3), seed=2)
    ok = 0
    for t in range(6):
        obs = sim.observation(t)
        hip = alg.identify(db, obs).hip
        assert not np.any((hip >= 0) & (hip != obs.truth_hip))
        ok += int(np.sum(hip == obs.truth_hip) >= 3)
    assert ok >= 5      # measured 6 of 6; one spare


def test_explain(catalog, camera, db):
    obs = Simulator(catalog, camera, SimConfig(sigma_px=0.5), seed=3).observation(0)
    ex = LPT().explain(db, obs)
    assert len(ex.segments) > 2 and "LPT" in ex.caption


def test_bad_parameters():
    for kw in ({"n_levels": 0}, {"n_levels": 300}, {"sector_tol": 50}, {"min_score": 0}, {"radius_deg": 0.0},
               {"level_tol": -1}, {"double_px": -2.0}):
        with pytest.raises(ConfigError):
            LPT(**kw)
