"""``starid show``: every registered algorithm on one image, and the explain() layer when a plugin has one."""

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

import starid
from starid.cli import main
from starid.plugin import Explanation
from starid.registry import unregister
from starid.report.show import explain, show

PTP = starid.get_algorithm("ptp")
CAPTION = "The three brightest stars form the triangle that matched."


@dataclass(frozen=True)
class ExplainedPTP(PTP):
    """PTP with a toy explain(): the triangle of the three brightest detections (a test plugin)."""

    name: ClassVar[str] = "explained_ptp"

    def explain(self, database, observation):
        top = np.argsort(observation.mag, kind="stable")[:3]
        xy = np.column_stack([observation.x_px[top], observation.y_px[top]])
        hip = self.identify(database, observation).hip[top]
        return Explanation(segments=[[xy[0], xy[1]], [xy[1], xy[2]], [xy[2], xy[0]]], polygons=(xy,),
                           points=xy, labels=tuple(f"HIP {h}" for h in hip), caption=CAPTION, highlight=[0])


@dataclass(frozen=True)
class BrokenExplainPTP(PTP):
    """PTP whose explain() raises (a test plugin)."""

    name: ClassVar[str] = "broken_explain_ptp"

    def explain(self, database, observation):
        raise RuntimeError("boom")


@dataclass(frozen=True)
class PlainPTP(PTP):
    """PTP without its explain() (a test plugin: a plugin need not explain itself)."""

    name: ClassVar[str] = "plain_ptp"
    explain = None


@pytest.fixture
def explained():
    for cls in (ExplainedPTP, BrokenExplainPTP, PlainPTP):
        starid.register(cls)
    yield
    for name in ("explained_ptp", "broken_explain_ptp", "plain_ptp"):
        unregister(name)


def _texts(fig):
    return [t.get_text() for ax in fig.axes for t in ax.texts] + [t.get_text() for t in fig.texts]


def test_show_every_registered_algorithm_on_one_trial(tmp_path, catalog, camera):
    names = starid.available()
    shown = show(names, trial=3, seed=5, world={"sigma_px": 0.5, "sigma_mag": 0.2, "false_stars": 1},
                 camera=camera, catalog=catalog)
    assert list(shown.results["label"]) == names
    assert not (shown.results["status"] == "error").any(), shown.results[["label", "error"]]
    panels = [ax for ax in shown.figure.axes if ax.get_visible() and ax.axison]
    assert len(panels) == len(names)
    assert [ax.get_title().split(" — ")[0] for ax in panels] == names
    n = len(shown.stars)
    assert len(shown.ids) == n * len(names) and shown.stars["truth_hip"].eq(-1).sum() == 1
    for ax in panels:  # one HIP text per star, inverted y (pixel convention: y down)
        assert len(ax.texts) >= n and ax.get_ylim()[0] > ax.get_ylim()[1]
    out = tmp_path / "all.png"
    shown.figure.savefig(out)
    assert out.read_bytes()[:4] == b"\x89PNG"


def test_explain_layer_is_drawn_with_its_caption(explained, catalog, camera):
    shown = show(["plain_ptp", "explained_ptp", "broken_explain_ptp"], trial=0, seed=2, camera=camera,
                 catalog=catalog)
    plain, drawn, broken = (ax for ax in shown.figure.axes if ax.get_visible() and ax.axison)
    assert isinstance(shown.explanations["explained_ptp"], Explanation)
    assert shown.explanations["plain_ptp"] is None and shown.explanations["broken_explain_ptp"] is None
    assert CAPTION in drawn.get_xlabel().replace("\n", " ")
    assert any(t.get_text().startswith("HIP ") for t in drawn.texts)
    assert len(drawn.lines) >= len(plain.lines) + 4          # three sides + the polygon outline
    assert len(drawn.patches) > len(plain.patches)            # the filled polygon
    assert "no explain()" in plain.get_xlabel()
    assert list(shown.results["explain"]) == ["no explain()", "yes", "explain failed: RuntimeError: boom"]
    # identical ids: explaining does not change what is identified
    ids = shown.ids.pivot(index="star", columns="label", values="hip")
    assert (ids["plain_ptp"] == ids["explained_ptp"]).all()


def test_explain_helper_refuses_a_wrong_return_type(catalog, camera):
    class Odd:
        def explain(self, database, observation):
            return {"segments": []}

    ex, why = explain(Odd(), None, None)
    assert ex is None and "not starid.Explanation" in why


def test_show_command(tmp_path, capsys):
    out = tmp_path / "sub" / "t.png"
    assert main(["show", "ptp", "--trial", "1", "--seed", "3", "--pos-noise-px", "1", "--sky", "paper",
                 "--out", str(out)]) == 0
    assert out.read_bytes()[:4] == b"\x89PNG"
    assert "wrote" in capsys.readouterr().out
    assert main(["show", "ptp", "--trial", "1", "--out", str(tmp_path / "t.txt")]) == 2
    assert main(["show", "nope", "--trial", "1", "--out", str(tmp_path / "t.png")]) == 2
