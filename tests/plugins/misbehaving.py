"""Methods that fail in every way a plug-in can, for the runner's isolation tests.

Loaded through ``BENCH_PLUGINS`` (see bench.core.registry) with this folder on PYTHONPATH.
"""

import os
import time
from dataclasses import dataclass

from bench.core.method import Method


class Crash(Method):
    """Kills its process the way a segfault in native code would."""

    name = "crash"

    def simplify(self, mesh, target_faces, ctx=None):
        os._exit(139)


class Hang(Method):
    name = "hang"
    warms_up = False  # a warm-up would hang too, outside the method's --timeout

    def simplify(self, mesh, target_faces, ctx=None):
        time.sleep(3600)


class Raise(Method):
    name = "raise"

    @dataclass
    class Params:
        message: str = "deliberate failure"

    def simplify(self, mesh, target_faces, ctx=None):
        raise RuntimeError(self.params.message)


class Sleep(Method):
    """Notes each attempt in ``marker`` (a line "pid parent-pid": the job process and the
    worker that runs it), then sleeps ``seconds`` — only on the first attempt when
    ``once`` — and returns the input unchanged. For the Dask tests: a job to kill a
    worker under, or to interrupt."""

    name = "sleep"
    warms_up = False  # a warm-up would be an attempt that sleeps and writes the marker

    @dataclass
    class Params:
        seconds: float = 0.0
        marker: str = ""
        once: bool = False

    def simplify(self, mesh, target_faces, ctx=None):
        from bench.core.method import SimplifyResult

        first = True
        if self.params.marker:
            first = not os.path.exists(self.params.marker)
            with open(self.params.marker, "a") as f:
                f.write(f"{os.getpid()} {os.getppid()}\n")
        if first or not self.params.once:
            time.sleep(self.params.seconds)
        return SimplifyResult(mesh, stop_reason="sleep returns its input")


class KillWorker(Method):
    """Kills the process that supervises it (a Dask worker), as a machine lost mid-job
    would, on every attempt."""

    name = "kill-worker"
    warms_up = False

    def simplify(self, mesh, target_faces, ctx=None):
        import signal

        os.kill(os.getppid(), signal.SIGKILL)
        time.sleep(3600)  # ended by the job process's watch on its parent


class KillSelf(Method):
    """SIGKILLs its own job process on the first attempt (noted in ``marker``), as the
    kernel's out-of-memory killer would; later attempts return the input."""

    name = "kill-self"
    warms_up = False

    @dataclass
    class Params:
        marker: str = ""

    def simplify(self, mesh, target_faces, ctx=None):
        import signal

        from bench.core.method import SimplifyResult

        if not os.path.exists(self.params.marker):
            with open(self.params.marker, "w") as f:
                f.write(f"{os.getpid()}\n")
            os.kill(os.getpid(), signal.SIGKILL)
        return SimplifyResult(mesh, stop_reason="kill-self returns its input")


class OutOfMemory(Method):
    """Runs out of memory: under a soft address-space limit 512 MiB above its size, asks
    for 4 GiB (numpy raises MemoryError); the limit is restored after."""

    name = "out-of-memory"
    warms_up = False

    def simplify(self, mesh, target_faces, ctx=None):
        import resource

        import numpy as np

        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        with open("/proc/self/statm") as f:
            size = int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        resource.setrlimit(resource.RLIMIT_AS, (size + (512 << 20), hard))
        try:
            np.ones(1 << 29)  # 4 GiB of float64
        finally:
            resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
        raise AssertionError("the allocation should have failed")
