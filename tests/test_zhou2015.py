"""zhou2015: the paper's figures have the paper's three as published beside starid's defaults."""

from starid.experiment import Study
from starid.experiments import table6, zhou2015
from starid.registry import get_algorithm


def _labels(study: Study) -> list[str]:
    return [v.label for v in study.variants]


def test_paper_figures_have_the_published_rows_and_the_other_sweeps_do_not():
    studies = {s.name: s for s in zhou2015.experiment(trials=10).studies}
    published = [f"{n}:paper" for n in table6.PAPER_ALGORITHMS]
    for name in ("table6", "fig12", "fig13"):
        labels = _labels(studies[name])
        assert labels[:6] == [*table6.PAPER_ALGORITHMS, *published], name
        for v in studies[name].variants[3:6]:
            assert dict(v.params) == get_algorithm(v.name).published
    assert _labels(studies["fig12"]) == _labels(studies["table6"]) == _labels(studies["fig13"])
    for name in ("false_stars", "lost_stars"):
        assert not any(":paper" in label for label in _labels(studies[name])), name
        assert _labels(studies[name])[:3] == list(table6.PAPER_ALGORITHMS)
    # Fig. 11 is drawn from Table 6's images, so its rows are Table 6's, the published ones included
    assert set(published) <= set(_labels(studies["table6"]))

