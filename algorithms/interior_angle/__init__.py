"""The interior-angle method as Galvizo & Lim (2018) ran it: see :class:`InteriorAngle`."""

from .algorithm import GALVIZO2018, InteriorAngle

__all__ = ["GALVIZO2018", "InteriorAngle"]
