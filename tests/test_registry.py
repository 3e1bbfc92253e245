"""Plugin discovery: entry points of other distributions, broken plugins, in-process registration."""

import os
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from typing import ClassVar

import pytest

import starid
from starid import PluginError
from starid.plugin import Algorithm
from starid.registry import available_algorithms, get_algorithm, register, unregister
from starid.testing import check_algorithm

PLUGIN_SOURCE = textwrap.dedent('''
    """A third-party starid plugin, installed as its own distribution."""
    from dataclasses import dataclass
    from typing import ClassVar

    from starid_algorithms.ptp import PTP


    @dataclass(frozen=True)
    class FiveSlavePTP(PTP):
        """PTP with five slave stars per master (Zhou & Ye 2015, Table 5), packaged by a third party."""

        name: ClassVar[str] = "toy_ptp5"
        n_slaves: int = 5
''')


@pytest.fixture
def third_party_site(tmp_path, monkeypatch):
    """A throwaway distribution on sys.path declaring one good and one broken entry point."""
    site = tmp_path / "site"
    (site / "toy_starid_plugin").mkdir(parents=True)
    (site / "toy_starid_plugin" / "__init__.py").write_text(PLUGIN_SOURCE)
    info = site / "toy_starid_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: toy-starid-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[starid.algorithms]\n"
        "toy_ptp5 = toy_starid_plugin:FiveSlavePTP\n"
        "toy_broken = toy_starid_plugin.does_not_exist:Nope\n")
    monkeypatch.syspath_prepend(str(site))
    return site


def test_third_party_plugin_is_discovered(third_party_site):
    infos = {i.name: i for i in available_algorithms()}
    assert infos["toy_ptp5"].status == "ok"
    assert infos["toy_ptp5"].cls().n_slaves == 5
    assert infos["toy_broken"].status == "broken"
    assert "ModuleNotFoundError" in infos["toy_broken"].error
    assert [i.name for i in available_algorithms()] == sorted(infos)
    with pytest.raises(PluginError, match="broken"):
        get_algorithm("toy_broken")


def test_conformance_suite_runs_on_third_party_plugin(third_party_site):
    assert check_algorithm(get_algorithm("toy_ptp5")) == list(starid.testing.CHECKS)


def _cli(site, *args):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, "-m", "starid", *args], capture_output=True, text=True, env=env,
                          timeout=300)


def test_third_party_plugin_in_cli(third_party_site, tmp_path):
    listing = _cli(third_party_site, "list")
    assert listing.returncode == 0
    lines = {line.split()[0]: line.split()[1] for line in listing.stdout.splitlines()}
    assert lines["toy_ptp5"] == "ok" and lines["toy_broken"] == "broken" and lines["ptp"] == "ok"
    out = tmp_path / "out"
    result = _cli(third_party_site, "run", "toy_ptp5", "ptp", "--trials", "20", "--seed", "2", "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert "toy_ptp5" in result.stdout
    import pandas as pd

    summary = pd.read_csv(out / "summary.csv")
    assert summary["label"].tolist() == ["toy_ptp5", "ptp"]
    trials = pd.read_csv(out / "trials.csv")
    assert set(trials.loc[trials["label"] == "toy_ptp5", "plugin_dist"]) == {"toy-starid-plugin"}
    assert set(trials.loc[trials["label"] == "toy_ptp5", "plugin_version"].astype(str)) == {"0.1"}


def test_unknown_algorithm():
    with pytest.raises(PluginError, match="unknown algorithm 'nope'"):
        get_algorithm("nope")


def test_register_decorator():
    @dataclass(frozen=True)
    class Notebook(Algorithm):
        """Registered in process, for notebooks."""

        name: ClassVar[str] = "notebook_algo"

        def build(self, catalog, camera):
            raise NotImplementedError

        def identify(self, database, observation):
            raise NotImplementedError

    register(Notebook)
    try:
        assert get_algorithm("notebook_algo") is Notebook
        assert {i.name: i.source for i in available_algorithms()}["notebook_algo"] == "registered in process"
    finally:
        unregister("notebook_algo")
    assert "notebook_algo" not in {i.name for i in available_algorithms()}
    with pytest.raises(PluginError):
        register(int)
