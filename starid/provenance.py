"""Where a result came from: package versions, machine, CPU, command line, time."""

from __future__ import annotations

import datetime as _dt
import os
import platform
import sys
from functools import lru_cache
from importlib.metadata import PackageNotFoundError, version


def _version(dist: str) -> str:
    try:
        return version(dist)
    except PackageNotFoundError:
        if dist == "starid-bench":      # a checkout installed before the rename (distribution "starid")
            return _version("starid")
        return "not installed"


@lru_cache(maxsize=1)
def versions() -> dict:
    """Versions of starid and the packages that can change a result (for every result row)."""
    return {"starid_version": _version("starid-bench"), "numpy_version": _version("numpy"),
            "numba_version": _version("numba"), "python_version": platform.python_version()}


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


@lru_cache(maxsize=1)
def machine() -> dict:
    """The machine a run used (for manifests; not for result rows)."""
    return {"hostname": platform.node(), "platform": platform.platform(), "cpu": _cpu_model(),
            "cpu_count": os.cpu_count() or 1, "python": sys.version.split()[0],
            "packages": {**versions(), "pandas_version": _version("pandas"), "scipy_version": _version("scipy"),
                         "pyarrow_version": _version("pyarrow")}}


def now() -> str:
    """The current time, ISO 8601 in UTC."""
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def command_line() -> str:
    return " ".join([os.path.basename(sys.argv[0]) or "python", *sys.argv[1:]])
