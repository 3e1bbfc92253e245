"""Algorithm discovery: entry points of the group ``starid.algorithms`` plus in-process registrations."""

from __future__ import annotations

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


def _load_entry_point(ep) -> AlgorithmInfo:
    source = f"entry point {ep.value}"
    try:
        cls = ep.load()
    except Exception as exc:  # a broken plugin must never break the listing
        return AlgorithmInfo(ep.name, "broken", "", None, source, f"{type(exc).__name__}: {exc}")
    if not (isinstance(cls, type) and issubclass(cls, Algorithm)):
        return AlgorithmInfo(ep.name, "broken", "", None, source,
                             f"{ep.value} is not a subclass of starid.plugin.Algorithm")
    if cls.name != ep.name:
        return AlgorithmInfo(ep.name, "broken", cls.summary(), None, source,
                             f"entry point name {ep.name!r} differs from {cls.__name__}.name {cls.name!r}")
    return AlgorithmInfo(ep.name, "ok", cls.summary(), cls, source)


def available_algorithms() -> list[AlgorithmInfo]:
    """Every registered algorithm, sorted by name; in-process registrations win over entry points."""
    found = {ep.name: _load_entry_point(ep) for ep in entry_points(group=ENTRY_POINT_GROUP)}
    for name, cls in _registered.items():
        found[name] = AlgorithmInfo(name, "ok", cls.summary(), cls, "registered in process")
    return [found[name] for name in sorted(found)]


def get_algorithm(name: str) -> type[Algorithm]:
    """The algorithm class registered as ``name``; :class:`PluginError` if unknown or broken."""
    infos = {info.name: info for info in available_algorithms()}
    if name not in infos:
        known = ", ".join(infos) or "none"
        raise PluginError(f"unknown algorithm {name!r}; registered: {known}")
    info = infos[name]
    if info.status != "ok":
        raise PluginError(f"algorithm {name!r} is broken: {info.error}")
    return info.cls
