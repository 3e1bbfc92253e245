"""starid: fair, fast and reproducible comparison of lost-in-space star-identification algorithms.

For a notebook::

    import starid
    catalog = starid.Catalog.embedded()
    sim = starid.Simulator(catalog, starid.Camera(), starid.SimConfig(sigma_px=1.0), seed=1)
    rows = starid.run([starid.get_algorithm("ptp")()], sim.generate(100), catalog, sim)
    starid.summarize(rows)

Sweeps, resumable results and parallel runs: :mod:`starid.experiment`.
"""

from . import jitcache as _jitcache  # noqa: F401  first: a regular install caches numba kernels in the user's cache folder

# isort: split
from .camera import Camera
from .catalog import Catalog, load_csv, load_hipparcos
from .errors import CatalogError, ConfigError, ObservationError, PluginError, StarIDError, StarIDWarning
from .harness import run
from .observation import Observation, TrialSet
from .plugin import Algorithm, Database, Explanation, Identification
from .provenance import versions as _versions
from .registry import available_algorithms, get_algorithm, register
from .simulate import SKIES, SimConfig, Simulator
from .stats import mcnemar, summarize, wilson_interval

__version__ = _versions()["starid_version"]


def available() -> list[str]:
    """Names of the registered algorithms that load (``starid list`` shows the broken ones too)."""
    return [i.name for i in available_algorithms() if i.status == "ok"]


__all__ = [
    "Algorithm", "Camera", "Catalog", "CatalogError", "ConfigError", "Database", "Explanation", "Identification",
    "Observation", "ObservationError", "PluginError", "SKIES", "SimConfig", "Simulator", "StarIDError",
    "StarIDWarning", "TrialSet", "available", "available_algorithms", "get_algorithm", "load_csv", "load_hipparcos",
    "mcnemar", "register", "run", "summarize", "wilson_interval",
]
