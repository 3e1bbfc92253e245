"""A/B timing of one plugin's kernels module against a modified copy, in one process, interleaved
image by image (issue #25, branch tailspeed2).

    python benchmarks/tools/tailspeed2_ab.py NAME ALT_KERNELS.py N R [real|paper]

NAME is a plugin (``pvector``) or variant (``pvector:paper``); ALT_KERNELS.py a copy of its
``kernels.py`` with a change. Both are identified on Table 6's images (1 px / 0.5 Mv, seed 0, N of
them), R rounds, A and B on each image in turn (which goes first alternates: the second call on an image finds
its data in the caches); each image's time is the minimum of its R. B runs with every
global of the plugin's ``algorithm`` module that came from ``kernels`` swapped for ALT's. Prints per
version the median, p95, p95 / median, the 90th-97th percentile images' summed time, the 20 slowest
under A summed, and whether the hip arrays and counters agree on every image.
"""

import importlib
import importlib.util
import sys
import time

import numpy as np

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.experiment.spec import Variant

TABLE6_SIM = {"sigma_px": 1.0, "sigma_mag": 0.5, "mag_limit": 6.0, "min_stars": 6}


def main(spec, alt_path, n, rounds, sky):
    cat, cam = load_hipparcos(), Camera()
    sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    a = Variant.parse(spec).make()
    db = a.build(cat, cam)
    pkg = type(a).__module__.rsplit(".", 1)[0]
    algo_mod = importlib.import_module(type(a).__module__)
    kern = importlib.import_module(pkg + ".kernels")
    # the copy is compiled, not cached: numba names its cache files after the source file, so a copy of
    # another checkout's kernels.py would share (and overwrite) that checkout's cache entries
    src = open(alt_path).read().replace("cache=True", "cache=False")
    s = importlib.util.spec_from_loader(pkg + ".kernels_alt", loader=None, origin=alt_path)
    alt = importlib.util.module_from_spec(s)
    alt.__file__ = alt_path
    sys.modules[pkg + ".kernels_alt"] = alt
    exec(compile(src, alt_path, "exec"), alt.__dict__)
    swaps = {}
    for k, v in vars(algo_mod).items():
        if v is kern:
            swaps[k] = (v, alt)
        elif hasattr(kern, k) and getattr(kern, k) is v and hasattr(alt, k) and callable(v):
            swaps[k] = (v, getattr(alt, k))

    def use(which):
        for k, pair in swaps.items():
            setattr(algo_mod, k, pair[which])

    for w in (0, 1):
        use(w)
        a.identify(db, obs[0])
    t = np.full((2, n), np.inf)
    res = [[None] * n, [None] * n]
    for rnd in range(rounds):
        for k, o in enumerate(obs):
            for w in ((0, 1) if (rnd + k) % 2 == 0 else (1, 0)):   # alternated: the second call finds warm caches
                use(w)
                t0 = time.perf_counter_ns()
                r = a.identify(db, o)
                t[w, k] = min(t[w, k], (time.perf_counter_ns() - t0) * 1e-9)
                res[w][k] = r
    use(0)
    same = all(np.array_equal(res[0][k].hip, res[1][k].hip) for k in range(n))
    same_c = all(res[0][k].counters == res[1][k].counters for k in range(n))
    order = np.argsort(-t[0])
    band = order[n // 33: n // 10]      # the images around the 95th percentile (A's 3rd to 10th slowest %)
    tail = order[: max(1, n // 10)]
    print(f"{sky} sky, {spec}, {n} images, min of {rounds}; swapped: {sorted(swaps)}")
    for w, label in ((0, "A (kernels.py)"), (1, f"B ({alt_path})")):
        med, p95 = np.median(t[w]), np.percentile(t[w], 95)
        print(f"  {label:40s} median {med * 1e6:7.1f} us  p95 {p95 * 1e6:7.1f} us  p95/med {p95 / med:5.2f}  "
              f"p90-97 band {t[w, band].sum() * 1e3:6.2f} ms  tail {t[w, tail].sum() * 1e3:6.2f} ms  "
              f"all {t[w].sum() * 1e3:6.2f} ms")
    print(f"  same hips {same}, same counters {same_c}")


if __name__ == "__main__":
    if len(sys.argv) not in (5, 6):
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5] if len(sys.argv) == 6 else "real")
