"""starid: fair, fast and reproducible comparison of lost-in-space star-identification algorithms."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("starid")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0+unknown"

from .camera import Camera
from .catalog import Catalog, load_csv, load_hipparcos
from .errors import CatalogError, ConfigError, ObservationError, PluginError, StarIDError
from .observation import Observation, TrialSet
from .plugin import Algorithm, Database, Identification
from .registry import available_algorithms, get_algorithm, register
from .simulate import SimConfig, Simulator

__all__ = [
    "Algorithm", "Camera", "Catalog", "CatalogError", "ConfigError", "Database", "Identification", "Observation",
    "ObservationError", "PluginError", "SimConfig", "Simulator", "StarIDError", "TrialSet", "available_algorithms",
    "get_algorithm", "load_csv", "load_hipparcos", "register",
]
