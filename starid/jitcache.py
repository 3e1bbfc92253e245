"""numba's on-disk caches: where they go, and recognising an unreadable cache file.

Where: in a source checkout (an editable install) numba keeps its caches beside the sources. In a
regular install (the package under ``site-packages``, or in a folder this user cannot write)
:func:`configure` points numba at a user cache folder instead (``NUMBA_CACHE_DIR``, numba's own
mechanism): ``$XDG_CACHE_HOME/starid/numba`` (``~/.cache/starid/numba``; ``~/Library/Caches`` on
macOS, ``%LOCALAPPDATA%`` on Windows). A ``NUMBA_CACHE_DIR`` the user set is never overridden.

``@njit(cache=True)`` keeps compiled machine code in ``__pycache__/*.nbi`` and ``*.nbc`` beside
each source file. A truncated or garbage cache file makes the kernel fail to load; starid then
records the failure with the folder to clear instead of a bare unpickling error.
"""

from __future__ import annotations

import os
import sys
import traceback
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent


def user_cache_dir(environ=os.environ, platform: str = sys.platform) -> Path:
    """The per-user cache folder of starid (platformdirs' rule, without the dependency)."""
    if platform == "win32":
        base = Path(environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    else:
        base = Path(environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "starid" / "numba"


def is_regular_install(package_dir: Path = PACKAGE_DIR) -> bool:
    """True when starid runs from ``site-packages``/``dist-packages`` or from a folder it cannot write."""
    parts = {p.lower() for p in Path(package_dir).parts}
    return bool(parts & {"site-packages", "dist-packages"}) or not os.access(package_dir, os.W_OK)


def choose_cache_dir(package_dir: Path = PACKAGE_DIR, environ=os.environ, platform: str = sys.platform) -> str | None:
    """The ``NUMBA_CACHE_DIR`` starid sets: ``None`` for a checkout or when the user set one."""
    if environ.get("NUMBA_CACHE_DIR"):
        return None
    if not is_regular_install(package_dir):
        return None
    return str(user_cache_dir(environ, platform))


def configure(package_dir: Path = PACKAGE_DIR, environ=os.environ) -> str:
    """Set ``NUMBA_CACHE_DIR`` for a regular install (run first thing in ``import starid``); the
    folder numba caches in (``"beside the sources"`` for a checkout)."""
    folder = choose_cache_dir(package_dir, environ)
    if folder is None:
        return environ.get("NUMBA_CACHE_DIR") or "beside the sources"
    environ["NUMBA_CACHE_DIR"] = folder            # worker processes inherit it
    config = sys.modules.get("numba.core.config")  # numba imported before starid: it read the env already
    if config is not None and not getattr(config, "CACHE_DIR", ""):
        config.CACHE_DIR = folder
    return folder


CACHE_DIR = configure()   # on import (``import starid`` imports this module first)


def is_cache_error(exc: BaseException) -> bool:
    """True when ``exc`` was raised while numba loaded a cached kernel."""
    frames = traceback.extract_tb(exc.__traceback__)
    return any(os.path.join("numba", "core", "caching") in f.filename for f in frames)


def cache_folders(exc: BaseException) -> list[str]:
    """The cache folders numba was reading when ``exc`` was raised (from its cache objects)."""
    out = []
    tb = exc.__traceback__
    while tb is not None:
        owner = tb.tb_frame.f_locals.get("self")
        folder = getattr(owner, "_cache_path", None)
        if isinstance(folder, str) and folder not in out:
            out.append(folder)
        tb = tb.tb_next
    return out


def describe(exc: BaseException) -> str:
    """A one-line description of ``exc``; for a broken numba cache, what to delete."""
    text = f"{type(exc).__name__}: {exc}"
    if not is_cache_error(exc):
        return text
    folders = cache_folders(exc) or ["the package's __pycache__ folders"]
    return (f"a numba cache file is unreadable ({text}); delete the *.nbi and *.nbc files in "
            f"{' and '.join(folders)} and run again (they are rebuilt)")
