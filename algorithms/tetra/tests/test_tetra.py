"""Tests of the Tetra plugin: conformance, hash table, pattern keys, verification, explain."""

from functools import lru_cache

import numpy as np
import pytest
from scipy.stats import binom
from starid_algorithms.tetra import Tetra
from starid_algorithms.tetra.kernels import (
    EMPTY,
    PAIRS,
    binom_sf,
    canonical_order,
    pattern_keys,
    ratio_bin,
    table_insert,
    table_lookup,
)

import starid
from starid.errors import ConfigError
from starid.plugin import Explanation
from starid.testing import cost_ratio


@lru_cache(maxsize=2)
def _database(catalog, camera):
    return Tetra().build(catalog, camera)


# ------------------------------------------------------------------ hash table


def _lookup_all(table_word, table_pattern, key):
    out = np.empty(64, dtype=np.int64)
    n = table_lookup(table_word, np.uint32(key), out, 0)
    return sorted(tuple(int(v) for v in table_pattern[s]) for s in out[:n])


@pytest.mark.parametrize("size, load", [(16, 0.7), (1000, 0.7), (997, 0.999)])
def test_hash_table_matches_dict_oracle(size, load):
    rng = np.random.default_rng(5)
    n = int(load * size)
    keys = rng.integers(0, 40, n).astype(np.uint32) * np.uint32(7919)   # many repeated keys
    patterns = rng.integers(0, 60000, (n, 4)).astype(np.uint16)
    edges = rng.integers(0, 65536, n).astype(np.uint16)
    table_word = np.full(size, EMPTY, dtype=np.uint64)
    table_pattern = np.zeros((size, 4), dtype=np.uint16)
    table_insert(table_word, table_pattern, keys, edges, patterns)
    oracle = {}
    for k, p in zip(keys.tolist(), patterns.tolist(), strict=True):
        oracle.setdefault(k, []).append(tuple(p))
    assert (table_word != EMPTY).sum() == n
    for k, values in oracle.items():
        assert _lookup_all(table_word, table_pattern, k) == sorted(values)
    for k in (1, 7918, 40 * 7919):            # absent keys find nothing
        assert k not in oracle
        assert _lookup_all(table_word, table_pattern, k) == []
    # each slot keeps its pattern's edge beside the key
    stored = {(int(w >> 16), int(w & 0xFFFF), tuple(int(v) for v in table_pattern[s]))
              for s, w in enumerate(table_word) if w != EMPTY}
    assert stored == set(zip(keys.tolist(), edges.tolist(), map(tuple, patterns.tolist()), strict=True))


def test_database_table_holds_every_pattern_under_its_key(catalog, camera):
    db = _database(catalog, camera)
    used = np.flatnonzero(db.table_word != EMPTY)
    assert used.size == db.n_patterns
    assert db.nbytes < 40e6
    rng = np.random.default_rng(0)
    unit = db.guide_unit.astype(np.float64)
    for s in rng.choice(used, 200, replace=False):
        rows = db.table_pattern[s].astype(np.int64)
        assert np.all(db.reportable[rows])
        # key from a plain numpy oracle: sorted edges / largest, floored into bins, largest ratio
        # the most significant digit (float32 vectors: skip ratios at a bin boundary)
        e = np.sort([np.linalg.norm(unit[rows[a]] - unit[rows[b]]) for a, b in PAIRS])
        scaled = e[:5] / e[5] * db.bins
        if np.any(np.abs(scaled - np.round(scaled)) < 1e-4):
            continue
        digits = np.minimum(np.floor(scaled).astype(int), db.bins - 1)[::-1]
        key = 0
        for d in digits:
            key = key * db.bins + d
        assert _lookup_all(db.table_word, db.table_pattern, key).count(tuple(int(v) for v in rows)) == 1
        assert abs(int(db.table_word[s] & 0xFFFF) / 65535 * db.edge_scale - e[5]) < 1e-4


def test_pattern_key_and_canonical_order_ignore_star_order():
    rng = np.random.default_rng(3)
    unit = rng.normal(size=(4, 3)) * 0.05 + [0, 0, 1]
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    largest = np.empty(1)
    base = pattern_keys(unit, np.array([[0, 1, 2, 3]], dtype=np.int64), 50, largest)
    chords = [np.linalg.norm(unit[a] - unit[b]) for a in range(4) for b in range(a + 1, 4)]
    assert largest[0] == max(chords)           # the largest edge, bit for bit as numpy's norm
    ref = np.array([[0, 1, 2, 3]], dtype=np.int64)
    pattern_keys(unit, ref, 50, largest)
    for perm in ([3, 2, 1, 0], [1, 3, 0, 2]):
        p = np.array([perm], dtype=np.int64)
        assert pattern_keys(unit, p, 50, largest)[0] == base[0]
        assert np.array_equal(p, ref)          # canonical order written in place
    d = np.linalg.norm(unit - unit.mean(axis=0), axis=1)
    out = np.empty(4, dtype=np.int64)
    dist = np.empty(4)
    canonical_order(unit, np.arange(4), out, dist)
    assert np.array_equal(out, np.argsort(d)) and np.allclose(dist, np.sort(d))
    assert ratio_bin(1.0, 50) == 49 and ratio_bin(-0.1, 50) == 0 and ratio_bin(0.5, 50) == 25


def test_binomial_tail_matches_scipy():
    for k, m, q in [(1, 8, 1e-3), (3, 20, 0.01), (5, 5, 0.3), (0, 4, 0.5), (6, 5, 0.2)]:
        assert binom_sf(k, m, q) == pytest.approx(binom.sf(k - 1, m, q) if k > 0 else 1.0, rel=1e-9, abs=1e-300)


# ------------------------------------------------------------------ identification


def test_noisy_real_sky_identifies_without_misidentification(catalog, camera):
    db = _database(catalog, camera)
    alg = Tetra()
    sim = starid.Simulator(catalog, camera, starid.SimConfig(sigma_px=1.0, sigma_mag=0.5, false_stars=2), seed=11)
    correct = 0
    for t in range(40):
        obs = sim.observation(t)
        hip = alg.identify(db, obs).hip
        ok = (hip >= 0) & (hip == obs.truth_hip)
        assert not np.any((hip >= 0) & (hip != obs.truth_hip)), f"trial {t} misidentified"
        correct += ok.sum() >= 3
    assert correct >= 34


def test_random_fields_give_no_identification(catalog, camera):
    db = _database(catalog, camera)
    alg = Tetra()
    rng = np.random.default_rng(2017)
    identified = loose = 0
    for _ in range(40):
        obs = starid.Observation(rng.uniform(0, camera.width_px, 30), rng.uniform(0, camera.height_px, 30),
                                 rng.uniform(2.0, 6.0, 30), camera)
        identified += np.any(alg.identify(db, obs).hip >= 0)
        # the same fields with a wide window and no checks do find look-alike patterns
        loose += np.any(Tetra(beta=15.0, min_extra=0, max_mismatch=1.0, mag_beta=0.0).identify(db, obs).hip >= 0)
    assert identified <= 1
    assert loose >= 5


def test_coincident_detections_and_read_only_input(catalog, camera):
    db = _database(catalog, camera)
    sim = starid.Simulator(catalog, camera, starid.SimConfig(), seed=4)
    obs = sim.observation(0)
    x = np.concatenate([obs.x_px, obs.x_px[:2]])
    y = np.concatenate([obs.y_px, obs.y_px[:2]])
    mag = np.concatenate([obs.mag, obs.mag[:2]])
    for arr in (x, y, mag):
        arr.flags.writeable = False
    hip = Tetra().identify(db, starid.Observation(x, y, mag, camera)).hip
    assert hip.shape == (len(x),) and hip.dtype == np.int64
    same = starid.Observation(np.full(6, 100.0), np.full(6, 200.0), np.full(6, 3.0), camera)
    assert np.all(Tetra().identify(db, same).hip == -1)


def test_ids_beyond_int32(catalog, camera):
    offset = 2 ** 31
    big = starid.Catalog.from_arrays(catalog.hip + offset, catalog.ra_deg, catalog.dec_deg, catalog.v_mag)
    db = Tetra().build(big, camera)
    assert db.guide_hip.dtype == np.int64
    sim = starid.Simulator(big, camera, starid.SimConfig(), seed=9)
    hits = 0
    for t in range(5):
        obs = sim.observation(t)
        hip = Tetra().identify(db, obs).hip
        assert not np.any((hip >= 0) & (hip != obs.truth_hip))
        hits += np.sum((hip >= 0) & (hip == obs.truth_hip)) >= 3
        assert np.all((hip == -1) | (hip > offset))
    assert hits >= 4


def test_very_wide_camera_finishes_quickly(catalog):
    """Building for a 170 deg camera and identifying two of its images costs a bounded multiple of a
    normal camera's build (a ratio in this run, never seconds). Measured 2026-12-05: ~4x; the bound
    100x is the former 30 s limit at ~0.3 s a normal build."""
    wide, normal = starid.Camera.from_fov(170.0), starid.Camera()
    sim = starid.Simulator(catalog, wide, starid.SimConfig(), seed=1)
    images = [sim.observation(t) for t in range(2)]

    def wide_build_and_identify():
        db = Tetra().build(catalog, wide)
        for obs in images:
            assert Tetra().identify(db, obs).hip.shape == (len(obs),)

    wide_build_and_identify()                   # compile
    ratio = cost_ratio(wide_build_and_identify, lambda: Tetra().build(catalog, normal), 1, repeats=2)
    assert ratio < 100.0, f"170 deg build and two images cost {ratio:.0f}x a normal build"


def test_explain_draws_the_matched_pattern(catalog, camera):
    db = _database(catalog, camera)
    obs = starid.Simulator(catalog, camera, starid.SimConfig(sigma_px=1.0), seed=3).observation(0)
    alg = Tetra()
    ex = alg.explain(db, obs)
    assert isinstance(ex, Explanation)
    assert ex.segments.shape == (6, 2, 2) and np.array_equal(ex.highlight, np.arange(6))
    assert len(ex.polygons) == 1 and ex.polygons[0].shape == (4, 2)
    hip = alg.identify(db, obs).hip
    assert len(ex.labels) == np.sum(hip >= 0) >= 4
    assert all(label.startswith("HIP ") for label in ex.labels)
    # the pattern's corners are image stars, and the catalogue outline lies on them (within a few px)
    corners = ex.segments.reshape(-1, 2)
    d = np.min(np.linalg.norm(ex.polygons[0][:, None, :] - corners[None, :, :], axis=2), axis=1)
    assert np.all(d < 5.0)
    empty = alg.explain(db, starid.Observation(np.array([10.0, 20.0]), np.array([10.0, 30.0]), np.ones(2), camera))
    assert isinstance(empty, Explanation) and empty.segments.shape == (0, 2, 2) and "No 4-star" in empty.caption


@pytest.mark.parametrize("bad", [dict(bins=1), dict(bins=85), dict(field_stars=3), dict(image_stars=3),
                                 dict(beta=0.0), dict(load_factor=1.0), dict(sigma_px=-1.0), dict(min_span=1.0),
                                 dict(max_mismatch=2.0), dict(mag_limit=float("nan")), dict(min_extra=True)])
def test_bad_parameters_are_refused(bad):
    with pytest.raises(ConfigError):
        Tetra(**bad)


def test_sigma_follows_the_simulator():
    assert Tetra().resolved(starid.SimConfig(sigma_px=2.5)).sigma_px == 2.5
    assert Tetra(sigma_px=0.5).resolved(starid.SimConfig(sigma_px=2.5)).sigma_px == 0.5
    assert Tetra(sigma_px=0.0)._sigma_px == 1.0        # the floor


def test_magnitude_check_keeps_implausible_stars_unreported(catalog, camera):
    db = _database(catalog, camera)
    obs = starid.Simulator(catalog, camera, starid.SimConfig(), seed=6).observation(0)
    dim = starid.Observation(obs.x_px, obs.y_px, obs.mag + 2.0, camera)   # 2 mag off: beyond 3 x 0.5
    assert np.all(Tetra().identify(db, dim).hip == -1)
    hip = Tetra(mag_beta=0.0).identify(db, dim).hip                       # check off: identified
    assert np.sum((hip >= 0) & (hip == obs.truth_hip)) >= 3
    assert np.sum((hip >= 0) & (hip == obs.truth_hip)) == np.sum(Tetra().identify(db, obs).hip >= 0)
