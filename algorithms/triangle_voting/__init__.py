"""triangle_voting plugin (being written)."""
