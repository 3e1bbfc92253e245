"""What the string scan of ``lpt`` must score, per reference star (issue #25, branch lptspeed2).

    python benchmarks/tools/lptspeed2_scan.py SKY N

Table 6's images (1 px / 0.5 Mv, seed 0), N of them; for every reference star the kernel scans
(up to the one accepted), every database string's level bound (``match_bound``) and exact score
(``shift_scores``) are computed, and the final candidate list's threshold; prints per reference:
the image string's length, the strings scored by the kernel's pruned scan, and the strings whose
exact score already reaches the final list's threshold (what any bound-and-score scan must score).
"""

import sys

import numpy as np
from numba import njit
from starid_algorithms.lpt import kernels as LK
from starid_algorithms.lpt_improved.planar import begin_identify, frame_at, reference_pattern

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import get_algorithm


@njit
def all_scores(x_px, y_px, params, char_sector, char_level, char_start, s, out_bound, out_score, out_len):
    sensor = frame_at(params, np.int64(0))
    search = LK.search_at(params, np.int64(10))
    chars = LK.Strings(char_sector, char_level, char_start)
    n = x_px.shape[0]
    trace = np.zeros(8, dtype=np.int64)
    rows, unit, usable, order = begin_identify(x_px, y_px, sensor, search.double_px, trace)
    m = search.n_sectors
    nbrs = np.empty(n, dtype=np.int64)
    r_px = np.empty(n)
    phi = np.empty(n)
    img = np.zeros(m, dtype=np.int64)
    img_sector = np.empty(m, dtype=np.int64)
    img_level = np.empty(m, dtype=np.int64)
    owner = np.empty(m, dtype=np.int64)
    level_start = np.zeros(search.n_levels + 2, dtype=np.int64)
    by_level = np.empty(m * (2 * search.level_tol + 1), dtype=np.int64)
    mask = np.zeros(search.n_levels + 1, dtype=np.int64)
    n_words = (m + 63) // 64
    sets = np.zeros((m + 1, n_words), dtype=np.int64)
    planes = np.zeros((9, n_words), dtype=np.int64)
    k = reference_pattern(unit, usable, x_px, y_px, s, search.cos_radius, sensor.f_px, nbrs, r_px, phi)
    if k < 1:
        return 0
    nz = LK.lpt_string(r_px, phi, k, search, img, owner)
    if nz < 1:
        return 0
    q = 0
    for j in range(m):
        if img[j] != 0:
            img_sector[q] = j
            img_level[q] = img[j]
            q += 1
    LK.index_image(img_sector, img_level, nz, search, level_start, by_level, mask)
    image = LK.ImageString(img_sector, img_level, nz, level_start, by_level, mask)
    for g in range(char_start.shape[0] - 1):
        out_len[g] = char_start[g + 1] - char_start[g]
        out_bound[g] = LK.match_bound(chars, g, image)
        sc, sh = LK.shift_scores(chars, g, image, search, sets, planes)
        out_score[g] = sc
    return nz


def main(sky, n):
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]), seed=0)
    trials = sim.generate(n)
    alg = get_algorithm("lpt")()
    db = alg.build(cat, cam)
    args = alg._kernel_args(db, cam)
    params = args[0]
    g = db.char_start.size - 1
    bound, score, length = np.zeros(g, np.int64), np.zeros(g, np.int64), np.zeros(g, np.int64)
    tot_scored = tot_need = tot_bound = 0
    for i in range(n):
        obs = trials.observation(i, truth=False)
        ident = alg.identify(db, obs)
        trace = alg._run(db, obs)[3]
        sensor = frame_at(params, np.int64(0))
        _, _, _, order = begin_identify(obs.x_px, obs.y_px, sensor, db.double_px, np.zeros(8, np.int64))
        last = int(trace[0])
        refs = []
        for s in order[:alg.max_refs]:
            nz = all_scores(obs.x_px, obs.y_px, params, *db.chars, int(s), bound, score, length)
            if nz >= alg.min_score:
                rank = np.where(score >= alg.min_score, 1024 * score - np.minimum(length - score, 1023), -10**9)
                thr = np.sort(rank)[-alg.n_candidates]
                # strings whose exact score makes a rank >= the list's last (must be scored)
                must = int((rank >= thr).sum())
                # the level bound's rank at the final threshold
                capped = np.minimum(bound, np.minimum(nz, 3 * length))
                brank = 1024 * capped - np.minimum(length - np.minimum(bound, nz), 1023)
                passb = int(((brank >= thr) & (bound >= alg.min_score)).sum())
                refs.append((int(s), nz, must, passb, int(thr // 1024 + 1)))
                tot_need += must
                tot_bound += passb
            if int(s) == last:
                break
        tot_scored += int(ident.counters.get("comparisons", 0))
        print(i, len(obs.x_px), "compared", ident.counters.get("comparisons"), "refs (s, nz, must, bound-pass, need):",
              refs)
    print("total scored", tot_scored, "must", tot_need, "bound at final threshold", tot_bound)


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
