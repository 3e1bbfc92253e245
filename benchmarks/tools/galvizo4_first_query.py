"""Our f and S (the galvizo2018 query table) for chosen readings, without the whole reproduction.

Runs the galvizo2018 experiment's false-star study (no noise, seed 0, the same images as
``starid reproduce galvizo2018`` at each point: images depend on the settings and seed only) for
the given variants and prints the query table's f / S columns and the accuracy per point.

    python benchmarks/tools/galvizo4_first_query.py TRIALS FALSE_STARS VARIANT...
    python benchmarks/tools/galvizo4_first_query.py 500 0 pyramid:galvizo2018 planar_triangle:galvizo2018

``--out DIR`` (first arguments) also writes the trial rows to ``DIR/results.parquet`` (for
``compare_rows.py``).
"""

from __future__ import annotations

import sys
from pathlib import Path

from starid.experiment import Experiment, Grid, Study, Variant, run_experiment
from starid.experiments import galvizo2018 as g


def main() -> None:
    args = sys.argv[1:]
    out = None
    if args[:1] == ["--out"]:
        out, args = Path(args[1]), args[2:]
    trials, points, names = int(args[0]), [int(x) for x in args[1].split(",")], args[2:]
    variants = tuple(Variant.parse(n) for n in names)   # NAME, NAME:SOURCE, NAME:SOURCE[KEY=VALUE,...]
    base = g.experiment(trials=trials, seed=0)
    study = Study("false_stars", variants, Grid({"false_stars": points, "sigma_px": [0.0]}))
    exp = Experiment(base.name, (study,), trials=trials, seed=0, camera=base.camera, sim=base.sim)
    frame = run_experiment(exp, None, jobs=1, progress=False)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        frame.to_parquet(out / "results.parquet")
    if 0 in points:
        q = g.query_table(frame).frame
        print(q[["label", "f_ours", "f_images", "S_ours_of_2000", "paper_f_correct_in_R", "paper_S_of_2000",
                 "time_mean_ms"]].to_string(index=False))
    acc = g.false_star_frame(frame)
    cols = ["label", "false_stars", "trials", "paper_accuracy", "printed_accuracy", "id_rate"]
    print(acc[cols].to_string(index=False))


if __name__ == "__main__":
    main()
