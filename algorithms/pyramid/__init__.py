"""Pyramid plugin (Mortari, Samaan, Bruccoleri & Junkins 2004): see :class:`Pyramid`."""

from .algorithm import PairDatabase, Pyramid

__all__ = ["PairDatabase", "Pyramid"]
