"""Where the string scan of ``lpt`` spends its time, filter by filter (issue #25, branch lptspeed2).

    python benchmarks/tools/lptspeed2_filters.py SKY N

Table 6's images (1 px / 0.5 Mv, seed 0), N of them, the first reference star of each. Every
database string is scanned with the need the final candidate list sets (as if the list were full
from the start), the kernel's stages switched on one after another: 0 the level bound
(``match_bound``, what ``n_comparisons`` counts), 1 + the per-reference tables (``shift_tables``,
``window_counts``), 2 + the window-sum bound, 3 + the pigeonhole filters (``image_groups`` /
``reaches_groups``), 4 + the exact sum test (``reaches_budget`` / ``reaches_tables``), 5 +
``shift_scores`` on the strings left (the whole scan as the kernel does it); 6 is the former scan
(``shift_scores`` on every string past the level bound). Prints per image the strings left after
each stage and its time (minimum of 7 calls, us), and the sums.
"""

import sys
import time

import numpy as np
from numba import njit
from starid_algorithms.lpt import kernels as LK
from starid_algorithms.lpt_improved.planar import begin_identify, frame_at, reference_pattern

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm


@njit
def first_image_string(x_px, y_px, params, img_sector, img_level, level_start, by_level, mask):
    sensor = frame_at(params, np.int64(0))
    search = LK.search_at(params, np.int64(10))
    n = x_px.shape[0]
    trace = np.zeros(8, dtype=np.int64)
    rows, unit, usable, order = begin_identify(x_px, y_px, sensor, search.double_px, trace)
    m = search.n_sectors
    nbrs, r_px, phi = np.empty(n, dtype=np.int64), np.empty(n), np.empty(n)
    img, owner = np.zeros(m, dtype=np.int64), np.empty(m, dtype=np.int64)
    if order.shape[0] == 0:
        return 0
    k = reference_pattern(unit, usable, x_px, y_px, order[0], search.cos_radius, sensor.f_px, nbrs, r_px, phi)
    if k < 1:
        return 0
    nz = LK.lpt_string(r_px, phi, k, search, img, owner)
    q = 0
    for j in range(m):
        if img[j] != 0:
            img_sector[q] = j
            img_level[q] = img[j]
            q += 1
    LK.index_image(img_sector, img_level, nz, search, level_start, by_level, mask)
    return nz


@njit
def scan(stage, params, cs, cl, cst, img_sector, img_level, nz, level_start, by_level, mask, needs):
    search = LK.search_at(params, np.int64(10))
    chars = LK.Strings(cs, cl, cst)
    image = LK.ImageString(img_sector, img_level, nz, level_start, by_level, mask)
    m = search.n_sectors
    sets, planes = np.zeros((m + 1, 2), np.int64), np.zeros((9, 2), np.int64)
    most = np.zeros(search.n_levels + 1, np.int64)
    tables = np.zeros((3, search.n_levels + 1, m, 2), np.int64)
    sum_planes = np.zeros((10, 2), np.int64)
    at_most = np.zeros((LK.BUDGET_MAX + 1, 2), np.int64)
    groups, xs = np.zeros((3 * m + 1, 2), np.int64), np.zeros((m, 2), np.int64)
    valid = np.zeros(2, np.int64)
    pattern = np.zeros((m, 2), np.int64)
    for s in range(m):
        valid[s >> 6] |= np.int64(1) << (s & 63)
        for d in range(-search.sector_tol, search.sector_tol + 1):
            x = (s - d) % m
            pattern[s, x >> 6] |= np.int64(1) << (x & 63)
    if stage >= 1 and stage <= 5:
        LK.window_counts(image, search, most)
        LK.shift_tables(image, search, tables)
    left = 0
    for g in range(cst.shape[0] - 1):
        need = needs[g]
        if need > nz or LK.match_bound(chars, g, image) < need:
            continue
        if stage >= 2 and stage <= 5:
            total = 0
            for q in range(cst[g], cst[g + 1]):
                total += most[cl[q]]
            if total < need:
                continue
        if stage >= 3 and stage <= 5:
            if nz - need < total - need:
                if not LK.image_groups(chars, g, image, nz - need, pattern, valid, xs, groups):
                    continue
            elif not LK.reaches_groups(chars, g, total - need, most, tables, valid, groups):
                continue
        if stage >= 4 and stage <= 5:
            if total - need <= LK.BUDGET_MAX:
                if not LK.reaches_budget(chars, g, total - need, most, tables, valid, at_most):
                    continue
            elif not LK.reaches_tables(chars, g, need, tables, sum_planes):
                continue
        if stage >= 5:
            matched, sh = LK.shift_scores(chars, g, image, search, sets, planes)
            if matched < need:
                continue
        left += 1
    return left


def main(sky, n):
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]), seed=0)
    trials = sim.generate(n)
    alg = get_algorithm("lpt")()
    db = alg.build(cat, cam)
    params = alg._kernel_args(db, cam)[0]
    search = LK.search_at(params, np.int64(10))
    length = np.diff(db.char_start).astype(np.int64)
    img_sector, img_level = np.zeros(alg.n_sectors, np.int64), np.zeros(alg.n_sectors, np.int64)
    level_start, mask = np.zeros(alg.n_levels + 2, np.int64), np.zeros(alg.n_levels + 1, np.int64)
    by_level = np.zeros(3 * alg.n_sectors, np.int64)
    sets, planes = np.zeros((alg.n_sectors + 1, 2), np.int64), np.zeros((9, 2), np.int64)
    tot_t, tot_n = np.zeros(7), np.zeros(7)
    for i in range(n):
        obs = trials.observation(i, truth=False)
        nz = first_image_string(obs.x_px, obs.y_px, params, img_sector, img_level, level_start, by_level, mask)
        if nz < alg.min_score:
            continue
        image = LK.ImageString(img_sector, img_level, nz, level_start, by_level, mask)
        score = np.array([LK.shift_scores(db.chars, g, image, search, sets, planes)[0] for g in range(length.size)])
        rank = np.where(score >= alg.min_score, 1024 * score - np.minimum(length - score, 1023), -(10 ** 9))
        thr = np.sort(rank)[-alg.n_candidates]
        needs = np.array([LK.least_needed(thr, int(c), alg.min_score) for c in length], np.int64)
        row = []
        for stage in range(7):
            args = (stage, params, *db.chars, img_sector, img_level, nz, level_start, by_level, mask, needs)
            scan(*args)
            best = np.inf
            for _ in range(7):
                t0 = time.perf_counter()
                left = scan(*args)
                best = min(best, (time.perf_counter() - t0) * 1e6)
            tot_t[stage] += best
            tot_n[stage] += left
            row.append(f"{left:5d} {best:7.1f}")
        print(i, "nz", nz, " | ".join(row))
    print("stage: strings left, us (sums)")
    for stage in range(7):
        print(stage, int(tot_n[stage]), round(tot_t[stage], 1))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]))
