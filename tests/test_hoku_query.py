"""hoku's query step (starid.experiments.hoku_query): determinism, bounds, and recounts by brute force."""

import numpy as np
import pandas as pd
import pytest

from starid.catalog import load_hipparcos
from starid.experiments import hoku_query as hq


@pytest.fixture(scope="module")
def catalog():
    return load_hipparcos()


def test_the_step_is_determined_by_its_seed(catalog):
    a = hq.query_step(catalog, n_queries=40, seed=3, n_stars=800)
    b = hq.query_step(catalog, n_queries=40, seed=3, n_stars=800)
    pd.testing.assert_frame_equal(a, b)
    assert list(a["method"]) == list(hq.METHODS) and (a["n_queries"] == 40).all()
    _, u = hq.bright_stars(catalog, 800)
    assert np.array_equal(hq.draw_queries(u, "PYR", 40, 3), hq.draw_queries(u, "PYR", 40, 3))
    assert not np.array_equal(hq.draw_queries(u, "PYR", 40, 3), hq.draw_queries(u, "PYR", 40, 4))
    assert not np.array_equal(hq.draw_queries(u, "PLN", 40, 3), hq.draw_queries(u, "COM", 40, 3))


def test_f_and_s_are_in_bounds_and_angle_is_far_less_selective(catalog):
    df = hq.query_step(catalog, n_queries=150, seed=1, n_stars=2500).set_index("method")
    assert ((df["f"] >= 0) & (df["f"] <= 1)).all() and ((df["S_rows"] >= 0) & (df["S_rows"] <= 2000)).all()
    assert (df["n_empty"] == 0).all()          # no noise: every query finds at least its own set
    # no noise, so every method but PYR (whose set differences can drop a true star) holds the set
    assert (df.drop(index="PYR")["f"] == 1.0).all() and df.loc["PYR", "f"] >= 0.9
    # one angle matches many pairs; two features of a trio almost never match two trios
    assert df.loc["ANG", "S_rows"] < 0.6 * df.loc[["SPH", "PLN", "COM"], "S_rows"].min()
    assert df.loc["ANG", "mean_R_rows"] > 1.5 and (df.loc[["SPH", "PLN", "COM"], "mean_R_rows"] < 1.1).all()
    assert (df.loc[["ANG", "SPH", "PLN", "COM"], "S_sets"] == df.loc[["ANG", "SPH", "PLN", "COM"], "S_rows"]).all()


def _brute_pairs_and_trios(u):
    cmin = np.cos(np.radians(hq.FOV_DEG))
    close = u @ u.T >= cmin
    i, j, k = np.array([(i, j, k) for i in range(len(u)) for j in range(i + 1, len(u)) if close[i, j]
                        for k in range(j + 1, len(u)) if close[i, k] and close[j, k]]).T
    return close, i, j, k


def _planar_np(b1, b2, b3):
    a, b, c = (np.linalg.norm(x - y, axis=-1) for x, y in ((b1, b2), (b2, b3), (b3, b1)))
    s = (a + b + c) / 2
    area = np.sqrt(np.clip(s * (s - a) * (s - b) * (s - c), 0, None))
    return area, area * (a * a + b * b + c * c) / 36


def _arc(x, y):
    return np.arccos(np.clip((x * y).sum(-1) / (np.linalg.norm(x, axis=-1) * np.linalg.norm(y, axis=-1)), -1, 1))


def _spherical_np(b1, b2, b3):
    a, b, c = _arc(b1, b2), _arc(b2, b3), _arc(b3, b1)
    s = (a + b + c) / 2
    t = np.tan(s / 2) * np.tan((s - a) / 2) * np.tan((s - b) / 2) * np.tan((s - c) / 2)
    return 4 * np.arctan(np.sqrt(np.clip(t, 0, None)))


def _moment_np(b1, b2, b3, root=None, depth=hq.MOMENT_DEPTH):
    """Recursively: the sum over the 4**depth pieces of area x angle(root centroid, piece centroid)^2."""
    root = (b1 + b2 + b3) / 3 if root is None else root
    if depth == 0:
        return _spherical_np(b1, b2, b3) * _arc(root, (b1 + b2 + b3) / 3) ** 2

    def mid(x, y):
        return (x + y) / np.linalg.norm(x + y, axis=-1, keepdims=True)

    m12, m13, m23 = mid(b1, b2), mid(b1, b3), mid(b2, b3)
    return sum(_moment_np(*t, root=root, depth=depth - 1)
               for t in ((b1, m12, m13), (m12, b2, m23), (m13, m23, b3), (m12, m13, m23)))


@pytest.mark.parametrize("method, features", [("PLN", _planar_np),
                                              ("SPH", lambda *b: (_spherical_np(*b), _moment_np(*b)))])
def test_triangle_search_matches_a_brute_force_recount(catalog, monkeypatch, method, features):
    """Every trio of a 400-star catalog, with features computed independently in numpy, checked against
    every query with a wide window (R has up to tens of rows, query windows overlap and the moment
    rejects some rows the area admits): the kernel's one pass over K3 gives the same |R| and in_R."""
    eps = 1e-5
    monkeypatch.setattr(hq, "WINDOW_TRIANGLE", eps)
    _, u = hq.bright_stars(catalog, 400)
    tables = hq.HokuTables(u)
    stars = hq.draw_queries(u, method, 60, 2)
    got = hq.query_results(tables, method, stars)

    _, i, j, k = _brute_pairs_and_trios(u)
    assert tables.k3_counts["trios"] == len(i)
    area, mom = features(u[i], u[j], u[k])
    q_area, q_mom = features(u[stars[:, 0]], u[stars[:, 1]], u[stars[:, 2]])
    by_area = np.abs(area[None] - q_area[:, None]) <= eps
    match = by_area & (np.abs(mom[None] - q_mom[:, None]) <= eps)
    truth = np.sort(stars, axis=1)
    own = (i[None] == truth[:, :1]) & (j[None] == truth[:, 1:2]) & (k[None] == truth[:, 2:])
    assert np.array_equal(got["rows"], match.sum(1)) and np.array_equal(got["in_R"], (match & own).any(1))
    assert got["rows"].max() > 5 and by_area.sum() > match.sum() and (got["in_R"] == 1).all()


def test_angle_search_matches_a_brute_force_recount(catalog, monkeypatch):
    monkeypatch.setattr(hq, "WINDOW_PAIR_DEG", 0.05)
    _, u = hq.bright_stars(catalog, 300)
    tables = hq.HokuTables(u)
    stars = hq.draw_queries(u, "ANG", 80, 4)
    got = hq.query_results(tables, "ANG", stars)
    close = np.triu(u @ u.T >= np.cos(np.radians(hq.FOV_DEG)), 1)
    a, b = np.nonzero(close)
    theta = np.degrees(np.arccos(np.clip((u[a] * u[b]).sum(1), -1, 1)))
    q = np.degrees(np.arccos(np.clip((u[stars[:, 0]] * u[stars[:, 1]]).sum(1), -1, 1)))
    assert len(a) == tables.pairs.t.size
    match = np.abs(theta[None] - q[:, None]) <= 0.05
    assert np.array_equal(got["rows"], match.sum(1)) and got["rows"].max() > 1 and (got["in_R"] == 1).all()


def test_pyramid_rows_are_the_product_of_its_three_lists(catalog):
    """|R| = |T_i| max(|T_j|, 1) max(|T_k|, 1) and sets <= rows, for each query (no noise: T_i holds i)."""
    _, u = hq.bright_stars(catalog, 1500)
    tables = hq.HokuTables(u)
    r = hq.query_results(tables, "PYR", hq.draw_queries(u, "PYR", 60, 5))
    assert (r["rows"] >= 1).all() and (r["sets"] <= r["rows"]).all() and (r["sets"] >= 1).all()
    assert set(r["removed"]) <= {0, 1, 2} and (r["longest_side_deg"] < hq.FOV_DEG).all()
