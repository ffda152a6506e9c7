"""The one way the package writes a file: atomically, with the permissions a new file
gets (the umask's), or the replaced file's own.

Data goes to a temporary file in the target's folder, which is then renamed over the
target, so a reader (the report, ``--resume``, a browser, an engine's importer) sees the
old file or the new one, never half of one. The temporary file is opened normally, not
by :func:`tempfile.mkstemp` (which makes it 0600 whatever the umask), so a new file
gets the mode any program's new file gets; a file that is replaced (``bench simplify
--force``, a second ``bench report``) keeps the mode it had.
"""

from __future__ import annotations

import os
import secrets
import stat
from pathlib import Path

__all__ = ["write_atomic"]


def write_atomic(path: str | os.PathLike, data: str | bytes) -> Path:
    """Write ``data`` (text as UTF-8) to ``path`` through a temporary file beside it and
    a rename; returns ``path`` as a Path.

    A new file gets the permissions the umask gives it; an existing regular file's mode
    is kept. The temporary file is removed when anything fails (the error propagates,
    an :class:`OSError` for an unwritable folder).
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        old = os.stat(path)
    except OSError:
        old = None
    try:
        with open(tmp, "xb") as f:
            f.write(data.encode("utf-8") if isinstance(data, str) else data)
        if old is not None and stat.S_ISREG(old.st_mode):
            os.chmod(tmp, stat.S_IMODE(old.st_mode))
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path
