"""Grid plugin (Padgett & Kreutz-Delgado 1997, modified-grid options of Na, Zheng & Jia 2009): see :class:`Grid`."""

from .algorithm import Grid, GridDatabase

__all__ = ["Grid", "GridDatabase"]
