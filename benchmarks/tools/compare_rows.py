"""Compare two results folders trial row by trial row (the "no correct identification lost" check).

    python benchmarks/tools/compare_rows.py BEFORE_DIR AFTER_DIR

Reads each folder's ``results.parquet``, joins the rows on (study, label, point, trial) where those
columns exist, and prints: the non-time columns that differ (NaN equal to NaN; ``time_us``,
``build_s``, ``compile_s`` left out), the columns only one side has, and per label and point the
correct counts before and after with the images that turned correct -> not correct ("lost") and the
reverse ("gained"). Exit status 1 when a correct identification was lost.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

TIME_COLUMNS = {"time_us", "build_s", "compile_s"}


def main(before: str, after: str) -> int:
    a = pd.read_parquet(Path(before) / "results.parquet")
    b = pd.read_parquet(Path(after) / "results.parquet")
    key = [c for c in ("study", "label", "point", "trial") if c in a.columns and c in b.columns]
    common = [c for c in a.columns if c in b.columns and c not in key and c not in TIME_COLUMNS]
    m = a.merge(b, on=key, suffixes=("_a", "_b"))
    print(f"rows: {len(a)} before, {len(b)} after, {len(m)} joined on {key}")
    only_a, only_b = sorted(set(a.columns) - set(b.columns)), sorted(set(b.columns) - set(a.columns))
    print("only before:", only_a, "| only after:", only_b)
    differ = []
    for c in common:
        x, y = m[f"{c}_a"], m[f"{c}_b"]
        same = (x == y) | (x.isna() & y.isna())
        if not same.all():
            differ.append((c, int((~same).sum())))
    print(f"non-time columns compared: {len(common)}; differing (column, rows): {differ}")
    lost_total = 0
    group = [k for k in key if k != "trial"]
    for g, x in m.groupby(group, sort=True):
        ca, cb = x["status_a"] == "correct", x["status_b"] == "correct"
        lost, gained = int((ca & ~cb).sum()), int((cb & ~ca).sum())
        lost_total += lost
        print(f"{g}: correct {int(ca.sum())} -> {int(cb.sum())}  lost {lost}  gained {gained}")
    return 1 if lost_total else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))
