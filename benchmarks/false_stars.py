"""False-star comparison (issue #4): every registered algorithm with 0-3 false stars per image.

    python benchmarks/false_stars.py [--trials 2000] [--seed 1] [--jobs 2] [--out DIR]

Conditions otherwise as Table 6 (1 px / 0.5 Mv, > 5 stars, deep V <= 8 sky). For each number of
false stars all algorithms run on the same images. Prints a Markdown table of id rate and misid
rate (a misidentification is worse than no answer, so both are shown) and, with ``--out``, writes
``false_stars.md`` and ``false_stars.csv`` (the summary columns plus ``false_stars``).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import pandas as pd

from starid import Camera, SimConfig, Simulator, available_algorithms, load_hipparcos
from starid.harness import run, summarize
from starid.io import atomic_write_text, write_frame


def sweep(trials: int, seed: int, jobs: int, false_stars=(0, 1, 2, 3)) -> pd.DataFrame:
    catalog = load_hipparcos()
    algorithms = [info.cls() for info in available_algorithms() if info.status == "ok"]
    frames = []
    for k in false_stars:
        sim = Simulator(catalog, Camera(), SimConfig(sigma_px=1.0, sigma_mag=0.5, false_stars=k), seed=seed)
        summary = summarize(run(algorithms, sim.generate(trials), catalog, sim, jobs=jobs))
        frames.append(summary.assign(false_stars=k))
    return pd.concat(frames, ignore_index=True)


def markdown(table: pd.DataFrame, trials: int, seed: int) -> str:
    ks = sorted(table["false_stars"].unique())
    head = "| algorithm | " + " | ".join(f"{k} false: id / misid" for k in ks) + " |"
    lines = [f"False stars, {trials} images each, seed {seed}, 1 px / 0.5 Mv noise:", "", head,
             "|---|" + "---|" * len(ks)]
    for name, g in table.groupby("algorithm", sort=False):
        cells = [f"{100 * r.id_rate:.2f}% / {100 * r.misid_rate:.2f}%" for r in g.sort_values("false_stars").itertuples()]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    table = sweep(args.trials, args.seed, args.jobs)
    text = markdown(table, args.trials, args.seed)
    print(text, end="")
    if args.out:
        atomic_write_text(args.out / "false_stars.md", text)
        write_frame(table, args.out / "false_stars.csv")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
