"""A results folder: a manifest and one Parquet file per computed chunk, each written atomically.

Layout of ``DIR/``::

    manifest.json          the experiment, its digest, versions, machine, CPU, command, times
    chunks/<key>.parquet   the trial rows of one (grid point, algorithm variant, trial block)
    results.parquet        every row of the current definition, in plan order (rewritten at the end)

A chunk's file name is the hash of everything that determines its rows (settings, variant,
plugin version, trial range, seed, starid version), so resuming is a file-existence test and
rows of two definitions can never mix: a changed experiment simply asks for other keys. A folder
holding anything else, or another experiment's results, is refused.

Ownership (the command line, :func:`claim_folder`): a folder belongs to one definition (its
manifest's digest). Running another definition into it is refused, naming what it holds, unless
``overwrite`` (the folder is cleared, reports included) or ``extend`` (same experiment name: its
chunks are reused). Derived files (``results.parquet``, reports, figures, tables) are recorded in
``derived.json`` with the digest they were made from (:func:`record_derived`); when the folder's
definition changes they are deleted (:func:`retire_stale`), and a stale ``results.parquet`` is
refused by :func:`check_current`: never shown as current.

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
DERIVED = "derived.json"
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
        retire_stale(self.root, experiment.digest())     # derived files of another definition go

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
        record_derived(self.root, [path], self.experiment.digest())
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




# ---------------------------------------------------------------------------------------------- ownership

def describe_holdings(manifest: dict) -> str:
    """What a results folder holds, in one phrase (experiment, digest, studies, labels, trials, command)."""
    exp = manifest.get("experiment", {})
    studies = "; ".join(f"{s.get('name')}: " + ", ".join(v.get("label") or v.get("name", "?")
                                                         for v in s.get("variants", []))
                        for s in exp.get("studies", []))
    when = "unfinished" if not manifest.get("finished") else f"finished {manifest['finished']}"
    return (f"experiment {exp.get('name')!r} (definition {manifest.get('digest', '?')}; {studies or 'no studies'}; "
            f"{exp.get('trials', '?')} trials, seed {exp.get('seed', '?')}; made by `{manifest.get('command', '?')}`, "
            f"{when})")


def definition_differences(old: dict, new: dict) -> list[str]:
    """The top-level keys of two experiment definitions (``Experiment.to_dict``) that differ, and for
    ``sim``/``camera`` the settings inside them."""
    out = []
    for key in sorted(set(old) | set(new)):
        if key == "description" or old.get(key) == new.get(key):
            continue
        a, b = old.get(key), new.get(key)
        if isinstance(a, dict) and isinstance(b, dict) and key in ("sim", "camera"):
            out += [f"{key}.{k}: {a.get(k)!r} -> {b.get(k)!r}" for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
        elif key == "studies":
            out.append("studies: " + _studies_text(a) + " -> " + _studies_text(b))
        else:
            out.append(f"{key}: {a!r} -> {b!r}")
    return out


def _studies_text(studies) -> str:
    return "[" + "; ".join(f"{s.get('name')}: " + ",".join(v.get("label", "?") for v in s.get("variants", []))
                           + (f" grid {s['grid']['axes']}" if s.get("grid", {}).get("axes") else "")
                           for s in studies or []) + "]"


def _manifest_or_none(root: Path) -> dict | None:
    path = root / MANIFEST
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and "experiment" in data else None


def claim_folder(root: str | Path | None, experiment, overwrite: bool = False, extend: bool = False) -> str:
    """Make ``root`` the folder of ``experiment`` before any work; what happened (``new``, ``resume``,
    ``overwrite``, ``extend``).

    A folder holding another definition is refused (:class:`ConfigError`, CLI exit 2) naming what it
    holds and what differs, unless ``overwrite`` (everything in it is deleted, reports included) or
    ``extend`` (the same experiment name: its chunks are reused; derived files are retired by
    :class:`Store`). A non-empty folder that is not a results folder is never cleared.
    """
    if root is None:
        return "new"
    root = Path(root)
    if not root.is_dir() or not any(root.iterdir()):
        return "new"
    manifest = _manifest_or_none(root)
    if manifest is None:
        return "new"          # Store refuses it: not a starid results folder (nothing is deleted)
    digest = experiment.digest()
    if manifest.get("digest") == digest:
        if overwrite:
            _refuse_if_in_use(root)
            clear_folder(root)
            return "overwrite"
        return "resume"
    if overwrite:
        _refuse_if_in_use(root)
        clear_folder(root)
        return "overwrite"
    old_name = manifest.get("experiment", {}).get("name")
    if extend and old_name == experiment.name:
        return "extend"
    diff = definition_differences(manifest.get("experiment", {}), experiment.to_dict())
    hint = ("--extend (same experiment: reuse its chunks; its reports are removed), " if old_name == experiment.name
            else "")
    raise ConfigError(f"--out {root} holds {describe_holdings(manifest)}; this command defines experiment "
                      f"{experiment.name!r} (definition {digest}), which differs in "
                      f"{'; '.join(diff) or 'its definition'}. Give --overwrite to clear the folder (reports "
                      f"included), {hint}or choose another folder")


def _refuse_if_in_use(root: Path) -> None:
    """``--overwrite`` never clears a folder another run is writing: its lock is tried first (a
    :class:`ConfigError` naming the holder when it is held; a stale lock is simply free)."""
    if (root / LOCK).exists():
        with FolderLock(root):
            pass


def clear_folder(root: str | Path) -> list[str]:
    """Delete everything in a starid results folder (it must hold a manifest); the names deleted."""
    import shutil

    root = Path(root)
    if _manifest_or_none(root) is None:
        raise ConfigError(f"--overwrite: {root} is not a starid results folder (no readable {MANIFEST}); "
                          f"nothing deleted")
    gone = []
    for child in sorted(root.iterdir()):
        if child.is_dir() and not child.is_symlink():
            shutil.rmtree(child)
        else:
            child.unlink()
        gone.append(child.name)
    return gone


def read_derived(root: str | Path) -> dict:
    """``derived.json``: relative path -> ``{"digest": ..., "made": ...}`` (empty when absent)."""
    try:
        data = json.loads((Path(root) / DERIVED).read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def record_derived(root: str | Path, paths, digest: str | None = None, **extra) -> None:
    """Record that ``paths`` (inside ``root``) were made from definition ``digest`` (default: the
    folder's manifest's)."""
    from ..provenance import now

    root = Path(root)
    if digest is None:
        digest = (_manifest_or_none(root) or {}).get("digest")
    data = read_derived(root)
    stamp = now()
    base = root.resolve()
    for p in paths:
        p = Path(p).resolve() if Path(p).is_absolute() or Path(p).resolve().is_relative_to(base) else base / p
        rel = p.resolve().relative_to(base).as_posix()
        data[rel] = {"digest": digest, "made": stamp, **extra}
    atomic_write_text(root / DERIVED, json.dumps(data, indent=1, sort_keys=True) + "\n")


def stale_derived(root: str | Path, digest: str | None = None) -> list[str]:
    """Recorded derived files (still present) made from another definition than ``digest`` (default:
    the manifest's)."""
    root = Path(root)
    if digest is None:
        digest = (_manifest_or_none(root) or {}).get("digest")
    return [rel for rel, rec in read_derived(root).items()
            if (root / rel).exists() and rec.get("digest") != digest]


def retire_stale(root: str | Path, digest: str) -> list[str]:
    """Delete the derived files of ``root`` made from another definition than ``digest`` (they would
    describe data that is no longer the folder's); the names deleted."""
    root = Path(root)
    data = read_derived(root)
    gone = [rel for rel, rec in data.items() if rec.get("digest") != digest]
    if not gone:
        return []
    for rel in gone:
        (root / rel).unlink(missing_ok=True)
        data.pop(rel)
    atomic_write_text(root / DERIVED, json.dumps(data, indent=1, sort_keys=True) + "\n")
    return gone


def check_current(root: str | Path, rel: str = "results.parquet") -> None:
    """Refuse a derived file made from another definition than the folder's manifest (an interrupted
    run of a changed definition): :class:`ConfigError` naming both digests."""
    root = Path(root)
    rec = read_derived(root).get(rel)
    digest = (_manifest_or_none(root) or {}).get("digest")
    if rec is not None and rec.get("digest") != digest:
        raise ConfigError(f"{root / rel} was made from definition {rec.get('digest')}, but {root} now holds "
                          f"definition {digest} (an unfinished run?): run the same command again to finish it")
