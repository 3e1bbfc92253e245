"""``list`` and ``info``: what is registered, and what each algorithm's parameters mean."""

from __future__ import annotations

import dataclasses
import inspect
import re
import typing

from ..camera import Camera
from ..catalog import load_hipparcos
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


def parameter_table(cls) -> list[dict]:
    """Each dataclass field of an algorithm: name, type, default, unit, what ``follows`` it, the value
    ``derived`` gives it on the default camera when it defaults to None, meaning."""
    hints = typing.get_type_hints(cls)
    derived = _derived_defaults(cls)
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


def cmd_info(args) -> int:
    info = algorithm_info(args.name)
    cls = info.cls
    print(f"{info.name}: {info.summary}")
    print(f"from {info.dist or 'this process'} {info.dist_version} ({info.source})\n")
    print(inspect.cleandoc(cls.__doc__ or "").split("\n", 1)[-1].strip())
    print("\nparameters (set with NAME[KEY=VALUE,...] or --set NAME.KEY=VALUE):")
    rows = parameter_table(cls) if dataclasses.is_dataclass(cls) else []
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
    if not args.no_build:
        db = cls().build(load_hipparcos(), Camera())
        print(f"\ndatabase for the default camera and the embedded catalog: {db.nbytes / 1e6:.3f} MB")
    print(f"\nmore: docs/algorithms/{info.name}.md (built-ins) or the plugin's own documentation")
    return 0


def add_parsers(sub, formatter) -> None:
    p = sub.add_parser("list", help="registered algorithms: name, ok/broken, summary", formatter_class=formatter)
    p.set_defaults(func=cmd_list)
    p = sub.add_parser("info", help="an algorithm's reference, reconstruction notes and parameters",
                       formatter_class=formatter, epilog="example:\n  starid info ptp")
    p.add_argument("name", metavar="ALGO", help="a registered name (see 'starid list')")
    p.add_argument("--no-build", action="store_true", help="skip building the database to report its size")
    p.set_defaults(func=cmd_info)
