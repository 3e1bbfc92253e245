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


def compare(before: str | Path, after: str | Path) -> dict:
    """The comparison as data: ``rows`` (before, after, joined), ``key``, ``compared`` (non-time columns),
    ``only_before`` / ``only_after`` (columns), ``differing`` [(column, rows)], and per group of rows
    (label and point) ``groups`` [(group, correct before, correct after, lost, gained)]."""
    a = pd.read_parquet(Path(before) / "results.parquet")
    b = pd.read_parquet(Path(after) / "results.parquet")
    key = [c for c in ("study", "label", "point", "trial") if c in a.columns and c in b.columns]
    common = [c for c in a.columns if c in b.columns and c not in key and c not in TIME_COLUMNS]
    m = a.merge(b, on=key, suffixes=("_a", "_b"))
    differ = []
    for c in common:
        x, y = m[f"{c}_a"], m[f"{c}_b"]
        same = (x == y) | (x.isna() & y.isna())
        if not same.all():
            differ.append((c, int((~same).sum())))
    groups = []
    for g, x in m.groupby([k for k in key if k != "trial"], sort=True):
        ca, cb = x["status_a"] == "correct", x["status_b"] == "correct"
        groups.append((g, int(ca.sum()), int(cb.sum()), int((ca & ~cb).sum()), int((cb & ~ca).sum())))
    return {"rows": (len(a), len(b), len(m)), "key": key, "compared": len(common),
            "only_before": sorted(set(a.columns) - set(b.columns)),
            "only_after": sorted(set(b.columns) - set(a.columns)), "differing": differ, "groups": groups}


def main(before: str, after: str) -> int:
    r = compare(before, after)
    print(f"rows: {r['rows'][0]} before, {r['rows'][1]} after, {r['rows'][2]} joined on {r['key']}")
    print("only before:", r["only_before"], "| only after:", r["only_after"])
    print(f"non-time columns compared: {r['compared']}; differing (column, rows): {r['differing']}")
    for g, ca, cb, lost, gained in r["groups"]:
        print(f"{g}: correct {ca} -> {cb}  lost {lost}  gained {gained}")
    return 1 if any(lost for *_, lost, _ in r["groups"]) else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))
