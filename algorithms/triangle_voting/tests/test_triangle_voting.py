"""Tests of the triangle_voting plugin (Fan & Zhong 2018, reconstructed)."""

from __future__ import annotations

import math
from itertools import combinations

import numpy as np
import pytest
from starid_algorithms.planar_triangle.testing import (
    assert_explain_draws_triangles,
    assert_sigma_follows_with_1px_floor,
)
from starid_algorithms.triangle_voting import TriangleVoting
from starid_algorithms.triangle_voting.kernels import triangle_features

from starid import ConfigError, Observation, SimConfig, Simulator, run, summarize
from starid.harness import Prepared, score
from starid.kernels import chord
from starid.plugin import check_identification
from starid.registry import get_algorithm


@pytest.fixture(scope="module")
def algo():
    return TriangleVoting()


@pytest.fixture(scope="module")
def db(algo, catalog, camera):
    return algo.build(catalog, camera)


@pytest.fixture(scope="module")
def noisy_sim(catalog, camera):
    return Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=11)


# -- registration and parameters -----------------------------------------------------------

def test_registered_and_summary():
    cls = get_algorithm("triangle_voting")
    assert cls is TriangleVoting
    assert "Fan & Zhong" in cls.summary()


@pytest.mark.parametrize("kwargs", [
    {"sigma_px": -1.0}, {"sigma_px": float("nan")}, {"mag_limit": float("inf")},
    {"pattern_radius_deg": 0.0}, {"pattern_radius_deg": 91.0}, {"d_min_deg": -0.1},
    {"d_min_deg": 5.0, "pattern_radius_deg": 5.0}, {"n_neighbours": 1}, {"n_neighbours": 5.0},
    {"lambda_extra": -1}, {"k_sigma": 0.0}, {"double_star_deg": -1.0}, {"grid_cell_tol": 0.0},
    {"side_check": 1}, {"vote_neighbours": "yes"}, {"v_min": 0}, {"min_support": 0},
    {"n_candidates": 1}, {"min_stars": 1}, {"max_hypotheses": -1}, {"n_neighbours": True},
])
def test_parameter_validation(kwargs):
    with pytest.raises(ConfigError):
        TriangleVoting(**kwargs)


# -- features and database ------------------------------------------------------------------

def test_triangle_features_hand_checked():
    # apex at (0, h) over the base from (0, 0) to (b, 0), in the plane z = 1 (not unit vectors:
    # the features are plain planar geometry of the three points)
    s = np.array([0.3, 0.4, 1.0])
    a = np.array([0.0, 0.0, 1.0])
    b = np.array([1.0, 0.0, 1.0])
    base, height, t = triangle_features(s, a, b)
    assert base == pytest.approx(1.0)
    assert height == pytest.approx(0.4)
    assert t == pytest.approx(0.3)
    base2, height2, t2 = triangle_features(s, b, a)  # neighbours swapped: same base and height
    assert (base2, height2) == pytest.approx((base, height))
    assert t2 == pytest.approx(0.7)


def test_database_invariants(algo, db, catalog, camera):
    guide = catalog.brighter_than(algo.mag_limit)
    n = db.hip.size
    assert n <= len(guide) and n > 0.99 * len(guide)  # only close doubles dropped
    assert np.all(np.isin(db.hip, guide.hip)) and np.unique(db.hip).size == n
    assert db.base.dtype == np.float32 and db.height.dtype == np.float32
    for arr in (db.main, db.n_i, db.n_j):
        assert arr.dtype == np.uint16 and int(arr.max()) < n
    m = db.base.size
    assert m <= n * math.comb(algo.n_neighbours, 2)
    assert m > 0.9 * n * math.comb(algo.n_neighbours, 2)
    # no triangle twice, main never its own neighbour
    key = np.sort(np.c_[db.n_i, db.n_j], axis=1)
    trip = np.c_[db.main, key]
    assert np.unique(trip, axis=0).shape[0] == m
    assert np.all(db.main != db.n_i) and np.all(db.main != db.n_j)
    # grid: every record lies in the cell the grid says
    assert db.cell_start[0] == 0 and db.cell_start[-1] == m and np.all(np.diff(db.cell_start) >= 0)
    cell = (np.floor(db.base / db.cell_b).astype(np.int64) * db.n_cells_h
            + np.floor(db.height / db.cell_h).astype(np.int64))
    assert np.all(np.diff(cell) >= 0)
    assert np.array_equal(np.searchsorted(cell, np.arange(cell.max() + 2)), db.cell_start[:cell.max() + 2])
    # sky grid: rows of each sky cell contiguous
    assert db.sky_start[-1] == n and np.all(np.diff(db.sky_start) >= 0)
    # measured 1.58 MB at V <= 6.5, 2.24 MB with the records' side chords (8 bytes a record)
    assert db.nbytes - db.deep.nbytes - db.deep_v_mag.nbytes <= 2_600_000
    assert db.side_i.dtype == np.float32 and db.side_i.shape == db.side_j.shape == db.main.shape


def test_records_match_recomputed_features(db):
    rng = np.random.default_rng(0)
    unit = db.unit_icrs.astype(np.float64)
    for r in rng.choice(db.base.size, 200, replace=False):
        s, a, b = unit[db.main[r]], unit[db.n_i[r]], unit[db.n_j[r]]
        base, height, _ = triangle_features(s, a, b)
        assert db.base[r] == pytest.approx(base, abs=2e-6)
        assert db.height[r] == pytest.approx(height, abs=2e-6)
        assert db.d_min_chord <= chord(s, a) <= db.pattern_radius_chord + 1e-6
        assert db.d_min_chord <= chord(s, b) <= db.pattern_radius_chord + 1e-6
        assert base >= db.d_min_chord - 1e-6


def test_neighbours_are_the_brightest(algo, db, catalog):
    """Star by star, the triangle vertices are exactly the lambda brightest stars in [D_min, PR]."""
    unit = db.unit_icrs.astype(np.float64)
    vmag = catalog.v_mag[catalog.index_of(db.hip)]
    rng = np.random.default_rng(1)
    for s in rng.choice(db.hip.size, 30, replace=False):
        d = np.linalg.norm(unit - unit[s], axis=1)
        ring = np.flatnonzero((d >= db.d_min_chord) & (d <= db.pattern_radius_chord))
        ring = ring[np.lexsort((db.hip[ring], vmag[ring]))][:algo.n_neighbours]
        expected = {tuple(sorted(p)) for p in combinations(ring.tolist(), 2)
                    if chord(unit[p[0]], unit[p[1]]) >= db.d_min_chord}
        got = {tuple(sorted((int(i), int(j)))) for i, j in zip(db.n_i[db.main == s], db.n_j[db.main == s], strict=True)}
        assert got == expected


def test_grid_cell_changes_index_not_answers(catalog, camera, noisy_sim):
    fine, coarse = TriangleVoting(), TriangleVoting(grid_cell_tol=2.5)
    db_f, db_c = fine.build(catalog, camera), coarse.build(catalog, camera)
    assert db_c.cell_start.size < db_f.cell_start.size
    for t in range(40):
        obs = noisy_sim.observation(t)
        assert np.array_equal(fine.identify(db_f, obs).hip, coarse.identify(db_c, obs).hip)


# -- identification contract -----------------------------------------------------------------

def test_small_inputs(algo, db, catalog, camera):
    for n in range(4):
        obs = Observation(np.linspace(100, 900, n), np.linspace(200, 800, n), np.full(n, 4.0), camera)
        res = check_identification(algo.identify(db, obs), n, catalog.hip)
        assert np.all(res.hip == -1)


def test_hand_built_image(algo, db, catalog, camera):
    """Project the guide stars around a chosen boresight exactly: every guide star is found."""
    from starid.attitude import random_attitude

    A = random_attitude(np.random.default_rng(3))
    v = catalog.unit_icrs @ A.T
    x, y = camera.project(np.where(v[:, 2:] > 0, v, np.array([0, 0, 1.0])))
    keep = (v[:, 2] > 0) & camera.in_image(x, y) & (catalog.v_mag <= 6.0)
    assert keep.sum() >= 6
    obs = Observation(x[keep], y[keep], catalog.v_mag[keep], camera, catalog.hip[keep])
    res = TriangleVoting(assign_all=False).identify(db, obs).hip
    in_db = np.isin(obs.truth_hip, db.hip)
    assert np.all((res == -1) | (res == obs.truth_hip))
    assert np.all(res[in_db] == obs.truth_hip[in_db])


def test_order_invariance_and_determinism(algo, db, catalog, noisy_sim):
    rng = np.random.default_rng(5)
    for t in range(25):
        obs = noisy_sim.observation(t)
        ref = algo.identify(db, obs).hip
        assert np.array_equal(ref, algo.identify(db, obs).hip)
        perm = rng.permutation(len(obs))
        assert np.array_equal(algo.identify(db, obs.permuted(perm)).hip, ref[perm])
        check_identification(algo.identify(db, obs), len(obs), catalog.hip)


def test_vote_scratch_is_left_zero(algo, db, catalog, noisy_sim):
    """The vote counters kept between images (reset through the touched list) are all zero after
    every call, and an image's answer does not depend on the images identified before it."""
    from starid_algorithms.triangle_voting.algorithm import _scratch

    obs = [noisy_sim.observation(t) for t in range(12)]
    first = [algo.identify(db, o).hip for o in obs]
    votes, mark = _scratch(db, 1)
    assert votes.shape[1] == mark.shape[1] == db.unit_icrs.shape[0]
    assert not votes.any() and not mark.any()
    for o, ref in zip(reversed(obs), reversed(first), strict=True):
        assert np.array_equal(algo.identify(db, o).hip, ref)
        assert not votes.any() and not mark.any()


def test_work_counters(algo, db, noisy_sim):
    """Counters of the voting: image triangles looked up, records scanned >= records in both windows
    >= records whose sides matched too; deterministic and independent of the star order."""
    from starid_algorithms.triangle_voting.kernels import WORK_COUNTERS

    obs = noisy_sim.observation(3)
    c = algo.identify(db, obs).counters
    assert tuple(c) == WORK_COUNTERS
    assert c["triangles"] > 0 and c["records"] >= c["matches"] >= c["side_matches"] > 0
    assert algo.identify(db, obs.permuted(np.arange(len(obs))[::-1])).counters == c


# -- identification rates (thresholds well below the measured values) -----------------------

def test_noise_free_rate(algo, db, catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(), seed=21)
    trials = sim.generate(300)
    s = summarize(score(Prepared(algo, algo.name, db, 0.0, 0.0), trials, catalog)).iloc[0]
    assert s.id_rate >= 0.97  # measured 1.0 on these 300 (0.997 on 2,000, seed 1): margin 0.03
    assert s.misid_rate <= 0.01  # measured 0 on these 300
    assert s.error_rate == 0


def test_noisy_rate_with_false_stars(algo, db, catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5, false_stars=3), seed=22)
    trials = sim.generate(300)
    s = summarize(score(Prepared(algo, algo.name, db, 0.0, 0.0), trials, catalog)).iloc[0]
    assert s.id_rate >= 0.85  # measured 0.97 on these 300 (0.92 on 2,000, seed 1): margin 0.12
    assert s.misid_rate <= 0.02  # measured 0.0067 on these 300


def test_extensions_help(catalog, camera):
    """Neighbour votes and the single-triangle fallback each raise the rate under noise."""
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=23)
    trials = sim.generate(200)
    rates = {}
    for label, kw in {"full": {}, "no_neighbour_votes": {"vote_neighbours": False},
                      "no_fallback": {"max_hypotheses": 0}}.items():
        algo = TriangleVoting(**kw)
        rates[label] = summarize(run([algo], trials, catalog, sim)).iloc[0].id_rate
    assert rates["full"] > rates["no_neighbour_votes"]
    assert rates["full"] > rates["no_fallback"]



def test_sigma_px_follows_the_simulator_with_a_1px_floor():
    assert_sigma_follows_with_1px_floor(TriangleVoting)


# --- explain --------------------------------------------------------------------------------

def test_explain_draws_its_reasoning(db, catalog, camera):
    assert_explain_draws_triangles(TriangleVoting(), db, catalog, camera)


def test_close_pairs_on_coarse_pixels_are_not_swapped(catalog):
    """Luo et al.'s camera (71 arcsec pixels) at 2 px of noise: the 8.5 px window cannot separate two
    stars 3-6 px apart, and the triangles swapped such a pair in image 7 of seed 7. An id with two
    catalog stars bright enough to be it predicted within the window is no longer reported: none
    of these 20 images has a wrong id (before: 1), and no image loses its identification."""
    from starid import Camera
    wide = Camera.from_fov(20.0, 1024)
    sim = Simulator(catalog, wide, SimConfig(sigma_px=2.0, mag_limit=6.5, sky_mag_limit=6.5, min_stars=3), seed=7)
    algo = TriangleVoting(sigma_px=2.0)
    db = algo.build(catalog, wide)
    n_ok = 0
    for t in range(20):
        obs = sim.observation(t)
        hip = algo.identify(db, obs).hip
        assert not np.any((hip >= 0) & (hip != obs.truth_hip)), t
        n_ok += int(np.sum(hip >= 0) >= 3)
    assert n_ok == 20
