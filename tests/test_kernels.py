import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from starid.kernels import (
    angular_distance_rad,
    chord,
    kvector_build,
    kvector_range,
    pairwise_chords,
    rad_to_chord,
    triangle_sides,
    triple_product,
    verify_pairwise,
)

values = st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=0, max_size=60)


@settings(max_examples=300, deadline=None)
@given(values, st.floats(-1.2e3, 1.2e3), st.floats(0, 500))
def test_kvector_matches_searchsorted(vals, lo, width):
    s = np.sort(np.asarray(vals, dtype=np.float64))
    k, m, q = kvector_build(s)
    hi = lo + width
    start, stop = kvector_range(s, k, m, q, lo, hi)
    assert (start, stop) == (np.searchsorted(s, lo, "left"), np.searchsorted(s, hi, "right"))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.integers(-5, 5), min_size=2, max_size=40), st.integers(-6, 6))
def test_kvector_with_many_ties(vals, lo):
    s = np.sort(np.asarray(vals, dtype=np.float64))
    k, m, q = kvector_build(s)
    start, stop = kvector_range(s, k, m, q, float(lo), float(lo))
    assert stop - start == int(np.sum(s == lo))


def test_kvector_float32_values():
    s = np.sort(np.random.default_rng(0).normal(size=1000)).astype(np.float32)
    k, m, q = kvector_build(s.astype(np.float64))
    for lo in np.linspace(-3, 3, 41):
        start, stop = kvector_range(s, k, m, q, lo, lo + 0.1)
        assert (start, stop) == (np.searchsorted(s, lo, "left"), np.searchsorted(s, lo + 0.1, "right"))


def test_kvector_rejects_unsorted():
    with pytest.raises(ValueError):
        kvector_build(np.array([2.0, 1.0]))


def test_distances():
    u = np.array([1.0, 0.0, 0.0])
    v = np.array([math.cos(0.3), math.sin(0.3), 0.0])
    assert angular_distance_rad(u, v) == pytest.approx(0.3)
    assert chord(u, v) == pytest.approx(rad_to_chord(0.3))
    assert triangle_sides(u, v, -u) == pytest.approx((chord(u, v), chord(v, -u), 2.0))
    pc = pairwise_chords(np.stack([u, v, -u]))
    assert pc[0, 2] == pytest.approx(2.0) and pc[2, 0] == pc[0, 2] and pc[1, 1] == 0


def _sky(n, seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3)) * [0.03, 0.03, 0] + [0, 0, 1]
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_triple_product_matches_numpy():
    rng = np.random.default_rng(4)
    for _ in range(20):
        u, v, w = rng.normal(size=(3, 3))
        assert triple_product(u, v, w) == pytest.approx(np.dot(u, np.cross(v, w)), rel=1e-12, abs=1e-15)
    u, v, w = np.eye(3)
    assert triple_product(u, v, w) == 1.0 and triple_product(u, w, v) == -1.0  # handedness
    assert triple_product(u, u, w) == 0.0


def test_verify_pairwise_rejects_outlier_and_duplicates():
    cat = _sky(8, 1)
    obs = cat.copy()                     # camera frame = catalog frame
    rows = np.arange(8)
    assert verify_pairwise(obs, rows, cat, 1e-6, 2).all()
    wrong = rows.copy()
    wrong[3] = 7                         # star 3 proposed as catalog 7: inconsistent and a duplicate
    keep = verify_pairwise(obs, wrong, cat, 1e-6, 2)
    assert not keep[3] and keep[[0, 1, 2, 4, 5, 6]].all()


def test_verify_pairwise_majority_beats_small_wrong_cluster():
    cat = _sky(10, 2)
    obs = cat[:10].copy()
    rows = np.arange(10)
    # a self-consistent wrong cluster of 3: stars 7, 8, 9 proposed as a rotated copy of themselves
    c, s = np.cos(1.0), np.sin(1.0)
    rotation = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    cat2 = np.vstack([cat, obs[7:] @ rotation.T])
    rows[7:] = [10, 11, 12]
    keep_weak = verify_pairwise(obs, rows, cat2, 1e-6, 2)
    keep_majority = verify_pairwise(obs, rows, cat2, 1e-6, 2, 0.5)
    assert keep_weak[7:].all()           # pairwise support alone keeps both clusters
    assert keep_majority[:7].all() and not keep_majority[7:].any()


def test_wahba_rows_matches_svd_reference():
    from starid.attitude import random_attitude, rotation_angle_rad, solve_wahba
    from starid.kernels import wahba_rows

    rng = np.random.default_rng(3)
    for n in (2, 3, 8):
        A = random_attitude(rng)
        r = _sky(n, n)
        b = r @ A.T + rng.normal(0, 1e-5, (n, 3))
        b /= np.linalg.norm(b, axis=1, keepdims=True)
        rows = np.arange(n)
        fast = wahba_rows(b, rows, r)
        assert np.allclose(fast @ fast.T, np.eye(3), atol=1e-12)
        assert rotation_angle_rad(fast, solve_wahba(b, r)) < 1e-9
    rows = np.array([0, -1, 2])                      # -1 rows are skipped
    r = _sky(3, 9)
    assert rotation_angle_rad(wahba_rows(r, rows, r), np.eye(3)) < 1e-9


def test_reproject_assign_counts_predicted_and_seen():
    from starid import Camera
    from starid.kernels import reproject_assign, z_band_rows

    cam = Camera()
    rng = np.random.default_rng(4)
    sky = rng.normal(size=(40_000, 3))
    sky /= np.linalg.norm(sky, axis=1, keepdims=True)
    sky = sky[np.argsort(sky[:, 2])]
    start, stop = z_band_rows(sky, 0.3, 0.1)
    inside = np.flatnonzero(np.abs(np.arcsin(sky[:, 2]) - np.arcsin(0.3)) <= 2 * np.arcsin(0.05) - 1e-12)
    assert start <= inside.min() and inside.max() < stop
    # camera frame = ICRS (A = I): the boresight is +z
    front = sky[sky[:, 2] > 0.9]
    visible = front[cam.in_image(*cam.project(front))]
    seen = visible[: len(visible) // 2]                    # half of them observed
    out = np.empty(len(seen), dtype=np.int64)
    c_fov = 2 * np.sin(cam.half_diagonal_rad / 2)
    n_seen, n_predicted = reproject_assign(np.eye(3), seen, sky, c_fov, 1e-9, out, cam.f_px, cam.cx_px, cam.cy_px,
                                           cam.width_px, cam.height_px)
    assert len(visible) > 10
    assert n_predicted == len(visible) and n_seen == len(seen)
    assert np.allclose(sky[out], seen)


def test_assign_all_gives_every_detection_its_star(catalog, camera):
    from starid import SimConfig, Simulator
    from starid.kernels import assign_all, camera_frame, deep_sky, rad_to_chord

    sim = Simulator(catalog, camera, SimConfig(sigma_px=0.3), seed=8)
    _, x, y, _, truth, _ = sim.draw(0)
    attitude = sim.draw(0)[0]
    hip = np.full(x.size, -1, dtype=np.int64)
    hip[0] = truth[0]
    deep = deep_sky(catalog)
    n = assign_all(attitude, x, y, camera_frame(camera), deep, rad_to_chord(3 * camera.pixel_rad), hip)
    known = truth >= 0
    assert n == int((hip >= 0).sum()) and (hip[known] == truth[known]).mean() > 0.95
    assert len(np.unique(hip[hip >= 0])) == int((hip >= 0).sum())
    assert np.all(np.diff(deep.unit[:, 2]) >= 0) and deep.hip.dtype == np.int64


def test_explained_counts_the_detections_of_stars_to_the_check_limit(catalog, camera):
    """The whole-image check against a numpy oracle: with the true attitude, the detections it explains are
    those whose true star has V <= the check limit (7), the guide rows name the true stars, and refining the
    attitude on them keeps them."""
    from starid.kernels import camera_frame, check_stars, deep_sky, explained, field_chord, refine_explained
    from starid.simulate import SimConfig, Simulator

    guide = deep_sky(catalog, 6.0)
    extra = check_stars(catalog, guide.hip, 7.0)
    assert extra.dtype == np.float32 and np.all(np.diff(extra[:, 2]) >= 0)
    assert len(guide.hip) + len(extra) == int(np.count_nonzero(catalog.v_mag <= 7.0))
    frame = camera_frame(camera)
    eps = 3 * math.sqrt(2) / camera.f_px
    c_fov = field_chord(frame) + eps
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=41)    # real sky
    v_mag = dict(zip(catalog.hip.tolist(), catalog.v_mag.tolist(), strict=True))
    agree = 0
    for t in range(20):
        attitude, x, y, _, truth, _ = sim.draw(t)
        unit = camera.backproject(x, y)
        rows_g, rows_x = np.empty(len(x), dtype=np.int64), np.empty(len(x), dtype=np.int64)
        count, n_seen, n_predicted = explained(attitude, unit, guide.unit, extra, frame, c_fov, eps, rows_g, rows_x)
        expect = sum(1 for h in truth if h >= 0 and v_mag[int(h)] <= 7.0)
        agree += count == expect
        assert all(guide.hip[r] == h for r, h in zip(rows_g, truth, strict=True) if r >= 0)      # guide rows are right
        assert n_seen == (rows_g >= 0).sum() and n_predicted >= n_seen
        _, again, _, _ = refine_explained(unit, guide.unit, extra, frame, c_fov, eps, rows_g, rows_x)
        assert again >= count - 1
    assert agree >= 18      # measured: 20 of 20


@pytest.mark.parametrize("n", [50, 200])   # below and above PRESORT_ROWS
def test_order_by_is_lexsort_and_sort_rows_agrees(n):
    from starid.kernels import order_by, sort_rows
    from starid.kernels.order import PRESORT_ROWS

    assert 50 <= PRESORT_ROWS < 200
    rng = np.random.default_rng(0)
    mag = rng.integers(0, 4, n).astype(float)                    # many exact ties
    x = rng.integers(0, 5, n).astype(float)
    y = rng.uniform(0, 100, n)
    want = np.lexsort((y, x, mag))
    assert np.array_equal(order_by(mag, x, y), want)
    rows = rng.permutation(n)
    sort_rows(rows, n, mag, x, y)
    assert np.array_equal(rows, want)


def test_no_two_kernel_bundles_share_a_name_and_fields():
    """numba's dispatcher caches a namedtuple argument's type by its class name and values, so two
    bundle classes with the same name and fields slow every call of whichever is used second
    (measured: 300 us per identify); one class per bundle, shared where two plugins need it."""
    import importlib
    import inspect
    import pkgutil

    import starid_algorithms

    import starid.kernels

    prefix = "starid.kernels."
    modules = [importlib.import_module(m.name) for m in pkgutil.walk_packages(starid.kernels.__path__, prefix)]
    for pkg in pkgutil.iter_modules(starid_algorithms.__path__, "starid_algorithms."):
        for sub in ("algorithm", "kernels", "planar"):
            try:
                modules.append(importlib.import_module(f"{pkg.name}.{sub}"))
            except ModuleNotFoundError:
                pass
    seen = {}
    for module in modules:
        for cls in vars(module).values():
            if inspect.isclass(cls) and issubclass(cls, tuple) and hasattr(cls, "_fields"):
                other = seen.setdefault((cls.__name__, cls._fields), cls)
                assert other is cls, f"{other.__module__}.{cls.__name__} and {cls.__module__}.{cls.__name__}"
    assert ("Frame", ("f_px", "cx_px", "cy_px", "width_px", "height_px")) in seen
