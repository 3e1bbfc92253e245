"""Angle-specific tests: the direct-match test against a numpy oracle, noisy accuracy, Galvizo & Lim's reading.

Conformance (random fields, coincident stars, ids beyond 2^31, explain, determinism, order
invariance, read-only input) runs for every plugin in tests/test_conformance.py and is not repeated.
"""

import dataclasses

import numpy as np
import pytest
from starid_algorithms.angle import GALVIZO2018, Angle
from starid_algorithms.angle.kernels import support
from starid_algorithms.pyramid.kernels import select_stars
from starid_algorithms.pyramid.testing import noisy_results

from starid import ConfigError, SimConfig, Simulator
from starid.kernels import backproject_px, kvector_query


@pytest.fixture(scope="module")
def algo(catalog, camera):
    return Angle(sigma_px=1.0).derived(catalog, camera)


@pytest.fixture(scope="module")
def db(algo, catalog, camera):
    return algo.build(catalog, camera)


def _rows(db, obs):
    """Guide row of each detection from its true id (-1: not a guide star)."""
    where = {int(h): r for r, h in enumerate(db.guide_hip)}
    return np.array([where.get(int(h), -1) for h in obs.truth_hip])


def _support_oracle(v, sel, a, b, big_i, big_j, unit, eps, n_check):
    """Stars among the next ``n_check`` with some guide star at both distances and the same handedness."""
    others = [k for k in range(len(sel)) if k not in (a, b)][:n_check]
    count = 0
    for k in others:
        ci = np.linalg.norm(v[sel[a]] - v[sel[k]])
        cj = np.linalg.norm(v[sel[b]] - v[sel[k]])
        di = np.linalg.norm(unit - unit[big_i], axis=1)
        dj = np.linalg.norm(unit - unit[big_j], axis=1)
        t = np.linalg.det(np.stack([v[sel[a]], v[sel[b]], v[sel[k]]]))
        tk = np.linalg.det(np.stack([np.broadcast_to(unit[big_i], unit.shape), np.broadcast_to(unit[big_j], unit.shape),
                                     unit], axis=1))
        ok = (np.abs(di - ci) <= eps) & (np.abs(dj - cj) <= eps) & (tk * t > 0) & (di > 0) & (dj > 0)
        count += bool(ok.any())
    return count


def test_support_matches_oracle(algo, db, catalog, camera):
    """The direct-match test counts what the brute-force overlay test counts, for the true pairing,
    its mirror (the other orientation) and random pairings."""
    trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(), seed=3).generate(3)
    unit = db.guide_unit.astype(np.float64)
    eps = algo.tolerances(camera, db).eps
    rng = np.random.default_rng(1)
    for t in range(3):
        obs = trials.observation(t)
        v = backproject_px(obs.x_px, obs.y_px, camera.f_px, camera.cx_px, camera.cy_px)
        sel = select_stars(obs.x_px, obs.y_px, obs.mag, v, 0.0, 12)
        rows = _rows(db, obs)
        true_i, true_j = rows[sel[0]], rows[sel[1]]
        cases = [(true_i, true_j), (true_j, true_i)] + [tuple(rng.integers(0, unit.shape[0], 2)) for _ in range(3)]
        for big_i, big_j in cases:
            got = support(v, sel, 0, 1, big_i, big_j, db.nbr, db.nbr_chord, db.nbr_start, db.guide_unit, eps, 8, -1,
                          True)
            assert got == _support_oracle(v, sel, 0, 1, big_i, big_j, unit, eps, 8)
        assert support(v, sel, 0, 1, true_i, true_j, db.nbr, db.nbr_chord, db.nbr_start, db.guide_unit, eps, 8, -1,
                       True) == min(8, len(sel) - 2)


def test_noisy_paper_sky_identified_without_misidentification(algo, db, catalog, camera):
    results = noisy_results(algo, db, catalog, camera, 30, seed=21)      # asserts: no star misidentified
    assert sum(bool((r.hip >= 0).any()) for _, r, _ in results) >= 28


def test_galvizo_reading_works_noise_free_only(catalog, camera):
    """hoku's fixed 3e-4 deg window and |R| = 1: every noise-free image, almost no 1 px image."""
    reading = Angle(**GALVIZO2018).derived(catalog, camera)
    assert Angle.published == GALVIZO2018 and Angle.published_readings == {"galvizo2018": GALVIZO2018}
    db = reading.build(catalog, camera)
    rates = []
    for sigma in (0.0, 1.0):
        trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(sigma_px=sigma), seed=5).generate(10)
        ok = 0
        for t in range(10):
            obs = trials.observation(t)
            hip = reading.identify(db, obs).hip
            found = hip >= 0
            assert np.all(hip[found] == obs.truth_hip[found]) or sigma > 0
            ok += bool(found.any()) and np.all(hip[found] == obs.truth_hip[found])
        rates.append(ok)
    assert rates[0] >= 9 and rates[1] <= 2


def test_work_counters(algo, db, catalog, camera):
    """Identification.counters against a recount in Python of the same image (the pair windows by
    k-vector), for hoku's test (compare, |R| = 1: one candidate per usable pair, two orientations each)
    and starid's; the first query's |R|, whether its R holds the pair the image is named as, and the
    pairs up to the first window of one catalog pair (to_r)."""
    trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(), seed=8).generate(4)
    hoku = dataclasses.replace(algo, **{k: GALVIZO2018[k] for k in (
        "sigma_query_deg", "sigma_overlay_deg", "unique_window", "compare", "n_check", "min_support", "chirality",
        "max_pairs", "confirm_fraction", "min_extra")})
    for reading in (hoku, algo):
        tol = reading.tolerances(camera, db)
        for t in range(4):
            obs = trials.observation(t)
            c = reading.identify(db, obs).counters
            rows, pair, work = reading._run(db, obs)
            assert list(c.values()) == work.tolist()
            v = backproject_px(obs.x_px, obs.y_px, camera.f_px, camera.cx_px, camera.cy_px)
            sel = select_stars(obs.x_px, obs.y_px, obs.mag, v, tol.d_min, tol.max_stars)
            m = len(sel)
            order = [(a, b) for a in range(m - 1) for b in range(a + 1, m)]

            def size(a, b, v=v, sel=sel, tol=tol):
                ch = np.linalg.norm(v[sel[a]] - v[sel[b]])
                if ch - tol.eps > tol.c_max:
                    return 0
                lo, hi = kvector_query(db.kv, ch - tol.eps, ch + tol.eps)
                return 0 if hi - lo > tol.max_window else hi - lo

            assert c["windows"] == m * (m - 1) // 2 and c["first_R"] == size(0, 1)
            ones = [k + 1 for k, ab in enumerate(order) if size(*ab) == 1]
            assert c["to_r"] == (ones[0] if ones else len(order))  # hoku's reduction: pairs to |R| = 1
            if pair[0] >= 0:
                a, b = (int(np.flatnonzero(sel == s)[0]) for s in pair)
                assert c["pairs"] == order.index((a, b)) + 1 and 1 <= c["confirms"] <= c["tests"]
            else:
                assert c["pairs"] == min(len(order), tol.max_pairs)
            if reading is hoku:
                assert c["candidates"] == sum(size(*ab) == 1 for ab in order[:c["pairs"]])
                assert c["tests"] == 2 * c["candidates"]
            true_rows = _rows(db, obs)
            assert np.array_equal(rows[rows >= 0], true_rows[rows >= 0])
            assert c["first_named"] == int(rows[sel[0]] >= 0 and rows[sel[1]] >= 0)
            assert c["first_in_R"] == int(c["first_named"] == 1 and c["first_R"] >= 1)
    one = dataclasses.replace(algo, max_pairs=1).identify(db, trials.observation(0)).counters
    assert one["pairs"] == 1
    empty = Angle().identify(db, dataclasses.replace(trials.observation(0), x_px=np.zeros(1), y_px=np.zeros(1),
                                                     mag=np.zeros(1), truth_hip=None)).counters
    assert set(empty.values()) == {0}


@pytest.mark.parametrize("bad", [{"beta": 0.0}, {"max_pairs": 0}, {"min_support": -1}, {"confirm_fraction": 2.0},
                                 {"sigma_query_deg": -1.0}, {"compare": "yes"}])
def test_bad_parameters(bad):
    with pytest.raises(ConfigError):
        dataclasses.replace(Angle(), **bad)
