"""Labels in pictures do not sit on each other, and the documentation site's generated parts are the code's."""

import dataclasses
import importlib.util
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import starid
from starid.plots import place_labels

ROOT = Path(__file__).resolve().parents[1]


def _boxes(annotations, renderer):
    return [a.get_window_extent(renderer) for a in annotations]


def _overlaps(boxes):
    return [(i, j) for i in range(len(boxes)) for j in range(i + 1, len(boxes)) if boxes[i].overlaps(boxes[j])]


def test_labels_of_close_points_do_not_overlap():
    fig = Figure(figsize=(4, 4), layout="constrained")
    ax = fig.add_subplot()
    ax.set_xlim(0, 100)
    ax.set_ylim(0, 100)
    x = np.array([50, 52, 54, 50, 52, 20, 80])
    y = np.array([50, 50, 52, 53, 47, 20, 80])
    texts = [f"HIP {10000 + i}" for i in range(len(x))]
    placed = place_labels(ax, x, y, texts, fontsize=7)
    renderer = fig.canvas.get_renderer()
    assert _overlaps(_boxes(placed, renderer)) == []
    assert len(placed) >= 4                           # the isolated ones and some of the cluster
    naive = [ax.annotate(t, (a, b), xytext=(7, -7), textcoords="offset points", fontsize=7)
             for t, a, b in zip(texts, x, y, strict=True)]
    fig.canvas.draw()
    assert _overlaps(_boxes(naive, renderer))        # the old fixed offset did collide here


def test_required_labels_are_all_placed():
    fig = Figure(figsize=(3, 3), layout="constrained")
    ax = fig.add_subplot()
    ax.set_xlim(0, 10)
    ax.set_ylim(0, 10)
    x, y = np.full(12, 5.0), np.full(12, 5.0)
    placed = place_labels(ax, x, y, [f"label {i}" for i in range(12)], required=True, fontsize=7)
    assert len(placed) == 12


def _hook():
    spec = importlib.util.spec_from_file_location("starid_docs", ROOT / "docs" / "hooks" / "starid_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_site_parameter_tables_list_every_parameter():
    hook = _hook()
    for name in ("ptp", "tetra"):
        table = hook.params_table(name)
        cls = starid.get_algorithm(name)
        for f in dataclasses.fields(cls):
            assert f"| `{f.name}` |" in table
        for key, value in cls.published.items():
            assert f"| `{key}` |" in table and f"`{hook._cell(value)}`" in table


def test_every_algorithm_page_asks_for_its_generated_table_and_picture():
    for info in starid.available_algorithms():
        page = ROOT / "docs" / "algorithms" / f"{info.name}.md"
        if info.dist != "starid" or not page.is_file():
            continue
        text = page.read_text()
        assert f"<!-- starid:params {info.name} -->" in text
        assert f"reasoning_{info.name}.png" in text
        heads = [line for line in text.splitlines() if line.startswith("## ")]
        assert heads[:3] == ["## Method as implemented", "## Paper versus reconstruction", "## Measurements"]
