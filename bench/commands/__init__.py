"""One module per ``bench`` subcommand, each with ``add_parser`` and ``run``; and
:func:`one_line`, for every line the commands print from data they did not write."""

import os
import sys


def one_line(text) -> str:
    """``text`` as one line: newlines and other control characters (from a file name, a
    record, a backend's message) are shown escaped, never passed to the terminal."""
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in str(text))


def stdout_closed() -> None:
    """After a :class:`BrokenPipeError` on standard output (``bench ... | head``): send
    what is still to be printed there to the null device, so neither a later print nor
    the interpreter's flush at exit raises again."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
