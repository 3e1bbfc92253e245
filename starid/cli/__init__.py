"""The ``starid`` command line: it parses arguments, calls the library and prints.

Commands: ``list``, ``info``, ``check``, ``run``, ``sweep``, ``experiment``, ``reproduce``, ``table6``,
``identify``, ``simulate``, ``report``, ``show`` (``starid COMMAND --help`` for each). Bad input exits with status 2
and one line saying what is wrong; Ctrl-C exits 130 and SIGTERM 143, keeping every finished
chunk of a results folder (run the same command again to resume); a closed output pipe
(``starid info ptp | head``) exits 141 without a traceback.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import warnings

from ..errors import StarIDError, StarIDWarning
from ..provenance import versions
from . import cameras, check, experiments, identify, images, plugins, report, scaffold
from .options import Formatter


class Terminated(BaseException):
    """SIGTERM, turned into an exception so that workers are stopped and outputs stay whole.

    A ``BaseException``, as ``KeyboardInterrupt`` is: raised wherever the main thread happens to be when the
    signal arrives, it must not be swallowed by an ``except Exception`` on the way (pandas and pyarrow reading
    or writing a chunk, a plugin's failure being recorded); as an ``Exception`` it was, now and then, and the
    run went on after SIGTERM (tests/test_trust.py::test_interrupt_stops_workers_and_exits_cleanly)."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="starid", formatter_class=Formatter,
        description="Compare lost-in-space star-identification algorithms on one catalog, one simulator and one "
                    "scoring harness.",
        epilog="start with:\n  starid list\n  starid table6 --trials 1000\n  starid run ptp pvector --trials 500")
    parser.add_argument("--version", action="version", version=f"starid {versions()['starid_version']}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    plugins.add_parsers(sub, Formatter)
    experiments.add_parsers(sub, Formatter)
    identify.add_parsers(sub, Formatter)
    images.add_parsers(sub, Formatter)
    check.add_parsers(sub, Formatter)
    report.add_parsers(sub, Formatter)
    scaffold.add_parsers(sub, Formatter)
    cameras.add_parsers(sub, Formatter)
    return parser


def _on_sigterm(signum, frame):
    raise Terminated()


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", StarIDWarning)
            warnings.showwarning = lambda message, *a, **k: print(f"starid: warning: {message}", file=sys.stderr)
            return args.func(args)
    except StarIDError as exc:
        print(f"starid: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("starid: interrupted; finished chunks are kept (run the same command again to resume)", file=sys.stderr)
        return 130
    except Terminated:
        print("starid: terminated; finished chunks are kept (run the same command again to resume)", file=sys.stderr)
        return 143
    except BrokenPipeError:
        # the reader went away (``starid info ptp | head``): stop quietly, as a shell tool does;
        # stdout goes to devnull so that the interpreter's final flush cannot fail again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    finally:
        signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    raise SystemExit(main())
