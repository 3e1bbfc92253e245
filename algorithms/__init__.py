"""Built-in algorithm plugins of starid (installed as ``starid_algorithms``), one folder each."""
