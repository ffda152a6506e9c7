"""The terminal's view of a long simplification (a :class:`bench.core.progress.Listener`)."""

from __future__ import annotations

import contextlib
import sys
import time

from bench.core.progress import listening

#: A simplification shorter than this many seconds shows no bar.
DELAY_SECONDS = 2.0


class FacesBar:
    """One bar on ``file`` (stderr) per engine loop: faces removed of those to remove,
    the rate and the time left, after the stage the method named. Nothing is drawn
    before ``delay`` seconds of the whole simplification, and the bar is wiped when its
    loop ends, so the command's own lines stay as they were."""

    def __init__(self, label: str, delay: float = DELAY_SECONDS, file=None):
        self.label = label
        self.delay = delay
        self.file = file
        self._start = time.perf_counter()
        self._stage = None
        self._bar = None

    def stage(self, name: str) -> None:
        self._stage = name

    def begin(self, total: int) -> None:
        from tqdm import tqdm

        self.end()
        waited = time.perf_counter() - self._start
        self._bar = tqdm(total=total, unit="face", unit_scale=True, leave=False,
                         desc=self.label + (f", {self._stage}" if self._stage else ""),
                         delay=max(0.0, self.delay - waited), dynamic_ncols=True,
                         file=self.file if self.file is not None else sys.stderr)
        self._stage = None

    def advance(self, removed: int) -> None:
        if self._bar is not None:
            self._bar.update(min(removed, self._bar.total) - self._bar.n)

    def end(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def terminal_progress(label: str):
    """A :class:`FacesBar` listening while stderr is a terminal; otherwise nothing."""
    if not sys.stderr.isatty():
        return contextlib.nullcontext()
    return listening(FacesBar(label))
