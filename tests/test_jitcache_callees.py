"""numba's cache and callees in other files (starid.jitcache.install_locators; issue #25, stop 44).

numba keys a cached kernel on its own source file only, so a caller in an unchanged file kept running
the old code of a callee edited in another file. With starid imported, the key also holds the
fingerprint of the package's compiled modules: the caller compiles again, and nothing else changes
(an untouched package still loads from the cache).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

RUN = textwrap.dedent("""
    import sys
    {starid}
    sys.path.insert(0, sys.argv[1])
    from pkg.a import f
    print(f(), sum(f.stats.cache_hits.values()))
""")


def _write(root, value: int, stamp: float) -> None:
    """``pkg/a.py`` (the caller: written once, its stamp fixed) and ``pkg/b.py`` (the callee: returns ``value``,
    modified at ``stamp``)."""
    (root / "pkg").mkdir(exist_ok=True)
    (root / "pkg" / "__init__.py").write_text("")
    a = root / "pkg" / "a.py"
    if not a.exists():
        a.write_text("from numba import njit\n\nfrom .b import g\n\n\n"
                     "@njit(cache=True)\ndef f():\n    return g() + 1\n")
        os.utime(a, (1_600_000_000, 1_600_000_000))
    b = root / "pkg" / "b.py"
    b.write_text(f"from numba import njit\n\n\n@njit(cache=True)\ndef g():\n    return {value}\n")
    os.utime(b, (stamp, stamp))


def _run(root, with_starid: bool = True) -> tuple[int, int]:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(root / "numba")}
    code = RUN.format(starid="import starid" if with_starid else "")
    out = subprocess.run([sys.executable, "-c", code, str(root)], env=env, capture_output=True, text=True, check=True)
    value, hits = out.stdout.split()
    return int(value), int(hits)


def test_an_edited_callee_in_another_file_is_compiled_again(tmp_path):
    _write(tmp_path, 1, 1_700_000_000)
    assert _run(tmp_path) == (2, 0)             # compiled and cached
    assert _run(tmp_path) == (2, 1)             # nothing edited: loaded from the cache
    _write(tmp_path, 5, 1_700_000_100)          # only b.py changes (a.py's stamp is the same)
    assert _run(tmp_path) == (6, 0)             # the caller compiled again with the new callee
    assert _run(tmp_path) == (6, 1)


def test_without_starid_numba_keeps_the_stale_callee(tmp_path):
    """The behaviour the locators mend, so that the test above can fail: numba alone runs the old g."""
    _write(tmp_path, 1, 1_700_000_000)
    assert _run(tmp_path, with_starid=False) == (2, 0)
    _write(tmp_path, 5, 1_700_000_100)
    assert _run(tmp_path, with_starid=False) == (2, 1)
