"""``starid report OLD NEW``: two results folders of one experiment compared on the same images.

Trials are matched by study, grid values, label and trial index: common random numbers make trial
k the same image in both folders, so every rate is compared *paired*.

For every label and grid point present on both sides (and, per study and label, all points
pooled):

* **id rate, misidentification rate, failure rate** (error + timeout + crashed; the counts by status
  are listed): the paired difference new − old with a 95 % interval by Newcombe's hybrid score
  method for paired proportions (Newcombe 1998, *Stat. Med.* 17:2635, method 10: Wilson intervals
  of both rates combined with the phi correlation of the 2 x 2 table), and McNemar's exact test
  (the discordant images are Binomial(m, 1/2) under equal rates). The Newcombe interval stays
  informative when every discordant image goes one way (the conditional Clopper-Pearson interval of
  the old code put its upper end on the estimate, "+5.33 pp [+3.14, +5.33]") and when there is no
  discordant image at all (the old "+0.00 [+0.00, +0.00]"; now e.g. [−3.70, +3.70] pp for 100
  images that are all correct in both).
* **time**: the median and 95th-percentile identify time of both sides over the images that ran
  on both, and their ratio new / old with a 95 % percentile-bootstrap interval over images
  (images resampled with replacement, pairs kept together; 1000 resamples, seeded: the same folders
  give the same interval).
* **database size and build time** of both sides.

The two folders' settings (trials, seed, camera, simulated world, grids) are compared key by key;
when they differ the report refuses (:class:`~starid.errors.ConfigError`, exit 2) naming every
differing key, unless ``allow_different_worlds``. Labels and points present on one side only are
listed, not dropped.

``fail_on`` (CLI ``--fail-on``) names the conditions that make :func:`gate` true, for CI:
``worse`` (a label/point's id rate significantly lower, McNemar p < 0.05), ``misid`` (its
misidentification rate significantly higher) and ``slower:R`` (the lower end of its median-time
ratio interval above R, i.e. significantly more than R times slower). The pooled rows ("all points")
do not trigger a gate; every per-point row does.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import binomtest, norm

from .. import plots
from ..errors import ConfigError
from ..scoring import CORRECT, FAILED, MISIDENTIFIED
from . import figures as figs
from .tables import markdown, p_value, pct
from .tables import setting as _fmt

ALPHA = 0.05
BOOTSTRAP = 1000
#: CLI flags of the simulator settings whose manifest key is not the flag's name
FLAGS = {"sigma_px": "pos_noise_px (--pos-noise-px)", "sigma_mag": "mag_noise (--mag-noise)",
         "mag_limit": "mag_limit (--mag-limit)", "false_stars": "false_stars (--false-stars)",
         "lost_stars": "lost_stars (--lost-stars)", "min_stars": "min_stars (--min-stars)",
         "merge_radius_px": "merge_radius_px (--merge-radius-px)", "sky_mag_limit": "sky_mag_limit (--sky-mag-limit)"}


# ---------------------------------------------------------------------------------------------- statistics

def _wilson(k: int, n: int, z: float) -> tuple[float, float]:
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, mid - half), min(1.0, mid + half)


def newcombe_paired(both: int, only_new: int, only_old: int, neither: int,
                    confidence: float = 0.95) -> tuple[float, float]:
    """95 % interval of p_new − p_old for paired proportions: Newcombe (1998) method 10.

    ``p_new = (both + only_new) / n``, ``p_old = (both + only_old) / n``; with Wilson intervals
    (l1, u1) of p_new and (l2, u2) of p_old and phi the correlation of the 2 x 2 table (0 when a
    margin is empty), ``L = D − sqrt((p1 − l1)² − 2 phi (p1 − l1)(u2 − p2) + (u2 − p2)²)`` and
    ``U = D + sqrt((u1 − p1)² − 2 phi (u1 − p1)(p2 − l2) + (p2 − l2)²)``.
    """
    n = both + only_new + only_old + neither
    z = float(norm.ppf(0.5 + confidence / 2))
    p1, p2 = (both + only_new) / n, (both + only_old) / n
    l1, u1 = _wilson(both + only_new, n, z)
    l2, u2 = _wilson(both + only_old, n, z)
    den = (both + only_new) * (only_old + neither) * (both + only_old) * (only_new + neither)
    phi = (both * neither - only_new * only_old) / math.sqrt(den) if den > 0 else 0.0
    d = p1 - p2
    lo = d - math.sqrt(max(0.0, (p1 - l1) ** 2 - 2 * phi * (p1 - l1) * (u2 - p2) + (u2 - p2) ** 2))
    hi = d + math.sqrt(max(0.0, (u1 - p1) ** 2 - 2 * phi * (u1 - p1) * (p2 - l2) + (p2 - l2) ** 2))
    return max(-1.0, lo), min(1.0, hi)


def paired(old: np.ndarray, new: np.ndarray) -> dict:
    """Paired comparison of two boolean outcomes on the same images: both rates, the difference new −
    old with its Newcombe interval, the discordant counts and McNemar's exact p."""
    old, new = np.asarray(old, bool), np.asarray(new, bool)
    n = old.size
    only_old = int((old & ~new).sum())
    only_new = int((new & ~old).sum())
    both = int((old & new).sum())
    m = only_old + only_new
    p = binomtest(only_new, m, 0.5).pvalue if m else 1.0
    lo, hi = newcombe_paired(both, only_new, only_old, n - both - only_new - only_old)
    return {"trials": n, "old": float(old.mean()), "new": float(new.mean()), "diff": (only_new - only_old) / n,
            "lo": float(lo), "hi": float(hi), "only_old": only_old, "only_new": only_new, "p": float(p)}


def time_ratio(old_us: np.ndarray, new_us: np.ndarray, q: float, seed: int = 0) -> tuple[float, float, float]:
    """``quantile_q(new) / quantile_q(old)`` over paired images and its 95 % percentile-bootstrap
    interval (images resampled with replacement, pairs together, :data:`BOOTSTRAP` resamples)."""
    old_us, new_us = np.asarray(old_us, float), np.asarray(new_us, float)
    n = old_us.size
    if n == 0:
        return (math.nan,) * 3
    est = float(np.quantile(new_us, q) / np.quantile(old_us, q))
    rng = np.random.default_rng(seed)
    chunk = max(1, int(4_000_000 // n))
    ratios = []
    for start in range(0, BOOTSTRAP, chunk):
        idx = rng.integers(0, n, size=(min(chunk, BOOTSTRAP - start), n))
        ratios.append(np.quantile(new_us[idx], q, axis=1) / np.quantile(old_us[idx], q, axis=1))
    r = np.concatenate(ratios)
    return est, float(np.quantile(r, 0.025)), float(np.quantile(r, 0.975))


# ---------------------------------------------------------------------------------------------- matching

def _grid(frame: pd.DataFrame) -> list[str]:
    return [c for c in frame.columns if c.startswith("grid_")]


def _where(frame: pd.DataFrame, grid: list[str]) -> pd.Series:
    if not grid:
        return pd.Series("-", index=frame.index)
    cells = frame[grid].map(_fmt)
    return cells.apply(lambda r: ", ".join(f"{c[5:]}={v}" for c, v in r.items() if v != "none") or "-", axis=1)


def one_sided(old: pd.DataFrame, new: pd.DataFrame) -> pd.DataFrame:
    """The (study, point, label) found in one folder only: ``study, where, label, side, trials``."""
    grid = sorted(set(_grid(old)) | set(_grid(new)))
    rows = []
    keyed = {}
    for name, f in (("old", old), ("new", new)):
        f = f.assign(**{c: np.nan for c in grid if c not in f.columns})
        k = pd.DataFrame({"study": f["study"], "where": _where(f, grid), "label": f["label"]})
        keyed[name] = k.groupby(["study", "where", "label"], sort=False).size()
    for name, other in (("old", "new"), ("new", "old")):
        for key, count in keyed[name].items():
            if key not in keyed[other].index:
                rows.append({"study": key[0], "where": key[1], "label": key[2], "side": name, "trials": int(count)})
    return pd.DataFrame(rows, columns=["study", "where", "label", "side", "trials"])


def compare(old: pd.DataFrame, new: pd.DataFrame) -> pd.DataFrame:
    """Per study, point and label present in both folders (and per study and label, ``where = all
    points`` pooled when there are several points): every metric of the module docstring, paired on
    the trials both ran (matched by study, grid values, label and trial index).

    Columns: ``study, where, label, trials``; the id rate as ``old_rate, new_rate, diff, diff_lo,
    diff_hi, only_old_correct, only_new_correct, p_value``; ``misid_*`` and ``failed_*`` the same
    way (``*_old, *_new, *_diff, *_lo, *_hi, *_p``); ``failures_old/new`` (counts by status);
    ``time_median_old_us, time_median_new_us, time_ratio, time_ratio_lo, time_ratio_hi`` and the same
    ``time_p95_*``; ``db_mb_old/new, build_s_old/new``.
    """
    grid = sorted(set(_grid(old)) & set(_grid(new)))
    key = ["study", "where", "label", "trial"]
    cols = ["status", "time_us", "db_mb", "build_s"]
    old = old.assign(**{c: np.nan for c in cols[1:] if c not in old.columns})
    new = new.assign(**{c: np.nan for c in cols[1:] if c not in new.columns})
    a = old[["study", "label", "trial"] + cols].assign(where=_where(old, grid))
    b = new[["study", "label", "trial"] + cols].assign(where=_where(new, grid))
    m = a.merge(b, on=key, suffixes=("_old", "_new"))
    if m.empty:
        raise ConfigError("the two folders share no (study, point, label, trial): nothing to compare")
    rows = []
    for (study, label), g in m.groupby(["study", "label"], sort=False):
        parts = list(g.groupby("where", sort=False))
        if len(parts) > 1:
            parts.append(("all points", g))
        for where, h in parts:
            rows.append({"study": study, "where": where, "label": label, **_metrics(h)})
    return pd.DataFrame(rows)


def _failures(status: pd.Series) -> str:
    counts = status[status.isin(FAILED)].value_counts()
    return ", ".join(f"{s} {int(counts[s])}" for s in FAILED if s in counts) or "none"


def _metrics(h: pd.DataFrame) -> dict:
    so, sn = h["status_old"], h["status_new"]
    ident = paired((so == CORRECT).to_numpy(), (sn == CORRECT).to_numpy())
    out = {"trials": ident["trials"], "old_rate": ident["old"], "new_rate": ident["new"], "diff": ident["diff"],
           "diff_lo": ident["lo"], "diff_hi": ident["hi"], "only_old_correct": ident["only_old"],
           "only_new_correct": ident["only_new"], "p_value": ident["p"]}
    for name, hit in (("misid", lambda s: s == MISIDENTIFIED), ("failed", lambda s: s.isin(FAILED))):
        r = paired(hit(so).to_numpy(), hit(sn).to_numpy())
        out.update({f"{name}_old": r["old"], f"{name}_new": r["new"], f"{name}_diff": r["diff"],
                    f"{name}_lo": r["lo"], f"{name}_hi": r["hi"], f"{name}_p": r["p"]})
    out["failures_old"], out["failures_new"] = _failures(so), _failures(sn)
    ran = ~so.isin(FAILED) & ~sn.isin(FAILED)
    to, tn = h.loc[ran, "time_us_old"].to_numpy(float), h.loc[ran, "time_us_new"].to_numpy(float)
    for name, q in (("median", 0.5), ("p95", 0.95)):
        est, lo, hi = time_ratio(to, tn, q)
        out.update({f"time_{name}_old_us": float(np.quantile(to, q)) if to.size else math.nan,
                    f"time_{name}_new_us": float(np.quantile(tn, q)) if tn.size else math.nan,
                    f"time_{name}_ratio" if name == "p95" else "time_ratio": est,
                    f"time_{name}_ratio_lo" if name == "p95" else "time_ratio_lo": lo,
                    f"time_{name}_ratio_hi" if name == "p95" else "time_ratio_hi": hi})
    for c in ("db_mb", "build_s"):
        # one database per label and point: the mean over the (study, point) blocks pooled here
        out[f"{c}_old"] = float(h[f"{c}_old"].mean())
        out[f"{c}_new"] = float(h[f"{c}_new"].mean())
    return out


# ---------------------------------------------------------------------------------------------- worlds

def _flat(d: dict, prefix: str = "") -> dict:
    """Nested dicts as ``{"a.b": value}``."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def world(manifest: dict, frame: pd.DataFrame) -> dict:
    """The settings that define the images a folder scored, flattened ``key -> value``: trials, seed,
    camera, the simulated world (manifest and the rows' ``sim_*`` / ``camera_*`` columns), and each
    study's grid axes. The algorithms (variants) are not part of the world."""
    exp = manifest.get("experiment", {})
    out = {"trials": exp.get("trials"), "seed": exp.get("seed")}
    out.update({f"camera.{k}": v for k, v in _flat(exp.get("camera") or {}).items()})
    out.update({f"sim.{k}": v for k, v in _flat(exp.get("sim") or {}).items()})
    for s in exp.get("studies", []):
        grid = s.get("grid", {})
        for axis, values in (grid.get("axes") or {}).items():
            out[f"study {s.get('name')}: grid {axis}"] = values
        out[f"study {s.get('name')}: grid mode"] = grid.get("mode")
    for c in frame.columns:
        if c.startswith(("sim_", "camera_")):
            values = sorted({_fmt(v) for v in frame[c].unique()})
            out[f"rows {c}"] = values[0] if len(values) == 1 else values
    return out


def _setting_name(key: str) -> str:
    for prefix in ("sim.", "rows sim_"):
        if key.startswith(prefix) and key[len(prefix):] in FLAGS:
            return f"{key[:len(prefix)]}{key[len(prefix):]} = {FLAGS[key[len(prefix):]]}"
    return key


def world_differences(mo: dict, fo: pd.DataFrame, mn: dict, fn: pd.DataFrame) -> list[tuple[str, str, str]]:
    """``(setting, old value, new value)`` for every world setting that differs (absent = "not set")."""
    wo, wn = world(mo, fo), world(mn, fn)
    out = []
    for k in list(dict.fromkeys([*wo, *wn])):
        vo, vn = wo.get(k, "not set"), wn.get(k, "not set")
        if _fmt_value(vo) != _fmt_value(vn):
            out.append((_setting_name(k), _fmt_value(vo), _fmt_value(vn)))
    return out


def _fmt_value(v) -> str:
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_fmt_value(x) for x in v) + "]"
    return _fmt(v)


# ---------------------------------------------------------------------------------------------- gates

def parse_fail_on(values) -> list[tuple[str, float | None]]:
    """``["worse", "misid,slower:1.2"]`` -> ``[("worse", None), ("misid", None), ("slower", 1.2)]``."""
    out = []
    for text in values or []:
        for item in (x.strip() for x in str(text).split(",")):
            if not item:
                continue
            name, _, arg = item.partition(":")
            if name in ("worse", "misid") and not arg:
                out.append((name, None))
            elif name == "slower" and arg:
                try:
                    r = float(arg)
                except ValueError:
                    r = math.nan
                if not (math.isfinite(r) and r > 0):
                    raise ConfigError(f"--fail-on {item}: slower takes a positive ratio, e.g. slower:1.2")
                out.append(("slower", r))
            else:
                raise ConfigError(f"--fail-on takes worse, misid or slower:RATIO (comma-separated), got {item!r}")
    return out


def judged(diff: pd.DataFrame) -> pd.DataFrame:
    """The rows a gate looks at: every label and point (not the pooled 'all points' rows)."""
    return diff[diff["where"] != "all points"]


def gate(diff: pd.DataFrame, fail_on) -> list[str]:
    """The reasons ``fail_on`` (from :func:`parse_fail_on`) fails, one line per label/point; empty = pass."""
    d = judged(diff)
    out = []
    for name, arg in fail_on:
        if name == "worse":
            bad = d[(d["p_value"] < ALPHA) & (d["diff"] < 0)]
            out += [f"worse: {r.study}/{r.label} @ {r.where}: id rate {100 * r.diff:+.2f} pp (McNemar p = "
                    f"{p_value(r.p_value)})" for r in bad.itertuples()]
        elif name == "misid":
            bad = d[(d["misid_p"] < ALPHA) & (d["misid_diff"] > 0)]
            out += [f"misid: {r.study}/{r.label} @ {r.where}: misidentification {100 * r.misid_diff:+.2f} pp "
                    f"(McNemar p = {p_value(r.misid_p)})" for r in bad.itertuples()]
        elif name == "slower":
            bad = d[d["time_ratio_lo"] > arg]
            out += [f"slower:{arg:g}: {r.study}/{r.label} @ {r.where}: median time x{r.time_ratio:.2f} "
                    f"[{r.time_ratio_lo:.2f}, {r.time_ratio_hi:.2f}]" for r in bad.itertuples()]
    return out


# ---------------------------------------------------------------------------------------------- document

def _pp(d, lo, hi) -> str:
    return f"{100 * d:+.2f} pp [{100 * lo:+.2f}, {100 * hi:+.2f}]"


def _ratio(r, lo, hi) -> str:
    return "" if not math.isfinite(r) else f"x{r:.2f} [{lo:.2f}, {hi:.2f}]"


def _mark(p, d, judge: bool, worse_if_negative: bool = True) -> str:
    if not judge or p >= ALPHA or d == 0:
        return ""
    return "**worse**" if (d < 0) == worse_if_negative else "**better**"


def build_regression(old: str | Path, new: str | Path, out: str | Path | None = None, formats=("md", "html"),
                     svg: bool = True, allow_different_worlds: bool = False) -> tuple[dict, pd.DataFrame]:
    """``regression.md`` / ``regression.html`` / ``figures/regression.*`` in ``out`` (default: ``new``).

    Refuses (:class:`ConfigError`) two experiments of different names, and two folders whose worlds
    differ (the differing settings named) unless ``allow_different_worlds``. Returns the written
    paths (plus ``written["differences"]``, ``written["one_sided"]``) and the :func:`compare` rows.
    """
    from .build import Block, _kv_table, _write_documents, load

    old, new = Path(old), Path(new)
    out = Path(out) if out is not None else new
    mo, fo = load(old)
    mn, fn = load(new)
    no, nn = mo.get("experiment", {}).get("name"), mn.get("experiment", {}).get("name")
    if no != nn:
        raise ConfigError(f"{old} holds experiment {no!r} and {new} holds {nn!r}: a regression report compares two "
                          f"folders of the same experiment")
    differences = world_differences(mo, fo, mn, fn)
    if differences and not allow_different_worlds:
        listed = "; ".join(f"{k}: {a} (old) vs {b} (new)" for k, a, b in differences)
        raise ConfigError(f"{old} and {new} simulate different worlds, so a difference in rate would not be the "
                          f"algorithm's: {listed}. Run both with the same settings, or pass "
                          f"--allow-different-worlds to compare anyway")
    diff = compare(fo, fn)
    lone = one_sided(fo, fn)
    fig = figs.ReportFigure("regression", "Rate differences, new − old",
                            "Identification rate of the new folder minus the old one per label and point, with a 95 % "
                            "interval for paired proportions (Newcombe's hybrid score method); filled markers: "
                            "McNemar's exact test p < 0.05 (the same images in both folders, matched by trial index).",
                            plots.regression(diff, f"{nn}: new − old on the same images"))
    figs.save([fig], out / "figures", svg=svg)
    d = judged(diff)
    worse = d[(d["p_value"] < ALPHA) & (d["diff"] < 0)]
    better = d[(d["p_value"] < ALPHA) & (d["diff"] > 0)]
    if differences:
        verdict = (f"**The worlds differ** ({len(differences)} setting(s), listed below): compared anyway "
                   f"(--allow-different-worlds), so a difference may be the world's and not the algorithm's. ")
    else:
        verdict = ""
    verdict += (f"Id rate: {len(worse)} label/point(s) significantly worse, {len(better)} significantly better "
                f"(McNemar p < 0.05) out of {len(d)}; with many points a few p < 0.05 arise by chance (about 1 in "
                f"20).")
    ident = pd.DataFrame({
        "study": diff["study"], "point": diff["where"], "label": diff["label"], "trials": diff["trials"],
        "old": diff["old_rate"].map(pct), "new": diff["new_rate"].map(pct),
        "new − old [95% CI]": [_pp(a, b, c)
                               for a, b, c in zip(diff["diff"], diff["diff_lo"], diff["diff_hi"], strict=True)],
        "only old correct": diff["only_old_correct"], "only new correct": diff["only_new_correct"],
        "McNemar p": diff["p_value"].map(p_value),
        "": [_mark(p, x, w != "all points")
             for p, x, w in zip(diff["p_value"], diff["diff"], diff["where"], strict=True)]})
    errs = pd.DataFrame({
        "study": diff["study"], "point": diff["where"], "label": diff["label"],
        "misid old": diff["misid_old"].map(pct), "misid new": diff["misid_new"].map(pct),
        "misid new − old [95% CI]": [_pp(a, b, c) for a, b, c in zip(diff["misid_diff"], diff["misid_lo"],
                                                                     diff["misid_hi"], strict=True)],
        "misid p": diff["misid_p"].map(p_value),
        "failed old": diff["failed_old"].map(pct) + " (" + diff["failures_old"] + ")",
        "failed new": diff["failed_new"].map(pct) + " (" + diff["failures_new"] + ")",
        "failed new − old [95% CI]": [_pp(a, b, c) for a, b, c in zip(diff["failed_diff"], diff["failed_lo"],
                                                                      diff["failed_hi"], strict=True)],
        "failed p": diff["failed_p"].map(p_value),
        "": [(_mark(p, x, w != "all points", False) + " " + _mark(q, y, w != "all points", False)).strip()
             for p, x, q, y, w in zip(diff["misid_p"], diff["misid_diff"], diff["failed_p"], diff["failed_diff"],
                                      diff["where"], strict=True)]})
    cost = pd.DataFrame({
        "study": diff["study"], "point": diff["where"], "label": diff["label"],
        "median time old / new (ms)": [f"{a / 1e3:.3f} / {b / 1e3:.3f}" for a, b in
                                       zip(diff["time_median_old_us"], diff["time_median_new_us"], strict=True)],
        "median ratio [95% CI]": [_ratio(a, b, c) for a, b, c in zip(diff["time_ratio"], diff["time_ratio_lo"],
                                                                     diff["time_ratio_hi"], strict=True)],
        "p95 time old / new (ms)": [f"{a / 1e3:.3f} / {b / 1e3:.3f}" for a, b in
                                    zip(diff["time_p95_old_us"], diff["time_p95_new_us"], strict=True)],
        "p95 ratio [95% CI]": [_ratio(a, b, c) for a, b, c in zip(diff["time_p95_ratio"], diff["time_p95_ratio_lo"],
                                                                  diff["time_p95_ratio_hi"], strict=True)],
        "DB old / new (MB)": [f"{a:.3f} / {b:.3f}" for a, b in zip(diff["db_mb_old"], diff["db_mb_new"], strict=True)],
        "build old / new (s)": [f"{a:.2f} / {b:.2f}"
                                for a, b in zip(diff["build_s_old"], diff["build_s_new"], strict=True)]})

    def side(m, f, name, path):
        plug = f.drop_duplicates("label")
        # a missing column is "": the zip is then empty, so not strict
        pv = ", ".join(f"{lab} {dd} {v}" for lab, dd, v in zip(plug["label"], plug.get("plugin_dist", ""),
                                                             plug.get("plugin_version", ""), strict=False))
        ver = ", ".join(f"{c[:-8]} {f[c].iloc[0]}" for c in f.columns if c.endswith("_version") and
                        c != "plugin_version")
        return [(f"{name} folder", f"`{path}`"), (f"{name} versions", ver), (f"{name} plugins", pv),
                (f"{name} run", f"{m.get('started')} / {m.get('finished')} on {m.get('machine', {}).get('hostname')}"),
                (f"{name} digest", f"`{m.get('digest')}`")]

    pairs = side(mo, fo, "old", old) + side(mn, fn, "new", new)
    title = f"Regression report: {nn}, {new.name} vs {old.name}"
    blocks = [Block("h1", title),
              Block("p", f"Every label and point present in both folders compared on the same images (trials "
                         f"matched by index: common random numbers make trial k the same image in both). {verdict}"),
              Block("h2", "Settings")]
    if differences:
        blocks.append(Block("p", "The settings that differ between the two folders:"))
        blocks.append(Block("md", markdown(pd.DataFrame(differences, columns=["setting", "old", "new"]))))
    else:
        blocks.append(Block("p", "Both folders simulate the same world (trials, seed, camera, simulated world and "
                                 "grids equal key by key); only the algorithms may differ."))
    blocks.append(Block("h2", "Labels and points on one side only"))
    if lone.empty:
        blocks.append(Block("p", "None: every label and point is in both folders."))
    else:
        blocks.append(Block("p", "Not compared (found in one folder only):"))
        blocks.append(Block("md", markdown(lone.astype(str))))
    blocks += [Block("h2", "Identification rate"),
               Block("p", "New − old with a 95 % interval for paired proportions (Newcombe 1998, hybrid score "
                          "method 10); McNemar's exact test on the discordant images."),
               Block("md", markdown(ident)),
               Block("h2", "Misidentification and failures"),
               Block("p", "Misidentified: an image where some star got a wrong HIP. Failed: error, timeout or "
                          "crash (counts by status in brackets). Same interval and test as the id rate; here an "
                          "increase is worse."),
               Block("md", markdown(errs)),
               Block("h2", "Time, database size and build time"),
               Block("p", f"Times over the images that ran in both folders, on each folder's machine (compare "
                          f"ratios, and only from the same machine); ratio new / old with a 95 % bootstrap "
                          f"interval over images ({BOOTSTRAP} paired resamples)."),
               Block("md", markdown(cost)),
               Block("h2", "Figure"), Block("fig", fig.caption, fig),
               Block("h2", "Provenance"), Block("md", _kv_table(pairs))]
    written = _write_documents(blocks, title, out, "regression", formats)
    if (out / "manifest.json").is_file():    # inside a results folder: made from NEW's definition (and OLD's)
        from ..experiment.store import record_derived

        record_derived(out, [written[f] for f in formats] + sorted((out / "figures").glob("regression.*")),
                       mn.get("digest") if out.resolve() == new.resolve() else None, old_digest=mo.get("digest"),
                       new_digest=mn.get("digest"))
    written["differences"] = differences
    written["one_sided"] = lone
    return written, diff


__all__ = ["build_regression", "compare", "gate", "newcombe_paired", "one_sided", "paired", "parse_fail_on",
           "time_ratio", "world", "world_differences"]
