"""The pictures behind ``starid report`` and ``starid show``: each takes pandas frames, returns a Figure.

Every function draws on a fresh :class:`matplotlib.figure.Figure` (no pyplot state, any
backend), in one style (:data:`STYLE`) that stays readable in black and white: each algorithm
label gets its own marker *and* line style as well as a colour (:func:`label_styles`), bands are
light grey-tinted fills, and every axis names its unit. Pass the same ``styles`` mapping to
several functions so that a label looks the same in every picture of a report.

Trial-row frames are the engine's (``starid.experiment.run_experiment`` or
``results.parquet``): columns ``label, trial, status, time_us, db_mb, n_true_stars`` and the
``grid_<axis>`` columns of a sweep. In a notebook::

    import starid.plots as sp
    fig = sp.rate_curve(frame[frame.study == "fig12"], "sigma_px")
    fig.savefig("fig12.png")
"""

from __future__ import annotations

import functools
import math
import textwrap

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullFormatter

from .stats import mcnemar, wilson_interval

#: The one style of every picture (fonts, grid, no top/right spines).
STYLE = {
    "font.size": 9, "axes.titlesize": 10, "axes.labelsize": 9, "legend.fontsize": 8, "xtick.labelsize": 8,
    "ytick.labelsize": 8, "axes.grid": True, "grid.color": "0.85", "grid.linewidth": 0.6,
    "axes.spines.top": False, "axes.spines.right": False, "axes.edgecolor": "0.2", "lines.linewidth": 1.4,
    "lines.markersize": 5, "legend.frameon": False, "figure.dpi": 100, "savefig.dpi": 150,
    "svg.fonttype": "none", "hatch.linewidth": 0.6,
}
#: Okabe-Ito colours (colour-blind safe), ordered so that neighbours differ in lightness too.
COLORS = ("#000000", "#E69F00", "#0072B2", "#009E73", "#D55E00", "#56B4E9", "#CC79A7", "#7F7F7F")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "h")
LINESTYLES = ("-", "--", ":", "-.", (0, (5, 1, 1, 1, 1, 1)), (0, (1, 2)), (0, (8, 2)), (0, (3, 1, 1, 1)))
#: Axis names as printed, with their units.
AXIS_NAMES = {
    "sigma_px": "centroid noise σ (px)", "sigma_mag": "magnitude noise σ (mag)", "false_stars": "false stars per image",
    "lost_stars": "lost stars per image", "mag_limit": "detection limit (mag)", "sky_mag_limit": "sky limit V (mag)",
    "min_stars": "minimum true stars per image", "merge_radius_px": "merge radius (px)", "sky": "sky",
    "rate_deg_s": "angular rate (deg/s)", "velocity_kms": "observer speed (km/s)",
    "planets_in_view": "planets in view (count)", "focal_error_pct": "focal-length error (%)",
    "assumed_distortion": "lens the algorithms assume",
}
#: How ``starid show`` marks each star (shape first, colour second).
STAR_MARKS = {
    "correct": {"marker": "o", "color": "#009E73", "size": 13, "fill": False, "text": "true HIP = identified"},
    "wrong": {"marker": "X", "color": "#D55E00", "size": 11, "fill": True, "text": "wrong id (id / true)"},
    "missed": {"marker": "s", "color": "0.45", "size": 12, "fill": False, "text": "missed (true HIP)"},
    "false": {"marker": "^", "color": "#0072B2", "size": 12, "fill": False, "text": "false star, not identified"},
}


#: boxplot's horizontal switch (``orientation`` since Matplotlib 3.10, ``vert`` before)
_HORIZONTAL = ({"orientation": "horizontal"} if tuple(int(x) for x in matplotlib.__version__.split(".")[:2]) >= (3, 10)
               else {"vert": False})


def label_styles(labels) -> dict:
    """``label -> {color, marker, linestyle}``, in order; distinct in colour, marker and dash."""
    out = {}
    for i, label in enumerate(dict.fromkeys(labels)):
        out[label] = {"color": COLORS[i % len(COLORS)], "marker": MARKERS[i % len(MARKERS)],
                      "linestyle": LINESTYLES[i % len(LINESTYLES)]}
    return out


def _styles(labels, styles):
    base = label_styles(labels)
    if styles:
        extra = [x for x in base if x not in styles]
        more = label_styles(list(styles) + extra)
        base = {x: styles.get(x, more[x]) for x in base}
    return base


def _styled(fn):
    """Draw the whole figure under :data:`STYLE` (rcParams are read as artists are made)."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with matplotlib.rc_context(STYLE):
            return fn(*args, **kwargs)
    return wrapper


def _figure(width_in: float, height_in: float) -> Figure:
    return Figure(figsize=(width_in, height_in), layout="constrained")


#: Where a label may go relative to its point (points), tried in order: beside it first, then farther.
LABEL_OFFSETS_PT = ((7, -7), (7, 7), (-7, -7), (-7, 7), (9, 0), (-9, 0), (0, 10), (0, -10), (14, -14), (14, 14),
                    (-14, -14), (-14, 14), (0, 18), (0, -18), (22, 0), (-22, 0))


def _renderer(fig):
    """A renderer with the figure's layout settled (constrained layout runs at draw time): the draw
    computes every artist's extent without rasterizing (a full Agg draw per call made a 14-panel
    ``starid show`` spend a minute in drawing alone)."""
    if not hasattr(fig.canvas, "get_renderer"):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        FigureCanvasAgg(fig)
    fig.draw_without_rendering()
    return fig.canvas.get_renderer()


def place_labels(ax, x, y, texts, obstacles_xy=None, obstacle_pt: float = 6.0, required: bool = False,
                 taken: list | None = None, pad_pt: float = 1.5, renderer=None, **text_kw) -> list:
    """Annotate point i with ``texts[i]`` at the first of :data:`LABEL_OFFSETS_PT` where its box
    overlaps no label placed before it (``taken`` carries boxes between calls), no obstacle point
    (a square of ``obstacle_pt`` around each of ``obstacles_xy``, e.g. the other stars) and stays
    inside the axes. A label that fits nowhere is left out, unless ``required``: then it goes to
    the offset with the least overlap, joined to its point by a thin line. Greedy and deterministic,
    in the order given (put the labels a caption refers to first). Returns the annotations.
    ``renderer``: one from :func:`_renderer` after the layout is settled, for several calls on one figure
    (labels are outside the layout, so placing some moves nothing; otherwise each call draws the figure)."""
    renderer = renderer if renderer is not None else _renderer(ax.figure)
    taken = [] if taken is None else taken
    to_px = ax.figure.dpi / 72.0
    pad = pad_pt * to_px
    frame = ax.get_window_extent(renderer)
    points = ax.transData.transform(np.column_stack([x, y])) if len(x) else np.zeros((0, 2))
    blocks = []
    if obstacles_xy is not None and len(obstacles_xy):
        half = 0.5 * obstacle_pt * to_px
        for ox, oy in ax.transData.transform(np.asarray(obstacles_xy, dtype=float)):
            blocks.append((ox - half, oy - half, ox + half, oy + half))

    def overlap(box, others):
        return sum(max(0.0, min(box[2], o[2]) - max(box[0], o[0])) * max(0.0, min(box[3], o[3]) - max(box[1], o[1]))
                   for o in others)

    out = []
    for (px, py), xd, yd, text in zip(points, x, y, texts, strict=True):
        best = None
        for dx, dy in LABEL_OFFSETS_PT:
            ann = ax.annotate(text, (xd, yd), xytext=(dx, dy), textcoords="offset points",
                              ha="left" if dx > 0 else "right" if dx < 0 else "center",
                              va="bottom" if dy > 0 else "top" if dy < 0 else "center", **text_kw)
            ann.set_in_layout(False)
            bb = ann.get_window_extent(renderer)
            box = (bb.x0 - pad, bb.y0 - pad, bb.x1 + pad, bb.y1 + pad)
            inside = bb.x0 >= frame.x0 and bb.x1 <= frame.x1 and bb.y0 >= frame.y0 and bb.y1 <= frame.y1
            own = [b for b in blocks if not (b[0] <= px <= b[2] and b[1] <= py <= b[3])]
            cost = overlap(box, taken) + overlap(box, own) + (0.0 if inside else 1e9)
            if cost == 0.0:
                if best is not None:
                    best[0].remove()
                best = (ann, box, 0.0)
                break
            if best is None or cost < best[2]:
                if best is not None:
                    best[0].remove()
                best = (ann, box, cost)
            else:
                ann.remove()
        ann, box, cost = best
        if cost > 0.0 and not required:
            ann.remove()
            continue
        if cost > 0.0:
            ax.annotate("", (xd, yd), xytext=ann.xyann, textcoords="offset points",
                        arrowprops={"arrowstyle": "-", "linewidth": 0.5, "color": "0.4"}).set_in_layout(False)
        taken.append(box)
        out.append(ann)
    return out


def axis_name(axis: str) -> str:
    """The printed name of a grid axis, with its unit."""
    return AXIS_NAMES.get(axis, axis)


def _rates(frame: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    ok = frame.assign(_ok=frame["status"] == "correct").groupby(by, sort=False)["_ok"].agg(["sum", "count"])
    ok = ok.reset_index()
    ci = [wilson_interval(int(k), int(n)) for k, n in zip(ok["sum"], ok["count"], strict=True)]
    ok["rate"] = ok["sum"] / ok["count"]
    ok["lo"] = [c[0] for c in ci]
    ok["hi"] = [c[1] for c in ci]
    return ok


def _numeric(values) -> bool:
    try:
        np.asarray(list(values), dtype=float)
        return True
    except (TypeError, ValueError):
        return False


@_styled
def rate_curve(frame: pd.DataFrame, axis: str, paper: pd.DataFrame | None = None, title: str = "",
               styles: dict | None = None, paper_name: str = "paper") -> Figure:
    """Id rate (%) vs one swept axis, one line per label with its 95 % Wilson band.

    ``frame``: trial rows with ``grid_<axis>`` (or ``<axis>``), ``label``, ``status``; other grid
    columns with several values split a label into several lines. ``paper``: printed points
    (``value, algorithm, paper_id_rate``; ``algorithm`` is matched to the labels), drawn as large
    open markers of the label's shape.
    """
    col = f"grid_{axis}" if f"grid_{axis}" in frame.columns else axis
    others = [c for c in frame.columns if c.startswith("grid_") and c != col and frame[c].nunique(dropna=False) > 1]
    frame = frame.assign(_line=frame["label"].astype(str))
    if others:
        frame["_line"] = frame["_line"] + " (" + frame[others].astype(str).apply(
            lambda r: ", ".join(f"{c[5:]}={v}" for c, v in r.items()), axis=1) + ")"
    r = _rates(frame, ["_line", "label", col])
    numeric = _numeric(r[col])
    cats = list(dict.fromkeys(frame[col])) if not numeric else None
    lines = list(dict.fromkeys(r["_line"]))
    st = _styles(lines, styles if not others else None)
    n_paper = paper["algorithm"].nunique() if paper is not None and len(paper) else 0
    fig = _figure(6.4, 4.2 + 0.2 * math.ceil((len(lines) + n_paper) / 2))
    ax = fig.add_subplot()
    n = len(lines)
    for i, line in enumerate(lines):
        g = r[r["_line"] == line]
        s = st[line]
        if numeric:
            x = g[col].astype(float).to_numpy()
            order = np.argsort(x)
            x = x[order]
            y, lo, hi = (100 * g[c].to_numpy()[order] for c in ("rate", "lo", "hi"))
            ax.fill_between(x, lo, hi, color=s["color"], alpha=0.09, linewidth=0)
            ax.plot(x, lo, color=s["color"], linewidth=0.5, alpha=0.5, linestyle=s["linestyle"])
            ax.plot(x, hi, color=s["color"], linewidth=0.5, alpha=0.5, linestyle=s["linestyle"])
            ax.plot(x, y, color=s["color"], marker=s["marker"], linestyle=s["linestyle"], label=line,
                    markeredgecolor="black" if s["color"] != "#000000" else "black", markeredgewidth=0.5)
        else:
            x = np.array([cats.index(v) for v in g[col]], dtype=float) + (i - (n - 1) / 2) * 0.08
            y, lo, hi = (100 * g[c].to_numpy() for c in ("rate", "lo", "hi"))
            ax.errorbar(x, y, yerr=[y - lo, hi - y], color=s["color"], marker=s["marker"], linestyle="none",
                        capsize=3, label=line, markeredgecolor="black", markeredgewidth=0.5)
    handles, names = ax.get_legend_handles_labels()
    if paper is not None and len(paper):
        for algorithm, g in paper.groupby("algorithm", sort=False):
            match = [x for x in lines if x == algorithm or x.startswith(f"{algorithm} (")]
            if not match:
                continue
            s = st[match[0]]
            xs = g["value"].astype(float).to_numpy() if numeric else np.array([cats.index(v) for v in g["value"]])
            ax.plot(xs, 100 * g["paper_id_rate"].astype(float).to_numpy(), linestyle="none", marker=s["marker"],
                    markersize=11, markerfacecolor="none", markeredgecolor=s["color"], markeredgewidth=1.8, zorder=5)
            handles.append(Line2D([], [], linestyle="none", marker=s["marker"], markersize=9, markerfacecolor="none",
                                  markeredgecolor=s["color"], markeredgewidth=1.8))
            names.append(f"{algorithm}: {paper_name}'s printed value")
    if not numeric:
        ax.set_xticks(range(len(cats)), [str(c) for c in cats])
        ax.set_xlim(-0.5, len(cats) - 0.5)
    elif np.all(np.mod(r[col].astype(float).to_numpy(), 1.0) == 0.0):   # a count: no 0.5 ticks
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel(axis_name(axis))
    ax.set_ylabel("identification rate (%), 95 % Wilson band")
    lo_y = min(100 * r["lo"].min(), 100 * paper["paper_id_rate"].astype(float).min()
               if paper is not None and len(paper) else 100)
    ax.set_ylim(max(0.0, math.floor(lo_y / 5) * 5 - 2), 101.8)
    ax.set_title(title or f"identification rate vs {axis_name(axis)}")
    fig.legend(handles, names, loc="outside lower center", ncol=2 if len(names) > 3 else len(names))
    return fig


@_styled
def time_distributions(frame: pd.DataFrame, title: str = "", styles: dict | None = None) -> Figure:
    """Identify time per image (µs, log axis), one box per label: box 25-75 %, whiskers 5-95 %,
    the median printed beside it. Failed images (error, timeout, crash) are left out."""
    ran = frame[~frame["status"].isin(["error", "timeout", "crashed"]) & frame["time_us"].gt(0)]
    labels = list(dict.fromkeys(frame["label"]))
    st = _styles(labels, styles)
    fig = _figure(6.4, 0.8 + 0.45 * len(labels))
    ax = fig.add_subplot()
    data = [ran.loc[ran["label"] == x, "time_us"].to_numpy() for x in labels]
    pos = np.arange(len(labels))[::-1]
    keep = [i for i, d in enumerate(data) if d.size]
    if keep:
        bp = ax.boxplot([data[i] for i in keep], positions=pos[keep], **_HORIZONTAL, whis=(5, 95), widths=0.55,
                        patch_artist=True, showfliers=True, flierprops={"marker": ".", "markersize": 2,
                                                                         "markerfacecolor": "0.4",
                                                                         "markeredgecolor": "none"},
                        medianprops={"color": "black", "linewidth": 1.6})
        for patch, i in zip(bp["boxes"], keep, strict=True):
            patch.set_facecolor(st[labels[i]]["color"])
            patch.set_alpha(0.35)
            patch.set_hatch(["", "//", "..", "xx", "\\\\", "oo", "++", "--"][i % 8])
            med = float(np.median(data[i]))
            ax.annotate(_us(med), (med, pos[i] + 0.3), fontsize=7, ha="center", va="bottom")
    ax.set_xscale("log")
    _plain_log(ax)
    ax.set_yticks(pos, labels)
    ax.set_ylim(-0.7, len(labels) - 0.3)
    ax.set_xlabel("identify time per image (µs, log scale); box 25-75 %, whiskers 5-95 %")
    ax.grid(axis="y", visible=False)
    ax.set_title("\n".join(textwrap.wrap(title or "identify time per image", 75)))
    return fig


def _us(v: float) -> str:
    return f"{v / 1e3:.3g} ms" if v >= 1000 else f"{v:.3g} µs"


@_styled
def tradeoff(summary: pd.DataFrame, title: str = "", styles: dict | None = None) -> Figure:
    """Two panels: id rate vs median identify time and vs database size (both log), one marker per
    label with its Wilson interval. ``summary``: :func:`starid.stats.summarize` rows."""
    labels = list(summary["label"])
    st = _styles(labels, styles)
    fig = _figure(7.6, 3.6)
    axes = fig.subplots(1, 2, sharey=True)
    for ax, col, name in ((axes[0], "time_median_us", "median identify time (µs, log scale)"),
                          (axes[1], "db_mb", "database size (MB, log scale)")):
        for r in summary.itertuples():
            s = st[r.label]
            x = getattr(r, col)
            if not (x > 0):
                continue
            y = 100 * r.id_rate
            ax.errorbar([x], [y], yerr=[[y - 100 * r.id_rate_lo], [100 * r.id_rate_hi - y]], marker=s["marker"],
                        color=s["color"], markeredgecolor="black", markeredgewidth=0.5, markersize=8, capsize=3,
                        linestyle="none", label=r.label)
        ax.set_xscale("log")
        ax.set_xlabel(name)
        _pad_log(ax)
    axes[0].set_ylabel("identification rate (%), 95 % Wilson interval")
    axes[0].set_title("rate vs time (up-left is better)", fontsize=9)
    axes[1].set_title("rate vs memory (up-left is better)", fontsize=9)
    if title:
        fig.suptitle("\n".join(textwrap.wrap(title, 90)))
    for ax, col in ((axes[0], "time_median_us"), (axes[1], "db_mb")):
        drawn = summary[summary[col] > 0]
        xy = np.column_stack([drawn[col].to_numpy(dtype=float), 100 * drawn["id_rate"].to_numpy(dtype=float)])
        place_labels(ax, xy[:, 0], xy[:, 1], list(drawn["label"]), obstacles_xy=xy, obstacle_pt=9.0,
                     required=True, fontsize=7)
    return fig


def _pad_log(ax) -> None:
    lo, hi = ax.get_xlim()
    if lo > 0 and hi > 0:
        ax.set_xlim(lo / 1.6, hi * 2.5)
    _plain_log(ax)


def _plain_log(ax) -> None:
    """Log x axis ticked at 1, 2, 5 x 10^k (1 x 10^k over more than two decades), plain numbers."""
    lo, hi = ax.get_xlim()
    wide = lo > 0 and hi / lo > 200   # 1-2-5 ticks crowd the axis beyond two decades
    ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0,) if wide else (1.0, 2.0, 5.0)))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())


@_styled
def star_histogram(frame: pd.DataFrame, by: str | None = None, paper: dict | None = None, title: str = "") -> Figure:
    """Fig. 10: how many true stars the images hold (``n_true_stars``, one count per image).

    ``by`` (e.g. ``grid_sky``) draws one outline per value; ``paper`` (``min, max, mean,
    share_above_8``) is printed in the legend beside the measured statistics.
    """
    key = [c for c in ("study", "point", "trial") if c in frame.columns]
    first = frame[frame["label"] == frame["label"].iloc[0]] if "label" in frame.columns else frame
    images = first.drop_duplicates(key)
    groups = list(images.groupby(by, sort=False)) if by else [("images", images)]
    fig = _figure(6.4, 3.9 + 0.2 * (len(groups) + bool(paper)))
    ax = fig.add_subplot()
    top = int(images["n_true_stars"].max()) if len(images) else 1
    bins = np.arange(0.5, top + 1.5, 1.0)
    for i, (name, g) in enumerate(groups):
        n = g["n_true_stars"].to_numpy()
        text = (f"{name}: {n.size} images, min {n.min()}, max {n.max()}, mean {n.mean():.2f}, "
                f"> 8 stars {100 * (n > 8).mean():.1f} %")
        ax.hist(n, bins=bins, histtype="step" if i else "stepfilled", color=COLORS[i % len(COLORS)],
                facecolor="0.8" if not i else "none", hatch=None if not i else "//", linewidth=1.4,
                linestyle=LINESTYLES[i % len(LINESTYLES)], label=text, density=True)
    if paper:
        ax.plot([], [], " ", label=f"paper (Fig. 10): min {paper['min']}, max {paper['max']}, mean "
                                   f"{paper['mean']:.2f}, > 8 stars {100 * paper['share_above_8']:.2f} %")
    ax.axvline(8.5, color="0.3", linestyle=":", linewidth=1)
    low = int(images["n_true_stars"].min()) if len(images) else 0
    ax.set_xlim(min(low, 8) - 1, top + 1)
    ax.set_xlabel("true stars in the image (count)")
    ax.set_ylabel("share of images per star count")
    ax.set_title(title or "stars in the field of view")
    fig.legend(loc="outside lower center", fontsize=7)
    return fig


@_styled
def rate_by_stars(frame: pd.DataFrame, bins=((6, 8), (9, 10), (11, 13), (14, 17), (18, 1000)), title: str = "",
                  styles: dict | None = None) -> Figure:
    """Fig. 11: id rate vs the number of true stars in the image (binned), one line per label."""
    edges = [lo for lo, _ in bins]
    names = [f"{lo}-{hi}" if hi < 1000 else f"≥ {lo}" for lo, hi in bins]
    b = np.searchsorted(edges, frame["n_true_stars"].to_numpy(), side="right") - 1
    f = frame.assign(_bin=np.clip(b, 0, len(bins) - 1))
    r = _rates(f, ["label", "_bin"])
    labels = list(dict.fromkeys(frame["label"]))
    st = _styles(labels, styles)
    fig = _figure(6.4, 3.8)
    ax = fig.add_subplot()
    for k, label in enumerate(labels):
        g = r[r["label"] == label].sort_values("_bin")
        s = st[label]
        yerr = [100 * (g["rate"] - g["lo"]), 100 * (g["hi"] - g["rate"])]
        ax.errorbar(g["_bin"] + (k - (len(labels) - 1) / 2) * 0.06, 100 * g["rate"], yerr=yerr,
                    color=s["color"], marker=s["marker"], linestyle=s["linestyle"], capsize=2, label=label,
                    markeredgecolor="black", markeredgewidth=0.5)
    ax.set_xticks(range(len(bins)), names)
    ax.set_xlabel("true stars in the image (count)")
    ax.set_ylabel("identification rate (%), 95 % Wilson interval")
    ax.set_ylim(max(0.0, math.floor(100 * r["lo"].min() / 5) * 5 - 2), 101.8)
    ax.set_title(title or "identification rate vs stars in the field")
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncol=min(len(labels), 4))
    return fig


@_styled
def mcnemar_matrix(frame: pd.DataFrame, title: str = "") -> Figure:
    """Pairwise McNemar tests on the same images: cell (row A, column B) prints A's rate minus B's in
    percentage points and the exact p-value; the shade deepens with significance (−log10 p)."""
    labels = list(dict.fromkeys(frame["label"]))
    rates = frame.assign(_ok=frame["status"] == "correct").groupby("label")["_ok"].mean()
    n = len(labels)
    p = np.full((n, n), np.nan)
    for i in range(n):
        for j in range(i + 1, n):
            p[i, j] = p[j, i] = mcnemar(frame, labels[i], labels[j])["p_value"]
    fig = _figure(max(4.8, 1.8 + 1.15 * n), 1.4 + 0.8 * n)
    ax = fig.add_subplot()
    shade = np.clip(-np.log10(np.where(np.isnan(p), 1.0, np.maximum(p, 1e-300))), 0, 6)
    ax.imshow(shade, cmap="Greys", vmin=0, vmax=9, aspect="auto")
    for i in range(n):
        for j in range(n):
            if i == j:
                ax.text(j, i, f"{100 * rates[labels[i]]:.2f} %", ha="center", va="center", fontsize=7, style="italic")
                continue
            d = 100 * (rates[labels[i]] - rates[labels[j]])
            star = "*" if p[i, j] < 0.05 else ""
            ax.text(j, i, f"{d:+.2f} pp{star}\np = {p[i, j]:.2g}", ha="center", va="center", fontsize=7,
                    fontweight="bold" if star else "normal")
    ax.set_xticks(range(n), labels, rotation=30, ha="right")
    ax.set_yticks(range(n), labels)
    ax.grid(False)
    ax.set_xticks(np.arange(n + 1) - 0.5, minor=True)
    ax.set_yticks(np.arange(n + 1) - 0.5, minor=True)
    ax.grid(which="minor", color="0.6", linewidth=0.6)
    ax.tick_params(which="minor", length=0)
    for spine in ax.spines.values():
        spine.set_visible(False)
    ax.set_xlabel("B")
    ax.set_ylabel("A")
    fig.suptitle("\n".join(textwrap.wrap(title or "McNemar's exact test on the same images", 50)), fontsize=9)
    fig.text(0.01, 0.005, "cell: rate A − rate B (pp) and p; * p < 0.05; diagonal: rate", fontsize=7, ha="left",
             va="bottom", style="italic")
    return fig


@_styled
def regression(diff: pd.DataFrame, title: str = "") -> Figure:
    """Rate differences new − old (pp) per label and point with their 95 % interval; filled markers
    where McNemar's exact test gives p < 0.05. ``diff``: :func:`starid.report.build.compare` rows."""
    d = diff.reset_index(drop=True)
    fig = _figure(6.4, 0.9 + 0.32 * len(d))
    ax = fig.add_subplot()
    y = np.arange(len(d))[::-1]
    for yi, r in zip(y, d.itertuples(), strict=True):
        sig = r.p_value < 0.05
        ax.plot([100 * r.diff_lo, 100 * r.diff_hi], [yi, yi], color="0.3", linewidth=1.2)
        ax.plot([100 * r.diff], [yi], marker="o", markersize=6, color="black",
                markerfacecolor="black" if sig else "white", markeredgewidth=1.2)
    ax.axvline(0, color="0.2", linewidth=0.8)
    studies = d["study"].nunique() > 1 if "study" in d.columns else False
    ax.set_yticks(y, [(f"{r.study}: " if studies else "") + f"{r.label} @ {r.where}" for r in d.itertuples()])
    ax.grid(axis="y", visible=False)
    ax.set_xlabel("identification rate new − old (percentage points), 95 % interval")
    ax.set_title((title or "regression: new vs old on the same images") + "\nfilled: McNemar's exact p < 0.05")
    return fig


def _status_of(hip: np.ndarray, truth: np.ndarray) -> np.ndarray:
    out = np.where(hip == -1, np.where(truth >= 0, "missed", "false"), np.where(hip == truth, "correct", "wrong"))
    return out


@_styled
def show_figure(stars: pd.DataFrame, ids: pd.DataFrame, explanations: dict | None = None,
                width_px: int = 1024, height_px: int = 1024, titles: dict | None = None,
                label_stars: bool = True, suptitle: str = "") -> Figure:
    """The simulated image, one panel per label: stars sized by magnitude, each with its true and
    identified HIP, correct / wrong / missed / false marked by shape, and the label's explanation
    (``starid.Explanation``) drawn over it with its caption.

    ``stars``: ``star, x_px, y_px, mag, truth_hip`` (``Observation.to_frame()``); ``ids``:
    ``label, star, hip``; ``explanations``: ``label -> Explanation or None``; ``titles``: ``label ->
    extra title text``; ``suptitle``: the figure's heading, wrapped to its width (set here, before the
    labels are placed, so that the layout they were placed in is the one drawn).
    """
    explanations = explanations or {}
    labels = list(dict.fromkeys(ids["label"]))
    n = max(len(labels), 1)
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    fig = _figure(4.6 * cols, 5.0 * rows + 0.8)
    grid = fig.add_gridspec(rows + 1, cols, height_ratios=[1.0] * rows + [0.12])
    axes = np.array([fig.add_subplot(grid[i // cols, i % cols]) for i in range(rows * cols)])
    legend_ax = fig.add_subplot(grid[rows, :])
    legend_ax.axis("off")
    x, y, mag = (stars[c].to_numpy(dtype=float) for c in ("x_px", "y_px", "mag"))
    truth = stars["truth_hip"].to_numpy(dtype=np.int64)
    # magnitude -> dot area (pt^2): brighter is bigger (mag 6 -> 9, mag 3 -> 72, mag 0 -> 260)
    size = np.clip(9.0 * (10 ** (0.4 * (6.0 - mag))) ** 0.75, 5, 260)
    placements = []
    ex_none = np.zeros((0, 2))
    for ax, label in zip(axes[:len(labels)], labels, strict=True):    # the grid may have spare panels
        got = ids[ids["label"] == label].set_index("star")["hip"].reindex(stars["star"]).fillna(-1)
        hip = got.to_numpy(dtype=np.int64)
        status = _status_of(hip, truth)
        ax.set_facecolor("white")
        ax.scatter(x, y, s=size, color="black", zorder=3, linewidths=0)
        ex = explanations.get(label)
        if ex is not None:
            _draw_explanation(ax, ex)
        jobs = [] if ex is None or not len(ex.points) else [
            (ex.points[:, 0], ex.points[:, 1], list(ex.labels), True,
             {"fontsize": 7, "color": "#7A2E5B", "fontweight": "bold", "zorder": 7})]
        for kind, m in STAR_MARKS.items():
            sel = status == kind
            if sel.any():
                ax.scatter(x[sel], y[sel], s=m["size"] ** 2, marker=m["marker"], zorder=4, linewidths=1.4,
                           facecolors=m["color"] if m["fill"] else "none", edgecolors=m["color"], alpha=0.9)
        if label_stars:
            texts = [{"correct": f"{truth[i]}", "wrong": f"{hip[i]} / {truth[i]}" if truth[i] >= 0
                      else f"{hip[i]} / false", "missed": f"({truth[i]})", "false": "false"}[status[i]]
                     for i in range(len(x))]
            # wrong ids first: a label that fits nowhere is left out, and those are the ones a reader needs
            order = np.argsort([{"wrong": 0, "correct": 1, "missed": 2, "false": 3}[k] for k in status], kind="stable")
            named = ex.points[[bool(t) for t in ex.labels]] if ex is not None and len(ex.points) else ex_none
            if len(named):   # a star the explanation labels is not labelled twice
                near = np.hypot(x[:, None] - named[None, :, 0], y[:, None] - named[None, :, 1]).min(axis=1)
                order = order[(near[order] > 2.0) | (status[order] == "wrong")]
            jobs.append((x[order], y[order], [texts[i] for i in order], False,
                         {"fontsize": 6, "color": "black", "zorder": 6}))
        placements.append((ax, jobs))
        counts = {k: int((status == k).sum()) for k in STAR_MARKS}
        head = f"{label}" + (f" — {titles[label]}" if titles and label in titles else "")
        ax.set_title(f"{head}\n{counts['correct']} correct, {counts['wrong']} wrong, {counts['missed']} missed, "
                     f"{counts['false']} false", fontsize=9)
        ax.set_xlim(0, width_px)
        ax.set_ylim(height_px, 0)
        ax.set_aspect("equal")
        ax.grid(False)
        ax.set_ylabel("y (px)")
        caption = ex.caption if ex is not None and ex.caption else (
            "no explain(): identification only" if ex is None else "")
        # the caption goes under the x label (part of it, so the layout keeps room for it)
        ax.set_xlabel("x (px)" + ("\n\n" + "\n".join(textwrap.wrap(caption, 70)) if caption else ""), fontsize=8,
                      loc="left" if caption else "center")
    for ax in axes[len(labels):]:
        ax.set_visible(False)
    handles = [Line2D([], [], linestyle="none", marker="o", markersize=5, color="black",
                      label="star (size ~ brightness)")]
    for m in STAR_MARKS.values():
        handles.append(Line2D([], [], linestyle="none", marker=m["marker"], markersize=8, markeredgewidth=1.4,
                              markerfacecolor=m["color"] if m["fill"] else "none", markeredgecolor=m["color"],
                              label=m["text"]))
    handles += [Line2D([], [], color="#7F7F7F", linewidth=0.8, linestyle="--", label="explain: considered"),
                Line2D([], [], color="#CC79A7", linewidth=2.2, label="explain: decisive / matched")]
    legend_ax.legend(handles=handles, loc="center", ncol=4 if cols > 1 else 2, fontsize=7)
    if suptitle:   # about 13 characters per inch at 10 pt, so one panel keeps it whole
        fig.suptitle("\n".join(textwrap.wrap(suptitle, max(40, int(13 * fig.get_figwidth())))), fontsize=10)
    # labels last, once the layout is settled: the explanation's (its caption refers to them) placed
    # first and always, then the HIP numbers where they fit beside their star without covering another
    stars_xy = np.column_stack([x, y])
    renderer = _renderer(fig)     # one draw settles the layout for every panel's labels
    for ax, jobs in placements:
        taken = []
        for jx, jy, texts, required, kw in jobs:
            place_labels(ax, jx, jy, texts, obstacles_xy=stars_xy, obstacle_pt=14.0, required=required, taken=taken,
                         renderer=renderer, **kw)
    return fig


def _draw_explanation(ax, ex) -> None:
    hl = set(int(i) for i in ex.highlight)
    for k, seg in enumerate(ex.segments):
        bold = k in hl
        ax.plot(seg[:, 0], seg[:, 1], color="#CC79A7" if bold else "#7F7F7F", linewidth=2.2 if bold else 0.8,
                linestyle="-" if bold else "--", zorder=2 if not bold else 5, alpha=0.95)
    for poly in ex.polygons:
        if len(poly) >= 2:
            closed = np.vstack([poly, poly[:1]])
            ax.fill(closed[:, 0], closed[:, 1], facecolor="#CC79A7", alpha=0.12, edgecolor="none", zorder=1)
            ax.plot(closed[:, 0], closed[:, 1], color="#CC79A7", linewidth=2.2, zorder=5)
    if len(ex.points):   # their labels are placed by show_figure, with the stars' (place_labels)
        ax.scatter(ex.points[:, 0], ex.points[:, 1], marker="+", s=90, color="#CC79A7", linewidths=1.6, zorder=6)


__all__ = ["STYLE", "axis_name", "label_styles", "mcnemar_matrix", "rate_by_stars", "rate_curve", "regression",
           "place_labels", "show_figure", "star_histogram", "time_distributions", "tradeoff"]
