"""Every numba kernel is compiled for one type signature (issue #25: compile time).

A kernel called with an int constant (``n = 0``, ``f(x, 0)``) or a bool constant is compiled by
numba for the literal (``Literal[int](0)``) and again for the runtime type; arrays of two dtypes
give two compilations too. Each extra signature is a whole extra compilation of the kernel (and of
everything it inlines), paid on every cold cache. This test runs each registered plugin on a
couple of images and asserts that it adds at most one signature to every ``@njit`` dispatcher of
``starid/kernels`` and of ``algorithms/*``, except the few listed in :data:`EXCEPTIONS` (only the
added ones count: unit tests in the same worker may call kernels directly with other types).

A kernel loaded from numba's on-disk cache does not compile the kernels it calls, so those
callees show their signatures only when the cache is cold (as on a fresh clone or in CI); with a
warm cache the test checks the kernels that Python calls directly.
"""

import importlib
import pkgutil

import pytest
import starid_algorithms
from numba.core.registry import CPUDispatcher

import starid.kernels
from starid import SimConfig, Simulator
from starid.registry import available_algorithms

#: kernel (module.function) -> why it keeps more than one signature.
EXCEPTIONS = {
    "starid.kernels.geometry.chord_rows": "float32 catalogue and float64 image vectors, int16/uint16 row ids "
                                          "(float() casts: equal values); a 4-line helper, casting catalogues "
                                          "would double their memory",
    "starid.kernels.geometry.triple_product": "float32 catalogue and float64 image vectors; a 1-line helper",
    "starid.kernels.geometry.backproject_px": "read-only observation arrays and writable sorted copies; 10 lines",
    "starid.kernels.attitude.wahba_rows": "float32 and float64 catalogue vectors of different plugins",
    "starid.kernels.verify.verify_pairwise": "float32/float64 catalogue vectors of different plugins; "
                                             "triangle_voting (owned by #26) omits min_fraction",
    "starid.kernels.verify.reproject_assign": "float32/float64 catalogue vectors of different plugins",
    "starid.kernels.kvector.kvector_query": "k-vectors with uint16 and int32 ids (different plugins)",
    "starid.kernels.kvector.kvector_range": "k-vectors with uint16 and int32 ids (different plugins)",
    "starid.kernels.order.before": "read-only observation arrays and writable copies",
    "starid.kernels.order.sort_rows": "read-only observation arrays and writable copies",
    "starid_algorithms.lpt_improved.planar.keep_best": "float scores (grid) and int scores (lpt, lpt_improved)",
    "starid_algorithms.lpt_improved.planar.tangent_basis": "float32 catalogue and float64 image vectors",
    "starid_algorithms.pyramid.kernels.triple": "float32 catalogue and float64 image vectors; a 1-line helper",
    "starid_algorithms.pvector.kernels._sort_by": "read-only observation arrays and writable copies",
}

ALGORITHMS = [i for i in available_algorithms() if i.status == "ok"]


def _dispatchers():
    """Every njit dispatcher defined in starid.kernels and starid_algorithms (tests excluded)."""
    found = {}
    for pkg in (starid.kernels, starid_algorithms):
        for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            if ".tests" in info.name:
                continue
            module = importlib.import_module(info.name)
            for value in vars(module).values():
                if isinstance(value, CPUDispatcher) and value.py_func.__module__ == info.name:
                    found[f"{info.name}.{value.py_func.__name__}"] = value
    return found


@pytest.fixture(scope="module")
def observations(catalog, camera):
    trials = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=0).generate(2)
    return [trials.observation(i, truth=False) for i in range(len(trials))]


@pytest.mark.parametrize("info", ALGORITHMS, ids=[i.name for i in ALGORITHMS])
def test_every_kernel_has_one_signature(info, catalog, camera, observations):
    before = {name: set(d.signatures) for name, d in _dispatchers().items()}
    algorithm = info.cls()
    db = algorithm.build(catalog, camera)
    for obs in observations:
        algorithm.identify(db, obs)
    # only the signatures this plugin added: unit tests in the same process may call kernels directly
    many = {name: [str(s) for s in set(d.signatures) - before.get(name, set())]
            for name, d in _dispatchers().items() if name not in EXCEPTIONS}
    many = {name: sigs for name, sigs in many.items() if len(sigs) > 1}
    assert not many, f"kernels compiled for more than one signature after {info.name}: {many}"


def test_exceptions_name_existing_kernels():
    assert set(EXCEPTIONS) <= set(_dispatchers())
