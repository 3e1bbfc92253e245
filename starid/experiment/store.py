"""A results folder: a manifest and one Parquet file per computed chunk, each written atomically.

Layout of ``DIR/``::

    manifest.json          the experiment, its digest, versions, machine, CPU, command, times
    chunks/<key>.parquet   the trial rows of one (grid point, algorithm variant, trial block)
    results.parquet        every row of the current definition, in plan order (rewritten at the end)

A chunk's file name is the hash of everything that determines its rows (settings, variant,
plugin version, trial range, seed, starid version), so resuming is a file-existence test and
rows of two definitions can never mix: a changed experiment simply asks for other keys. A folder
holding anything else, or another experiment's results, is refused.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import pandas as pd

from ..errors import ConfigError
from ..io import atomic_write_bytes, atomic_write_text
from ..provenance import command_line, machine

MANIFEST = "manifest.json"


class Store:
    """The results folder of one experiment (see the module docstring)."""

    def __init__(self, root: str | Path, experiment):
        self.root = Path(root)
        self.experiment = experiment
        self.chunks = self.root / "chunks"
        self._check()

    def _check(self) -> None:
        root = self.root
        if root.exists() and not root.is_dir():
            raise ConfigError(f"--out {root} is a file, not a folder")
        manifest = root / MANIFEST
        if root.is_dir() and any(root.iterdir()):
            if not manifest.is_file():
                raise ConfigError(f"--out {root} already holds files that are not a starid results folder; "
                                  f"choose a new or empty folder")
            try:
                old = json.loads(manifest.read_text())
            except (OSError, ValueError) as exc:
                raise ConfigError(f"{manifest} is unreadable ({exc}); choose a new folder") from None
            name = old.get("experiment", {}).get("name")
            if name != self.experiment.name:
                raise ConfigError(f"--out {root} holds results of experiment {name!r}, not {self.experiment.name!r}; "
                                  f"choose another folder")
        try:
            self.chunks.mkdir(parents=True, exist_ok=True)
            probe = root / ".write-test"
            probe.write_bytes(b"")
            probe.unlink()
        except OSError as exc:
            raise ConfigError(f"cannot write to --out {root}: {exc.strerror}") from None

    def has(self, key: str) -> bool:
        return (self.chunks / f"{key}.parquet").is_file()

    def write(self, key: str, frame: pd.DataFrame) -> None:
        buf = io.BytesIO()
        frame.to_parquet(buf, index=False)
        atomic_write_bytes(self.chunks / f"{key}.parquet", buf.getvalue())

    def read(self, key: str) -> pd.DataFrame:
        return pd.read_parquet(self.chunks / f"{key}.parquet")

    def write_manifest(self, keys: list[str], started: str, finished: str | None, extra: dict | None = None) -> None:
        data = {"experiment": self.experiment.to_dict(), "digest": self.experiment.digest(),
                "machine": machine(), "command": command_line(), "started": started, "finished": finished,
                "chunks": keys, **(extra or {})}
        data["camera"] = self.experiment.make_camera().as_dict()    # the resolved camera, every field (#23)
        atomic_write_text(self.root / MANIFEST, json.dumps(data, indent=2, default=str) + "\n")

    def write_results(self, frame: pd.DataFrame) -> Path:
        buf = io.BytesIO()
        frame.to_parquet(buf, index=False)
        path = self.root / "results.parquet"
        atomic_write_bytes(path, buf.getvalue())
        return path


def read_manifest(root: str | Path) -> dict:
    """The manifest of a results folder; :class:`ConfigError` when there is none."""
    path = Path(root) / MANIFEST
    try:
        return json.loads(path.read_text())
    except OSError:
        raise ConfigError(f"{root} is not a starid results folder (no {MANIFEST})") from None
    except ValueError as exc:
        raise ConfigError(f"{path} is unreadable: {exc}") from None


