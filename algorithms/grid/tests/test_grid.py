"""Grid-specific tests: database layout, cells and soft credit against numpy, Luo's set-up and
Padgett's variant, explain, parameters.

Conformance (random fields, coincident stars, ids beyond 2^31, explain's type, determinism, order
invariance) runs for every plugin in tests/test_conformance.py and is not repeated here.
"""

import numpy as np
import pytest
from starid_algorithms.grid import Grid
from starid_algorithms.grid.kernels import GridSpec, by_cell, by_pattern, grid_cells, image_weights

from starid import Camera, ConfigError, SimConfig, Simulator


@pytest.fixture(scope="module")
def db(catalog, camera):
    return Grid().build(catalog, camera)


def _spec(**kw):
    base = dict(g=10, half_px=100.0, buffer_px=0.0, cos_radius=0.0, soft_edge=0.4, soft_diag=0.2, normalise=False,
                min_score=0.0, max_refs=1, image_orientations=1, n_candidates=1, double_px=0.0)
    base.update(kw)
    return GridSpec(**base)


def test_database_layout(db):
    assert db.cells.dtype == np.uint16 and db.cells.max() < 40 * 40
    assert db.start[0] == 0 and db.start[-1] == db.cells.size and np.all(np.diff(db.start) >= 1)
    for p in (0, 100, db.guide.size - 1):
        c = db.cells[db.start[p]:db.start[p + 1]]
        assert np.all(np.diff(c.astype(int)) > 0)                       # sorted, distinct
        assert np.any((c // 40 == 20) & (c % 40 >= 20))                # the orientation star, on +x
    cells, start = by_pattern(db.patterns, db.cell_start)              # the cell index inverts exactly
    assert np.array_equal(start, db.start)
    patterns, cell_start = by_cell(cells, start, 40 * 40)
    assert np.array_equal(patterns, db.patterns) and np.array_equal(cell_start, db.cell_start)
    for c in (0, 820, 1599):
        p = db.patterns[db.cell_start[c]:db.cell_start[c + 1]].astype(int)
        assert np.all(np.diff(p) > 0)
        assert all(c in cells[start[q]:start[q + 1]] for q in p)


def test_grid_cells_match_numpy():
    rng = np.random.default_rng(2)
    spec = _spec()
    for _ in range(20):
        r = rng.uniform(5, 150, 12)
        phi = rng.uniform(0, 2 * np.pi, 12)
        out = np.empty(12, dtype=np.int64)
        k = grid_cells(r, phi, 12, 3, spec, out)
        x, y = r * np.cos(phi - phi[3]), r * np.sin(phi - phi[3])
        inside = (np.abs(x) < 100) & (np.abs(y) < 100)
        col = np.floor((x[inside] + 100) / 20).astype(int)
        row = np.floor((y[inside] + 100) / 20).astype(int)
        assert np.array_equal(out[:k], np.unique(row * 10 + col))


def test_image_weights_soft_credit():
    spec = _spec()
    weight = np.zeros(100)
    touched = np.empty(100, dtype=np.int64)
    nt = image_weights(np.array([55, 57]), 2, spec, weight, touched)
    assert weight[55] == 1.0 and weight[57] == 1.0
    assert weight[56] == pytest.approx(0.4) and weight[45] == pytest.approx(0.4) and weight[44] == pytest.approx(0.2)
    assert weight[59] == 0.0 and nt == np.count_nonzero(weight)
    padgett = _spec(soft_edge=0.0, soft_diag=0.0)
    weight[:] = 0
    image_weights(np.array([55]), 1, padgett, weight, touched)
    assert np.count_nonzero(weight) == 1


def test_luo_setup_and_padgett_variant(catalog):
    camera = Camera.from_fov(20.0, 1024)
    sim = Simulator(catalog.brighter_than(6.5), camera, SimConfig(sigma_px=0.5, mag_limit=6.5, min_stars=3), seed=2)
    for alg in (Grid(mag_limit=6.5, sigma_px=0.5), Grid(mag_limit=6.5, soft_edge=0.0, soft_diag=0.0,
                                                         image_orientations=1, normalise=True, min_score=0.2)):
        db = alg.build(catalog, camera)
        assert db.radius_deg == pytest.approx(6.0)
        ok = 0
        for t in range(6):
            obs = sim.observation(t)
            hip = alg.identify(db, obs).hip
            assert not np.any((hip >= 0) & (hip != obs.truth_hip))
            ok += int(np.sum(hip == obs.truth_hip) >= 3)
        assert ok >= 5      # measured 6 of 6 for both; one spare


def test_explain(catalog, camera, db):
    obs = Simulator(catalog, camera, SimConfig(sigma_px=0.5), seed=3).observation(0)
    ex = Grid().explain(db, obs)
    assert ex.highlight.size == 1 and ex.caption.startswith("Grid")
    assert len(ex.segments) >= 22                                      # neighbours + 2 x 11 grid lines


def test_bad_parameters():
    for kw in ({"grid_size": 1}, {"grid_size": 300}, {"soft_edge": 1.5}, {"normalise": 1}, {"buffer_px": -1.0},
               {"db_orientations": 0}, {"min_score": -1.0}):
        with pytest.raises(ConfigError):
            Grid(**kw)
