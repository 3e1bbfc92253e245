"""planar_triangle plugin (being written)."""
