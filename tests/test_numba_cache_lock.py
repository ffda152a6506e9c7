"""numba's cache saves hold a lock (bench.core.numba_cache), so two processes saving two
signatures of one function cannot leave an index that points at the other's code."""

from __future__ import annotations

import fcntl
import threading

from numba.core import caching

import methods.corners  # noqa: F401 - a module with cached kernels installs the lock
from bench.core.numba_cache import LOCK_NAME, lock_cache_writes


def test_a_module_with_cached_kernels_installs_the_lock_once():
    save = caching.IndexDataCacheFile.save
    assert getattr(save, "locked", False)
    lock_cache_writes()
    assert caching.IndexDataCacheFile.save is save  # not wrapped twice


def test_a_save_waits_while_another_holds_the_lock(tmp_path):
    cache = caching.IndexDataCacheFile(str(tmp_path), "kernel-1.py311", source_stamp=(1.0, 2))
    with open(tmp_path / LOCK_NAME, "a") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        saving = threading.Thread(target=cache.save, args=(("sig", "magic"), b"code"))
        saving.start()
        saving.join(0.5)
        assert saving.is_alive(), "the save did not wait for the lock"
        assert not (tmp_path / "kernel-1.py311.nbi").exists()
    saving.join(10)  # the lock is released when its file closes
    assert not saving.is_alive()
    assert cache.load(("sig", "magic")) == b"code"


def test_a_lock_file_that_cannot_be_opened_does_not_stop_the_save(tmp_path, monkeypatch):
    import builtins

    real_open = builtins.open

    def no_lock(path, *args, **kwargs):
        if str(path).endswith(LOCK_NAME):
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", no_lock)
    cache = caching.IndexDataCacheFile(str(tmp_path), "kernel-2.py311", source_stamp=(1.0, 2))
    cache.save(("sig", "magic"), b"code")
    monkeypatch.undo()
    assert cache.load(("sig", "magic")) == b"code"
    assert not (tmp_path / LOCK_NAME).exists()
