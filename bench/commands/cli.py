"""The ``bench`` command line: one module per subcommand in :mod:`bench.commands`.

Errors meant for the user (:class:`~bench.core.errors.BenchError`) print one line,
``bench: error: ...``, and exit with code 2; warnings print ``bench: warning: ...``.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback
import warnings

from bench import __version__
from bench.commands import one_line, stdout_closed
from bench.core.errors import BenchError

#: The subcommands, each defined by the module of :mod:`bench.commands` of its name. A
#: command's module is imported only when the command runs (or for ``bench --help``), so
#: ``bench simplify`` never loads what ``bench run`` or the report need.
COMMANDS = ("list", "simplify", "run", "report", "baseline", "check", "compare", "history",
            "reproduce", "warmup")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The whole command line, or with ``only`` (a name of :data:`COMMANDS`) the parser
    of that one subcommand, without importing the others' modules."""
    parser = argparse.ArgumentParser(
        prog="bench", description="Benchmark suite for appearance-preserving mesh simplification.")
    parser.add_argument("--version", action="version", version=f"bench {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show full tracebacks of failures (for bug reports)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        if only is None or name == only:
            importlib.import_module(f"bench.commands.{name}").add_parser(sub, name)
    return parser


def _command_named(argv: list[str]) -> str | None:
    """The subcommand ``argv`` names, when its first word that is not an option is one
    (then only its module need be imported); None otherwise."""
    for word in argv:
        if word == "--":
            return None
        if not word.startswith("-"):
            return word if word in COMMANDS else None
    return None


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"bench: warning: {one_line(message)}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(_command_named(argv))
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
