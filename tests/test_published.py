"""``published``: a plugin's paper-literal overrides, the ``NAME:paper`` variant and its checks."""

from dataclasses import dataclass
from typing import ClassVar

import pytest
from starid_algorithms.ptp import PTP

from starid.errors import ConfigError
from starid.experiment import Experiment, Study, Variant, run_experiment
from starid.registry import register, unregister
from starid.testing import ConformanceError, check_algorithm


@dataclass(frozen=True)
class Published(PTP):
    """PTP whose paper-literal form drops starid's verification (a test double)."""

    name: ClassVar[str] = "published_ptp"
    published: ClassVar[dict] = {"verify": False, "confirm_fraction": 0.0}


@pytest.fixture
def registered():
    register(Published)
    yield
    unregister("published_ptp")


def test_paper_variant_parses_and_labels(registered):
    v = Variant.parse("published_ptp:paper")
    assert v.label == "published_ptp:paper" and v.name == "published_ptp"
    assert dict(v.params) == {"verify": False, "confirm_fraction": 0.0}
    on_top = Variant.parse("published_ptp:paper[n_slaves=5,verify=true]")
    assert on_top == Variant.as_published("published_ptp", n_slaves=5, verify=True)
    assert on_top.label == "published_ptp:paper[n_slaves=5,verify=True]"
    assert dict(on_top.params) == {"n_slaves": 5, "verify": True, "confirm_fraction": 0.0}
    with pytest.raises(ConfigError, match="declares no 'published'"):
        Variant.parse("tetra:paper")


def test_paper_variant_runs_beside_the_default_on_the_same_images(registered):
    exp = Experiment("pub", (Study("s", ("published_ptp", "published_ptp:paper")),), trials=12, seed=3,
                     sim={"sigma_px": 1.0})
    frame = run_experiment(exp, None, jobs=1, progress=False)
    default, paper = (frame[frame["label"] == lab] for lab in ("published_ptp", "published_ptp:paper"))
    assert list(default["trial"]) == list(paper["trial"])
    assert not paper["param_verify"].any() and default["param_verify"].all()


def test_conformance_refuses_a_published_dict_that_names_no_parameter():
    @dataclass(frozen=True)
    class Typo(PTP):
        """PTP with a misspelt published parameter (a test double)."""

        name: ClassVar[str] = "typo_ptp"
        published: ClassVar[dict] = {"verfiy": False}

    with pytest.raises(ConformanceError, match="'published' names a parameter"):
        check_algorithm(Typo, checks=["default_constructible"])

    @dataclass(frozen=True)
    class Same(PTP):
        """PTP whose published dict repeats a default (a test double)."""

        name: ClassVar[str] = "same_ptp"
        published: ClassVar[dict] = {"verify": True}

    with pytest.raises(ConformanceError, match="changes no parameter"):
        check_algorithm(Same, checks=["default_constructible"])
