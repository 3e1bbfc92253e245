"""Spherical-triangle plugin (Cole & Crassidis 2004; as Galvizo & Lim 2018 ran it): see :class:`SphericalTriangle`."""

from .algorithm import GALVIZO2018, SphericalTriangle, TriangleDatabase

__all__ = ["GALVIZO2018", "SphericalTriangle", "TriangleDatabase"]
