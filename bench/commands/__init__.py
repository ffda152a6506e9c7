"""One module per ``bench`` subcommand, each with ``add_parser`` and ``run``; and
:func:`one_line`, for every line the commands print from data they did not write."""


def one_line(text) -> str:
    """``text`` as one line: newlines and other control characters (from a file name, a
    record, a backend's message) are shown escaped, never passed to the terminal."""
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in str(text))
