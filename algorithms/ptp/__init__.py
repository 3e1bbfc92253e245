"""PTP plugin (Zhou & Ye 2015): see :class:`PTP`."""

from .algorithm import PTP, PTPDatabase

__all__ = ["PTP", "PTPDatabase"]
