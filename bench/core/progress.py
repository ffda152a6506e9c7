"""The progress of one long simplification, told to whoever listens.

A method names its stages (:func:`stage`); the engine's loop hands over its array of
live faces, which it updates in place while it runs without the GIL, and
:func:`watching_faces` reads it from a thread a few times a second. A listener, such
as the terminal bar of ``bench simplify``, is installed with :func:`listening`. With
none (the default, and always under ``bench run``) nothing is read and no thread
starts. Results never depend on a listener: it only reads.
"""

from __future__ import annotations

import contextlib
import contextvars
import threading
from typing import Protocol

import numpy as np

__all__ = ["Listener", "listening", "stage", "watching_faces"]

#: Seconds between two readings of the live faces.
POLL_SECONDS = 0.25


class Listener(Protocol):
    """What :func:`listening` installs."""

    def stage(self, name: str) -> None:
        """The method has started the stage ``name`` (e.g. a pre-simplification)."""

    def begin(self, total: int) -> None:
        """A loop starts that will remove ``total`` faces if it reaches its target."""

    def advance(self, removed: int) -> None:
        """The loop has removed ``removed`` faces so far (it never decreases)."""

    def end(self) -> None:
        """The loop has ended; the last :meth:`advance` gave its exact count."""


_LISTENER: contextvars.ContextVar[Listener | None] = contextvars.ContextVar(
    "bench_progress_listener", default=None)


@contextlib.contextmanager
def listening(listener: Listener):
    """Tell ``listener`` the progress of the simplifications run inside the block."""
    token = _LISTENER.set(listener)
    try:
        yield listener
    finally:
        _LISTENER.reset(token)


def stage(name: str) -> None:
    """Say that the stage ``name`` starts (nothing without a listener)."""
    listener = _LISTENER.get()
    if listener is not None:
        listener.stage(name)


@contextlib.contextmanager
def watching_faces(alive: np.ndarray, target: int):
    """Report the faces removed from ``alive`` (bool per face, updated in place by the
    code inside the block, which must release the GIL for the readings to come
    between) on the way to ``target`` live faces: every :data:`POLL_SECONDS` and once,
    exactly, when the block ends."""
    listener = _LISTENER.get()
    if listener is None:
        yield
        return
    start = int(np.count_nonzero(alive))
    listener.begin(max(start - target, 0))
    done = threading.Event()

    def poll():
        while not done.wait(POLL_SECONDS):
            listener.advance(start - int(np.count_nonzero(alive)))

    reader = threading.Thread(target=poll, name="bench-progress", daemon=True)
    reader.start()
    try:
        yield
    finally:
        done.set()
        reader.join()
        listener.advance(start - int(np.count_nonzero(alive)))
        listener.end()
