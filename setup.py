"""Package discovery (the rest of the metadata is in pyproject.toml).

``algorithms/`` installs as ``starid_algorithms``; every plugin folder below it with an
``__init__.py`` is found here, so a new plugin reaches the wheel without editing any list.
Plugin tests (``algorithms/<name>/tests``) stay in the source tree.
"""

from setuptools import find_packages, setup

plugins = find_packages("algorithms", exclude=["*.tests", "*.tests.*", "tests"])
setup(packages=find_packages(include=["starid", "starid.*"])
      + ["starid_algorithms"] + [f"starid_algorithms.{p}" for p in plugins])
