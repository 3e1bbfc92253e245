"""``starid check``: the conformance suite on a registered algorithm or every algorithm of a package."""

from __future__ import annotations

from ..errors import PluginError
from ..registry import available_algorithms, get_algorithm
from ..testing import run_checks


def targets(name: str) -> list[str]:
    """Algorithm names for ``name``: a registered algorithm, or a distribution's algorithms."""
    infos = available_algorithms()
    if any(i.name == name for i in infos):
        return [name]
    wanted = name.lower().replace("_", "-")
    mine = [i.name for i in infos if i.dist and i.dist.lower().replace("_", "-") == wanted]
    if not mine:
        raise PluginError(f"{name!r} is neither a registered algorithm nor a distribution that registers one "
                          f"(see 'starid list')")
    return mine


def cmd_check(args) -> int:
    failed = 0
    for name in targets(args.name):
        cls = get_algorithm(name)
        print(f"{name}:")
        for check, verdict, message in run_checks(cls):
            print(f"  {check:<24} {verdict}{'  ' + message if message else ''}")
            failed += verdict != "ok"
    print(f"{failed} check(s) failed" if failed else "all checks passed")
    return 1 if failed else 0


def add_parsers(sub, formatter) -> None:
    p = sub.add_parser("check", help="run the conformance suite on a plugin (the plugin author's command)",
                       formatter_class=formatter,
                       epilog="examples:\n  starid check ptp\n  starid check my-starid-plugin   # every algorithm "
                              "the distribution registers")
    p.add_argument("name", metavar="ALGO|PACKAGE", help="a registered algorithm or an installed distribution")
    p.set_defaults(func=cmd_check)
