"""``list`` and ``info``: what is registered, and what each algorithm's parameters mean."""

from __future__ import annotations

import dataclasses
import inspect
import re
import typing

from ..camera import Camera
from ..catalog import load_hipparcos
from ..experiment.executors import BUILD_TIME_LIMIT_S, Limits, call_supervised
from ..experiment.spec import Variant
from ..registry import algorithm_info, available_algorithms
from ..simulate import SimConfig


def cmd_list(args) -> int:
    infos = available_algorithms()
    if not infos:
        print("no algorithms registered")
        return 0
    width = max(len(i.name) for i in infos)
    for info in infos:
        text = info.summary if info.status == "ok" else info.error
        print(f"{info.name:<{width}}  {info.status:<6}  {text}")
    return 0


UNITS = {"_deg": "deg", "_rad": "rad", "_px": "px", "_mag": "mag", "_s": "s", "_mb": "MB", "_um": "um",
         "_mm": "mm", "_arcsec": "arcsec"}


def unit_of(name: str) -> str:
    """The unit a parameter's name carries (``d_max_deg`` -> deg), or ``""``."""
    return next((u for suffix, u in UNITS.items() if name.endswith(suffix)), "")


def meaning_of(cls, name: str) -> str:
    """The first sentence of the class docstring that names ``name`` in double back-quotes."""
    doc = " ".join(inspect.cleandoc(cls.__doc__ or "").split())
    for sentence in re.split(r"(?<=[.;])\s+", doc):
        if f"``{name}``" in sentence:
            return sentence.strip(" *-")
    return ""


def _derived_defaults(cls) -> dict:
    """The values :meth:`Algorithm.derived` gives the parameters left None, on the default camera and
    the embedded catalog after following the default simulator; {} when it cannot be made."""
    try:
        return cls().resolved(SimConfig()).derived(load_hipparcos(), Camera()).params()
    except Exception:   # a plugin whose derivation fails still gets its parameter list
        return {}


def parameter_table(cls, derived: dict | None = None) -> list[dict]:
    """Each dataclass field of an algorithm: name, type, default, unit, what ``follows`` it, the value
    ``derived`` gives it on the default camera when it defaults to None (``derived``: those values,
    already computed), meaning."""
    hints = typing.get_type_hints(cls)
    derived = _derived_defaults(cls) if derived is None else derived
    rows = []
    for f in dataclasses.fields(cls):
        kind = hints.get(f.name, object)
        type_text = getattr(kind, "__name__", None) or str(kind).replace("typing.", "")
        follows = cls.follows.get(f.name)
        default = f.default if f.default is not dataclasses.MISSING else "(required)"
        value = derived.get(f.name) if default is None and not follows else None
        # declared metadata (starid.params.param(help=, unit=)) first, else the naming conventions
        rows.append({"name": f.name, "type": type_text, "default": default,
                     "unit": f.metadata["unit"] if "unit" in f.metadata else unit_of(f.name),
                     "follows": f"simulator {follows}" if follows else "", "derived": value,
                     "meaning": f.metadata.get("help") or meaning_of(cls, f.name)})
    return rows


def _supervised_info(cls, no_build: bool, control) -> tuple[dict, float | None]:
    """In the supervised process: the derived defaults, and the database size in MB (None: ``no_build``)."""
    control.phase("derived", build=True)
    derived = _derived_defaults(cls)
    if no_build:
        return derived, None
    control.phase("build", build=True)
    return derived, cls().build(load_hipparcos(), Camera()).nbytes / 1e6


def cmd_info(args) -> int:
    limits = Limits(build_time_limit_s=args.build_time_limit, memory_limit_gb=args.memory_limit_gb).checked()
    info = algorithm_info(args.name)
    cls = info.cls
    derived, db_mb, failure = {}, None, ""
    if dataclasses.is_dataclass(cls):   # the plugin's derived and build in a supervised process, under the limits
        load_hipparcos()                # loaded once here: the process inherits it
        outcome = call_supervised(lambda control: _supervised_info(cls, args.no_build, control), limits)
        if outcome.status:
            failure = f"{outcome.status}: {outcome.error}"
        else:
            derived, db_mb = outcome.value
    print(f"{info.name}: {info.summary}")
    print(f"from {info.dist or 'this process'} {info.dist_version} ({info.source})\n")
    print(inspect.cleandoc(cls.__doc__ or "").split("\n", 1)[-1].strip())
    print("\nparameters (set with NAME[KEY=VALUE,...] or --set NAME.KEY=VALUE):")
    rows = parameter_table(cls, derived) if dataclasses.is_dataclass(cls) else []
    width = max((len(r["name"]) for r in rows), default=4)
    for r in rows:
        unit = f" {r['unit']}" if r["unit"] else ""
        tail = f"  (None: follows the {r['follows']})" if r["follows"] else ""
        if r["derived"] is not None:
            value = r["derived"] if isinstance(r["derived"], bool) else f"{r['derived']:.6g}"
            tail = f"  (None: derived from the camera; {value} on the default one)"
        print(f"  {r['name']:<{width}}  {r['type']:<14} default {r['default']!r}{unit}{tail}")
        if r["meaning"]:
            print(f"  {'':<{width}}  {r['meaning'][:300]}")
    if getattr(cls, "published", None):
        print(f"\nas published ({info.name}:paper): {Variant(info.name, cls.published).label}")
    for source, overrides in (getattr(cls, "published_readings", None) or {}).items():
        print(f"as {source} ran it ({info.name}:{source}): {Variant(info.name, overrides).label}")
    if failure:
        print(f"\nderived defaults and database size not known: {failure}")
    elif not args.no_build and db_mb is not None:
        print(f"\ndatabase for the default camera and the embedded catalog: {db_mb:.3f} MB")
    print(f"\nmore: docs/algorithms/{info.name}.md (built-ins) or the plugin's own documentation")
    return 0


def add_parsers(sub, formatter) -> None:
    p = sub.add_parser("list", help="registered algorithms: name, ok/broken, summary", formatter_class=formatter)
    p.set_defaults(func=cmd_list)
    p = sub.add_parser("info", help="an algorithm's reference, reconstruction notes and parameters",
                       formatter_class=formatter, epilog="example:\n  starid info ptp")
    p.add_argument("name", metavar="ALGO", help="a registered name (see 'starid list')")
    p.add_argument("--no-build", action="store_true", help="skip building the database to report its size")
    g = p.add_argument_group("limits (derived and build run in a supervised process)")
    g.add_argument("--build-time-limit", type=float, default=BUILD_TIME_LIMIT_S, metavar="S",
                   help="seconds derived + build may take; beyond, info says so without them")
    g.add_argument("--memory-limit-gb", type=float, default=None, metavar="GB",
                   help="address-space limit of that process (default: the machine's memory)")
    p.set_defaults(func=cmd_info)
