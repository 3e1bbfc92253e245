"""numba's on-disk caches: recognise an unreadable cache file and say which folder to clear.

``@njit(cache=True)`` keeps compiled machine code in ``__pycache__/*.nbi`` and ``*.nbc`` beside
each source file. A truncated or garbage cache file makes the kernel fail to load; starid then
records the failure with the folder to clear instead of a bare unpickling error.
"""

from __future__ import annotations

import os
import traceback


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
