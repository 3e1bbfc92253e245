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
from .simulate import SimConfig, Simulator

__all__ = [
    "Camera", "Catalog", "CatalogError", "ConfigError", "Observation", "ObservationError",
    "PluginError", "SimConfig", "Simulator", "StarIDError", "TrialSet", "load_csv", "load_hipparcos",
]
