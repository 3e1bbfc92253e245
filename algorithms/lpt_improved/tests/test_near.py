"""The cheaper acceptance and search of lpt_improved give the base versions' answers exactly.

``confirm_pair_near`` against ``confirm_pair``, ``assign_near`` against ``reproject_assign`` and
``sad_search_pairs`` against ``sad_search`` with the pair filter, on every candidate of a few
noisy images of both skies (issue #25, branch lpispeed).
"""

import numpy as np
import pytest
from starid_algorithms.lpt_improved import ImprovedLPT
from starid_algorithms.lpt_improved import kernels as LI
from starid_algorithms.lpt_improved import planar as P

from starid import SKIES, SimConfig, Simulator
from starid.kernels import chord_rows, reproject_assign


@pytest.fixture(scope="module")
def setup(catalog, camera):
    alg = ImprovedLPT()
    db = alg.build(catalog, camera)
    return alg, db, alg._kernel_args(db, camera)


@pytest.mark.parametrize("sky", ["paper", "real"])
def test_same_answers_on_every_candidate(setup, catalog, camera, sky):
    alg, db, args = setup
    params, columns, total, count_start, guide, align, align_chord, gu, zs, by_chord, chords = args
    sensor, acc, search = P.frame_at(params, 0), P.acceptance_at(params, 5), LI.search_at(params, 10)
    table = LI.FeatureTable(columns, total, count_start, guide, align, align_chord)
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5, min_stars=6, **SKIES[sky]), seed=5)
    trials = sim.generate(6)
    n_cand = n_accepted = 0
    for t in range(len(trials)):
        o = trials.observation(t, truth=False)
        n = len(o.x_px)
        _, unit, usable, order = P.begin_identify(o.x_px, o.y_px, sensor, search.double_px, P.new_trace())
        nbrs, r_px, phi = np.empty(n, dtype=np.int64), np.empty(n), np.empty(n)
        vec, nz_idx = np.zeros(search.n_sectors, dtype=np.int64), np.zeros(search.n_sectors, dtype=np.int64)
        sums = np.empty(len(total), dtype=np.int32)
        work, A0 = P.pair_work(n)
        for s in order[:4]:
            k = P.reference_pattern(unit, usable, o.x_px, o.y_px, s, search.cos_radius, sensor.f_px, nbrs, r_px, phi)
            for a in range(min(2, k)):
                nz = LI.feature_vector(r_px, phi, k, a, search.n_sectors, search.log_scale, vec)
                nz_idx[:nz] = np.flatnonzero(vec)
                chord = chord_rows(unit, s, unit, nbrs[a])
                out = []
                for f in (LI.sad_search, LI.sad_search_pairs):
                    rows_, sads = np.empty(8, dtype=np.int64), np.empty(8, dtype=np.int64)
                    call = (table, vec, nz_idx, nz, search.count_tol, 8, rows_, sads, search.count_tol_above)
                    if f is LI.sad_search:
                        found = f(*call, sums, chord, 2 * acc.eps0)
                    else:
                        found = f(*call, chord, 2 * acc.eps0, by_chord, chords)
                    out.append((rows_[:found].tolist(), sads[:found].tolist()))
                assert out[0] == out[1]
                for r in out[0][0]:
                    seed = np.full(n, -1, dtype=np.int64)
                    r1, r2 = np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64)
                    ok1, A1 = P.confirm_pair(unit, r1, seed, s, nbrs[a], guide[r], align[r], gu, sensor, acc)
                    ok2, A2 = P.confirm_pair_near(unit, r2, seed, s, nbrs[a], guide[r], align[r], gu, zs, sensor, acc,
                                                  work, A0)
                    assert ok1 == ok2
                    if ok1:
                        assert np.array_equal(r1, r2) and np.array_equal(A1, A2)
                        n_accepted += 1
                    n_cand += 1
    assert n_cand > 50 and n_accepted > 0


def test_assign_near_is_reproject_assign():
    """Dense and sparse windows, several stars per prediction, and the pair buffers overflowing."""
    rng = np.random.default_rng(3)
    g = rng.normal(size=(20000, 3))
    g /= np.linalg.norm(g, axis=1)[:, None]
    g = np.ascontiguousarray(g[np.argsort(g[:, 2])], dtype=np.float32)
    zs = P.z_index(g)
    A = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    if np.linalg.det(A) < 0:
        A[:, 0] *= -1
    near = np.flatnonzero(g.astype(np.float64) @ A[2] > np.cos(0.1))
    v = (A @ g[near].astype(np.float64).T).T + 3e-4 * rng.normal(size=(len(near), 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    for eps in (3e-4, 1e-3, 5e-3, 2e-2):
        r1, r2 = np.empty(len(v), dtype=np.int64), np.empty(len(v), dtype=np.int64)
        n1, _ = reproject_assign(A, v, g, 0.2 + eps, eps, r1, 1000.0, 0.0, 0.0, 10.0, 10.0)
        n2 = P.assign_near(A, v, g, zs, 0.2 + eps, eps, r2, np.empty(1, dtype=np.int64), np.empty(1, dtype=np.int64),
                           np.zeros(len(v), dtype=np.int64))
        assert n1 == n2 and np.array_equal(r1, r2)
