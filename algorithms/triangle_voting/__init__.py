"""triangle_voting plugin: Fan & Zhong's triangle voting with double (base, height) feature constraints."""

from .algorithm import TriangleVoting, TriangleVotingDatabase

__all__ = ["TriangleVoting", "TriangleVotingDatabase"]
