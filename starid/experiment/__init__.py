"""The experiment engine: any sweep as data, run in chunks, resumable, local or on Dask.

* :mod:`.spec` -- :class:`Experiment`, :class:`Study`, :class:`Grid`, :class:`Variant` (and TOML);
* :mod:`.runner` -- plan into chunks, run the missing ones, assemble the tidy frame;
* :mod:`.store` -- the results folder (manifest + Parquet chunks, written atomically);
* :mod:`.executors` -- supervised local worker processes, or Dask.
"""

from .runner import run_experiment
from .spec import Experiment, Grid, Study, Variant
from .store import read_manifest

__all__ = ["Experiment", "Grid", "Study", "Variant", "read_manifest", "run_experiment"]
