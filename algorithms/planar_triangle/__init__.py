"""planar_triangle: Cole & Crassidis (2006) planar-triangle star identification."""

from .algorithm import PlanarTriangle, PlanarTriangleDatabase

__all__ = ["PlanarTriangle", "PlanarTriangleDatabase"]
