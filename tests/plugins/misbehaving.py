"""Methods that fail in every way a plug-in can, for the runner's isolation tests.

Loaded through ``BENCH_PLUGINS`` (see bench.registry) with this folder on PYTHONPATH.
"""

import os
import time
from dataclasses import dataclass

from bench.method import Method


class Crash(Method):
    """Kills its process the way a segfault in native code would."""

    name = "crash"

    def simplify(self, mesh, target_faces, ctx=None):
        os._exit(139)


class Hang(Method):
    name = "hang"

    def simplify(self, mesh, target_faces, ctx=None):
        time.sleep(3600)


class Raise(Method):
    name = "raise"

    @dataclass
    class Params:
        message: str = "deliberate failure"

    def simplify(self, mesh, target_faces, ctx=None):
        raise RuntimeError(self.params.message)
