"""Errors and warnings meant for the user, not for a debugger.

Every :class:`BenchError` carries a one-line message that names the thing at fault
(a file, a method, a parameter) and, where possible, what to do about it. The CLI
prints it as ``bench: error: <message>`` and exits with :attr:`BenchError.exit_code`
(2), never with a traceback.
"""


class BenchError(Exception):
    """A problem with what the user asked for; the message is shown as is."""

    exit_code = 2


class InputError(BenchError, ValueError):
    """An input file or array is unusable (missing, unreadable, malformed)."""


class UnknownNameError(BenchError, LookupError):
    """A method, model or metric name that is not registered."""

    def __str__(self) -> str:  # LookupError would repr() a single argument
        return str(self.args[0]) if self.args else ""


class RegistryError(BenchError):
    """Two plug-ins claim the same name, or an entry point is malformed."""


class UnavailableError(BenchError):
    """A registered plug-in whose optional backend is not installed."""


class ParamError(BenchError, ValueError):
    """A ``--param key=value`` that the method does not accept."""


class MethodError(BenchError):
    """A method failed while running (a bug or a backend failure, not bad input)."""

    exit_code = 1


class ClusterError(BenchError):
    """The Dask executor cannot run: ``distributed`` is missing, the scheduler cannot be
    reached, or it dropped the run."""


class RenderError(BenchError, RuntimeError):
    """The evaluation renderer cannot run in this process (no usable EGL context)."""


class MeshWarning(UserWarning):
    """Something about an input mesh the user should know, which did not stop us."""


class RecordWarning(UserWarning):
    """A record, or an image it names, that a report or table left out (and why)."""
