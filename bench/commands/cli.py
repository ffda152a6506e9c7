"""The ``bench`` command line: one module per subcommand in :mod:`bench.commands`.

Errors meant for the user (:class:`~bench.core.errors.BenchError`) print one line,
``bench: error: ...``, and exit with code 2; warnings print ``bench: warning: ...``.
"""

from __future__ import annotations

import argparse
import sys
import traceback
import warnings

from bench import __version__
from bench.commands import baseline as baseline_cmd
from bench.commands import check as check_cmd
from bench.commands import compare as compare_cmd
from bench.commands import history as history_cmd
from bench.commands import list as list_cmd
from bench.commands import one_line, stdout_closed
from bench.commands import report as report_cmd
from bench.commands import reproduce as reproduce_cmd
from bench.commands import run as run_cmd
from bench.commands import simplify as simplify_cmd
from bench.commands import warmup as warmup_cmd
from bench.core.errors import BenchError

COMMANDS = {"list": list_cmd, "simplify": simplify_cmd, "run": run_cmd, "report": report_cmd,
            "baseline": baseline_cmd, "check": check_cmd, "compare": compare_cmd,
            "history": history_cmd, "reproduce": reproduce_cmd,
            "warmup": warmup_cmd}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bench", description="Benchmark suite for appearance-preserving mesh simplification.")
    parser.add_argument("--version", action="version", version=f"bench {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show full tracebacks of failures (for bug reports)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, module in COMMANDS.items():
        module.add_parser(sub, name)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"bench: warning: {one_line(message)}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    warnings.showwarning = _show_warning
    try:
        return int(args.run(args) or 0)
    except BenchError as exc:
        if args.debug:
            traceback.print_exception(exc)
        print(f"bench: error: {one_line(exc)}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("bench: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader of standard output left (`| head`): stop quietly
        stdout_closed()
        return 141  # as a shell reports a process ended by SIGPIPE


def entry() -> None:  # console script
    sys.exit(main())
