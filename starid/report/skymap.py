"""Where on the sky each algorithm fails: id rate by boresight, Mollweide maps and the worst cells.

Cells are equal-area: ``N_DEC`` bands equal in ``sin(dec)`` times ``N_RA`` equal RA bins (each cell
``4 pi / (N_DEC N_RA)`` sr, 254.6 deg^2 at 9 x 18). A trial falls in the cell of its boresight
(``boresight_ra_deg``, ``boresight_dec_deg``). Maps are drawn for results with at least
:data:`MIN_TRIALS` distinct trials at the main condition, one panel per algorithm label, the
galactic plane (b = 0) dashed, in a perceptually uniform colour scale (``cividis``: its
lightness rises monotonically, so it reads in grey).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from .tables import Table, markdown

#: A results folder gets sky maps from this many distinct trials on.
MIN_TRIALS = 2000
N_DEC, N_RA = 9, 18
#: Cells with fewer trials are left blank on the maps and out of the worst-cell table.
MIN_CELL_TRIALS = 5
#: ICRS -> galactic rotation (rows: galactic x, y, z in ICRS; Hipparcos Vol. 1, 1.5.3).
ICRS_TO_GAL = np.array([[-0.0548755604, -0.8734370902, -0.4838350155],
                        [+0.4941094279, -0.4448296300, +0.7469822445],
                        [-0.8676661490, -0.1980763734, +0.4559837762]])


def cell_of(ra_deg, dec_deg) -> np.ndarray:
    """Equal-area cell index of each direction: ``dec band * N_RA + ra bin``."""
    s = np.sin(np.radians(np.asarray(dec_deg, dtype=float)))
    band = np.clip(((s + 1.0) / 2.0 * N_DEC).astype(int), 0, N_DEC - 1)
    ra_bin = np.clip((np.asarray(ra_deg, dtype=float) % 360.0 / 360.0 * N_RA).astype(int), 0, N_RA - 1)
    return band * N_RA + ra_bin


def _dec_edges_deg() -> np.ndarray:
    return np.degrees(np.arcsin(np.linspace(-1.0, 1.0, N_DEC + 1)))


def cell_rates(frame: pd.DataFrame) -> pd.DataFrame:
    """Per label and cell: trials and id rate (share with status ``correct``)."""
    f = frame.assign(cell=cell_of(frame["boresight_ra_deg"], frame["boresight_dec_deg"]),
                     ok=(frame["status"] == "correct").astype(float))
    return f.groupby(["label", "cell"], sort=False).agg(trials=("ok", "size"), id_rate=("ok", "mean")).reset_index()


def _lon(ra_deg):
    """Mollweide longitude (rad) of RA: ``180 - RA`` deg, so RA grows to the left (0 at the right edge)."""
    return np.radians(180.0 - np.asarray(ra_deg, dtype=float) % 360.0)


def sky_map(frame: pd.DataFrame, labels: list[str], title: str) -> Figure:
    """One Mollweide panel per label: id rate per equal-area cell, the galactic plane dashed."""
    rates = cell_rates(frame)
    cols = min(2, len(labels))
    rows = math.ceil(len(labels) / cols)
    fig = Figure(figsize=(6.2 * cols, 3.5 * rows + 0.8), layout="constrained")
    ra_edges = np.linspace(0.0, 360.0, N_RA + 1)
    dec_edges = _dec_edges_deg()
    # galactic plane in ICRS
    l_rad = np.linspace(0, 2 * np.pi, 721)
    gal = np.column_stack([np.cos(l_rad), np.sin(l_rad), np.zeros_like(l_rad)]) @ ICRS_TO_GAL
    g_ra = np.degrees(np.arctan2(gal[:, 1], gal[:, 0])) % 360.0
    g_dec = np.degrees(np.arcsin(gal[:, 2]))
    mesh = None
    for k, label in enumerate(labels):
        ax = fig.add_subplot(rows, cols, k + 1, projection="mollweide")
        grid = np.full((N_DEC, N_RA), np.nan)
        part = rates[(rates["label"] == label) & (rates["trials"] >= MIN_CELL_TRIALS)]
        grid.flat[part["cell"].to_numpy()] = part["id_rate"].to_numpy()
        x, y = np.meshgrid(np.radians(180.0 - ra_edges[::-1]), np.radians(dec_edges))   # lon increasing
        mesh = ax.pcolormesh(x, y, np.ma.masked_invalid(grid[:, ::-1]), cmap="cividis", vmin=0.0, vmax=1.0,
                             shading="flat", edgecolors="0.7", linewidth=0.2)
        lon_g = _lon(g_ra)
        brk = np.flatnonzero(np.abs(np.diff(lon_g)) > np.pi) + 1
        for seg_x, seg_y in zip(np.split(lon_g, brk), np.split(np.radians(g_dec), brk), strict=True):
            ax.plot(seg_x, seg_y, color="white", linestyle="-", linewidth=2.4)
            ax.plot(seg_x, seg_y, color="black", linestyle="--", linewidth=1.3)
        ax.set_xticks(np.radians([-120, -60, 0, 60, 120]))
        ax.set_xticklabels(["300", "240", "180", "120", "60"], fontsize=7)
        ax.tick_params(axis="y", labelsize=7)
        ax.grid(True, color="0.6", linewidth=0.4)
        ax.set_title(label, fontsize=10)
        ax.set_xlabel("right ascension (deg)", fontsize=8)
        ax.set_ylabel("declination (deg)", fontsize=8)
    if mesh is not None:
        cb = fig.colorbar(mesh, ax=fig.axes, orientation="horizontal", shrink=0.5, aspect=40)
        cb.set_label(f"identification rate per equal-area cell (blank: < {MIN_CELL_TRIALS} trials)")
    fig.suptitle(title + " (dashed: galactic plane)", fontsize=11)
    return fig


def worst_cells(frame: pd.DataFrame, labels: list[str], n: int = 5) -> pd.DataFrame:
    """Each label's ``n`` cells with the lowest id rate (with >= MIN_CELL_TRIALS trials)."""
    rates = cell_rates(frame)
    rates = rates[rates["trials"] >= MIN_CELL_TRIALS]
    dec_edges = _dec_edges_deg()
    out = []
    for label in labels:
        part = rates[rates["label"] == label].sort_values(["id_rate", "trials"], ascending=[True, False]).head(n)
        for r in part.itertuples(index=False):
            band, ra_bin = divmod(int(r.cell), N_RA)
            out.append({"label": label, "ra_deg": f"{ra_bin * 360 / N_RA:.0f}-{(ra_bin + 1) * 360 / N_RA:.0f}",
                        "dec_deg": f"{dec_edges[band]:.1f} to {dec_edges[band + 1]:.1f}", "trials": int(r.trials),
                        "id_rate": f"{r.id_rate:.3f}"})
    return pd.DataFrame(out)


def skymap_parts(main: pd.DataFrame, where: str = "", suffix: str = ""):
    """``(figures, tables)`` for the report of ``main`` (the main condition's rows, or one study's);
    empty below :data:`MIN_TRIALS` distinct trials or without boresight columns. ``suffix`` keeps
    the names of a second map apart (``skymap`` + suffix, ``worst_cells`` + suffix)."""
    from .figures import ReportFigure

    if "boresight_ra_deg" not in main.columns or main["trial"].nunique() < MIN_TRIALS:
        return [], []
    main = main.dropna(subset=["boresight_ra_deg", "boresight_dec_deg"])
    labels = list(dict.fromkeys(main["label"]))
    n = main["trial"].nunique()
    fig = ReportFigure(
        "skymap" + suffix, "Where on the sky each algorithm fails" + (f" ({where})" if where else ""),
        f"Identification rate by boresight ({where}; {n} images), {N_DEC} x {N_RA} equal-area cells "
        f"({4 * 180 ** 2 / math.pi / (N_DEC * N_RA):.0f} deg^2 each, about {n / (N_DEC * N_RA):.0f} images per "
        f"cell), Mollweide projection, RA increasing to the left; dashed: the galactic plane.",
        sky_map(main, labels, "identification rate by boresight" + (f", {where}" if where else "")))
    worst = worst_cells(main, labels)
    table = Table("worst_cells" + suffix, "Worst sky cells" + (f" ({where})" if where else ""), worst, markdown(worst),
                  (f"The {5} cells of lowest identification rate per label (cells with >= {MIN_CELL_TRIALS} "
                   f"images).",))
    return [fig], [table]
