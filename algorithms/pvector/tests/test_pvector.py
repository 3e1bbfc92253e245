"""Tests of the P-vector plugin (algorithms/pvector).

The conformance checks (few stars, coincident stars, random fields, ids beyond 2^31, order,
determinism, explain, ...) run for every plugin in tests/test_conformance.py; here only what is
the P-vector's own. The catalog database does not depend on the camera, so every test shares one.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from starid_algorithms.pvector import PVector, PVectorDatabase
from starid_algorithms.pvector import kernels as K

from starid import Camera, Catalog, ConfigError, Observation, SimConfig, Simulator, run, summarize
from starid.kernels import assign_all, camera_frame, deep_sky, kvector_slice
from starid.plugin import Explanation, check_identification
from starid.registry import get_algorithm
from starid.testing import cost_ratio


@pytest.fixture(scope="module")
def algo():
    return PVector()


@pytest.fixture(scope="module")
def db(algo, catalog, camera):
    return algo.build(catalog, camera)


def _angle(a, b):
    return 2.0 * np.arcsin(np.minimum(1.0, 0.5 * np.linalg.norm(a - b, axis=-1)))


# ----------------------------------------------------------------------------- plugin basics
def test_registered_and_default_constructible():
    assert get_algorithm("pvector") is PVector
    algo = PVector()
    assert algo.name == "pvector"
    assert "Yang" in PVector.summary() and "2007" in PVector.summary()
    assert algo.params()["mag_limit"] == 6.0 and algo.params()["sigma_px"] is None


@pytest.mark.parametrize("kwargs", [
    dict(mag_limit=float("nan")), dict(mag_limit="6"), dict(sigma_px=-1.0),
    dict(sigma_px=float("inf")), dict(pattern_radius_deg=0.0), dict(pattern_radius_deg=95.0),
    dict(min_sep_deg=-0.1), dict(min_sep_deg=5.0, pattern_radius_deg=4.0), dict(beta=0.0),
    dict(k_min=-1), dict(k_min=1.5), dict(k_min=True), dict(side_order="perimeter"),
    dict(neighbour_rule="faintest"), dict(main_order="random"), dict(disc_inside_only=1),
    dict(max_stars=2), dict(max_candidates=0), dict(confirm_fraction=1.5),
    dict(hypotheses=-1), dict(image_neighbours=1), dict(check_min_stars=3), dict(check_fraction=-0.1),
    dict(check_mag_limit=float("nan")),
])
def test_parameter_validation(kwargs):
    with pytest.raises(ConfigError):
        PVector(**kwargs)


def test_sigma_px_follows_the_simulator_with_a_floor():
    assert PVector.follows == {"sigma_px": "sigma_px"}
    assert PVector().resolved(SimConfig(sigma_px=2.5))._tol.sigma_px == 2.5
    assert PVector(sigma_px=0.5).resolved(SimConfig(sigma_px=2.5)).sigma_px == 0.5    # pinned stays
    assert PVector()._tol.sigma_px == 1.0 and PVector(sigma_px=0.0)._tol.sigma_px == 1.0
    assert PVector().resolved(SimConfig())._tol.sigma_px == 1.0


def test_published_tolerance_is_the_papers_fixed_1px():
    """``pvector:paper`` keeps the 1 px windows whatever the simulated noise (Fig. 12's fall,
    docs/algorithms/pvector.md); at and below 1 px that is what following the noise gives."""
    paper = PVector(**PVector.published)
    assert paper.resolved(SimConfig(sigma_px=2.0))._tol.sigma_px == 1.0
    for noise in (0.0, 0.5, 1.0):
        assert paper.resolved(SimConfig(sigma_px=noise))._tol == dataclasses.replace(
            paper, sigma_px=None).resolved(SimConfig(sigma_px=noise))._tol


# ------------------------------------------------------------------------------- database
def test_database_invariants(algo, db, catalog):
    assert isinstance(db, PVectorDatabase)
    m = db.tri_sides.shape[0]
    guide = catalog.brighter_than(algo.mag_limit)
    n = len(guide)
    assert db.unit_icrs.shape == (n, 3) and db.unit_icrs.dtype == np.float32
    assert np.all(np.diff(db.unit_icrs[:, 2]) >= 0)  # z-sorted (declination bands)
    assert db.hip.dtype == np.int64 and np.array_equal(np.sort(db.hip), guide.hip)   # int64 ids end to end
    # K = 5: ten triangles per guide star with five neighbours, each star triple once (shared triples
    # are about a fifth: 47,957 -> 38,884)
    assert 7.5 * n < m <= 8.5 * n
    assert db.kv.values.size == 0          # the k-vector search does not store the keys
    assert db.key.dtype == np.float32 and np.all(np.diff(db.key) >= -4 * db.side_step_rad)  # from rounded sides
    assert db.kv.k.dtype == np.uint16 and db.kv.k.shape == (m,)     # m < 65,536
    assert db.tri_rows.dtype == np.int16 and db.tri_rows.shape == (m, 3)
    assert db.tri_sides.dtype == np.uint16 and db.tri_sides.shape == (m, 3)
    assert abs(np.linalg.norm(db.p_axis) - 1.0) < 1e-12 and db.p_axis.sum() > 0
    assert 0.5 < db.explained_variance <= 1.0
    # each main star appears once; the three stars of a triangle differ
    rows = db.tri_rows.astype(np.int64)
    assert np.unique(rows[:, 0]).size >= 0.9 * n and np.unique(np.sort(rows, axis=1), axis=0).shape[0] == m
    assert np.all((rows[:, 0] != rows[:, 1]) & (rows[:, 0] != rows[:, 2]) & (rows[:, 1] != rows[:, 2]))
    # the sides are the sorted angular distances, and the key is p . sides
    u = db.unit_icrs.astype(np.float64)
    s, n1, n2 = u[rows[:, 0]], u[rows[:, 1]], u[rows[:, 2]]
    sides = np.sort(np.stack([_angle(s, n1), _angle(s, n2), _angle(n1, n2)], axis=1), axis=1)
    assert db.side_step_rad * 65535 == pytest.approx(sides.max(), rel=1e-6)     # <= 2R: 3 urad, 0.02 px
    assert np.allclose(db.tri_sides * db.side_step_rad, sides, atol=db.side_step_rad / 2 + 2e-6)
    assert np.allclose(db.key, sides @ db.p_axis, atol=2 * db.side_step_rad)
    # neighbours lie between r_min and R
    r_min, r_max = math.radians(algo.min_sep_deg), math.radians(algo.pattern_radius_deg)
    for d in (_angle(s, n1), _angle(s, n2)):
        assert np.all((d >= r_min - 1e-6) & (d <= r_max + 1e-6))
    # K = 5, R = 5 deg (chosen on the real-sky rate, docs/algorithms/pvector.md): 0.77 MB with the
    # whole-image check's unit vectors (0.126 MB), against the paper's 0.537 MB (the 0.8 MB target)
    assert db.extra_unit.dtype == np.float32 and np.all(np.diff(db.extra_unit[:, 2]) >= 0)
    assert 0.7e6 < db.nbytes <= 0.8e6 and 0.12e6 < db.extra_unit.nbytes < 0.13e6


def test_linear_database_keeps_its_sorted_keys_and_the_slice_holds_every_match(db, catalog, camera):
    """search='linear' scans the stored keys (exact, ascending, p . sides); the k-vector search's
    untrimmed slice holds every key of the window, however the window falls."""
    lin = PVector(search="linear").build(catalog, camera)
    m = lin.tri_sides.shape[0]
    assert lin.kv.values.shape == (m,) and np.all(np.diff(lin.kv.values) >= 0)
    assert lin.nbytes == db.nbytes + 4 * m
    rng = np.random.default_rng(3)
    keys = lin.kv.values.astype(np.float64)
    for lo in rng.uniform(keys[0] - 0.01, keys[-1], 300):
        hi = lo + rng.uniform(0, 0.01)
        start, stop = kvector_slice(lin.kv.k, lin.kv.m, lin.kv.q, m, lo, hi)
        exact = np.searchsorted(keys, lo, "left"), np.searchsorted(keys, hi, "right")
        assert start <= exact[0] and exact[1] <= stop and stop - start <= exact[1] - exact[0] + 64


def test_each_star_triple_once_identifies_exactly_as_the_copies(catalog, camera):
    """unique_triangles drops the copies of a triple stored under its other main stars; with sorted
    sides identify tries every vertex correspondence, so the answers are the same (1 px / 0.5 Mv)."""
    once, copies = PVector(), PVector(unique_triangles=False)
    db_once, db_copies = once.build(catalog, camera), copies.build(catalog, camera)
    assert db_copies.tri_sides.shape[0] > 1.15 * db_once.tri_sides.shape[0]
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=5)   # the real sky
    for t in range(40):
        o = sim.observation(t)
        assert np.array_equal(once.identify(db_once, o).hip, copies.identify(db_copies, o).hip), t


def test_neighbours_are_among_the_k_brightest(algo, db, catalog):
    mag = dict(zip(catalog.hip.tolist(), catalog.v_mag.tolist(), strict=True))
    u = db.unit_icrs.astype(np.float64)
    v_mag = np.array([mag[int(h)] for h in db.hip])
    r_min, r_max = math.radians(algo.min_sep_deg), math.radians(algo.pattern_radius_deg)
    for t in range(0, db.key.size, 97):
        S, N1, N2 = (int(x) for x in db.tri_rows[t])
        d = _angle(u, u[S])
        nb = np.flatnonzero((d >= r_min) & (d <= r_max))
        nb = nb[nb != S]
        brightest = nb[np.lexsort((d[nb], v_mag[nb]))][:algo.triangles_per_star].tolist()
        assert N1 in brightest and N2 in brightest and brightest.index(N1) < brightest.index(N2)


# ------------------------------------------------------------------------ hand-made sky
def _small_sky():
    """A 40-star catalog around (ra, dec) = (40, 30) deg with distinct magnitudes."""
    rng = np.random.default_rng(7)
    ra = 40.0 + rng.uniform(-6, 6, 40) / math.cos(math.radians(30))
    dec = 30.0 + rng.uniform(-6, 6, 40)
    mag = np.linspace(2.0, 5.9, 40)
    return Catalog.from_arrays(np.arange(1, 41) * 10, ra, dec, mag, name="small")


def test_hand_made_sky_identified_exactly(camera):
    cat = _small_sky()
    algo = PVector()
    db = algo.build(cat, camera)
    # attitude: boresight at (40, 30) deg, some roll
    ra, dec, roll = map(math.radians, (40.0, 30.0, 25.0))
    z = np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])
    east = np.array([-math.sin(ra), math.cos(ra), 0.0])
    north = np.cross(z, east)
    x_axis = math.cos(roll) * east + math.sin(roll) * north
    A = np.stack([x_axis, np.cross(z, x_axis), z])
    v_cam = cat.unit_icrs @ A.T
    x, y = camera.project(v_cam)
    inside = camera.in_image(x, y) & (v_cam[:, 2] > 0)
    assert inside.sum() >= 8
    obs = Observation(x[inside], y[inside], cat.v_mag[inside], camera, cat.hip[inside])
    res = algo.identify(db, obs)
    assert np.array_equal(res.hip, cat.hip[inside])
    assert res.attitude is not None and np.allclose(res.attitude, A, atol=1e-9)
    # a mirrored sky (x -> width - x) is not a rotation of the catalog: nothing is identified
    mirrored = Observation(camera.width_px - x[inside], y[inside], cat.v_mag[inside], camera)
    assert np.all(algo.identify(db, mirrored).hip == -1)


# ------------------------------------------------------------------------- contract
@pytest.mark.parametrize("n", [0, 1, 2, 3])
def test_few_stars(algo, db, camera, n):
    rng = np.random.default_rng(n)
    obs = Observation(rng.uniform(0, 1024, n), rng.uniform(0, 1024, n), rng.uniform(2, 6, n), camera)
    res = algo.identify(db, obs)
    assert res.hip.shape == (n,) and res.hip.dtype == np.int64 and np.all(res.hip == -1)


# --------------------------------------------------------------------- identification rate
def test_noise_free_rate(algo, catalog):
    sim = Simulator(catalog, Camera(), SimConfig(), seed=11)
    summary = summarize(run([algo], sim.generate(100), catalog, sim)).iloc[0]
    # measured on these 100 trials: 0.99 (300 trials: 0.983; 2,000 trials, seed 1: 0.961); margin 4 points
    assert summary.id_rate >= 0.95
    assert summary.misid_rate == 0.0
    assert summary.error_rate == 0.0


def test_magnitude_noise_hurts_as_in_the_paper(catalog):
    """The triangle is chosen by brightness, so magnitude noise costs far more than position noise (the
    earlier one-guess-per-star form: K = 3, R = 4 deg, no whole-image pass); the defaults recover most of it."""
    rates = {}
    literal = PVector(triangles_per_star=3, pattern_radius_deg=4.0, image_neighbours=3, hypotheses=0)
    for name, algo in (("literal", literal), ("default", PVector())):
        for label, cfg in (("pos", SimConfig(sigma_px=1.0)), ("mag", SimConfig(sigma_mag=0.5))):
            sim = Simulator(catalog, Camera(), cfg, seed=12)
            rates[name, label] = summarize(run([algo], sim.generate(100), catalog, sim)).iloc[0]
    # measured on these 100 trials: literal pos 0.98, mag 0.90; default pos 0.99, mag 0.95; no misidentification
    assert rates["literal", "pos"].id_rate >= 0.94                                # margin 4 points
    assert rates["literal", "mag"].id_rate < rates["literal", "pos"].id_rate - 0.05    # measured gap 0.08
    assert rates["default", "mag"].id_rate >= rates["literal", "mag"].id_rate + 0.03   # measured + 0.05
    assert max(rates[k].misid_rate for k in rates) <= 0.01


def test_coincident_detections_without_min_sep(catalog, camera):
    """With r_min = 0, a coincident detection (distance 0) is still never a neighbour: the duplicated
    stars give no wrong id (the conformance check only runs the defaults)."""
    algo = PVector(min_sep_deg=0.0)
    base = algo.build(catalog, camera)
    sim = Simulator(catalog, camera, SimConfig(sigma_px=0.5), seed=8)
    for t in range(5):
        o = sim.observation(t)
        twice = np.concatenate([np.arange(len(o)), [0, 1]])     # the first two stars twice
        hip = check_identification(algo.identify(base, o.permuted(twice)), twice.size, catalog.hip).hip
        assert not np.any((hip >= 0) & (hip != o.truth_hip[twice]))


@pytest.mark.parametrize("fov_deg", [170.0, 40.0])
def test_wide_field_finishes_quickly(algo, db, catalog, camera, fov_deg):
    """A wide field costs at most a bounded multiple of a normal field's image (a ratio measured in
    this run, never an absolute limit), against the mean of 100 Table 4 images timed as one batch.
    Measured 2026-12-03 at load 8 on 2 cores: 170 deg 65x, 40 deg 2,595x (~0.3 s); the bound, 20,000x,
    is the former 2 s limit at ~0.1 ms per normal image and catches the minutes-long searches this
    test was written against."""
    cam = Camera.from_fov(fov_deg)      # the database does not depend on the camera
    cfg = SimConfig(sigma_px=1.0, sigma_mag=0.5)
    obs = Simulator(catalog, cam, cfg, seed=1).observation(1)
    sim = Simulator(catalog, camera, cfg, seed=1)
    normals = [sim.observation(t) for t in range(100)]
    algo.identify(db, obs)                     # compile
    algo.identify(db, normals[0])

    def all_normal():
        for o in normals:
            algo.identify(db, o)

    ratio = cost_ratio(lambda: algo.identify(db, obs), all_normal, len(normals))
    assert ratio < 20_000.0, f"{fov_deg} deg field costs {ratio:.0f}x a normal field's image"
    hip = algo.identify(db, obs).hip
    assert not np.any((hip >= 0) & (hip != obs.truth_hip))   # 40 deg: was 6 wrong ids before confirm_fraction


def test_search_variants_agree(db, catalog, camera):
    """search='linear' finds exactly what the k-vector finds (only slower)."""
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=21)
    fast, slow = PVector(), PVector(search="linear")
    for t in range(10):
        o = sim.observation(t)
        assert np.array_equal(fast.identify(db, o).hip, slow.identify(db, o).hip)


def test_assign_all_extends_the_reported_attitude(db, catalog, camera):
    """assign_all = starid.kernels.assign_all with the attitude the P-vector reports, over the deep
    catalog, within eps_d; it adds stars (noisy images, 1 px / 0.5 mag)."""
    algo = PVector(assign_all=True)
    deep_db = dataclasses.replace(db, deep=deep_sky(catalog, algo.deep_mag_limit))
    eps = algo.beta * math.sqrt(2.0) * algo._tol.sigma_px / camera.f_px
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=22)
    gained = 0
    for t in range(12):
        o = sim.observation(t)
        plain = PVector().identify(db, o)
        hip = algo.identify(deep_db, o).hip
        expect = plain.hip.copy()
        if plain.attitude is not None:
            assign_all(plain.attitude, o.x_px, o.y_px, camera_frame(camera), deep_db.deep, eps, expect)
        assert np.array_equal(hip, expect)
        gained += int(np.sum(hip >= 0) - np.sum(plain.hip >= 0))
    assert gained > 0


def test_explain_shows_the_guide_star_and_its_two_brightest_neighbours(algo, db, catalog, camera):
    obs = Simulator(catalog, camera, SimConfig(sigma_px=1.0), seed=31).observation(0)
    ex = algo.explain(db, obs)
    assert isinstance(ex, Explanation)
    assert ex.segments.shape == (3, 2, 2) and list(ex.highlight) == [0, 1, 2]
    hip = algo.identify(db, obs).hip
    corners = [int(np.flatnonzero((obs.x_px == p[0]) & (obs.y_px == p[1]))[0]) for p in ex.polygons[0]]
    assert all(hip[i] >= 0 for i in corners)
    main, n1, n2 = corners
    d = np.hypot(obs.x_px - obs.x_px[main], obs.y_px - obs.y_px[main])
    assert obs.mag[n1] <= obs.mag[n2] and d[n1] > 0
    assert algo.explain(db, Observation(obs.x_px[:2], obs.y_px[:2], obs.mag[:2], camera)).caption


def test_whole_image_pass_recovers_sparse_real_sky_fields(db, catalog):
    """The whole-image pass (``hypotheses``) raises the real-sky rate without misidentification, and its
    star list holds exactly the non-guide stars to V 7."""
    extra = np.sort(catalog.unit_icrs[(catalog.v_mag <= 7.0) & ~np.isin(catalog.hip, db.hip)][:, 2])
    assert np.allclose(np.sort(db.extra_unit[:, 2]), extra, atol=1e-7)
    assert PVector(hypotheses=0).build(catalog, Camera()).extra_unit.shape == (0, 3)
    sim = Simulator(catalog, Camera(), SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=43)    # real sky
    trials = sim.generate(150)
    s = summarize(run([PVector(), ("off", PVector(hypotheses=0))], trials, catalog, sim)).set_index("label")
    # measured on these 150 trials: default 0.973, hypotheses=0 0.947; no misidentification
    assert s.loc["pvector", "id_rate"] >= s.loc["off", "id_rate"] + 0.02
    assert s["misid_rate"].max() <= 0.01


def test_chance_k_min_keeps_k_min_on_the_reference_camera():
    """The confirmation count grows only where chance matches are likely: 2 (k_min) on the Table 4 camera at
    1 px even with 100 detections, more on a 20 deg, 1024 px camera at 2 px (eps_d 4x wider)."""
    from starid_algorithms.pvector.kernels import chance_k_min
    eps_t4 = 3 * math.sqrt(2) / Camera().f_px
    eps_luo = 3 * math.sqrt(2) * 2 / Camera.from_fov(20.0, 1024).f_px
    assert all(chance_k_min(n, 5000, eps_t4, 0.05) <= 2 for n in (3, 20, 100))
    assert chance_k_min(86, 5000, eps_luo, 0.05) == 4
    assert chance_k_min(86, 5000, eps_luo, 0.0) == 0


def test_wide_pixels_at_2px_noise(catalog):
    """Luo et al.'s camera (20 deg, 1024 px, 71 arcsec pixels, sky V <= 6.5) at 2 px: eps_d = 600 arcsec.
    With a fixed k_min = 2 every wrong correspondence reached 2 chance distance matches (ambiguous) and the
    fixed cap of 16 side-matching candidates skipped most triangles: 2 of these 20 images (seed 7) were
    identified. The chance-scaled k_min and the eps^3-scaled cap (bounded at 64) identify 19."""
    cam = Camera.from_fov(20.0, 1024)
    sim = Simulator(catalog, cam, SimConfig(sigma_px=2.0, mag_limit=6.5, sky_mag_limit=6.5, min_stars=3), seed=7)
    s = summarize(run([PVector()], sim.generate(20), catalog, sim)).iloc[0]
    assert s.id_rate >= 0.75      # measured 0.95 (before: 0.10)
    assert s.misid_rate == 0.0


def test_work_counters(algo, db, catalog, camera):
    """Identification.counters: k-vector searches, database triangles in the windows, those passing the
    side check (at most the window's), correspondences confirmed, hypotheses; zeros below three stars."""
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=23)
    for t in range(4):
        r = algo.identify(db, sim.observation(t))
        c = r.counters
        assert tuple(c) == K.WORK_NAMES and all(isinstance(v, int) for v in c.values())
        assert c["searches"] >= 1 and c["candidates"] <= c["window_triangles"]
        if r.attitude is not None and c["hypotheses"] == 0:
            assert c["correspondences"] >= 1
    two = Observation(np.array([10.0, 20.0]), np.array([10.0, 20.0]), np.array([3.0, 3.0]), camera)
    assert set(algo.identify(db, two).counters.values()) == {0}
