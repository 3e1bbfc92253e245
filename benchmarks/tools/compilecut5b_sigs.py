"""Which numba dispatchers the named plugins compile, and for which signatures (compilecut5b): build
and warm-up identify of each plugin in this process (as ``starid.harness.prepare``), then every
dispatcher of ``starid.kernels`` and ``starid_algorithms`` with its signatures. Run on an empty cache:

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/compilecut5b_sigs.py pyramid angle
"""

from __future__ import annotations

import importlib
import pkgutil
import sys

import starid_algorithms
from numba.core.registry import CPUDispatcher

import starid.kernels
from starid import SimConfig, Simulator, load_hipparcos
from starid.experiment.spec import sim_settings
from starid.experiments import table6
from starid.harness import prepare
from starid.registry import algorithm_info


def main(names):
    catalog = load_hipparcos()
    exp = table6.experiment(trials=2)
    trials = Simulator(catalog, exp.make_camera(), SimConfig(**sim_settings(exp.sim, {"sky": "paper"})),
                       seed=0).generate(2)
    for name in names:
        prepare(algorithm_info(name).cls(), catalog, trials.camera, trials.warmup, name)
    for pkg in (starid.kernels, starid_algorithms):
        for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            if ".tests" in info.name:
                continue
            module = importlib.import_module(info.name)
            for key, value in vars(module).items():
                if isinstance(value, CPUDispatcher) and value.py_func.__module__ == info.name and value.signatures:
                    print(f"{len(value.signatures)}  {info.name}.{key}")
                    for s in value.signatures:
                        print("      ", s)


if __name__ == "__main__":
    main(sys.argv[1:])
