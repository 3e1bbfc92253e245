"""``starid new-plugin``: the generated package installs, passes ``starid check`` and its own tests unchanged.

The package is installed (a regular, non-editable ``pip install --target``) into a temporary folder
that only the subprocesses of this test put on their path, so no other test sees its entry point;
pytest's ``tmp_path`` removes it afterwards, and the numba cache files of its kernel are deleted.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from starid.cli import main
from starid.errors import ConfigError
from starid.scaffold import new_plugin

NAME = "scaffold_probe"


def _numba_cache_of(folder: Path) -> Path | None:
    """Where numba keeps the cache of the sources in ``folder`` when NUMBA_CACHE_DIR is set."""
    root = os.environ.get("NUMBA_CACHE_DIR")
    if not root:
        return None  # beside the sources, in __pycache__: removed with the folder
    from numba.core.caching import _CacheLocator

    return Path(root) / _CacheLocator.get_suitable_cache_subpath(str(folder / "kernels.py"))


def test_generated_plugin_installs_and_passes_check_and_its_tests(tmp_path):
    pkg, site = tmp_path / "pkg", tmp_path / "site"
    assert main(["new-plugin", NAME, "--out", str(pkg)]) == 0
    # a regular install, offline, against this environment's setuptools and starid
    pip = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                          "--no-index", "--target", str(site), str(pkg)], capture_output=True, text=True)
    assert pip.returncode == 0, pip.stdout[-2000:] + pip.stderr[-3000:]
    assert (site / NAME / "kernels.py").is_file()
    assert any(p.name.startswith("starid_scaffold_probe-") for p in site.glob("*.dist-info"))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), *filter(None, [os.environ.get("PYTHONPATH")])]))
    starid = [sys.executable, "-m", "starid"]
    try:
        check = subprocess.run([*starid, "check", NAME], env=env, capture_output=True, text=True, timeout=300)
        assert check.returncode == 0, check.stdout + check.stderr
        assert "all checks passed" in check.stdout and " failed" not in check.stdout
        # its own tests, unchanged, from its folder (its pyproject is the pytest root), against the installed
        # copy (-P: the working folder is not put on the path)
        tests = subprocess.run([sys.executable, "-P", "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
                                "tests"], cwd=pkg, env=env, capture_output=True, text=True, timeout=300)
        assert tests.returncode == 0, tests.stdout[-3000:] + tests.stderr[-2000:]
        assert " passed" in tests.stdout and "failed" not in tests.stdout
        # the entry point was the installed one, and this process never saw it
        listing = subprocess.run([*starid, "list"], env=env, capture_output=True, text=True, timeout=120)
        assert any(line.split()[:2] == [NAME, "ok"] for line in listing.stdout.splitlines()), listing.stdout
    finally:
        cache = _numba_cache_of(site / NAME)
        if cache is not None:
            shutil.rmtree(cache, ignore_errors=True)
    from starid import registry
    assert NAME not in {info.name for info in registry.available_algorithms()}


def test_new_plugin_refuses_bad_names_and_used_folders(tmp_path):
    for bad in ("Bad", "1x", "class", "numpy", "with-dash"):
        with pytest.raises(ConfigError):
            new_plugin(bad, tmp_path / bad)
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    with pytest.raises(ConfigError, match="not an empty folder"):
        new_plugin("fine_name", tmp_path / "full")
