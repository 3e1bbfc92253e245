"""Improved log-polar plugin (Luo, Xu, Zhang & Sun 2015): see :class:`ImprovedLPT`."""

from .algorithm import ImprovedLPT, ImprovedLPTDatabase

__all__ = ["ImprovedLPT", "ImprovedLPTDatabase"]
