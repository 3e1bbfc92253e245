"""P-vector star identification (Yang, Zhang & Jiang 2007), reconstructed; see :class:`PVector`."""

from .algorithm import PVector, PVectorDatabase

__all__ = ["PVector", "PVectorDatabase"]
