"""numba's on-disk cache written by one process at a time.

numba saves a compiled kernel by reading the function's index, adding the signature with
the name of a new data file, and writing the index and the data file (each renamed into
place whole). Two processes saving two signatures of one function at once can read the
same index, pick the same data file name, and leave an index entry that points at the
other signature's code; numba's issue #10128 reports the segmentation faults that
follow, and its maintainers proposed a file lock. The suite compiles in several processes
at once (``bench warmup`` compiles the engine's two halves side by side, ``bench run``'s
job processes the evaluation's kernels, pytest's workers whatever they meet), so every
module with cached kernels calls :func:`lock_cache_writes` when imported: from then on
this process holds an exclusive lock on a file in the cache's folder from reading the
index until both files are written. Loading takes no lock: the files it reads are
replaced whole. (``metrics.views``, a leaf that imports nothing of the suite, does not
call it: its two kernels have one signature each, and two saves of one signature write
the same file with the same code.)
"""

from __future__ import annotations

import fcntl
import functools
import os

#: The lock file, one in each folder of numba's cache.
LOCK_NAME = "numba-save.lock"


def lock_cache_writes() -> None:
    """Make this process's numba cache saves hold :data:`LOCK_NAME` (once per process)."""
    from numba.core import caching

    save = caching.IndexDataCacheFile.save
    if getattr(save, "locked", False):
        return

    @functools.wraps(save)
    def locked_save(self, key, data):
        try:
            lock = open(os.path.join(self._cache_path, LOCK_NAME), "a")  # noqa: SIM115
        except OSError:  # e.g. a shared cache's lock file made by another user
            return save(self, key, data)
        with lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file is closed
            return save(self, key, data)

    locked_save.locked = True
    caching.IndexDataCacheFile.save = locked_save
