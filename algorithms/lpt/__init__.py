"""Log-polar-transform plugin (Wei, Zhang & Jiang 2009): see :class:`LPT`."""

from .algorithm import LPT, LPTDatabase

__all__ = ["LPT", "LPTDatabase"]
