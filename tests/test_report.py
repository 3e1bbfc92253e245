"""``starid report``: figures, tables and one self-contained HTML from a small results folder; the
regression report of two folders; the plotting functions on frames."""

import re
from html import escape as html_escape

import numpy as np
import pandas as pd
import pytest

from starid import plots
from starid.cli import main
from starid.errors import ConfigError
from starid.experiment import Experiment, Grid, Study, Variant, read_manifest, run_experiment
from starid.experiment.store import read_derived
from starid.experiments import table6
from starid.report.build import build_regression, build_report, compare, markdown_to_html

LABELS = ("ptp", "ptp[n_slaves=3]")


def _tiny(name="tiny", variants=LABELS, trials=12):
    return Experiment(name, (Study("noise", variants, Grid({"sigma_px": [0.0, 2.0]})),
                             Study("skies", variants, Grid({"sky": ["paper", "real"]}))),
                      trials=trials, seed=1, sim={"sigma_mag": 0.3}, description="a tiny test experiment")


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("tiny")
    run_experiment(_tiny(), out, jobs=1, progress=False)
    return out


def _external_references(html: str) -> list[str]:
    bad = re.findall(r"""(?:src|href)\s*=\s*["']?\s*(?:https?:)?//[^"'\s>]*""", html, flags=re.I)
    bad += re.findall(r"<script[^>]*\bsrc\s*=", html, flags=re.I)
    bad += re.findall(r"@import|url\(\s*['\"]?(?:https?:)?//", html, flags=re.I)
    return bad


def test_report_of_a_small_folder(folder):
    written = build_report(folder)
    md = (folder / "report.md").read_text()
    html = (folder / "report.html").read_text()
    names = {p.stem for p in written["figures"]}
    assert {"rate_noise_sigma_px", "rate_skies_sky", "time", "tradeoff", "mcnemar", "stars", "rate_by_stars"} <= names
    for stem in names:
        png = folder / "figures" / f"{stem}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000
        assert (folder / "figures" / f"{stem}.svg").read_text().lstrip().startswith("<?xml")
        assert f"figures/{stem}.png" in md
    # one self-contained file: every figure embedded, nothing fetched, no script
    assert html.count('src="data:image/png;base64,') == len(names)
    assert _external_references(html) == []
    assert "<script" not in html.lower()
    # every table in both documents, with the conditions and provenance
    for title in ("Study noise: summary per point and label", "Study skies: summary per point and label"):
        assert f"### {title}" in md and f"<h3>{title}</h3>" in html
    assert html.count("<table>") >= 6
    for word in ("Conditions", "Provenance", "focal_mm = 70.2262", "sigma_mag = 0.3", "sky_mag_limit", "seed",
                 "McNemar", "started / finished"):
        assert word in md
    assert md.count("| ptp[n_slaves=3] |") >= 4
    # the documents and figures record the definition they were made from (#27), visibly and in derived.json
    digest = read_manifest(folder)["digest"]
    assert f"definition digest `{digest}`" in md
    made = read_derived(folder)
    for name in ("report.md", "report.html", *(f"figures/{stem}.png" for stem in names),
                 *(f"figures/{stem}.svg" for stem in names)):
        assert made[name]["digest"] == digest, name


def test_builtin_experiment_gets_its_own_tables(tmp_path):
    exp = Experiment("table6", (Study("table6", LABELS, Grid({"sky": ["paper", "real"]})),), trials=10, seed=2,
                     sim=dict(table6.SIM))
    run_experiment(exp, tmp_path, jobs=1, progress=False)
    assert main(["report", str(tmp_path), "--format", "md,html", "--no-svg"]) == 0
    md = (tmp_path / "report.md").read_text()
    html = (tmp_path / "report.html").read_text()
    for t in table6.tables(pd.read_parquet(tmp_path / "results.parquet"), exp):
        assert f"### {t.title}" in md
        assert f"<h3>{html_escape(t.title, quote=False)}</h3>" in html
    assert "paper DB (MB)" in md and "<th>paper DB (MB)</th>" in html
    assert not list((tmp_path / "figures").glob("*.svg"))
    assert _external_references(html) == []


def test_report_refuses_what_is_not_a_results_folder(tmp_path, capsys):
    assert main(["report", str(tmp_path / "missing")]) == 2
    (tmp_path / "x").mkdir()
    assert main(["report", str(tmp_path / "x")]) == 2
    assert "not a starid results folder" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="--format"):
        build_report(tmp_path / "x", ("pdf",))


def test_regression_report_matches_trials_and_tests_them(folder, tmp_path):
    # the "new version": the label ptp now runs with 3 slave stars (worse), the other label is unchanged
    changed = _tiny(variants=(Variant("ptp", (("n_slaves", 3),), label="ptp"), "ptp[n_slaves=3]"))
    new = tmp_path / "new"
    run_experiment(changed, new, jobs=1, progress=False)
    written, diff = build_regression(folder, new)
    assert written["md"].is_file() and (new / "figures" / "regression.png").is_file()
    same = diff[diff["label"] == "ptp[n_slaves=3]"]
    assert (same["diff"] == 0).all() and (same["p_value"] == 1).all()
    old_frame, new_frame = pd.read_parquet(folder / "results.parquet"), pd.read_parquet(new / "results.parquet")
    ptp = diff[(diff["label"] == "ptp") & (diff["where"] == "sigma_px=0")].iloc[0]
    a = old_frame[(old_frame["label"] == "ptp") & (old_frame["grid_sigma_px"] == 0.0)].sort_values("trial")
    b = new_frame[(new_frame["label"] == "ptp") & (new_frame["grid_sigma_px"] == 0.0)].sort_values("trial")
    ok_a, ok_b = (a["status"] == "correct").to_numpy(), (b["status"] == "correct").to_numpy()
    assert ptp["only_old_correct"] == int((ok_a & ~ok_b).sum()) and ptp["only_new_correct"] == int((ok_b & ~ok_a).sum())
    assert ptp["diff"] == pytest.approx(ok_b.mean() - ok_a.mean())
    assert ptp["diff_lo"] <= ptp["diff"] <= ptp["diff_hi"]
    assert set(diff["where"]) >= {"sigma_px=0", "sigma_px=2", "sky=paper", "sky=real", "all points"}
    html = written["html"].read_text()
    assert _external_references(html) == [] and "data:image/png;base64," in html
    assert "same world" in written["md"].read_text()  # only the algorithms differ


def test_regression_refuses_two_different_experiments(folder, tmp_path, capsys):
    other = tmp_path / "other"
    run_experiment(_tiny(name="other", trials=3), other, jobs=1, progress=False)
    assert main(["report", str(folder), str(other)]) == 2
    assert "same experiment" in capsys.readouterr().err


def test_compare_pools_points_and_counts_discordant_pairs():
    old = pd.DataFrame({"study": "s", "grid_x": [0.0] * 4 + [1.0] * 4, "label": "a", "trial": [0, 1, 2, 3] * 2,
                        "status": ["correct"] * 8})
    new = old.assign(status=["correct", "no_result", "no_result", "correct"] * 2)
    d = compare(old, new).set_index("where")
    assert d.loc["x=0", "only_old_correct"] == 2 and d.loc["x=0", "only_new_correct"] == 0
    assert d.loc["all points", "trials"] == 8 and d.loc["all points", "diff"] == pytest.approx(-0.5)
    assert d.loc["all points", "p_value"] == pytest.approx(2 * 0.5 ** 4)


def test_rate_curve_overlays_the_papers_points_and_styles_are_greyscale_safe():
    rng = np.random.default_rng(0)
    rows = [{"study": "s", "point": i, "grid_sigma_px": x, "label": lab, "trial": t,
             "status": "correct" if rng.random() < 0.9 - 0.1 * x else "no_result"}
            for i, x in enumerate([0.0, 1.0, 2.0]) for lab in ("ptp", "pvector") for t in range(40)]
    paper = pd.DataFrame({"value": [0.0, 2.0], "algorithm": ["ptp", "ptp"], "paper_id_rate": [0.993, 0.955]})
    fig = plots.rate_curve(pd.DataFrame(rows), "sigma_px", paper)
    ax = fig.axes[0]
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "ptp: paper's printed value" in legend and "pvector" in legend
    assert ax.get_xlabel() == "centroid noise σ (px)" and "%" in ax.get_ylabel()
    styles = plots.label_styles(["a", "b", "c", "d"])
    assert len({s["marker"] for s in styles.values()}) == 4 and len({str(s["linestyle"]) for s in styles.values()}) == 4


def test_markdown_to_html_tables_and_escaping():
    out = markdown_to_html("Some <b> text `x`\n\n| a | b |\n|---|---|\n| 1 | <2> |\n\n* item")
    assert "<p>Some &lt;b&gt; text <code>x</code></p>" in out
    assert "<table><thead><tr><th>a</th><th>b</th></tr></thead><tbody><tr><td>1</td><td>&lt;2&gt;</td></tr>" in out
    assert "<ul><li>item</li></ul>" in out
