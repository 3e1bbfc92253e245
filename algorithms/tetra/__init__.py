"""Tetra plugin (Brown 2017, four-star pattern hashing): see :class:`Tetra`."""

from .algorithm import Tetra, TetraDatabase

__all__ = ["Tetra", "TetraDatabase"]
