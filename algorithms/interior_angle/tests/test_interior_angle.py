"""Interior-angle-specific tests: the trio query against a numpy oracle, noisy accuracy, Galvizo & Lim's reading.

Conformance (random fields, coincident stars, ids beyond 2^31, explain, determinism, order
invariance, read-only input) runs for every plugin in tests/test_conformance.py and is not repeated.
"""

import dataclasses

import numpy as np
import pytest
from starid_algorithms.interior_angle import GALVIZO2018, InteriorAngle
from starid_algorithms.interior_angle.kernels import angle_at, interior_angle, nearest_two, trio_query
from starid_algorithms.pyramid.kernels import select_stars
from starid_algorithms.pyramid.testing import noisy_results

from starid import ConfigError, SimConfig, Simulator
from starid.kernels import backproject_px


@pytest.fixture(scope="module")
def algo(catalog, camera):
    return InteriorAngle(sigma_px=1.0).derived(catalog, camera)


@pytest.fixture(scope="module")
def db(algo, catalog, camera):
    return algo.build(catalog, camera)


def _phi(u, c, i, j):
    """Interior angle at u[c] by projecting onto its tangent plane (numpy)."""
    a = u[i] - np.dot(u[i], u[c]) * u[c]
    b = u[j] - np.dot(u[j], u[c]) * u[c]
    return np.arccos(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))


def test_interior_angle_matches_tangent_plane():
    rng = np.random.default_rng(2)
    u = rng.normal(size=(30, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    for c, i, j in rng.integers(0, 30, (40, 3)):
        if len({c, i, j}) == 3:
            assert interior_angle(u, c, i, j) == pytest.approx(_phi(u, c, i, j), abs=1e-9)
            assert angle_at(*u[c], *u[i], *u[j]) == pytest.approx(_phi(u, c, i, j), abs=1e-9)


def test_trio_query_matches_brute_force(algo, db, catalog, camera):
    """The k-vector + partner-list query returns exactly the brute-force permutation-table matches."""
    trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(), seed=4).generate(1)
    unit = db.guide_unit.astype(np.float64)
    tol = algo.tolerances(camera, db)._replace(chirality=False, ordered=True, eps_phi=np.radians(0.05))
    where = {int(h): r for r, h in enumerate(db.guide_hip)}
    for t in range(1):
        obs = trials.observation(t)
        v = backproject_px(obs.x_px, obs.y_px, camera.f_px, camera.cx_px, camera.cy_px)
        sel = select_stars(obs.x_px, obs.y_px, obs.mag, v, 0.0, 12)
        k1, k2 = nearest_two(v, sel, 0)
        sc, s1, s2 = sel[0], sel[k1], sel[k2]
        out = np.empty((512, 3), dtype=np.int64)
        n = trio_query(v, sc, s1, s2, db.kv, db.pairs, db.nbr, db.nbr_chord, db.nbr_start, db.guide_unit, tol, out)
        got = {tuple(r) for r in out[:n]}
        t1, t2 = np.linalg.norm(v[sc] - v[s1]), np.linalg.norm(v[sc] - v[s2])
        phi = _phi(v, sc, s1, s2)
        expect = set()
        for big_c in range(unit.shape[0]):
            d = np.linalg.norm(unit - unit[big_c], axis=1)
            ones = np.flatnonzero(np.abs(d - t1) <= tol.eps)
            twos = np.flatnonzero(np.abs(d - t2) <= tol.eps)
            for big_1 in ones:
                for big_2 in twos:
                    if big_1 == big_2 or d[big_1] >= d[big_2]:
                        continue
                    if abs(_phi(unit, big_c, big_1, big_2) - phi) <= tol.eps_phi:
                        expect.add((big_c, big_1, big_2))
        assert got == expect
        truth = tuple(where.get(int(obs.truth_hip[s]), -1) for s in (sc, s1, s2))
        assert -1 in truth or truth in got


def test_work_counters(algo, db, catalog, camera):
    """Identification.counters against a recount in Python: the central stars tried up to the one
    accepted, one query each, the trios the queries return (re-run one by one), and the first query's
    |R| and whether its R holds the trio the image is named as."""
    trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(), seed=9).generate(4)
    tol = algo.tolerances(camera, db)
    out = np.empty((max(tol.max_candidates, 1), 3), dtype=np.int64)
    where = {int(h): r for r, h in enumerate(db.guide_hip)}
    for t in range(4):
        obs = trials.observation(t)
        c = algo.identify(db, obs).counters
        rows, trio, work = algo._run(db, obs)
        assert list(c.values()) == work.tolist()
        v = backproject_px(obs.x_px, obs.y_px, camera.f_px, camera.cx_px, camera.cy_px)
        sel = select_stars(obs.x_px, obs.y_px, obs.mag, v, tol.d_min, tol.max_stars)
        assert trio[0] >= 0                                       # noise-free: identified
        centre = int(np.flatnonzero(sel == trio[0])[0])
        assert c["centres"] == c["queries"] == centre + 1
        counts = []
        for k in range(centre + 1):
            k1, k2 = nearest_two(v, sel, k)
            counts.append(max(trio_query(v, sel[k], sel[k1], sel[k2], db.kv, db.pairs, db.nbr, db.nbr_chord,
                                         db.nbr_start, db.guide_unit, tol, out), 0))
        assert c["candidates"] == sum(counts) and c["first_R"] == counts[0]
        assert 1 <= c["confirms"] <= c["candidates"]
        k1, k2 = nearest_two(v, sel, 0)
        first = (sel[0], sel[k1], sel[k2])
        named = all(rows[s] >= 0 for s in first)
        assert c["first_named"] == int(named)
        truth = tuple(where.get(int(obs.truth_hip[s]), -1) for s in first)
        if named:
            n = trio_query(v, *first, db.kv, db.pairs, db.nbr, db.nbr_chord, db.nbr_start, db.guide_unit, tol, out)
            assert c["first_in_R"] == int(truth in {tuple(r) for r in out[:max(n, 0)]})
    strict = dataclasses.replace(algo, max_centres=1)
    assert strict.identify(db, trials.observation(0)).counters["centres"] == 1


def test_noisy_paper_sky_identified_without_misidentification(algo, db, catalog, camera):
    results = noisy_results(algo, db, catalog, camera, 30, seed=21)      # asserts: no star misidentified
    assert sum(bool((r.hip >= 0).any()) for _, r, _ in results) >= 27


def test_galvizo_reading(catalog, camera):
    """The paper's reading (|R| = 1, no verification) identifies noise-free images."""
    assert InteriorAngle.published == GALVIZO2018
    assert InteriorAngle.published_readings == {"galvizo2018": GALVIZO2018}
    reading = InteriorAngle(**GALVIZO2018).derived(catalog, camera)
    db = reading.build(catalog, camera)
    trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(), seed=5).generate(10)
    ok = 0
    for t in range(10):
        obs = trials.observation(t)
        hip = reading.identify(db, obs).hip
        found = hip >= 0
        ok += bool(found.any()) and bool(np.all(hip[found] == obs.truth_hip[found]))
    assert ok >= 8


@pytest.mark.parametrize("bad", [{"beta": 0.0}, {"max_centres": 0}, {"max_candidates": 0}, {"min_extra": -1},
                                 {"sigma_phi_deg": 0.0}, {"unique": 1}])
def test_bad_parameters(bad):
    with pytest.raises(ConfigError):
        dataclasses.replace(InteriorAngle(), **bad)


def test_a_refused_pairing_is_recognised_in_any_star_order():
    """``seen_before`` keys a pairing star -> row independently of the order of its three stars, and
    tells a different pairing of the same stars and rows apart."""
    from starid_algorithms.interior_angle.kernels import remember, seen_before

    failed = np.empty((4, 6), dtype=np.int64)
    n = remember(np.array([7, 2, 5]), np.array([70, 20, 50]), failed, np.int64(0))
    assert n == 1
    for perm in ([0, 1, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]):
        assert seen_before(np.array([7, 2, 5])[perm], np.array([70, 20, 50])[perm], failed, np.int64(n))
    assert not seen_before(np.array([7, 2, 5]), np.array([20, 70, 50]), failed, np.int64(n))
    assert not seen_before(np.array([7, 2, 5]), np.array([70, 20, 50]), failed, np.int64(0))
