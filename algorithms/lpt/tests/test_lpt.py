"""LPT-specific tests: database layout, shift voting against brute force, Luo's set-up, explain, parameters.

Conformance (random fields, coincident stars, ids beyond 2^31, explain's type, determinism, order
invariance) runs for every plugin in tests/test_conformance.py and is not repeated here.
"""

import numpy as np
import pytest
from starid_algorithms.lpt import LPT
from starid_algorithms.lpt.kernels import (
    ImageString,
    StringSearch,
    dense_string,
    image_groups,
    image_groups_padded,
    index_image,
    least_needed,
    match_bound,
    rank_key,
    reaches_budget,
    reaches_groups,
    reaches_tables,
    shift_scores,
    shift_tables,
    sparse_strings,
    window_counts,
)

from starid import Camera, ConfigError, SimConfig, Simulator


@pytest.fixture(scope="module")
def db(catalog, camera):
    return LPT().build(catalog, camera)


def test_database_layout(db):
    assert db.strings.dtype == np.uint8 and db.strings.shape == (db.guide_hip.size, 100)
    assert db.strings.max() <= 16
    assert np.all(np.diff(db.guide_unit[:, 2]) >= 0)
    assert (db.strings > 0).sum(axis=1).mean() > 3
    assert db.char_sector.dtype == np.uint8 and db.char_level.dtype == np.uint8 and db.char_start.dtype == np.int32
    assert np.array_equal(np.diff(db.char_start), (db.strings > 0).sum(axis=1))
    row = np.zeros(100, dtype=np.uint8)
    for g in (0, 17, db.guide_hip.size - 1):
        dense_string(db.chars, g, row)
        assert np.array_equal(row, db.strings[g])


def _brute_force(row, img, m, level_tol, sector_tol):
    """Oracle: compare the image string with every circular shift of the database string (numpy)."""
    k = np.flatnonzero(img)
    shifts = np.arange(m)[:, None, None]
    d = np.arange(-sector_tol, sector_tol + 1)[None, None, :]
    c = row[(k[None, :, None] + shifts + d) % m].astype(int)                 # (shift, image char, d)
    hit = (c > 0) & (np.abs(c - img[k].astype(int)[None, :, None]) <= level_tol)
    scores = hit.any(axis=2).sum(axis=1)
    return int(scores.max()), int(np.argmax(scores))


@pytest.mark.parametrize("m,sector_tol", [(60, 0), (60, 1), (100, 2), (130, 1)])
def test_shift_scores_equal_brute_force_circular_match(m, sector_tol):
    rng = np.random.default_rng(1)
    search = StringSearch(m, 16, 0.0, 1.0, 0.0, 1, sector_tol, 1, 1, 1, 0.0)
    rows = np.zeros((30, m), dtype=np.uint8)
    images = []
    for i in range(30):
        rows[i, rng.choice(m, 8 + i % 5, replace=False)] = rng.integers(1, 17, 8 + i % 5)
        img = np.roll(rows[i], -int(rng.integers(m))).astype(np.int64)
        img[rng.choice(m, 3, replace=False)] = rng.integers(0, 17, 3)
        images.append(img)
    chars = sparse_strings(rows)
    words = (m + 63) // 64
    sets, planes = np.zeros((m + 1, words), dtype=np.int64), np.zeros((9, words), dtype=np.int64)
    sum_planes, at_most = np.zeros((12, 2), dtype=np.int64), np.zeros((3 * m + 1, 2), dtype=np.int64)
    groups, xs = np.zeros((3 * m + 1, 2), dtype=np.int64), np.zeros((m, 2), dtype=np.int64)
    xs2 = np.zeros((2 * m + 1, 2), dtype=np.int64)
    pattern = np.zeros((m, 128), dtype=bool)
    for d in range(-sector_tol, sector_tol + 1):
        pattern[np.arange(m), (np.arange(m) - d) % m % 128] = True
    pattern = np.packbits(pattern, axis=1, bitorder="little").view(np.int64)
    valid = np.zeros(128, dtype=bool)
    valid[:m] = True
    valid = np.packbits(valid, bitorder="little").view(np.int64)
    for img in images:
        sec = np.flatnonzero(img)
        nz = sec.size
        level_start, mask = np.zeros(18, dtype=np.int64), np.zeros(17, dtype=np.int64)
        by_level = np.zeros(3 * m, dtype=np.int64)
        index_image(sec, img[sec], nz, search, level_start, by_level, mask)
        image = ImageString(sec, img[sec], nz, level_start, by_level, mask)
        most, tables = np.zeros(17, dtype=np.int64), None
        if m <= 128 and sector_tol <= 1:
            window_counts(image, search, most)
            tables = np.zeros((3, 17, m, 2), dtype=np.int64)
            shift_tables(image, search, tables)
        for g in range(len(rows)):      # every string against every image: true matches and unrelated ones
            expect = _brute_force(rows[g], img, m, 1, sector_tol)
            assert shift_scores(chars, g, image, search, sets, planes) == expect
            assert match_bound(chars, g, image) >= expect[0]
            if tables is not None:              # the scan's filter: never below the score
                total = int(most[rows[g][rows[g] > 0]].sum())
                assert total >= expect[0]
                assert reaches_tables(chars, g, expect[0], tables, sum_planes)
                assert image_groups(chars, g, image, nz - expect[0], pattern, valid, xs, groups)
                for u in range(nz):             # the scan's padded form gives the same answer
                    assert image_groups_padded(chars, g, image, u, pattern, valid, xs2, groups) == image_groups(
                        chars, g, image, u, pattern, valid, xs, groups)
                for need in range(1, total + 1):    # the two forms of the filter agree
                    exact = reaches_tables(chars, g, need, tables, sum_planes)
                    assert reaches_budget(chars, g, total - need, most, tables, valid, at_most) == exact
                    assert reaches_groups(chars, g, total - need, most, tables, valid, groups) or not exact


def test_least_needed_is_the_pruning_threshold():
    """The scan skips a string whose best score is below least_needed: exactly those keep_best would drop."""
    for threshold in (1, 1023, 1024, 2047, 2048, 5119, 6141, 9300):
        for n_chars in (0, 1, 3, 7, 20, 60):
            for min_score in (1, 2, 4):
                need = least_needed(threshold, n_chars, min_score)
                assert need >= min_score and rank_key(need, n_chars) > threshold
                assert need == min_score or rank_key(need - 1, n_chars) <= threshold


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
