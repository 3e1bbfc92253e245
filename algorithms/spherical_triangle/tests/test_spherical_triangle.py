"""Spherical-triangle tests: the shared triangle kernels against oracles, the database, noisy accuracy,
the Galvizo & Lim reading, explain, parameters. Conformance runs in tests/test_conformance.py."""

import math

import numpy as np
import pytest
from starid_algorithms.pyramid.testing import noisy_results
from starid_algorithms.spherical_triangle import GALVIZO2018, SphericalTriangle
from starid_algorithms.spherical_triangle.testing import first_single_query

from starid import ConfigError, SimConfig, Simulator
from starid.kernels import triangles as T


@pytest.fixture(scope="module")
def algo():
    return SphericalTriangle()


@pytest.fixture(scope="module")
def db(algo, catalog, camera):
    return algo.build(catalog, camera)


def _unit(rng, n, spread=0.05):
    r = rng.normal(size=(n, 3)) * spread + np.array([0.0, 0.0, 1.0])
    return r / np.linalg.norm(r, axis=1)[:, None]


def test_spherical_features_exact_and_order_free():
    octant = np.eye(3)
    for depth in (1, 3):
        area, _ = T.tri_features(octant[0], octant[1], octant[2], T.SPHERICAL, depth)
        assert area == pytest.approx(math.pi / 2, rel=1e-12)        # the octant: a quarter hemisphere
    r = _unit(np.random.default_rng(1), 3)
    a0, m0 = T.tri_features(r[0], r[1], r[2], T.SPHERICAL, 3)
    a1, m1 = T.tri_features(r[2], r[0], r[1], T.SPHERICAL, 3)
    assert (a0, m0) == pytest.approx((a1, m1), rel=1e-12)             # a partition: vertex order free
    # the sub-triangles partition the spherical triangle; the moment converges, to ~ the planar one
    moments = [T.tri_features(r[0], r[1], r[2], T.SPHERICAL, d)[1] for d in (2, 3, 4, 5)]
    assert np.all(np.diff(moments) > 0) and moments[-1] - moments[-2] < 0.3 * (moments[1] - moments[0])
    ap, mp = T.tri_features(r[0], r[1], r[2], T.PLANAR, 1)
    assert a0 == pytest.approx(ap, rel=1e-2) and moments[-1] == pytest.approx(mp, rel=1e-2)


def test_windows_cover_the_noise():
    """~99.7 % of the features of noisy copies fall inside the 3-sigma windows of the noise-free triangle."""
    rng = np.random.default_rng(2)
    sigma = 1e-4
    inside = total = 0
    for _ in range(40):
        r = _unit(rng, 3)
        a, m, ha, hm = T.tri_windows(r[0], r[1], r[2], T.SPHERICAL, 2, sigma, 3.0)
        for _ in range(25):
            noisy = r + rng.normal(size=(3, 3)) * sigma
            noisy /= np.linalg.norm(noisy, axis=1)[:, None]
            a2, m2 = T.tri_features(noisy[0], noisy[1], noisy[2], T.SPHERICAL, 2)
            inside += abs(a2 - a) <= ha and abs(m2 - m) <= hm
            total += 1
    assert inside / total > 0.97


def test_index_query_matches_brute_force(db):
    idx = db.index
    assert idx.stars.dtype == np.uint16 and np.all(np.diff(idx.kv.values) >= 0)
    assert np.all(idx.stars[:, 0] < idx.stars[:, 1]) and np.all(idx.stars[:, 1] < idx.stars[:, 2])
    blocks = idx.moment[: (idx.moment.size // T.BLOCK) * T.BLOCK].reshape(-1, T.BLOCK)
    assert np.all(np.diff(blocks, axis=1) >= 0)                        # moment-sorted within each block
    assert np.array_equal(np.sort(idx.area), idx.kv.values)
    rng = np.random.default_rng(3)
    out = np.empty(200_000, dtype=np.int64)
    no_sides = np.zeros(3)
    for _ in range(20):
        p = rng.integers(idx.area.size)
        a, m = idx.area[p], idx.moment[p]
        ha, hm = a * rng.uniform(1e-4, 3e-2), m * rng.uniform(1e-3, 1e-1)
        count = T.tri_query(idx, a - ha, a + ha, m - hm, m + hm, 10**7, False, db.guide_unit, no_sides, 0.0, out)
        want = np.flatnonzero((np.abs(idx.area - a) <= ha) & (np.abs(idx.moment - m) <= hm))
        assert count >= 1 and np.array_equal(np.sort(out[:count]), want)


def test_noise_free_and_noisy_trials(algo, db, catalog, camera):
    trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(), seed=4).generate(20)
    ok = 0
    for t in range(20):
        obs = trials.observation(t)
        hip = algo.identify(db, obs).hip
        assert np.all(hip[hip >= 0] == obs.truth_hip[hip >= 0])
        ok += int((hip >= 0).sum() >= 3)
    assert ok >= 19
    results = noisy_results(algo.resolved(SimConfig(sigma_px=1.0)), db, catalog, camera, 30)
    assert sum((r.hip >= 0).any() for _, r, _ in results) >= 28


def test_galvizo_reading_fixed_windows(catalog, camera, db):
    """Galvizo's reading: 3e-9 windows on area and moment, the pivot and |R| = 1; noise-free it still
    identifies (the same database: the reading's depth 3 would rebuild it, so depth 2 here)."""
    reading = SphericalTriangle(**{**GALVIZO2018, "moment_depth": 2, "max_stars": 12, "max_trios": 300})
    assert SphericalTriangle.published_readings["galvizo2018"] is SphericalTriangle.published
    tol = reading.tolerances(camera, db)
    assert tol.fixed_area == pytest.approx(3e-9) and tol.pivot and tol.unique and not tol.match_sides
    trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(), seed=5).generate(10)
    ok = 0
    for t in range(10):
        obs = trials.observation(t)
        hip = reading.identify(db, obs).hip
        ok += bool((hip >= 0).any() and np.all(hip[hip >= 0] == obs.truth_hip[hip >= 0]))
    assert ok >= 8


def test_explain_draws_the_triangle(algo, db, catalog, camera):
    obs = Simulator(catalog.brighter_than(6.0), camera, SimConfig(), seed=6).generate(1).observation(0)
    ex = algo.explain(db, obs)
    assert len(ex.polygons) == 1 and ex.segments.shape == (3, 2, 2) and ex.highlight.size == 3
    assert "matched" in ex.caption and len(ex.labels) == len(ex.points) >= 3


@pytest.mark.parametrize("kwargs", [{"moment_depth": 0}, {"beta": 0.0}, {"sigma_area": -1.0}, {"max_stars": 2},
                                    {"pivot": 1}, {"confirm_fraction": 2.0}])
def test_invalid_parameters(kwargs):
    with pytest.raises(ConfigError):
        SphericalTriangle(**kwargs)


def test_follows_the_simulator(camera, db):
    algo = SphericalTriangle().resolved(SimConfig(sigma_px=2.0))
    assert algo.sigma_px == 2.0
    assert algo.tolerances(camera, db).sigma_rad == pytest.approx(2.0 / camera.f_px)
    assert SphericalTriangle(sigma_px=0.1).tolerances(camera, db).sigma_rad == pytest.approx(1.0 / camera.f_px)


def test_max_hits_follows_the_database(algo, db, camera):
    """The area-window bound is a fraction of the stored triangles (the windows hold a fixed fraction of
    the database whatever the field): on the 17.7 deg galvizo2018 camera (10.1 M triangles) a fixed
    50,000 skipped nearly every window (default 0.33 noise-free); Table 6's camera keeps 50,000."""
    from types import SimpleNamespace

    from starid_algorithms.spherical_triangle.algorithm import MAX_HITS_FLOOR, max_hits_for

    assert algo.tolerances(camera, db).max_hits == MAX_HITS_FLOOR          # Table 6 unchanged
    wide = SimpleNamespace(index=SimpleNamespace(area=np.empty(10_102_663)), fov_db_deg=17.7, d_min_deg=0.1)
    assert max_hits_for(algo, wide) >= 400_000
    assert algo.tolerances(camera, wide).max_hits == max_hits_for(algo, wide)
    assert max_hits_for(SphericalTriangle(max_hits=500), wide) == 500


def naive_order(m):
    return [(i, j, k) for i in range(m) for j in range(i + 1, m) for k in range(j + 1, m)]


def test_to_r_counts_queries_to_the_first_single_candidate(catalog, camera, db):
    """``to_r`` (hoku's accesses to r) recounted: without the pivot, queries are trios in the naive
    order and to_r is the first whose R has one member, or every query made when none has (with 1 px of
    noise the 3e-9 windows rarely hold one). With the pivot it never exceeds the queries."""
    base = {**GALVIZO2018, "moment_depth": 2, "max_stars": 8, "max_trios": 300}
    plain = SphericalTriangle(**{**base, "pivot": False})
    pivot = SphericalTriangle(**base)
    none_single = 0
    for sigma, seed in ((0.0, 5), (1.0, 6)):
        trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(sigma_px=sigma), seed=seed).generate(6)
        for t in range(6):
            obs = trials.observation(t)
            c = plain.identify(db, obs).counters
            first = first_single_query(plain, db, obs, naive_order)
            assert c["queries"] == c["trios"]
            assert c["to_r"] == (first if first else c["queries"])
            none_single += first == 0
            cp = pivot.identify(db, obs).counters
            assert 1 <= cp["to_r"] <= cp["queries"]
    assert none_single > 0  # the fallback (every query made) was exercised


def test_packed_params_rebuild_the_tuples(algo, db, camera):
    """The kernel's one float64 argument rebuilds the tolerances and frame identify used to pass: the same
    values, and ints and flags of the same kinds (so the kernels see one signature)."""
    from starid_algorithms.spherical_triangle.kernels import packed_params, params_sph

    from starid.kernels import camera_frame
    from starid.kernels.params import frame_at
    for reading in (algo, SphericalTriangle(**GALVIZO2018)):
        tol, frame = reading.tolerances(camera, db), camera_frame(camera)
        p = packed_params(tol, frame)
        assert frame_at.py_func(p, 0) == frame and params_sph.py_func(p) == tol
        for a, b in zip(params_sph.py_func(p), tol, strict=True):
            assert isinstance(a, (bool, np.bool_)) == isinstance(b, bool)
        assert reading.kernel_args(db, camera) is reading.kernel_args(db, camera)    # kept, not rebuilt
