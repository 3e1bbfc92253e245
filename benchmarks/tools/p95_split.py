"""What a plugin's p95 time per image is made of: the images it identifies, or those it fails on (issue #25, stop 46).

For each sky and label of a results folder (``starid table6 --trials 300 --out DIR``, say), prints the p95 /
median of ``time_us``, how many images are not correct and their median time against the label's median,
the share of the images at or above the p95 that are not correct, and the p95 / median over the correct
images alone:

    python benchmarks/tools/p95_split.py DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd


def main(folder: str) -> None:
    rows = pd.read_parquet(Path(folder) / "results.parquet")
    sky_column = "grid_sky" if "grid_sky" in rows.columns else None
    for sky, by_sky in (rows.groupby(sky_column) if sky_column else [("", rows)]):
        print(f"== {sky}")
        for label, x in by_sky.groupby("label"):
            med, p95 = x.time_us.median(), x.time_us.quantile(0.95)
            ok, bad = x[x.status == "correct"], x[x.status != "correct"]
            tail = x[x.time_us >= p95]
            bad_med = f"{bad.time_us.median() / med:5.1f}x" if len(bad) else "    -"
            print(f"{label:20s} median {med:7.1f} us  p95/median {p95 / med:5.1f} | not correct {len(bad):4d} of "
                  f"{len(x)}, their median {bad_med} | {100 * (tail.status != 'correct').mean():3.0f}% of the p95 "
                  f"tail | correct alone p95/median {ok.time_us.quantile(0.95) / ok.time_us.median():4.1f}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
