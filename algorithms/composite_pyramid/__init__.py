"""Composite Pyramid plugin (Galvizo & Lim 2018, after Toloei et al.): see :class:`CompositePyramid`."""

from .algorithm import GALVIZO2018, CompositePyramid

__all__ = ["GALVIZO2018", "CompositePyramid"]
