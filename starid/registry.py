"""Algorithm discovery: entry points of the group ``starid.algorithms`` plus in-process registrations."""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from importlib.metadata import entry_points

from .errors import PluginError
from .plugin import Algorithm

ENTRY_POINT_GROUP = "starid.algorithms"

_registered: dict[str, type[Algorithm]] = {}


@dataclass(frozen=True)
class AlgorithmInfo:
    """One registered algorithm: ``status`` is ``"ok"`` or ``"broken"`` (then ``error`` says why)."""

    name: str
    status: str
    summary: str
    cls: type[Algorithm] | None
    source: str
    error: str = ""
    dist: str = ""
    dist_version: str = ""


def register(cls: type[Algorithm]) -> type[Algorithm]:
    """Class decorator: register an algorithm in this process (for notebooks and tests)."""
    if not (isinstance(cls, type) and issubclass(cls, Algorithm)):
        raise PluginError(f"@register needs a subclass of starid.plugin.Algorithm, got {cls!r}")
    if not cls.name:
        raise PluginError(f"{cls.__name__} has no class attribute 'name'")
    _registered[cls.name] = cls
    return cls


def unregister(name: str) -> None:
    """Remove an in-process registration (no error if absent)."""
    _registered.pop(name, None)


def _dist(ep) -> tuple[str, str]:
    dist = getattr(ep, "dist", None)
    return (dist.name, dist.version) if dist is not None else ("", "")


def _load_entry_point(ep) -> AlgorithmInfo:
    source = f"entry point {ep.value}"
    dist, dist_version = _dist(ep)
    try:
        cls = ep.load()
    except Exception as exc:  # a broken plugin must never break the listing
        return AlgorithmInfo(ep.name, "broken", "", None, source, f"{type(exc).__name__}: {exc}", dist, dist_version)
    if not (isinstance(cls, type) and issubclass(cls, Algorithm)):
        return AlgorithmInfo(ep.name, "broken", "", None, source,
                             f"{ep.value} is not a subclass of starid.plugin.Algorithm", dist, dist_version)
    if cls.name != ep.name:
        return AlgorithmInfo(ep.name, "broken", cls.summary(), None, source,
                             f"entry point name {ep.name!r} differs from {cls.__name__}.name {cls.name!r}",
                             dist, dist_version)
    return AlgorithmInfo(ep.name, "ok", cls.summary(), cls, source, "", dist, dist_version)


#: the entry points' registrations as last read, with what they were read from (:func:`_path_state`)
_FROM_ENTRY_POINTS: dict = {}


def _path_state() -> tuple:
    """What the installed entry points depend on: the import path and each folder's modification time (a
    distribution installed into a folder changes it), and the ``entry_points`` function (a test's stand-in)."""
    stamps = []
    for p in sys.path:
        try:
            stamps.append(os.stat(p or ".").st_mtime_ns)
        except OSError:
            stamps.append(None)
    return (tuple(sys.path), tuple(stamps), entry_points)


def _entry_point_infos() -> list[tuple[str, str, AlgorithmInfo]]:
    """``(name, claim, info)`` of every entry point of the group, read again only when the import path or its
    folders changed: reading each distribution's metadata costs ~13 ms a call, and the planning of an
    experiment and each chunk a worker computes ask for it (``zhou2015``: 1,600 chunks)."""
    state = _path_state()
    if _FROM_ENTRY_POINTS.get("state") != state:
        out = []
        for ep in entry_points(group=ENTRY_POINT_GROUP):
            dist, version = _dist(ep)
            out.append((ep.name, f"{dist or '?'} {version}".strip() + f" ({ep.value})", _load_entry_point(ep)))
        _FROM_ENTRY_POINTS.clear()
        _FROM_ENTRY_POINTS.update(state=state, infos=out)
    return _FROM_ENTRY_POINTS["infos"]


def available_algorithms() -> list[AlgorithmInfo]:
    """Every registered algorithm, sorted by name.

    Two entry points (or an entry point and an in-process registration) claiming one name are a
    clash: neither may silently replace the other, so the name is listed as ``broken`` with an
    error naming both distributions, and running it is refused.
    """
    found: dict[str, AlgorithmInfo] = {}
    claims: dict[str, list[str]] = {}
    for name, claim, info in _entry_point_infos():
        claims.setdefault(name, []).append(claim)
        found[name] = info
    for name, cls in _registered.items():
        claims.setdefault(name, []).append(f"in-process registration of {cls.__module__}.{cls.__qualname__}")
        found[name] = AlgorithmInfo(name, "ok", cls.summary(), cls, "registered in process")
    for name, who in claims.items():
        if len(who) > 1:
            found[name] = AlgorithmInfo(name, "broken", "", None, "clash",
                                        f"the name {name!r} is claimed {len(who)} times: {'; '.join(who)}; "
                                        f"rename one plugin's entry point")
    return [found[name] for name in sorted(found)]


def algorithm_info(name: str) -> AlgorithmInfo:
    """The registration of ``name``; :class:`PluginError` if unknown or broken (run ``starid list``)."""
    infos = {info.name: info for info in available_algorithms()}
    if name not in infos:
        known = ", ".join(infos) or "none"
        raise PluginError(f"unknown algorithm {name!r}; registered: {known} (see 'starid list')")
    info = infos[name]
    if info.status != "ok":
        raise PluginError(f"algorithm {name!r} is broken: {info.error}")
    return info


def get_algorithm(name: str) -> type[Algorithm]:
    """The algorithm class registered as ``name``; :class:`PluginError` if unknown or broken."""
    return algorithm_info(name).cls
