"""Exceptions raised by starid. Every error a user can cause is a :class:`StarIDError`."""


class StarIDError(ValueError):
    """Base class of every starid error caused by bad input or configuration."""


class CatalogError(StarIDError):
    """A star catalog is malformed (missing columns, NaN, duplicate ids, bad ranges)."""


class ObservationError(StarIDError):
    """An observation is malformed (wrong shapes, NaN or out-of-image centroids)."""


class ConfigError(StarIDError):
    """A parameter of the camera, simulator, harness or an algorithm is invalid."""


class PluginError(StarIDError):
    """An algorithm plugin is unknown, failed to import, or broke the plugin contract."""


class StarIDWarning(UserWarning):
    """Input that is valid but probably not what was meant (e.g. a catalog in radians)."""
