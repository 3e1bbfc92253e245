"""Geometric-voting-specific tests: voting against a numpy oracle, shortlist, noisy accuracy, explain, variants.

Conformance (random fields, coincident stars, ids beyond 2^31, explain's type, determinism, order
invariance) runs for every plugin in tests/test_conformance.py; helpers shared with the pyramid
tests come from ``starid_algorithms.pyramid.testing``.
"""

import dataclasses

import numpy as np
import pytest
from starid_algorithms.geometric_voting import GeometricVoting
from starid_algorithms.geometric_voting.kernels import cast_votes, pick_candidates, vote
from starid_algorithms.pyramid.kernels import pair_windows, select_stars
from starid_algorithms.pyramid.testing import noisy_results, wide_field_work

from starid import Camera, ConfigError, SimConfig, Simulator


@pytest.fixture(scope="module")
def algo():
    return GeometricVoting()


@pytest.fixture(scope="module")
def db(algo, catalog, camera):
    return algo.build(catalog, camera)


@pytest.fixture(scope="module")
def voted(algo, db, catalog, camera):
    obs = Simulator(catalog, camera, SimConfig(sigma_px=1.0), seed=6).observation(2)
    tol = algo.tolerances(camera, db)
    v = camera.backproject(obs.x_px, obs.y_px)
    sel = select_stars(obs.x_px, obs.y_px, obs.mag, v, tol.d_min, tol.max_stars)
    start, stop = pair_windows(v, sel, db.kv, tol)
    return obs, tol, v, sel, start, stop


@pytest.mark.parametrize("level", [0, 2, 4])
@pytest.mark.parametrize("once, expected, saturate", [(True, False, False), (False, False, False),
                                                      (True, True, False), (True, True, True)])
def test_votes_match_numpy_oracle(db, voted, once, expected, saturate, level):
    obs, tol, v, sel, start, stop = voted
    n_guide = db.guide_hip.size
    rows, got = vote(v, sel, start, stop, db.pairs, db.degree, tol, once, expected, 5, level, saturate)
    chords = db.kv.values.astype(np.float64)
    degree = np.bincount(db.pairs.astype(np.int64).ravel(), minlength=n_guide)
    assert np.array_equal(db.degree, degree)
    for a in range(len(sel)):
        votes = np.zeros(n_guide, dtype=np.int64)
        w = 0.0
        chance = np.zeros(n_guide)
        for b in range(len(sel)):
            if b != a:
                c = np.linalg.norm(v[sel[a]] - v[sel[b]])
                hit = (chords >= c - tol.eps) & (chords <= c + tol.eps)
                hits = db.pairs[hit].astype(np.int64).ravel()
                if once:
                    hits = np.unique(hits)
                np.add.at(votes, hits, 1)
                p = 4 * tol.eps * c / tol.c_max**2 if hit.any() else 0.0
                w += p
                chance += 1.0 - np.exp(-degree * p)
        score = votes - ((chance if saturate else w * degree) if expected else 0.0)
        score = np.where(votes > 0, score, -np.inf)
        order = np.lexsort((np.arange(n_guide), -score))[:5]          # best score, then lowest row
        assert np.array_equal(rows[a], order) and np.array_equal(got[a], votes[order])


@pytest.mark.parametrize("spare", [0, 1])
@pytest.mark.parametrize("once", [True, False])
def test_votes_in_rounds_add_up_to_one_round(db, voted, once, spare):
    """Casting the pairs of the first 5 stars, then those with a fainter star, gives the votes of one
    round of all, and the level lists hold exactly the stars that reached the level (with a spare
    column, as the kernels allocate them, the fainter stars list without a branch)."""
    obs, tol, v, sel, start, stop = voted
    m, n_guide = len(sel), db.guide_hip.size
    dtype = np.uint8 if once else np.int32

    def cast(rounds, level):
        tally, stamp = np.zeros((m, n_guide), dtype), np.zeros(n_guide, np.uint16)
        listed, n_listed = np.empty((m, n_guide + spare), db.pairs.dtype), np.zeros(m, np.int64)
        for lo, hi in rounds:
            cast_votes(start, stop, db.pairs, lo, hi, once, stamp, tally, level, listed, n_listed)
        return tally, listed, n_listed

    whole, _, _ = cast([(0, m)], 0)
    split, listed, n_listed = cast([(0, 5), (5, 9), (9, m)], 3)
    assert m >= 10 and whole.max() >= 3 and np.array_equal(whole, split)
    for a in range(m):
        assert sorted(listed[a, :n_listed[a]].tolist()) == np.flatnonzero(whole[a] >= 3).tolist()


def test_rounds_find_the_same_stars_as_one_round(algo, db, catalog, camera):
    trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=4).generate(20)
    single = GeometricVoting(round_voters=0)
    n_both = 0
    for t in range(len(trials)):
        obs = trials.observation(t)
        a, b = algo.identify(db, obs).hip, single.identify(db, obs).hip
        for hip in (a, b):
            assert np.all(hip[hip >= 0] == obs.truth_hip[hip >= 0])
        n_both += (a >= 0).sum() >= 3 and (b >= 0).sum() >= 3
    assert n_both >= 19


def test_shortlist_recovers_true_stars(db, voted):
    obs, tol, v, sel, start, stop = voted
    rows, got = vote(v, sel, start, stop, db.pairs, db.degree, tol, True, True, 16, 3)
    pick, _ = pick_candidates(v, sel, rows, got, db.guide_unit, tol.eps)
    truth = obs.truth_hip[sel]
    assert np.sum(db.guide_hip[pick] == truth) >= np.sum(db.guide_hip[rows[:, 0]] == truth)
    assert np.mean(db.guide_hip[pick] == truth) >= 0.9


def test_database_has_no_neighbour_lists_but_the_pairs(db):
    assert db.nbr.size == 0 and db.pairs.shape[0] > 100_000 and db.guide_hip.dtype == np.int64


def test_noisy_trials_no_misidentification(algo, db, catalog, camera):
    correct = 0
    for _, result, _ in noisy_results(algo, db, catalog, camera, 15):
        if np.sum(result.hip >= 0) >= 3:
            correct += 1
            assert result.attitude is not None
    assert correct >= 14        # measured 15 of 15; one spare


def test_wide_field_camera_search_stays_bounded(catalog):
    work, algo = wide_field_work(GeometricVoting, catalog)
    m = algo.max_stars
    assert 0 < work["rounds"] <= m and work["windows"] <= m * (m - 1) // 2   # only the max_stars brightest vote
    assert work["pairs"] <= algo.max_window * work["windows"]     # windows wider than max_window do not vote


def test_explain_shows_votes_and_verified_pairs(algo, db, catalog, camera):
    obs = Simulator(catalog, camera, SimConfig(sigma_px=1.0), seed=3).observation(1)
    ex = algo.explain(db, obs)
    hip = algo.identify(db, obs).hip
    k = int(np.sum(hip >= 0))
    assert k >= 3 and sum("HIP" in label for label in ex.labels) == k
    voted = sum("votes: HIP" in label for label in ex.labels)
    assert voted >= 3 and all("votes" in label or "reprojection" in label for label in ex.labels)
    assert len(ex.points) == len(ex.labels)
    assert voted - 1 <= len(ex.segments) <= voted * (voted - 1) // 2


def test_paper_literal_variant_runs(db, catalog, camera):
    obs = Simulator(catalog, camera, SimConfig(), seed=8).observation(0)
    hip = GeometricVoting(n_candidates=1, once_per_pair=False, expected_votes=False, round_voters=0,
                          report_all=False).identify(db, obs).hip
    assert np.all(hip[hip >= 0] == obs.truth_hip[hip >= 0])


@pytest.mark.parametrize("kwargs", [{"sigma_px": -1}, {"beta": 0}, {"max_stars": 2}, {"min_support": 0},
                                    {"min_fraction": 2}, {"n_candidates": 0}, {"once_per_pair": "yes"},
                                    {"min_extra": -1}, {"expected_votes": 0}, {"round_voters": -1},
                                    {"round_voters": 256}, {"max_stars": 256}, {"report_all": 1},
                                    {"round_step": 0}, {"saturate_votes": 1},
                                    {"vote_window_px": 0.0}, {"vote_window_px": -1.0}])
def test_invalid_parameters(kwargs):
    with pytest.raises(ConfigError):
        GeometricVoting(**kwargs)


def test_camera_derived_defaults_on_a_20_degree_camera(catalog, camera):
    """Luo et al.'s camera (20 deg, 1024 px, sky and detection V <= 6.5, noise-free): with the guide
    limit and double-star distance of the 10 deg camera (V <= 6.0, 0.05 deg) the chance votes bury the
    true stars and a voter 2.6-4.2 px from another detection cannot be confirmed: 5 of these 12
    images. Derived from the camera (V <= 5.07, 0.1008 deg = 5.1 px): all 12. The default camera
    keeps exactly 6.0 and 0.05."""
    wide = Camera.from_fov(20.0, 1024)
    algo = GeometricVoting()
    db = algo.build(catalog, wide)
    sim = Simulator(catalog, wide, SimConfig(mag_limit=6.5, sky_mag_limit=6.5, min_stars=3), seed=7)
    n_ok = 0
    for t in range(12):
        obs = sim.observation(t)
        hip = algo.identify(db, obs).hip
        assert np.all(hip[hip >= 0] == obs.truth_hip[hip >= 0])
        n_ok += int(np.sum(hip >= 0) >= 3)
    assert n_ok == 12
    assert 5.0 < db.mag_limit < 5.1 and db.d_min_deg == pytest.approx(0.05 * camera.f_px / wide.f_px)
    ref = algo.build(catalog, camera)
    assert ref.mag_limit == 6.0 and ref.d_min_deg == 0.05 and ref.guide_hip.size == 4966
    fixed = GeometricVoting(mag_limit=5.5, d_min_deg=0.02).build(catalog, wide)
    assert fixed.mag_limit == 5.5 and fixed.d_min_deg == 0.02


def test_saturating_chance_votes_at_2_px_on_a_20_degree_camera(catalog, camera):
    """Luo et al.'s camera at 2 px of centroid noise: eps doubles, a catalog star then gets a chance
    vote from most image pairs, and the linear expectation ``degree * w`` (more chance votes than
    there are image pairs for stars with many neighbours) ranks the true stars, which have a vote
    from nearly every pair, below chance stars with few neighbours: 8 of these 20 images failed.
    ``saturate_votes`` (derived: the guide stars, V <= 5.07, are fainter than the 4.47 the chance
    rule allows at this window) counts sum_b 1 - exp(-degree p_b) instead: all 20, none wrong. It
    stays off on the default camera at 1 px and noise-free (Table 4 unchanged), and at 1 px on this
    camera; the image's isolation radius is at least eps. Measured at the full eps window (the
    derived ``vote_window_px`` now narrows the voting windows at 2 px, after which both models
    identify most of these images)."""
    wide = Camera.from_fov(20.0, 1024)
    algo = GeometricVoting(sigma_px=2.0)
    settled = algo.derived(catalog, wide)
    assert settled.saturate_votes is True and 5.0 < settled.mag_limit < 5.1
    assert GeometricVoting(sigma_px=1.0).derived(catalog, wide).saturate_votes is False
    assert GeometricVoting().derived(catalog, camera).saturate_votes is False
    assert GeometricVoting(sigma_px=1.0).derived(catalog, camera).saturate_votes is False
    assert GeometricVoting(sigma_px=2.0).derived(catalog, camera).saturate_votes is True
    db = algo.build(catalog, wide)
    assert db.saturate_votes is True
    tol = algo.tolerances(wide, db)
    assert tol.d_min == tol.eps
    sim = Simulator(catalog, wide, SimConfig(sigma_px=2.0, mag_limit=6.5, sky_mag_limit=6.5, min_stars=3), seed=7)
    n_ok = {True: 0, False: 0}
    for t in range(20):
        obs = sim.observation(t)
        for saturate in (True, False):
            hip = dataclasses.replace(algo, saturate_votes=saturate,
                                      vote_window_px=tol.eps * wide.f_px).identify(db, obs).hip
            assert np.all(hip[hip >= 0] == obs.truth_hip[hip >= 0])
            n_ok[saturate] += int(np.sum(hip >= 0) >= 3)
    assert n_ok[True] == 20 and n_ok[False] <= 14       # measured 20 and 12


def test_voting_window_at_the_reference_chance_level_at_2_px(catalog, camera):
    """The default (Table 4) camera at 2 px of centroid noise and 0.5 Mv, every catalog star to V 8
    imaged: eps doubles to 8.5 px, a window holds about 2,000 catalog pairs and a catalog star gets
    a chance vote from about half of the image pairs, so the true stars fall out of the shortlists.
    The derived ``vote_window_px`` holds the voting windows at the reference chance level (4.24 px,
    the 1 px window); verification and reprojection keep the full eps. Of these 24 images: 20
    identified (17 with the full window), none wrong. At 1 px and noise-free the voting window is eps
    itself (Table 6 unchanged), on this camera and on a 20 deg one."""
    algo = GeometricVoting(sigma_px=2.0)
    db = algo.build(catalog, camera)
    tol = algo.tolerances(camera, db)
    assert db.vote_window_px == pytest.approx(3.0 * np.sqrt(2.0)) and tol.eps * camera.f_px == pytest.approx(
        6.0 * np.sqrt(2.0))
    wide = Camera.from_fov(20.0, 1024)
    for cam in (camera, wide):
        for sigma in (None, 1.0):
            settled = GeometricVoting(sigma_px=sigma).derived(catalog, cam)
            assert settled.vote_window_px == GeometricVoting(sigma_px=sigma).tolerances(
                cam, GeometricVoting(sigma_px=sigma).build(catalog, cam)).eps * cam.f_px
    full = dataclasses.replace(algo, vote_window_px=tol.eps * camera.f_px)
    sim = Simulator(catalog, camera, SimConfig(sigma_px=2.0, sigma_mag=0.5, sky_mag_limit=None), seed=7)
    n_ok = {"derived": 0, "full": 0}
    for t in range(24):
        obs = sim.observation(t)
        for key, a in (("derived", algo), ("full", full)):
            hip = a.identify(db, obs).hip
            assert np.all(hip[hip >= 0] == obs.truth_hip[hip >= 0])
            n_ok[key] += int(np.sum(hip >= 0) >= 3)
    assert n_ok["derived"] >= 19 and n_ok["full"] <= 17        # measured 20 and 17


def test_work_counters(algo, db, voted):
    """Counters: rounds voted, image pairs with a window, catalog pairs read; one round of all stars
    reads every pair's window once, and voting in rounds reads a subset of those pairs."""
    from starid_algorithms.geometric_voting.kernels import WORK_COUNTERS

    obs = voted[0]
    c = algo.identify(db, obs).counters
    assert tuple(c) == WORK_COUNTERS
    assert c["rounds"] >= 1 and c["pairs"] >= c["windows"] > 0
    one = GeometricVoting(round_voters=0).identify(db, obs).counters
    assert one["rounds"] == 1
    assert c["windows"] <= one["windows"] and c["pairs"] <= one["pairs"]   # rounds add pairs, never repeat them
