"""``starid check``: the conformance suite on a registered algorithm or every algorithm of a package."""

from __future__ import annotations

from ..catalog import load_hipparcos
from ..errors import PluginError
from ..experiment.executors import BUILD_TIME_LIMIT_S, Limits, Outcome, call_per_item, memory_error
from ..registry import available_algorithms, get_algorithm
from ..testing import CHECKS, ConformanceError, check_algorithm


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


def _checks(cls, control, start: int) -> None:
    """In the supervised process: checks ``start..`` of :data:`~starid.testing.CHECKS` on ``cls``, each
    sent as ``(k, (verdict, message))`` (what :func:`~starid.testing.run_checks` yields, one check at a time)."""
    for k in range(start, len(CHECKS)):
        control.phase(f"check {CHECKS[k]!r}", build=True)
        try:
            check_algorithm(cls, [CHECKS[k]])
            control.emit((k, ("ok", "")))
        except ConformanceError as exc:
            control.emit((k, ("FAILED", str(exc))))


def cmd_check(args) -> int:
    limits = Limits(build_time_limit_s=args.build_time_limit, memory_limit_gb=args.memory_limit_gb).checked()
    load_hipparcos()        # loaded once here: each supervised process inherits it
    failed = 0
    for name in targets(args.name):
        cls = get_algorithm(name)
        print(f"{name}:")

        def shown(k, item):
            verdict, message = (f"FAILED ({item.status})", item.error) if isinstance(item, Outcome) else item
            message = memory_error(message, limits.memory_limit_gb) or message
            print(f"  {CHECKS[k]:<24} {verdict}{'  ' + message if message else ''}", flush=True)

        # the plugin's code in a supervised process: a check that hangs past --build-time-limit or dies
        # (memory past --memory-limit-gb) fails, and the next checks go on in a fresh process
        items = call_per_item(lambda control, start, cls=cls: _checks(cls, control, start), len(CHECKS), limits,
                              on_item=shown, build_fails_rest=False)
        failed += sum(isinstance(item, Outcome) or item[0] != "ok" for item in items.values())
    print(f"{failed} check(s) failed" if failed else "all checks passed")
    return 1 if failed else 0


def add_parsers(sub, formatter) -> None:
    p = sub.add_parser("check", help="run the conformance suite on a plugin (the plugin author's command)",
                       formatter_class=formatter,
                       epilog="examples:\n  starid check ptp\n  starid check my-starid-plugin   # every algorithm "
                              "the distribution registers")
    p.add_argument("name", metavar="ALGO|PACKAGE", help="a registered algorithm or an installed distribution")
    g = p.add_argument_group("limits (the checks run in a supervised process)")
    g.add_argument("--build-time-limit", type=float, default=BUILD_TIME_LIMIT_S, metavar="S",
                   help="seconds each check may take (it builds a database and identifies many images); beyond, "
                        "it fails as 'timeout' and the next checks go on")
    g.add_argument("--memory-limit-gb", type=float, default=None, metavar="GB",
                   help="address-space limit of the process the checks run in (default: the machine's memory); "
                        "exceeding it fails that check")
    p.set_defaults(func=cmd_check)
