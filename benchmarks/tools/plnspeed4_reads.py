"""planar_triangle's two database lookups, cold as in the benchmark: before and after stop 47's prefetch passes.

    python benchmarks/tools/plnspeed4_reads.py paper 100 4

Table 6's sky (1 px / 0.5 Mv, seed 0), N images. Before each timed call every other plugin of
``benchmarks/test_ratios.py`` identifies the image (the benchmark's interleaving), so the database
is as cold as there. Prints median µs per image of

* the moment filter of the image's first K image triangles (the median image makes ~4), with a read
  of their candidates' star rows (what the kernel does next, the hash tables): a copy of
  the base's filter (a binary search per block of the moment index), a copy of the fence alone
  (no prefetch; tried and not kept in the plnspeed round), and the checkout's ``_moment_filter``
  (fence, then the index, ``moment_perm`` and stars lines prefetched for every block), in turns;
  the three must return the same entries;
* the image triangles' area lookups: a copy of the base's one-pass ``_image_triangles`` and the
  checkout's three passes, cold and at once again (warm); the same triangles and slices.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit
from starid_algorithms.planar_triangle import kernels as ptk

from starid import Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import chord_rows, kvector_query
from starid.registry import get_algorithm

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/
from test_ratios import NAMES, SKIES, TABLE6_SIM  # noqa: E402

BLOCK = ptk.MOMENT_BLOCK


@njit
def _binary_search_filter(moment, moment_perm, start, stop, lo, hi):
    """The base's ``_moment_filter`` (before stop 47), verbatim but for its arguments."""
    out = np.empty(max(stop - start, 0), dtype=np.int64)
    m = 0
    if stop <= start:
        return out
    n = moment.shape[0]
    for b in range(start // BLOCK, (stop - 1) // BLOCK + 1):
        base = b * BLOCK
        end = min(base + BLOCK, n)
        pos = base
        hi_pos = end
        while pos < hi_pos:
            mid = (pos + hi_pos) >> 1
            if moment[mid] < lo:
                pos = mid + 1
            else:
                hi_pos = mid
        while pos > base and moment[pos - 1] >= lo:
            pos -= 1
        while pos < end and moment[pos] <= hi:
            if moment[pos] >= lo:
                t = base + np.int64(moment_perm[pos])
                if t >= start and t < stop:
                    out[m] = pos
                    m += 1
            pos += 1
    return out[:m]


@njit
def _fence_filter(moment, fence, moment_perm, start, stop, lo, hi):
    """The fence alone: each block's stretch from its fence line, then the scan; nothing prefetched."""
    out = np.empty(max(stop - start, 0), dtype=np.int64)
    m = 0
    if stop <= start:
        return out
    n = moment.shape[0]
    for b in range(start // BLOCK, (stop - 1) // BLOCK + 1):
        base = b * BLOCK
        end = min(base + BLOCK, n)
        below = 0
        for k in range(ptk.FENCE_POSTS):
            below += fence[b, k] < lo
        pos = base + max(below - 1, 0) * ptk.FENCE_STEP + (below > 0)
        last = min(pos + ptk.FENCE_STEP - 1, end)
        while pos < last and moment[pos] < lo:
            pos += 1
        while pos < end and moment[pos] <= hi:
            if moment[pos] >= lo:
                t = base + np.int64(moment_perm[pos])
                if t >= start and t < stop:
                    out[m] = pos
                    m += 1
            pos += 1
    return out[:m]


@njit
def _filters(which, tables, starts, stops, los, his):
    """Every window's filter by one of the three, and their candidates' star rows read (as the hash tables
    do next): the entries concatenated, and the sum of the stars (so the reads are not optimised away)."""
    parts = []
    for q in range(starts.shape[0]):
        if which == 0:
            parts.append(_binary_search_filter(tables.moment, tables.moment_perm, starts[q], stops[q], los[q], his[q]))
        elif which == 1:
            parts.append(_fence_filter(tables.moment, tables.fence, tables.moment_perm, starts[q], stops[q], los[q],
                                       his[q]))
        else:
            parts.append(ptk._moment_filter(tables, starts[q], stops[q], los[q], his[q]))
    total = 0
    for p in parts:
        total += p.shape[0]
    out = np.empty(total, dtype=np.int64)
    k = 0
    stars = 0      # what the caller reads next: the candidates' star rows (the hash tables' keys)
    for p in parts:
        out[k:k + p.shape[0]] = p
        k += p.shape[0]
        for e in p:
            stars += np.int64(tables.stars[e, 0]) + tables.stars[e, 1] + tables.stars[e, 2]
    return out, stars


@njit
def _one_pass_triangles(img_v, db, tol):
    """The base's ``_image_triangles`` (one ``kvector_query`` per triangle as it is found): (tri, start, stop)."""
    n = img_v.shape[0]
    rules = db.rules
    max_t = n * (n - 1) * (n - 2) // 6
    img_tri = np.empty((max_t, 3), dtype=np.int64)
    img_start = np.empty(max_t, dtype=np.int64)
    img_stop = np.empty(max_t, dtype=np.int64)
    m = 0
    for i in range(n):
        for j in range(i + 1, n):
            if chord_rows(img_v, i, img_v, j) > rules.chord_max:
                continue
            for k in range(j + 1, n):
                if chord_rows(img_v, j, img_v, k) > rules.chord_max or chord_rows(img_v, i, img_v, k) > rules.chord_max:
                    continue
                area, mo, diam = ptk.triangle_features(img_v[i], img_v[j], img_v[k])
                if diam > rules.fov_rad or area < rules.min_area:
                    continue
                var_a, _ = ptk.triangle_variances(img_v[i], img_v[j], img_v[k], tol.sigma_rad)
                half = tol.beta * math.sqrt(var_a)
                start, stop = kvector_query(db.area, area - half, area + half)
                if stop - start > tol.climit:
                    continue
                img_tri[m, 0] = i
                img_tri[m, 1] = j
                img_tri[m, 2] = k
                img_start[m] = start
                img_stop[m] = stop
                m += 1
    return img_tri[:m], img_start[:m], img_stop[:m]


@njit
def _windows(v, tri, m, sigma_rad, beta):
    """The moment windows ``[J - beta sJ, J + beta sJ]`` of image triangles ``0..m-1`` (as ``_moment_list``)."""
    los, his = np.empty(m), np.empty(m)
    for t in range(m):
        r1, r2, r3 = v[tri[t, 0]], v[tri[t, 1]], v[tri[t, 2]]
        _, moment, _ = ptk.triangle_features(r1, r2, r3)
        _, var_j = ptk.triangle_variances(r1, r2, r3, sigma_rad)
        half = beta * math.sqrt(var_j)
        los[t], his[t] = moment - half, moment + half
    return los, his


def _timed(fn, *args):
    t0 = time.perf_counter_ns()
    out = fn(*args)
    return out, (time.perf_counter_ns() - t0) / 1e3


def main(sky: str, n_images: int, k_triangles: int) -> None:
    catalog, camera = load_hipparcos(), Camera()
    trials = Simulator(catalog, camera, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0).generate(n_images)
    observations = [trials.observation(i, truth=False) for i in range(n_images)]
    planar = get_algorithm("planar_triangle")()
    db = planar.build(catalog, camera)
    others = [get_algorithm(n)() for n in NAMES if n != "planar_triangle"]
    other_dbs = [a.build(catalog, camera) for a in others]
    planar.identify(db, observations[0])
    held = planar._held(db, camera)
    tables, tol = held[2], held[3]
    names = ("binary search", "fence alone", "checkout")
    filt = {k: [] for k in names}
    tri = {"one pass cold": [], "one pass warm": [], "checkout cold": [], "checkout warm": []}
    blocks = []

    def cold(o):
        for a, d in zip(others, other_dbs, strict=True):
            a.identify(d, o)

    images = []
    for i, o in enumerate(observations):
        _, v, _ = ptk.choose_stars(o.x_px, o.y_px, o.mag, held[4], held[5], camera.f_px, camera.cx_px, camera.cy_px)
        if v.shape[0] < 3:
            continue
        img = ptk.image_triangles(v, tables, tol)
        m = min(k_triangles, img.start.shape[0])
        if m == 0:
            continue
        los, his = _windows(img.v, img.tri, m, tol.sigma_rad, tol.beta)
        starts, stops = img.start[:m].copy(), img.stop[:m].copy()
        blocks.append(int(np.sum((stops - 1) // BLOCK - starts // BLOCK + 1)))
        got = [_filters(w, tables, starts, stops, los, his)[0] for w in range(3)]
        if not all(np.array_equal(got[0], g) for g in got[1:]):
            raise SystemExit(f"image {i}: the filters differ")
        one, new = _one_pass_triangles(v, tables, tol), ptk.image_triangles(v, tables, tol)
        if not all(np.array_equal(a, b) for a, b in zip(one, (new.tri, new.start, new.stop), strict=True)):
            raise SystemExit(f"image {i}: the image triangles differ")
        images.append((o, v, (starts, stops, los, his)))
    # each image's calls in the rounds rotate over the variants, one call per image and round: no variant
    # runs right after another on the same image (whose lines it would find in the shared cache)
    for r in range(6):
        for i, (o, v, windows) in enumerate(images):
            w = (i + r) % 3
            cold(o)
            _, us = _timed(_filters, w, tables, *windows)
            filt[names[w]].append(us)
            which = ("one pass", "checkout")[(i + r) % 2]
            fn = _one_pass_triangles if which == "one pass" else ptk.image_triangles
            cold(o)
            _, us = _timed(fn, v, tables, tol)
            _, us_warm = _timed(fn, v, tables, tol)
            tri[f"{which} cold"].append(us)
            tri[f"{which} warm"].append(us_warm)
    print(f"{sky} sky, {len(images)} images x 6 rounds, the first {k_triangles} image triangles' moment filters "
          f"({np.median(blocks):.0f} blocks of the index, median), cold after the other plugins, median µs:")
    for k in names:
        print(f"  {k:14s} {np.median(filt[k]):7.1f}")
    print("  image triangles (area lookups), median µs: "
          + ", ".join(f"{k} {np.median(t):.1f}" for k, t in tri.items()))


if __name__ == "__main__":
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
