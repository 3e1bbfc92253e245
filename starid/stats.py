"""Intervals, paired tests and summaries of trial rows (grouped by algorithm label)."""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd

from .scoring import CORRECT, CRASHED, ERROR, MISIDENTIFIED, NO_RESULT, TIMEOUT

#: The summary columns, in order (the first 15 are the CLI's printed contract).
SUMMARY_COLUMNS = [
    "algorithm", "trials", "id_rate", "id_rate_lo", "id_rate_hi", "misid_rate", "no_result_rate",
    "star_recall", "star_precision", "time_median_us", "time_mean_us", "time_p95_us", "db_mb",
    "build_s", "compile_s", "error_rate", "attitude_err_median_arcsec", "timeout_rate", "crash_rate", "label",
]


#: Summary columns added when the images went through render -> extract (``pipeline = "image"``).
IMAGE_COLUMNS = ["detection_rate", "false_detections_per_image", "rms_centroid_err_px"]


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (scipy's ``proportion_ci``); NaN for n = 0."""
    if n == 0:
        return (float("nan"), float("nan"))
    from scipy.stats import binomtest  # here, not at import: scipy.stats costs every process ~0.4 CPU s

    ci = binomtest(int(successes), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
    return (float(ci.low), float(ci.high))


def mcnemar(trials: pd.DataFrame, a: str, b: str, by: str = "label") -> dict:
    """Exact McNemar test of ``a`` vs ``b`` (values of ``by``) on the trials both ran.

    Correct vs anything else; under equal rates the discordant trials are binomial(1/2).
    """
    key = ["trial"] if "point" not in trials.columns else ["point", "trial"]
    # only the columns the test reads: a wide trial frame (one column per parameter) would be
    # copied whole, block by block, by the pivot
    part = trials[[*key, by]].assign(ok=(trials["status"] == CORRECT).to_numpy())
    wide = part.pivot_table(index=key, columns=by, values="ok", aggfunc="first")
    both = wide[[a, b]].dropna().astype(bool)
    only_a = int((both[a] & ~both[b]).sum())
    only_b = int((both[b] & ~both[a]).sum())
    from scipy.stats import binomtest

    p = binomtest(only_a, only_a + only_b, 0.5).pvalue if only_a + only_b else 1.0
    return {"a": a, "b": b, "only_a_correct": only_a, "only_b_correct": only_b, "p_value": float(p)}


def mcnemar_all(trials: pd.DataFrame, by: str = "label") -> pd.DataFrame:
    """McNemar's test for every pair of labels (in order of first appearance)."""
    names = list(dict.fromkeys(trials[by]))
    return pd.DataFrame([mcnemar(trials, a, b, by) for a, b in itertools.combinations(names, 2)],
                        columns=["a", "b", "only_a_correct", "only_b_correct", "p_value"])


def counter_columns_of(df: pd.DataFrame) -> list[str]:
    """The work-counter columns of trial rows: ``n_<name>`` columns beyond the harness schema
    (:data:`starid.harness.TRIAL_COLUMNS`) holding numbers."""
    from .harness import TRIAL_COLUMNS

    return [c for c in df.columns if c.startswith("n_") and c not in TRIAL_COLUMNS
            and pd.api.types.is_numeric_dtype(df[c])]


def _rate(g: pd.DataFrame, status: str) -> float:
    return float((g["status"] == status).mean())


def summarize(df: pd.DataFrame, by=("label",)) -> pd.DataFrame:
    """One row per group (default: per algorithm label, in order of first appearance).

    ``by`` may add grid columns (e.g. ``("point", "label")``); they follow the summary columns.
    Times are over the trials that ran (not over failures).
    """
    by = [by] if isinstance(by, str) else list(by)
    if "label" in by and "label" not in df.columns:
        df = df.assign(label=df["algorithm"])
    out = []
    counters = counter_columns_of(df)
    for key, g in df.groupby(by, sort=False):
        key = key if isinstance(key, tuple) else (key,)
        n = len(g)
        n_ok = int((g["status"] == CORRECT).sum())
        lo, hi = wilson_interval(n_ok, n)
        reported = g["n_identified"].sum()
        ran = g[~g["status"].isin([ERROR, TIMEOUT, CRASHED])]
        t = ran["time_us"].to_numpy() if len(ran) else np.array([np.nan])
        att = g["attitude_err_arcsec"]
        row = dict(zip(by, key, strict=True))
        row.update({
            "algorithm": g["algorithm"].iloc[0], "trials": n, "id_rate": n_ok / n,
            "id_rate_lo": lo, "id_rate_hi": hi,
            "misid_rate": _rate(g, MISIDENTIFIED), "no_result_rate": _rate(g, NO_RESULT),
            "star_recall": g["n_correct"].clip(lower=0).sum() / max(g["n_true_stars"].sum(), 1),
            "star_precision": g["n_correct"].clip(lower=0).sum() / reported if reported else float("nan"),
            "time_median_us": float(np.median(t)), "time_mean_us": float(np.mean(t)),
            "time_p95_us": float(np.percentile(t, 95)),
            "db_mb": float(g["db_mb"].iloc[0]), "build_s": float(g["build_s"].iloc[0]),
            "compile_s": float(g["compile_s"].iloc[0]),
            "error_rate": _rate(g, ERROR),
            "attitude_err_median_arcsec": float(np.nanmedian(att)) if att.notna().any() else float("nan"),
            "timeout_rate": _rate(g, TIMEOUT), "crash_rate": _rate(g, CRASHED),
        })
        if "img_n_detectable" in g.columns:   # the image pipeline: what extraction did, beside the id rate
            n_match = g["img_n_matched"].sum()
            row.update({"detection_rate": g["img_n_detected"].sum() / max(g["img_n_detectable"].sum(), 1),
                        "false_detections_per_image": float(g["img_n_false"].mean()),
                        "rms_centroid_err_px": float(np.sqrt(g["img_sq_err_px2_sum"].sum() / n_match))
                        if n_match else float("nan")})
        for c in counters:   # work counters (harness ``n_<name>`` columns): mean per image that ran
            row[f"{c}_mean"] = float(ran[c].mean()) if ran[c].notna().any() else float("nan")
        out.append(row)
    cols = SUMMARY_COLUMNS + [c for c in by if c != "label"]
    cols += [c for c in IMAGE_COLUMNS if out and c in out[0]]
    cols += [f"{c}_mean" for c in counters]
    return pd.DataFrame(out, columns=cols)


def split_by_stars(df: pd.DataFrame, threshold: int = 8, by=("label",)) -> pd.DataFrame:
    """Id rate with its interval for images with ``<= threshold`` and ``> threshold`` true stars."""
    rows = []
    by = list(by)
    for key, g in df.groupby(by, sort=False):
        key = key if isinstance(key, tuple) else (key,)
        for name, part in ((f"<= {threshold}", g[g["n_true_stars"] <= threshold]),
                           (f"> {threshold}", g[g["n_true_stars"] > threshold])):
            n, k = len(part), int((part["status"] == CORRECT).sum())
            lo, hi = wilson_interval(k, n)
            rows.append({**dict(zip(by, key, strict=True)), "stars": name, "trials": n,
                         "id_rate": k / n if n else float("nan"), "id_rate_lo": lo, "id_rate_hi": hi})
    return pd.DataFrame(rows)
