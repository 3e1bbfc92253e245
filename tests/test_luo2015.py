"""luo2015: the paper's procedure beside starid's defaults, and the star count beside the paper's."""

from starid.experiment import Experiment, Variant, run_experiment
from starid.experiments import luo2015
from starid.registry import get_algorithm


def test_paper_procedure_runs_beside_the_defaults_with_valid_parameters():
    variants = [v for v in luo2015.variants() if isinstance(v, Variant)]
    for name in luo2015.PAPER_ALGORITHMS:
        (default,) = (v for v in variants if v.name == name and ":paper" not in v.label)
        (published,) = (v for v in variants if v.label.startswith(f"{name}:paper["))
        assert dict(default.params) == luo2015.PAPER_PARAMS
        assert dict(published.params) == {**get_algorithm(name).published, **luo2015.PAPER_PARAMS}
        assert dict(published.params)["max_refs"] == 1 and dict(published.params)["n_candidates"] == 1


def test_star_count_table_beside_the_papers(tmp_path):
    full = luo2015.experiment(trials=30, seed=4)
    exp = Experiment(full.name, tuple(s for s in full.studies if s.name == "stars"), trials=30, seed=4,
                     camera=full.camera, sim=full.sim)
    frame = run_experiment(exp, None, jobs=1, progress=False)
    table = luo2015.stars(frame, exp)
    ours, paper = table.frame.iloc[0], table.frame.iloc[1]
    n = frame["n_true_stars"]
    assert (ours["min"], ours["max"], ours["images"]) == (n.min(), n.max(), 30)
    assert ours["mean"] == n.mean() and ours["mean"] > 2 * paper["mean"]
    assert (paper["min"], paper["max"], paper["mean"]) == (3, 68, 30.32)
    assert "65 of them in a 20 x 20 deg field" in table.notes[0]


def test_density_study_runs_the_printed_points_at_the_papers_star_count():
    full = luo2015.experiment(trials=12, seed=4)
    (study,) = (s for s in full.studies if s.name == "density")
    points = study.grid.points()
    assert [(p["sigma_px"], p["false_stars"]) for p in points] == [(0.5, 0), (0.0, 1), (0.0, 3)]
    assert all(p["sky_mag_limit"] == p["mag_limit"] == luo2015.DENSE_MAG for p in points)
    assert {dict(v.params)["mag_limit"] for v in study.variants} == {luo2015.DENSE_MAG}
    exp = Experiment(full.name, (study,), trials=12, seed=4, camera=full.camera, sim=full.sim)
    frame = run_experiment(exp, None, jobs=1, progress=False)
    table = luo2015.density(frame)
    assert list(table.frame["condition"].unique()) == ["0.5 px", "1 false star", "3 false stars"]
    t = table.frame
    row = t[(t["condition"] == "3 false stars") & (t["label"].str.startswith("grid:paper"))]
    assert row["paper_id_rate"].item() == 0.865 and row["trials"].item() == 12
    mean = frame.drop_duplicates(["point", "trial"])["n_true_stars"].mean()
    assert f"{mean:.1f} stars per image" in table.notes[0]
    assert "| lpt_improved:paper[" in table.markdown
