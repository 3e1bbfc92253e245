"""Composite Pyramid tests: the fourth-star test against an oracle, noisy accuracy, the Galvizo & Lim
reading, explain, parameters. The shared triangle kernels are tested in spherical_triangle's tests;
conformance runs in tests/test_conformance.py."""

import numpy as np
import pytest
from starid_algorithms.composite_pyramid import GALVIZO2018, CompositePyramid
from starid_algorithms.composite_pyramid.kernels import composite_kernel, fourth_star
from starid_algorithms.pyramid.testing import noisy_results
from starid_algorithms.spherical_triangle.testing import first_single_query

from starid import ConfigError, SimConfig, Simulator
from starid.kernels import camera_frame
from starid.kernels import triangles as T


@pytest.fixture(scope="module")
def algo():
    return CompositePyramid()


@pytest.fixture(scope="module")
def db(algo, catalog, camera):
    return algo.build(catalog, camera)


def test_planar_database(db):
    idx = db.index
    r = db.guide_unit[idx.stars[:50].astype(np.int64)]
    area = 0.5 * np.linalg.norm(np.cross(r[:, 1] - r[:, 0], r[:, 2] - r[:, 0]), axis=1)
    sides2 = sum(np.sum((r[:, a] - r[:, b]) ** 2, axis=1) for a, b in ((0, 1), (0, 2), (1, 2)))
    assert np.allclose(idx.area[:50], area, rtol=1e-9) and np.allclose(idx.moment[:50], area * sides2 / 36, rtol=1e-9)


def test_fourth_star_oracle():
    """E is returned only when exactly one star completes a candidate pair in all three query results."""
    stars = np.array([[0, 1, 7], [0, 2, 7], [1, 2, 7], [0, 1, 8], [0, 2, 8], [3, 4, 9]], dtype=np.uint16)
    cat = np.array([0, 1, 2], dtype=np.int64)
    buf = np.empty(16, dtype=np.int64)
    hits = np.array([[0, 3, 5], [1, 4, 5], [2, 5, 5]], dtype=np.int64)
    assert fourth_star(stars, hits, np.array([3, 3, 2]), cat, buf) == 7      # 8 misses the (1, 2) query
    stars[5] = [1, 2, 8]
    assert fourth_star(stars, hits, np.array([3, 3, 2]), cat, buf) == -1     # 7 and 8 both complete all three
    assert fourth_star(stars, hits, np.array([3, 3, 0]), cat, buf) == -1


def test_noisy_trials_and_mortari_order(algo, db, catalog, camera):
    results = noisy_results(algo.resolved(SimConfig(sigma_px=1.0)), db, catalog, camera, 30)
    assert sum((r.hip >= 0).any() for _, r, _ in results) >= 28
    obs = results[0][0]
    tol = algo.resolved(SimConfig(sigma_px=1.0)).tolerances(camera, db)
    rows, _, four, work = composite_kernel(obs.x_px, obs.y_px, obs.mag, db.index, db.guide_unit, tol,
                                           camera_frame(camera))
    assert work[0] >= 1 and np.all(four >= 0) and len(set(four.tolist())) == 4
    assert np.all(rows[four[:3]] >= 0)


def test_galvizo_reading(catalog, camera, db):
    reading = CompositePyramid(**{**GALVIZO2018, "max_stars": 12, "max_trios": 300})
    assert CompositePyramid.published_readings == {"galvizo2018": CompositePyramid.published}
    tol = reading.tolerances(camera, db)
    assert tol.fixed_area == pytest.approx(3e-9) and tol.unique and tol.fourth_tries == 1 and tol.min_extra == 0
    trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(), seed=5).generate(10)
    ok = 0
    for t in range(10):
        obs = trials.observation(t)
        hip = reading.identify(db, obs).hip
        ok += bool((hip >= 0).any() and np.all(hip[hip >= 0] == obs.truth_hip[hip >= 0]))
    assert ok >= 8
    # with 1 px of noise the 3e-9 windows miss the true triangles: nothing is identified
    noisy = Simulator(catalog.brighter_than(6.0), camera, SimConfig(sigma_px=1.0), seed=5).generate(5)
    assert all((reading.identify(db, noisy.observation(t)).hip < 0).all() for t in range(5))


def test_explain(algo, db, catalog, camera):
    obs = Simulator(catalog.brighter_than(6.0), camera, SimConfig(), seed=6).generate(1).observation(0)
    ex = algo.explain(db, obs)
    assert len(ex.polygons) == 1 and ex.segments.shape == (3, 2, 2) and "matched" in ex.caption
    assert sum(label.startswith("4th: HIP") for label in ex.labels) == 1


@pytest.mark.parametrize("kwargs", [{"fourth_tries": 0}, {"beta": -1.0}, {"sigma_moment": 0.0}, {"max_stars": 3},
                                    {"unique_candidate": "yes"}, {"min_area_fov2": 2.0}])
def test_invalid_parameters(kwargs):
    with pytest.raises(ConfigError):
        CompositePyramid(**kwargs)


def test_shares_the_planar_features(db):
    r = db.guide_unit[db.index.stars[7].astype(np.int64)]
    assert T.tri_features(r[0], r[1], r[2], T.PLANAR, 1) == pytest.approx((db.index.area[7], db.index.moment[7]))


def test_default_on_the_galvizo2018_camera(catalog):
    """Regression: on the 17.7 deg, V <= 6 camera of ``starid reproduce galvizo2018`` (10.2 M stored
    triangles) the fixed max_hits = 50,000 skipped nearly every area window (0.01 identified); the
    default bound now follows the database size."""
    from starid import Camera
    from starid.experiments.galvizo2018 import CAMERA, SIM

    cam = Camera.from_fov(**CAMERA)
    config = SimConfig(**SIM)
    algo = CompositePyramid().resolved(config)
    db = algo.build(catalog, cam)
    trials = Simulator(catalog.brighter_than(SIM["sky_mag_limit"]), cam, config, seed=31).generate(40)
    ok = 0
    for t in range(40):
        obs = trials.observation(t)
        hip = algo.identify(db, obs).hip
        assert np.all(hip[hip >= 0] == obs.truth_hip[hip >= 0])
        ok += int((hip >= 0).any())
    assert ok >= 38


def test_to_r_counts_trio_queries_in_mortari_order(catalog, camera, db):
    """``to_r``: the trio queries, in Mortari's order, up to the first whose R has one member (no
    fourth-star query comes before it: those follow a single candidate), recounted in Python; every
    query made when none has."""
    def mortari(m):
        return [(i, i + dj, i + dj + dk) for dj in range(1, m - 1) for dk in range(1, m - dj)
                for i in range(0, m - dj - dk)]

    reading = CompositePyramid(**{**GALVIZO2018, "max_stars": 8, "max_trios": 300})
    for sigma, seed in ((0.0, 5), (1.0, 6)):
        trials = Simulator(catalog.brighter_than(6.0), camera, SimConfig(sigma_px=sigma), seed=seed).generate(6)
        for t in range(6):
            obs = trials.observation(t)
            c = reading.identify(db, obs).counters
            first = first_single_query(reading, db, obs, mortari)
            assert c["to_r"] == (first if first else c["queries"])


def test_packed_params_rebuild_the_tuples(algo, db, camera):
    """The kernel's one float64 argument rebuilds the tolerances and frame identify used to pass."""
    from starid_algorithms.composite_pyramid.kernels import params_com
    from starid_algorithms.spherical_triangle.kernels import packed_params

    from starid.kernels.params import frame_at

    for reading in (algo, CompositePyramid(**GALVIZO2018)):
        tol, frame = reading.tolerances(camera, db), camera_frame(camera)
        p = packed_params(tol, frame)
        assert frame_at.py_func(p, 0) == frame and params_com.py_func(p) == tol
        for a, b in zip(params_com.py_func(p), tol, strict=True):
            assert isinstance(a, (bool, np.bool_)) == isinstance(b, bool)
        assert reading.kernel_args(db, camera) is reading.kernel_args(db, camera)    # kept, not rebuilt
