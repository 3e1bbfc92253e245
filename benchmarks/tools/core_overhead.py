"""Where a built-in experiment's worker time goes outside the plugins' own ``identify``.

    python benchmarks/tools/core_overhead.py EXPERIMENT TRIALS [NAME ...] [--profile FILE] [--sort KEY]

Plans ``EXPERIMENT`` (``table6``, ``zhou2015``, ...) at ``TRIALS`` images per point, keeps the chunks
of the plugins ``NAME ...`` (all when none is given) and computes each one in this process exactly as
a worker does (:func:`starid.experiment.executors.execute_task`; a warm numba cache assumed: run the
command once before). Prints per plugin, then per study: chunks, images, the sum of ``time_us``
(identify alone) and the wall seconds (``time_us`` is wall time too, so on a loaded machine both grow
alike) of simulating the chunks' images, of preparing (database, warm-up) and of the rest of the chunk
(handing each image over, scoring, row assembly: the harness' overhead), and both per image.
``--profile FILE`` writes a cProfile of the chunks (``pstats`` file) and prints its top functions by
``--sort`` (default ``tottime``).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from collections import defaultdict


def main(argv=None) -> int:
    p = argparse.ArgumentParser()
    p.add_argument("experiment")
    p.add_argument("trials", type=int)
    p.add_argument("names", nargs="*")
    p.add_argument("--profile", default="")
    p.add_argument("--sort", default="tottime")
    p.add_argument("--top", type=int, default=35)
    args = p.parse_args(argv)

    t_import = time.perf_counter()
    from starid import experiments
    from starid.catalog import load_hipparcos
    from starid.experiment import executors
    from starid.experiment.runner import plan
    from starid.scoring import SuccessRule
    t_import = time.perf_counter() - t_import

    exp = experiments.get(args.experiment).experiment(args.trials, 0)
    catalog = load_hipparcos()
    placements = plan(exp, catalog, SuccessRule())
    camera = exp.make_camera()
    seen, tasks = set(), []
    for pl in placements:
        c = pl.chunk
        if c.key in seen or (args.names and c.variant.name not in args.names):
            continue
        seen.add(c.key)
        cam = camera if c.camera is None else c.camera
        tasks.append((pl.study, executors.Task(len(tasks), c, "", cam, exp.seed, 3)))
    print(f"{len(tasks)} chunks; imports {t_import:.2f} s", file=sys.stderr)

    prep_cpu = [0.0]
    real_prepare = executors.prepare

    def timed_prepare(*a, **k):         # s of preparing (database, warm-up)
        t = time.perf_counter()
        try:
            return real_prepare(*a, **k)
        finally:
            prep_cpu[0] += time.perf_counter() - t

    executors.prepare = timed_prepare
    per = defaultdict(lambda: defaultdict(float))
    per_study = defaultdict(lambda: defaultdict(float))
    profiler = cProfile.Profile() if args.profile else None
    for study, task in tasks:
        t0 = time.perf_counter()
        executors._trials(task, executors._catalog(""))       # simulate (cached per block, as a worker)
        sim_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        prep_cpu[0] = 0.0
        if profiler is not None:
            profiler.enable()
        frame = executors.execute_task(task)
        if profiler is not None:
            profiler.disable()
        total_s = time.perf_counter() - t0
        ident_s = float(frame["time_us"].sum()) / 1e6
        prep_s = prep_cpu[0]
        for d in (per[task.chunk.variant.label], per_study[study]):
            d["chunks"] += 1
            d["images"] += len(frame)
            d["identify_s"] += ident_s
            d["simulate_s"] += sim_s
            d["prepare_s"] += prep_s
            d["rest_s"] += total_s - ident_s - prep_s
    head = f"{'':24s} {'chunks':>6s} {'images':>7s} {'identify s':>10s} {'simulate s':>10s} {'prepare s':>9s} " \
           f"{'rest s':>7s} {'id us/img':>9s} {'rest us/img':>11s}"
    for title, table in (("per label", per), ("per study", per_study)):
        print(f"\n{title}\n{head}")
        tot = defaultdict(float)
        for name, d in sorted(table.items(), key=lambda kv: -kv[1]["identify_s"]):
            for k, v in d.items():
                tot[k] += v
            _line(name, d)
        _line("total", tot)
    if profiler is not None:
        profiler.dump_stats(args.profile)
        pstats.Stats(args.profile).sort_stats(args.sort).print_stats(args.top)
    return 0


def _line(name, d) -> None:
    n = max(d["images"], 1)
    print(f"{name:24s} {d['chunks']:6.0f} {d['images']:7.0f} {d['identify_s']:10.2f} {d['simulate_s']:10.2f} "
          f"{d['prepare_s']:9.2f} {d['rest_s']:7.2f} {d['identify_s'] / n * 1e6:9.1f} {d['rest_s'] / n * 1e6:11.1f}")


if __name__ == "__main__":
    sys.exit(main())
