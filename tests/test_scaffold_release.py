"""The release: the distribution is ``starid-bench``; a regular install caches numba kernels in the
user's cache folder (``NUMBA_CACHE_DIR``), a checkout beside its sources, and a user's own setting wins."""

from __future__ import annotations

from pathlib import Path

from starid import jitcache
from starid.provenance import versions

ROOT = Path(__file__).resolve().parents[1]


def test_distribution_is_starid_bench():
    text = (ROOT / "pyproject.toml").read_text()
    assert 'name = "starid-bench"' in text
    assert 'starid = "starid.cli:main"' in text                # the command stays starid
    assert versions()["starid_version"] != "not installed"     # found under the new name


def test_regular_install_caches_in_the_user_folder(tmp_path):
    site = tmp_path / "lib" / "python3.11" / "site-packages" / "starid"
    site.mkdir(parents=True)
    env = {"XDG_CACHE_HOME": str(tmp_path / "xdg")}
    assert jitcache.choose_cache_dir(site, env, "linux") == str(tmp_path / "xdg" / "starid" / "numba")
    # a checkout (writable, not in site-packages) keeps numba's default: beside the sources
    checkout = tmp_path / "src" / "starid"
    checkout.mkdir(parents=True)
    assert jitcache.choose_cache_dir(checkout, env, "linux") is None
    # the user's own NUMBA_CACHE_DIR is never overridden
    assert jitcache.choose_cache_dir(site, {**env, "NUMBA_CACHE_DIR": "/mine"}, "linux") is None
    environ = dict(env)
    assert jitcache.configure(site, environ) == environ["NUMBA_CACHE_DIR"] == str(tmp_path / "xdg" / "starid" / "numba")


def test_numba_imported_first_gets_the_folder_too(tmp_path, monkeypatch):
    """numba read the environment when it was imported (a notebook importing numba before starid): its config
    is pointed at the user folder as well; a CACHE_DIR numba already had is kept."""
    import numba.core.config as config

    monkeypatch.setattr(config, "CACHE_DIR", "")
    site = Path("/usr/lib/python3/site-packages/starid")
    folder = jitcache.configure(site, {"XDG_CACHE_HOME": str(tmp_path)})
    assert folder == config.CACHE_DIR == str(tmp_path / "starid" / "numba")
    monkeypatch.setattr(config, "CACHE_DIR", "/theirs")
    jitcache.configure(site, {"XDG_CACHE_HOME": str(tmp_path)})
    assert config.CACHE_DIR == "/theirs"
