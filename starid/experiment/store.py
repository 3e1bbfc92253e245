"""A results folder: a manifest and one Parquet file per computed chunk, each written atomically.

Layout of ``DIR/``::

    manifest.json          the experiment, its digest, versions, machine, CPU, command, times
    chunks/<key>.parquet   the trial rows of one (grid point, algorithm variant, trial block)
    results.parquet        every row of the current definition, in plan order (rewritten at the end)

A chunk's file name is the hash of everything that determines its rows (settings, variant,
plugin version, trial range, seed, starid version), so resuming is a file-existence test and
rows of two definitions can never mix: a changed experiment simply asks for other keys. A folder
holding anything else, or another experiment's results, is refused.

The manifest's ``checksums`` map each chunk key to the SHA-256 of its file (updated as each chunk
is written). On resume a chunk that does not match its checksum, or (written before checksums or
before the manifest caught up) does not read, is damaged -- a truncated or corrupted file after a
full disk or a partial copy: it is reported in one line, set aside as
``chunks/<key>.parquet.damaged`` (never deleted) and recomputed (:meth:`Store.usable`);
:func:`damaged_chunks` lists them for ``starid report``.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import socket
import warnings
from pathlib import Path

import pandas as pd

from ..errors import ConfigError, StarIDWarning
from ..io import atomic_write_bytes, atomic_write_text
from ..provenance import command_line, machine, now

MANIFEST = "manifest.json"
#: manifest key: chunk key -> SHA-256 (hex) of ``chunks/<key>.parquet``
CHECKSUMS = "checksums"
#: suffix a damaged chunk file is renamed to (set aside, never deleted)
DAMAGED = ".damaged"
#: the folder lock (``filelock``; an OS lock, so a killed run's lock is free) and who holds it
LOCK, HOLDER = ".starid.lock", ".starid.lock.json"
_HELD: list = []      # locks this process holds (closed in forked workers, see release_in_child)


def _holder_text(info: dict) -> str:
    return (f"pid {info.get('pid', '?')} on {info.get('host', '?')}, started {info.get('started', '?')}"
            + (f" ({info['command']})" if info.get("command") else ""))


def _read_holder(root: Path) -> dict:
    try:
        info = json.loads((root / HOLDER).read_text())
        return info if isinstance(info, dict) else {}
    except (OSError, ValueError):
        return {}


class FolderLock:
    """One run at a time per results folder: an exclusive ``filelock`` lock on ``DIR/.starid.lock``,
    its holder (pid, host, start time, command) in ``DIR/.starid.lock.json``.

    A second run is refused at once (:class:`ConfigError`, exit 2) naming the holder. The lock is
    the operating system's, so it dies with the process that held it: the holder file a killed run
    left behind is stale, and the next run takes the lock over, saying so in one line.
    """

    def __init__(self, root: str | Path):
        self.root = Path(root)
        self._lock = None

    def acquire(self) -> FolderLock:
        from filelock import FileLock, Timeout

        lock = FileLock(str(self.root / LOCK), timeout=0)
        try:
            lock.acquire()
        except Timeout:
            info = _read_holder(self.root)
            raise ConfigError(f"--out {self.root} is in use by another starid run: {_holder_text(info)}; wait for it "
                              f"to finish or choose another folder") from None
        self._lock = lock
        _HELD.append(lock)
        old = _read_holder(self.root)
        if old:
            warnings.warn(f"{self.root}: taking over the lock of a run that is no longer running "
                          f"({_holder_text(old)})", StarIDWarning, stacklevel=2)
        info = {"pid": os.getpid(), "host": socket.gethostname(), "started": now(), "command": command_line()}
        atomic_write_text(self.root / HOLDER, json.dumps(info) + "\n")
        return self

    def release(self) -> None:
        if self._lock is None:
            return
        (self.root / HOLDER).unlink(missing_ok=True)
        self._lock.release()
        if self._lock in _HELD:
            _HELD.remove(self._lock)
        self._lock = None

    def __enter__(self) -> FolderLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def release_in_child() -> None:
    """In a forked worker: let go of the inherited descriptors of the folder locks, so that a worker
    outliving a killed run does not keep its folder locked (filelock < 4 flocks the inherited file;
    filelock 4 also breaks a lock whose holder pid is dead)."""
    while _HELD:
        lock = _HELD.pop()
        fd = getattr(getattr(lock, "_context", None), "lock_file_fd", None)
        if isinstance(fd, int):     # /dev/null in its place: the number stays taken, the lock's file is let go
            try:
                null = os.open(os.devnull, os.O_RDWR)
                os.dup2(null, fd)
                os.close(null)
            except OSError:
                pass


def file_sha256(path: str | Path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def chunk_problem(path: str | Path, checksum: str | None) -> str | None:
    """Why the chunk file at ``path`` cannot be used (``None``: it can): unreadable, or not the
    ``checksum`` the manifest recorded for it. Without a checksum the file must read as Parquet."""
    path = Path(path)
    try:
        digest = file_sha256(path)
    except OSError as exc:
        return f"unreadable ({exc.strerror})"
    if checksum is not None:
        return None if digest == checksum else f"checksum mismatch (manifest {checksum[:12]}, file {digest[:12]})"
    try:
        pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises several types for a damaged file
        return f"unreadable ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})"
    return None


def damaged_chunks(root: str | Path) -> list[tuple[str, str]]:
    """``(chunk key, problem)`` of every chunk of the manifest whose file is there but damaged
    (checksum mismatch or unreadable; missing chunks are not listed), in manifest order."""
    root = Path(root)
    manifest = read_manifest(root)
    sums = manifest.get(CHECKSUMS) or {}
    out = []
    for key in manifest.get("chunks") or []:
        path = root / "chunks" / f"{key}.parquet"
        if path.is_file():
            problem = chunk_problem(path, sums.get(key))
            if problem is not None:
                out.append((key, problem))
    return out


def damaged_note(root: str | Path) -> str:
    """``""``, or a sentence naming the damaged chunks of a results folder (for ``starid report``)."""
    try:
        bad = damaged_chunks(root)
    except ConfigError:
        return ""
    if not bad:
        return ""
    return (f"; {len(bad)} damaged chunk(s) in {Path(root) / 'chunks'}: "
            + ", ".join(f"{key}.parquet ({problem})" for key, problem in bad)
            + " -- run the same command again: it sets them aside and recomputes them")


class Store:
    """The results folder of one experiment (see the module docstring)."""

    def __init__(self, root: str | Path, experiment):
        self.root = Path(root)
        self.experiment = experiment
        self.chunks = self.root / "chunks"
        self.checksums: dict[str, str] = {}
        self._manifest: dict | None = None
        self._check()

    def _check(self) -> None:
        root = self.root
        if root.exists() and not root.is_dir():
            raise ConfigError(f"--out {root} is a file, not a folder")
        manifest = root / MANIFEST
        if root.is_dir() and any(p.name not in (LOCK, HOLDER) for p in root.iterdir()):
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
            if isinstance(old.get(CHECKSUMS), dict):
                self.checksums = {str(k): str(v) for k, v in old[CHECKSUMS].items()}
        try:
            self.chunks.mkdir(parents=True, exist_ok=True)
            probe = root / ".write-test"
            probe.write_bytes(b"")
            probe.unlink()
        except OSError as exc:
            raise ConfigError(f"cannot write to --out {root}: {exc.strerror}") from None

    def has(self, key: str) -> bool:
        return (self.chunks / f"{key}.parquet").is_file()

    def lock(self) -> FolderLock:
        """Take the folder's :class:`FolderLock` (released by the caller)."""
        return FolderLock(self.root).acquire()

    def usable(self, key: str) -> bool:
        """The chunk is there and whole. A damaged one (:func:`chunk_problem`) is reported in one
        line (a :class:`StarIDWarning`), set aside as ``<key>.parquet.damaged`` and reported missing,
        so that it is recomputed."""
        path = self.chunks / f"{key}.parquet"
        if not path.is_file():
            return False
        problem = chunk_problem(path, self.checksums.get(key))
        if problem is None:
            if key not in self.checksums:
                self.checksums[key] = file_sha256(path)
            return True
        aside = path.with_name(path.name + DAMAGED)
        n = 1
        while aside.exists():
            n += 1
            aside = path.with_name(f"{path.name}{DAMAGED}-{n}")
        path.rename(aside)
        self.checksums.pop(key, None)
        warnings.warn(f"chunk {key} in {self.root} is damaged: {problem}; set aside as chunks/{aside.name}, "
                      f"recomputing it", StarIDWarning, stacklevel=2)
        return False

    def write(self, key: str, frame: pd.DataFrame) -> None:
        buf = io.BytesIO()
        frame.to_parquet(buf, index=False)
        data = buf.getvalue()
        atomic_write_bytes(self.chunks / f"{key}.parquet", data)
        self.checksums[key] = hashlib.sha256(data).hexdigest()
        if self._manifest is not None:      # the manifest follows every chunk (a killed run keeps its sums)
            self._manifest[CHECKSUMS] = dict(self.checksums)
            atomic_write_text(self.root / MANIFEST, json.dumps(self._manifest, indent=2, default=str) + "\n")

    def read(self, key: str) -> pd.DataFrame:
        return pd.read_parquet(self.chunks / f"{key}.parquet")

    def write_manifest(self, keys: list[str], started: str, finished: str | None, extra: dict | None = None) -> None:
        data = {"experiment": self.experiment.to_dict(), "digest": self.experiment.digest(),
                "machine": machine(), "command": command_line(), "started": started, "finished": finished,
                "chunks": keys, **(extra or {})}
        data["camera"] = self.experiment.make_camera().as_dict()    # the resolved camera, every field (#23)
        data[CHECKSUMS] = dict(self.checksums)
        self._manifest = data
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


