"""``new-plugin``: write a new, installable algorithm package (see :mod:`starid.scaffold`)."""

from __future__ import annotations

from pathlib import Path


def cmd_new_plugin(args) -> int:
    from ..scaffold import dist_name, new_plugin

    written = new_plugin(args.name, args.out)
    root = written[0].parent
    for path in written:
        print(f"wrote {path}")
    print(f"\nnext:\n  cd {root}\n  pip install -e .          # distribution {dist_name(args.name)}, entry point "
          f"{args.name}\n  starid check {args.name}\n  python -m pytest")
    return 0


def add_parsers(sub, formatter) -> None:
    p = sub.add_parser("new-plugin", help="write a new, installable algorithm plugin package that already works",
                       formatter_class=formatter,
                       epilog="example:\n  starid new-plugin my_voting --out my-voting && pip install -e my-voting "
                              "&& starid check my_voting",
                       description="Write the package of a new algorithm plugin: pyproject.toml with the "
                                   "starid.algorithms entry point, the algorithm class (declared parameters, a "
                                   "published dict, explain), a numba kernel that identifies stars (pair voting, "
                                   "the docs' example), a tests file running the conformance suite, a docs page "
                                   "with the sections of a built-in page, a README. Installed, it passes "
                                   "'starid check NAME' and its own tests unchanged.")
    p.add_argument("name", metavar="NAME", help="registered name and Python package: lower case, digits, _")
    p.add_argument("--out", type=Path, metavar="DIR", help="the package folder to write (default: ./NAME; must be "
                                                           "new or empty)")
    p.set_defaults(func=cmd_new_plugin)


__all__ = ["add_parsers"]
