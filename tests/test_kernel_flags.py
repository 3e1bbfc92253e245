"""Every kernel compiles with one of starid's two flag sets (starid.kernels.jit; issue #25: compile time).

numba compiles each numpy function a kernel uses once per set of flags of its callers, so a kernel
with other flags (a plain ``@njit(cache=True)``, say) makes every cold cache compile those again.
Allowed: ``cache=True`` and ``no_cfunc_wrapper=True`` always; ``no_cpython_wrapper``, ``inline`` and
ptp's ``error_model="numpy"`` on top. Tests' own kernels are not held to it.
"""

import importlib
import pkgutil

import pytest
import starid_algorithms
from numba.core.caching import FunctionCache
from numba.core.registry import CPUDispatcher

import starid.kernels

#: the only plugin whose kernels use numpy's error model (docs/algorithms/ptp.md)
NUMPY_ERROR_MODEL = ("starid_algorithms.ptp.",)
ALLOWED = {"no_cfunc_wrapper", "no_cpython_wrapper", "inline", "error_model", "nopython", "boundscheck"}


def _dispatchers():
    for pkg in (starid.kernels, starid_algorithms):
        for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            if ".tests" in info.name:
                continue
            for value in vars(importlib.import_module(info.name)).values():
                if isinstance(value, CPUDispatcher) and value.py_func.__module__ == info.name:
                    key = f"{info.name}.{value.py_func.__name__}"
                    yield key + (" (inline)" if value.targetoptions.get("inline") else ""), value


DISPATCHERS = dict(_dispatchers())


def test_there_are_kernels_to_check():
    assert len(DISPATCHERS) > 200


@pytest.mark.parametrize("name", sorted(DISPATCHERS))
def test_kernel_flags(name):
    dispatcher = DISPATCHERS[name]
    options = dispatcher.targetoptions
    # (a second dispatcher of a kernel for numba's inlining is never compiled on its own: nothing to cache)
    inlined = options.get("inline") == "always"
    assert inlined or isinstance(dispatcher._cache, FunctionCache), f"{name}: not cache=True"
    assert options.get("no_cfunc_wrapper") is True, f"{name}: compiles a C entry point (no_cfunc_wrapper=True)"
    assert set(options) <= ALLOWED, f"{name}: flags {sorted(set(options) - ALLOWED)} beyond starid's two sets"
    numpy_model = options.get("error_model", "python") == "numpy"
    assert numpy_model == name.startswith(NUMPY_ERROR_MODEL), f"{name}: error_model {options.get('error_model')}"
    assert options.get("boundscheck") in (None, False), f"{name}: boundscheck on"
