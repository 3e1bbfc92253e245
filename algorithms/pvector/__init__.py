"""pvector plugin (being written)."""
