"""numba's on-disk caches: where they go, and recognising an unreadable cache file.

Where: in a source checkout (an editable install) numba keeps its caches beside the sources. In a
regular install (the package under ``site-packages``, or in a folder this user cannot write)
:func:`configure` points numba at a user cache folder instead (``NUMBA_CACHE_DIR``, numba's own
mechanism): ``$XDG_CACHE_HOME/starid/numba`` (``~/.cache/starid/numba``; ``~/Library/Caches`` on
macOS, ``%LOCALAPPDATA%`` on Windows). A ``NUMBA_CACHE_DIR`` the user set is never overridden.

``@njit(cache=True)`` keeps compiled machine code in ``__pycache__/*.nbi`` and ``*.nbc`` beside
each source file. A truncated or garbage cache file makes the kernel fail to load; starid then
records the failure with the folder to clear instead of a bare unpickling error.

When: numba keys a kernel's cached code on its own source file (path, modification time, size), but
the code holds every callee it inlined or linked, from any file. In a checkout, an edit of a callee in
another file (a core kernel in ``starid/kernels``, a plugin's helper module) left every caller in an
unchanged file running the old callee from its cache, silently (issue #25, stop 44: a speed round
timed stale code this way). :func:`install_locators` (run on import) adds to each key of a kernel in
starid or in any package the fingerprint of the modules numba may compile there
(:func:`tree_stamp`: those that import numba or a jit flag set) and of starid's own: an
edit of any of them makes the kernels of that package, and of every package calling starid's kernels,
compile again on first use. A regular install is rewritten whole by pip, so nothing changes there.
"""

from __future__ import annotations

import functools
import hashlib
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


#: what marks a module numba may compile code from (a kernel, an intrinsic, a flag set's user)
_COMPILED_MARKS = (b"from numba", b"import numba", b"jit import")


def package_root(py_file: str | Path) -> Path:
    """The top-level package folder of ``py_file`` (its own folder when that is not a package)."""
    return _root_of(os.path.dirname(os.path.abspath(py_file)))


@functools.lru_cache(maxsize=256)
def _root_of(folder_name: str) -> Path:
    folder = Path(folder_name).resolve()
    while (folder.parent / "__init__.py").exists():
        folder = folder.parent
    return folder


@functools.lru_cache(maxsize=64)
def tree_stamp(root: str) -> str:
    """A fingerprint (path, modification time and size, as numba's own key) of every module under the folder
    ``root`` that imports numba or a jit flag set, tests left out: the modules whose code a cached
    kernel of that package can hold. Once per folder and process (numba reads a kernel's key when it is
    decorated)."""
    digest = hashlib.sha256()
    base = Path(root)
    for path in sorted(base.rglob("*.py")):
        rel = path.relative_to(base)
        if "__pycache__" in rel.parts or "tests" in rel.parts:
            continue
        try:
            text = path.read_bytes()
            st = path.stat()
        except OSError:
            continue
        if any(mark in text for mark in _COMPILED_MARKS):
            digest.update(f"{rel.as_posix()}\0{st.st_mtime_ns}\0{st.st_size}\n".encode())
    return digest.hexdigest()[:16]


def _with_tree_stamp(locator: type) -> type:
    """numba's ``locator`` class with :func:`tree_stamp` of the kernel's package and of starid in its key."""

    class Locator(locator):
        def get_source_stamp(self):
            return (super().get_source_stamp(), tree_stamp(str(package_root(self._py_file))),
                    tree_stamp(str(PACKAGE_DIR)))

    Locator.__name__ = Locator.__qualname__ = f"Starid{locator.__name__.lstrip('_')}"
    return Locator


def install_locators() -> None:
    """Put :func:`_with_tree_stamp` versions of numba's source-file cache locators (a user-set cache folder,
    beside the sources, the user-wide folder) in numba's list, once per process."""
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl   # numba 0.60+ names it without the underscore
    if getattr(impl, "_starid_tree_stamp", False):
        return
    wrapped = set()
    for name in ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator",
                 "_UserProvidedCacheLocator", "_InTreeCacheLocator", "_UserWideCacheLocator"):
        cls = getattr(caching, name, None)
        if cls is not None:
            wrapped.add(cls)
    impl._locator_classes = [_with_tree_stamp(c) if c in wrapped else c for c in impl._locator_classes]
    impl._starid_tree_stamp = True


CACHE_DIR = configure()   # on import (``import starid`` imports this module first)
install_locators()


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
