"""``starid report``: a results folder -> ``report.md``, one self-contained ``report.html``, ``figures/``.

A report is a list of blocks (headings, paragraphs, Markdown snippets with tables, figures)
rendered twice: as Markdown (figures linked as ``figures/<name>.png``) and as one HTML file
(figures embedded as base64 PNG, tables as HTML tables, a small inline stylesheet; no external
URL and no JavaScript). :func:`build_report` makes the report of one folder;
:func:`build_regression` (:mod:`starid.report.regression`) compares two folders of the same
experiment trial by trial.
"""

from __future__ import annotations

import base64
import html
import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from .. import experiments as builtin
from ..errors import ConfigError, StarIDWarning
from ..experiment import Experiment, read_manifest
from ..experiment.store import check_current, damaged_note, record_derived
from ..io import atomic_write_text
from ..provenance import versions
from ..stats import mcnemar_all, summarize
from . import figures as figs
from . import skymap
from .regression import build_regression, compare
from .tables import Table, markdown, mcnemar_markdown, pct, rate_ci
from .tables import setting as _fmt

FORMATS = ("md", "html")
SIM_FIELDS = ("sigma_px", "sigma_mag", "mag_limit", "false_stars", "lost_stars", "min_stars", "merge_radius_px",
              "sky_mag_limit")


# ---------------------------------------------------------------------------------------------- reading

def load(folder: str | Path) -> tuple[dict, pd.DataFrame]:
    """The manifest and the trial rows of a results folder (clear errors when it is not one)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError(f"{folder} is not a folder")
    manifest = read_manifest(folder)
    check_current(folder)     # results.parquet of another definition (an interrupted changed run) is refused
    path = folder / "results.parquet"
    if not path.is_file():
        raise ConfigError(f"{folder} has no results.parquet (an unfinished run? run the same command again to "
                          f"finish it){damaged_note(folder)}")
    try:
        frame = pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises several types for a damaged file
        raise ConfigError(f"{path} is unreadable: {exc}{damaged_note(folder)}") from None
    if frame.empty:
        raise ConfigError(f"{path} holds no rows")
    note = damaged_note(folder)
    if note:        # the report reads results.parquet; the damaged chunks matter only to a resumed run
        warnings.warn(f"{folder}: results.parquet reads{note}", StarIDWarning, stacklevel=2)
    return manifest, frame


def experiment_module(manifest: dict):
    """The built-in experiment module the folder was made by (``starid reproduce``), or ``None``."""
    name = manifest.get("experiment", {}).get("name")
    return builtin.get(name) if name in builtin.MODULES else None


# ---------------------------------------------------------------------------------------------- blocks

@dataclass
class Block:
    kind: str            # "h2", "h3", "p", "md" (Markdown text with tables), "fig"
    text: str = ""
    figure: figs.ReportFigure | None = None


def _kv_table(pairs: list[tuple[str, str]]) -> str:
    return markdown(pd.DataFrame(pairs, columns=["", "value"]))


def conditions(manifest: dict, frame: pd.DataFrame) -> list[Block]:
    """Camera, trials, seed and the simulated world of every study point (the settings that vary)."""
    exp = manifest.get("experiment", {})
    cam = {c[7:]: frame[c].iloc[0] for c in frame.columns if c.startswith("camera_")}
    cam_text = ", ".join(f"{k} = {_fmt(v)}" for k, v in cam.items())
    fov = ""
    if {"width_px", "focal_mm", "pixel_um"} <= set(cam):
        f_px = float(cam["focal_mm"]) / (float(cam["pixel_um"]) * 1e-3)
        fov = f" ({2 * math.degrees(math.atan(float(cam['width_px']) / 2 / f_px)):.2f} deg across)"
    pairs = [("experiment", f"{exp.get('name', '?')}: {exp.get('description', '') or 'no description'}"),
             ("trials per point", str(exp.get("trials", frame["trial"].nunique()))),
             ("seed", str(exp.get("seed", frame["seed"].iloc[0] if "seed" in frame else "?"))),
             ("camera", cam_text + fov),
             ("studies", ", ".join(s["name"] for s in exp.get("studies", [])) or ", ".join(frame["study"].unique())),
             ("success rule", "an image is correct when >= 3 stars get their true HIP and none a wrong one")]
    sim_cols = [f"sim_{k}" for k in SIM_FIELDS if f"sim_{k}" in frame.columns]
    points = frame.drop_duplicates(["study", "point"])[["study", "point"] + sim_cols].copy()
    varying = [c for c in sim_cols if points[c].map(_fmt).nunique() > 1]
    constant = [c for c in sim_cols if c not in varying]
    world = ", ".join(f"{c[4:]} = {_fmt(points[c].iloc[0])}" for c in constant)
    pairs.append(("simulated world (every point)", world + _sky_words(points)))
    blocks = [Block("h2", "Conditions"), Block("md", _kv_table(pairs))]
    if varying:
        shown = points[["study", "point"] + varying].rename(columns={c: c[4:] for c in varying})
        shown = shown.map(_fmt) if hasattr(shown, "map") else shown.applymap(_fmt)
        blocks.append(Block("p", "The settings that change from point to point (sky_mag_limit none = the real sky, "
                                 "every catalog star to V 8 imaged; 6 = the paper's sky, only its guide stars):"))
        blocks.append(Block("md", markdown(shown)))
    return blocks


def _sky_words(points: pd.DataFrame) -> str:
    if "sim_sky_mag_limit" not in points or points["sim_sky_mag_limit"].map(_fmt).nunique() > 1:
        return ""
    v = points["sim_sky_mag_limit"].iloc[0]
    return ("; the real sky (every catalog star to V 8 imaged)" if v is None or pd.isna(v)
            else f"; sky V <= {v:g} (only those stars imaged)")


def provenance(manifest: dict, frame: pd.DataFrame) -> list[Block]:
    """Versions, plugins, machine, command and dates."""
    m = manifest.get("machine", {})
    pk = m.get("packages", {})
    ver_cols = [c for c in frame.columns if c.endswith("_version") and c != "plugin_version"]
    row_versions = ", ".join(f"{c[:-8]} {frame[c].iloc[0]}" for c in ver_cols)
    pairs = [("results made by", row_versions or "?"),
             ("packages on that machine", ", ".join(f"{k.replace('_version', '')} {v}" for k, v in pk.items())),
             ("machine", f"{m.get('hostname', '?')}: {m.get('platform', '?')}, {m.get('cpu', '?')}, "
                         f"{m.get('cpu_count', '?')} cores"),
             ("command", f"`{manifest.get('command', '?')}`"),
             ("started / finished (UTC)", f"{manifest.get('started', '?')} / {manifest.get('finished', '?')}"),
             ("definition digest", f"`{manifest.get('digest', '?')}`"),
             ("report made by", f"starid {versions()['starid_version']}")]
    blocks = [Block("h2", "Provenance"), Block("md", _kv_table(pairs))]
    if "plugin_dist" in frame.columns:
        plug = frame.drop_duplicates("label")[["label", "algorithm", "plugin_dist", "plugin_version"]]
        params = [c for c in frame.columns if c.startswith("param_")]
        plug = plug.assign(parameters=[", ".join(f"{c[6:]}={_fmt(v)}" for c, v in zip(params, row, strict=True)
                                                 if not _missing(v))
                                       for row in frame.drop_duplicates("label")[params].itertuples(index=False)])
        blocks.append(Block("p", "Algorithm labels, the plugin distribution that provided them and the parameters "
                                 "they ran with (at the first point; parameters that follow the simulator change "
                                 "with it):"))
        blocks.append(Block("md", markdown(plug.map(_fmt) if hasattr(plug, "map") else plug.applymap(_fmt))))
    return blocks


def _missing(v) -> bool:
    return v is None or v is pd.NA or (isinstance(v, float) and math.isnan(v))


def generic_tables(frame: pd.DataFrame) -> list[Table]:
    """Per study: each label's summary at every point; McNemar for every pair at each point."""
    out = []
    for study, part in frame.groupby("study", sort=False):
        grid = [c for c in part.columns if c.startswith("grid_") and part[c].notna().any()]
        s = summarize(part, by=["point", *grid, "label"])
        shown = pd.DataFrame({c[5:]: s[c].map(_fmt) for c in grid})
        shown["label"] = s["label"]
        shown["trials"] = s["trials"]
        shown["id rate [95% CI]"] = [rate_ci(a, b, c) for a, b, c in zip(s["id_rate"], s["id_rate_lo"],
                                                                          s["id_rate_hi"], strict=True)]
        shown["misid"] = s["misid_rate"].map(pct)
        shown["no result"] = s["no_result_rate"].map(pct)
        shown["failed"] = (s["error_rate"] + s["timeout_rate"] + s["crash_rate"]).map(pct)
        shown["median time"] = s["time_median_us"].map(lambda v: f"{v / 1e3:.3f} ms")
        shown["DB (MB)"] = s["db_mb"].map(lambda v: f"{v:.3f}")
        notes = []
        if part["label"].nunique() > 1:
            rows = []
            for _point, g in part.groupby("point", sort=False):
                t = mcnemar_all(g)
                where = ", ".join(f"{c[5:]} = {_fmt(g[c].iloc[0])}" for c in grid) or "-"
                rows.append(t.assign(point=where))
            tests = pd.concat(rows, ignore_index=True)
            md = mcnemar_markdown(tests)
            md = _prepend_column(md, "point", list(tests["point"]))
            notes.append("McNemar's exact test on the same images (pairs of labels at each point):\n\n" + md)
        out.append(Table(f"summary_{study}", f"Study {study}: summary per point and label", s, markdown(shown),
                         tuple(notes)))
    return out


def _prepend_column(md: str, name: str, values: list) -> str:
    lines = md.rstrip("\n").split("\n")
    out = [f"| {name} " + lines[0], "|---" + lines[1]]
    out += [f"| {v} " + line for v, line in zip(values, lines[2:], strict=True)]
    return "\n".join(out) + "\n"


def tables_for(manifest: dict, frame: pd.DataFrame) -> tuple[list[Table], str]:
    """The experiment's own tables when it is a built-in one (else per-study summaries), and which."""
    mod = experiment_module(manifest)
    if mod is not None:
        try:
            exp = Experiment.from_dict(manifest["experiment"])
            return list(mod.tables(frame, exp)), f"the tables of the built-in experiment '{mod.NAME}' ({mod.TITLE})"
        except Exception as exc:  # a folder from another version: fall back, and say so
            return generic_tables(frame), f"per-study summaries (the built-in tables failed: {exc})"
    return generic_tables(frame), "per-study summaries"


# ---------------------------------------------------------------------------------------------- report

def _write_documents(blocks: list, title: str, folder: Path, stem: str, formats) -> dict:
    """``blocks`` written atomically as ``folder/stem.md`` and/or ``.html``; the paths by format."""
    written = {}
    if "md" in formats:
        written["md"] = folder / f"{stem}.md"
        atomic_write_text(written["md"], render_markdown(blocks))
    if "html" in formats:
        written["html"] = folder / f"{stem}.html"
        atomic_write_text(written["html"], render_html(blocks, title, folder))
    return written


def build_report(folder: str | Path, formats=FORMATS, svg: bool = True) -> dict:
    """Write ``report.md`` / ``report.html`` and ``figures/*`` into ``folder``; the written paths."""
    folder = Path(folder)
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        given = ",".join(formats) or "nothing"
        raise ConfigError(f"--format takes {', '.join(FORMATS)} (comma-separated), got {given}")
    manifest, frame = load(folder)
    mod = experiment_module(manifest)
    paper = mod.paper_points() if mod is not None and hasattr(mod, "paper_points") else None
    fig10 = getattr(mod, "PAPER_FIG10", None) if mod is not None else None
    tables, which = tables_for(manifest, frame)
    figures = figs.report_figures(frame, paper, fig10)
    # an experiment's own choice: one study or several (one map each); else the main condition
    sky_choice = getattr(mod, "SKYMAP_STUDY", None) if mod is not None else None
    sky_studies = [s for s in ([sky_choice] if isinstance(sky_choice, str) else list(sky_choice or ()))
                   if s in set(frame["study"])]
    sky_figures, sky_tables = [], []
    for k, study in enumerate(sky_studies or [None]):       # >= 2,000 trials each (sky issue)
        rows = figs.main_condition(frame) if study is None else frame[frame["study"] == study]
        f, t = skymap.skymap_parts(rows, where=study or "", suffix="" if k == 0 else f"_{study}")
        sky_figures, sky_tables = sky_figures + f, sky_tables + t
    figures, tables = figures + sky_figures, tables + sky_tables
    figs.save(figures, folder / "figures", svg=svg)
    exp = manifest.get("experiment", {})
    title = (mod.TITLE if mod is not None else f"Experiment {exp.get('name', folder.name)}") + " — starid report"
    blocks = [Block("h1", title), Block("p", _overview(manifest, frame, which))]
    blocks += conditions(manifest, frame)
    blocks += [Block("h2", "Tables"), Block("p", f"Tables: {which}. Rates carry their 95 % Wilson interval; "
                                                 f"times are medians on this machine (noisy, compare ratios).")]
    for t in tables:
        blocks += [Block("h3", t.title), Block("md", t.markdown)] + [Block("md", n) for n in t.notes]
    blocks.append(Block("h2", "Figures"))
    blocks.append(Block("p", "Every label keeps its colour, marker and line style in every figure, so the figures "
                             "read in black and white."))
    for f in figures:
        blocks += [Block("h3", f.title), Block("fig", f.caption, f)]
    blocks += provenance(manifest, frame)
    written = _write_documents(blocks, title, folder, "report", formats)
    written["figures"] = [folder / "figures" / f"{f.name}.png" for f in figures]
    svgs = [p.with_suffix(".svg") for p in written["figures"] if svg]
    record_derived(folder, [written[f] for f in formats] + written["figures"] + svgs, manifest.get("digest"))
    written["tables"] = [t.name for t in tables]
    return written


def _overview(manifest: dict, frame: pd.DataFrame, which: str) -> str:
    exp = manifest.get("experiment", {})
    labels = list(dict.fromkeys(frame["label"]))
    return (f"Results folder of experiment **{exp.get('name', '?')}**: {len(frame):,} trial rows, "
            f"{frame.groupby('study').ngroups} stud{'y' if frame['study'].nunique() == 1 else 'ies'}, "
            f"{frame.drop_duplicates(['study', 'point']).shape[0]} points, {len(labels)} algorithm labels "
            f"({', '.join(labels)}), {exp.get('trials', frame['trial'].nunique())} images per point (seed "
            f"{exp.get('seed', '?')}), definition digest `{manifest.get('digest', '?')}`. Below: the conditions, "
            f"{which}, the figures and the provenance.")


# ---------------------------------------------------------------------------------------------- rendering

def render_markdown(blocks: list[Block]) -> str:
    out = []
    for b in blocks:
        if b.kind == "h1":
            out.append(f"# {b.text}\n")
        elif b.kind == "h2":
            out.append(f"## {b.text}\n")
        elif b.kind == "h3":
            out.append(f"### {b.text}\n")
        elif b.kind in ("p", "md"):
            out.append(b.text.rstrip("\n") + "\n")
        elif b.kind == "fig":
            out.append(f"![{b.figure.title}](figures/{b.figure.name}.png)\n\n*{b.text}* "
                       f"([SVG](figures/{b.figure.name}.svg))\n")
    return "\n".join(out)


CSS = """
body { font-family: "DejaVu Sans", Helvetica, Arial, sans-serif; max-width: 1100px; margin: 2em auto;
       padding: 0 1em; color: #111; line-height: 1.45; font-size: 15px; }
h1 { font-size: 1.6em; border-bottom: 2px solid #111; padding-bottom: .2em; }
h2 { font-size: 1.3em; border-bottom: 1px solid #999; margin-top: 2em; }
h3 { font-size: 1.05em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: .6em 0 1em; font-size: 13px; }
th, td { border: 1px solid #999; padding: 3px 8px; text-align: left; vertical-align: top; }
th { background: #e8e8e8; }
tr:nth-child(even) td { background: #f6f6f6; }
figure { margin: 1em 0 2em; }
figure img { max-width: 100%; height: auto; border: 1px solid #ccc; }
figcaption { font-size: 13px; color: #333; margin-top: .3em; }
code { background: #f0f0f0; padding: 0 3px; }
"""


def _inline(text: str) -> str:
    t = html.escape(text, quote=False)
    t = re.sub(r"`([^`]+)`", r"<code>\1</code>", t)
    t = re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", t)
    return t


def markdown_to_html(text: str) -> str:
    """The little Markdown the reports use: pipe tables, headings, bullet lists and paragraphs."""
    out, para, table, items = [], [], [], []

    def flush():
        if para:
            out.append(f"<p>{_inline(' '.join(para))}</p>")
            para.clear()
        if items:
            out.append("<ul>" + "".join(f"<li>{_inline(i)}</li>" for i in items) + "</ul>")
            items.clear()
        if table:
            rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in table]
            body = [r for r in rows[1:] if not all(re.fullmatch(r":?-{3,}:?", c) for c in r)]
            head = "".join(f"<th>{_inline(c)}</th>" for c in rows[0])
            trs = "".join("<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in r) + "</tr>" for r in body)
            out.append(f"<table><thead><tr>{head}</tr></thead><tbody>{trs}</tbody></table>")
            table.clear()

    for line in text.splitlines():
        s = line.strip()
        if s.startswith("|"):
            if para or items:
                flush()
            table.append(s)
            continue
        if table:
            flush()
        if not s:
            flush()
        elif s.startswith("#"):
            flush()
            level = min(len(s) - len(s.lstrip("#")), 4)
            out.append(f"<h{level}>{_inline(s.lstrip('#').strip())}</h{level}>")
        elif s.startswith(("* ", "- ")):
            if para:
                flush()
            items.append(s[2:])
        else:
            para.append(s)
    flush()
    return "\n".join(out)


def render_html(blocks: list[Block], title: str, folder: Path) -> str:
    body = []
    for b in blocks:
        if b.kind in ("h1", "h2", "h3"):
            body.append(f"<{b.kind}>{_inline(b.text)}</{b.kind}>")
        elif b.kind in ("p", "md"):
            body.append(markdown_to_html(b.text))
        elif b.kind == "fig":
            data = base64.b64encode((folder / "figures" / f"{b.figure.name}.png").read_bytes()).decode("ascii")
            body.append(f'<figure><img alt="{html.escape(b.figure.title)}" src="data:image/png;base64,{data}">'
                        f"<figcaption>{_inline(b.text)}</figcaption></figure>")
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
            f"<style>{CSS}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")


# ---------------------------------------------------------------------------------------------- regression
# the regression report (every metric, world check, --fail-on gates) lives in regression.py

__all__ = ["build_regression", "build_report", "compare", "load", "markdown_to_html", "render_html",
           "render_markdown"]

