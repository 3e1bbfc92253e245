"""Kernels called through a registered symbol (``starid.kernels.symcall``) work from cached callers.

A caller compiled against :func:`starid.kernels.wahba_rows`, :func:`~starid.kernels.reproject_assign` or
:func:`~starid.kernels.verify_pairwise` refers to their C functions by symbol name; its cached machine
code is only usable in a new process if ``import starid.kernels`` binds those names again. Two fresh
processes on one empty numba cache: the first compiles the caller, the second must load it from the
cache (no compilation) and give the same numbers to the last bit.
"""

import json
import os
import subprocess
import sys
import textwrap

import numpy as np

CALLER = textwrap.dedent('''
    import hashlib, json, sys
    import numpy as np
    from numba import njit
    from starid.kernels import reproject_assign, verify_pairwise, wahba_rows

    @njit(cache=True)
    def caller(v, cand, unit32, unit64, out32, out64):
        keep = verify_pairwise(v, cand, unit32, 1e-3, np.int64(2), 0.5)
        rows = np.where(keep, cand, -1)
        A = wahba_rows(v, rows, unit32)
        B = wahba_rows(v, rows, unit64)
        r32 = reproject_assign(A, v, unit32, 0.3, 1e-3, out32, 1000.0, 512.0, 512.0, 1024, 1024)
        r64 = reproject_assign(B, v, unit64, 0.3, 1e-3, out64, 1000.0, 512.0, 512.0, 1024, 1024)
        return keep, A, B, r32[0], r32[1], r64[0], r64[1]

    rng = np.random.default_rng(7)
    unit = rng.normal(size=(2000, 3))
    unit /= np.sqrt((unit ** 2).sum(axis=1))[:, None]
    unit = unit[np.argsort(unit[:, 2])]
    cand = np.nonzero(unit[:, 2] > 0.99)[0][:10].astype(np.int64)
    v = unit[cand] + rng.normal(scale=1e-5, size=(len(cand), 3))
    v /= np.sqrt((v ** 2).sum(axis=1))[:, None]
    cand[0] = 5                                          # one wrong proposal for the verification to drop
    out32, out64 = np.empty(len(v), np.int64), np.empty(len(v), np.int64)
    got = caller(v, cand, unit.astype(np.float32), unit, out32, out64)
    h = hashlib.sha1()
    for x in got + (out32, out64):
        h.update(np.asarray(x).tobytes())
    print(json.dumps({"digest": h.hexdigest(), "assigned": int(got[3]), "kept": int(got[0].sum()),
                      "hits": sum(caller.stats.cache_hits.values()),
                      "misses": sum(caller.stats.cache_misses.values())}))
''')


def _run(script, cache):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    out = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_cached_caller_in_a_new_process(tmp_path):
    script = tmp_path / "symcall_caller.py"
    script.write_text(CALLER)
    first = _run(script, tmp_path / "cache")
    second = _run(script, tmp_path / "cache")
    assert first["misses"] == 1 and first["hits"] == 0
    assert second["hits"] == 1 and second["misses"] == 0, "the caller was compiled again, not loaded"
    assert second["digest"] == first["digest"]
    assert first["kept"] >= 8 and first["assigned"] >= 8     # the kernels did their work


def test_shim_raises_like_the_kernel():
    """A non-finite Wahba matrix still raises LinAlgError through the C function."""
    import pytest

    from starid.kernels import wahba_rows

    with pytest.raises(np.linalg.LinAlgError, match="infs or NaNs"):
        wahba_rows(np.full((3, 3), np.nan), np.arange(3), np.eye(3))
