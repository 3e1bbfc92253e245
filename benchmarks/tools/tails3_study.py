"""Issue #25's tails: which images are slow, what they answer, and how much work the correct ones needed.

    python benchmarks/tools/tails3_study.py RESULTS_DIR LABEL COUNTER [BOUND ...]
    python benchmarks/tools/tails3_study.py --bounds LABEL COUNTER B1,B2,... RESULTS_DIR [RESULTS_DIR ...]

Reads ``RESULTS_DIR/results.parquet`` (or its ``chunks/*.parquet`` while a run is still going) of one
``starid run`` (Table 6's settings: ``--trials 300 --jobs 1 --pos-noise-px 1 --mag-noise 0.5
--mag-limit 6 --min-stars 6 --sky real``) and prints, for ``LABEL``:

* time quantiles (median, p90, p95, max, p95 / median) from the rows' ``time_us``;
* the slowest 10 % of the images: outcome (correct / wrong / none), detections, and the work counter
  ``COUNTER`` (e.g. ``n_trios``, ``n_triads``, ``n_pairs``: the search's iterations);
* the distribution of ``COUNTER`` over the correct, wrong and unanswered images (work until the
  answer; for the unanswered, the work of the whole search);
* for each ``BOUND``: the images whose ``COUNTER`` exceeds it by outcome -- what an iteration cutoff at
  ``BOUND`` would turn into 'none' (a correct one over the bound would be lost).

``--bounds``: one line per results folder and bound: the images an iteration cutoff at the bound would
stop (their counter exceeds it), of them the correct ones (lost), the wrong ones (wrong -> none) and the
unanswered ones, and the counter's p95 / median with the counter clipped at the bound (the tail in
iterations, which the time follows on the no-answer images).

Counters, not times, decide the bound: they do not depend on the machine's load.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd


def load(folder: str) -> pd.DataFrame:
    p = Path(folder)
    if (p / "results.parquet").exists():
        return pd.read_parquet(p / "results.parquet")
    return pd.concat([pd.read_parquet(f) for f in sorted((p / "chunks").glob("*.parquet"))], ignore_index=True)


def outcome(status: pd.Series) -> pd.Series:
    return status.map(lambda s: s if s in ("correct", "wrong") else "none")


def main(folder: str, label: str, counter: str, bounds: list[int]) -> None:
    d = load(folder)
    d = d[d["label"] == label].copy()
    d["outcome"] = outcome(d["status"])
    t = d["time_us"].to_numpy()
    med, p90, p95 = np.percentile(t, [50, 90, 95])
    print(f"{label}: {len(d)} images; time_us median {med:.0f}, p90 {p90:.0f}, p95 {p95:.0f}, max {t.max():.0f};"
          f" p95/median {p95 / med:.1f}; outcomes {d['outcome'].value_counts().to_dict()}")
    slow = d.sort_values("time_us", ascending=False).head(max(1, len(d) // 10))
    print(f"slowest 10 % ({len(slow)} images): outcomes {slow['outcome'].value_counts().to_dict()}")
    print(slow[["trial", "outcome", "n_stars", "n_true_stars", counter, "time_us"]].to_string(index=False))
    print(f"\n{counter} by outcome (count, min, median, p90, p95, max; and the values of the correct ones over 5)")
    for o, g in d.groupby("outcome"):
        v = g[counter].to_numpy().astype(np.int64)
        print(f"  {o:8s} {len(v):4d}  {v.min():5d} {np.median(v):7.1f} {np.percentile(v, 90):7.1f} "
              f"{np.percentile(v, 95):7.1f} {v.max():5d}")
    c = np.sort(d.loc[d["outcome"] == "correct", counter].to_numpy().astype(np.int64))
    print("  correct, sorted values over 5:", c[c > 5].tolist())
    for b in bounds:
        over = d[d[counter] > b]
        print(f"bound {counter} <= {b}: images over it {len(over)}: {over['outcome'].value_counts().to_dict()}")


def bounds_table(label: str, counter: str, bounds: list[int], folders: list[str]) -> None:
    print(f"{label}, cutoff on {counter}: run | bound | images stopped | correct lost | wrong -> none | "
          f"none -> none | p95 / median of {counter} (clipped)")
    for folder in folders:
        d = load(folder)
        d = d[d["label"] == label]
        o = outcome(d["status"])
        v = d[counter].to_numpy().astype(np.int64)
        for b in [0, *bounds]:
            over = v > b if b else np.zeros(len(v), bool)
            w = np.minimum(v, b) if b else v
            print(f"{folder} | {b or 'none'} | {int(over.sum())} | {int((over & (o == 'correct')).sum())} | "
                  f"{int((over & (o == 'wrong')).sum())} | {int((over & (o == 'none')).sum())} | "
                  f"{np.percentile(w, 95) / np.median(w):.1f}")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--bounds":
        bounds_table(sys.argv[2], sys.argv[3], [int(x) for x in sys.argv[4].split(",")], sys.argv[5:])
        sys.exit(0)
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], sys.argv[3], [int(x) for x in sys.argv[4:]])
