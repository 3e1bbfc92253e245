"""Geometric-voting plugin (Kolomenkin, Pollak, Shimshoni & Lindenbaum 2008): see :class:`GeometricVoting`."""

from .algorithm import GeometricVoting

__all__ = ["GeometricVoting"]
