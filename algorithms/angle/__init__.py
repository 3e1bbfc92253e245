"""The two-star angle method as Galvizo & Lim (2018) ran it: see :class:`Angle`."""

from .algorithm import GALVIZO2018, Angle

__all__ = ["GALVIZO2018", "Angle"]
