"""The interface every simplification method implements, and how methods are run.

A method is a class with class attributes describing it and one ``simplify`` call::

    class MyMethod(Method):
        name = "my-method"
        version = "1"          # bump whenever the output for the same input changes
        summary = "one line"
        reference = "Author, Title, Venue Year"

        @dataclass
        class Params:
            strength: float = 1.0

        def simplify(self, mesh, target_faces, ctx=None) -> SimplifyResult: ...

Every parameter is checked by one rule (:func:`check_params`) when a method is made and
when parameters are parsed: a float must be finite (NaN, which compares false both
ways, would slip past any ``x < 0`` test, and infinity is no weight), and a number
must lie in the range its field declares with :func:`bounded`::

        @dataclass
        class Params:
            strength: float = bounded(1.0, ge=0)     # >= 0
            angle: float = bounded(90.0, gt=0, le=180)

Register it under the ``bench.methods`` entry-point group and it appears in
``bench list methods`` and can be used by ``bench simplify`` and ``bench run``.

``ctx`` is a dict or None. Under ``bench run`` it holds the evaluation's ``shading``
and ``specular`` (for methods that optimise for them) and ``cache_dir``, a directory
of the run where a method may keep work that its other jobs can reuse (keyed by the
model's ``content_hash``, its parameters and its version).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import time
import typing
import warnings
from dataclasses import dataclass, field
from typing import Any, ClassVar

from bench.core.errors import BenchError, InputError, MethodError, ParamError
from bench.core.mesh import Mesh
from bench.core.registry import suggest

__all__ = ["Method", "SimplifyResult", "bounded", "canonical_label", "canonical_params",
           "check_params", "method_label", "param_text", "parse_params", "resolve_target",
           "run_method", "target_tolerance"]


@dataclass
class SimplifyResult:
    """What a method returns.

    Attributes
    ----------
    mesh : Mesh
        The simplified mesh.
    stats : dict
        Method statistics (collapses, evaluations, ...), JSON-serialisable.
    stop_reason : str or None
        Why the method stopped away from the target; None when it reached it.
    artifacts : dict of str to ndarray
        Images a method wants shown in the report (name -> (h, w, 3) uint8), e.g. the
        texture borders canny-texture penalises.
    view_cuts : callable or None
        View-dependent methods only: ``view_cuts(cameras, protocol)`` returns one
        :class:`Mesh` per camera (that view's simplification at the same budget), which
        the protocol images instead of ``mesh``; ``mesh`` is then the method's
        view-independent result, used for the geometric and silhouette metrics. A
        ``stats`` dict attribute, if present, is merged into the record's statistics.
    """

    mesh: Mesh
    stats: dict = field(default_factory=dict)
    stop_reason: str | None = None
    artifacts: dict = field(default_factory=dict)
    view_cuts: Any = None


class Method:
    """Base class of simplification methods (see the module docstring)."""

    name: ClassVar[str] = ""
    version: ClassVar[str] = "1"
    summary: ClassVar[str] = ""
    reference: ClassVar[str] = ""
    view_dependent: ClassVar[bool] = False
    needs_uv: ClassVar[bool] = False  #: not applicable to meshes without texture coordinates
    requires: ClassVar[dict[str, str]] = {}  #: import name -> pip requirement
    #: run once on two tiny meshes before a process's first timed job of this method, so
    #: compilation and first-call costs stay out of ``wall_seconds``
    #: (bench.run.warmup); False for a method whose calls act beyond their result
    warms_up: ClassVar[bool] = True
    #: the families of compiled kernels the method runs (e.g. ``("engine", "imaging")``):
    #: ``bench warmup --jobs N`` compiles a family in one process before the other
    #: methods that need it start, so no two processes compile the same kernels
    kernels: ClassVar[tuple[str, ...]] = ()
    #: the jobs of one model share work through ``ctx["cache_dir"]`` (e.g. a structure
    #: built once for every budget): ``bench run`` starts one of them and the others
    #: of that model once it has ended, rather than two building the work side by side
    shares_work: ClassVar[bool] = False

    @dataclass
    class Params:
        pass

    def __init__(self, params: Any = None, **overrides):
        if params is None:
            params = self.Params()
        if overrides:
            params = dataclasses.replace(params, **overrides)
        self.params = check_params(params)

    def simplify(self, mesh: Mesh, target_faces: int, ctx: Any = None) -> SimplifyResult:
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.params})"


def target_tolerance(target: int) -> int:
    """Allowed distance from a face target: max(2, 0.5 % of the target)."""
    return max(2, int(0.005 * target))


def resolve_target(n_faces: int, faces: int | None = None, ratio: float | None = None) -> int:
    """A face target from an absolute count or a ratio of ``n_faces``."""
    if (faces is None) == (ratio is None):
        raise InputError("give exactly one of --faces N or --ratio R")
    if ratio is not None:
        if not 0 < ratio <= 1:
            raise InputError(f"--ratio must be in (0, 1], got {ratio}")
        faces = max(1, round(ratio * n_faces))
    if faces < 1:
        raise InputError(f"--faces must be at least 1, got {faces}")
    return int(faces)


def run_method(method: Method, mesh: Mesh, target_faces: int, ctx: Any = None) -> SimplifyResult:
    """Run ``method`` and record timing and whether it reached the target.

    A target at or above the input's face count returns the input unchanged (with a
    warning), since no simplification can reach it. A result outside
    :func:`target_tolerance` without a reason from the method gets one recorded. An
    empty result is a :class:`MethodError`: a method that cannot go lower stops above
    the target and says why.
    """
    if target_faces >= mesh.n_faces:
        warnings.warn(f"target of {target_faces} faces is not below the input's "
                      f"{mesh.n_faces}; returning the input unchanged", stacklevel=2)
        return SimplifyResult(mesh, {"wall_seconds": 0.0, "cpu_seconds": 0.0},
                              stop_reason=f"input already has {mesh.n_faces} faces")
    wall, cpu = time.perf_counter(), time.process_time()
    try:
        result = method.simplify(mesh, target_faces, ctx)
    except BenchError:
        raise
    except Exception as exc:  # a backend failure: one line for the user, cause chained
        lines = str(exc).strip().splitlines()
        raise MethodError(f"method '{method.name}' failed on {mesh.name}: "
                          f"{type(exc).__name__}: {lines[-1] if lines else ''}"
                          " (run with --debug for the traceback)") from exc
    if result.mesh.n_faces == 0:
        raise MethodError(f"method '{method.name}' returned no faces for a target of "
                          f"{target_faces} on {mesh.name}; it must stop at the fewest faces "
                          "it can keep and say so (stop_reason)")
    result.stats.setdefault("wall_seconds", time.perf_counter() - wall)
    result.stats.setdefault("cpu_seconds", time.process_time() - cpu)
    reached = result.mesh.n_faces
    if result.stop_reason is None and abs(reached - target_faces) > target_tolerance(target_faces):
        result.stop_reason = (f"reached {reached} faces for a target of {target_faces} "
                              f"(tolerance {target_tolerance(target_faces)})")
    return result


def parse_params(params_cls: type, items: list[str] | None) -> Any:
    """Build a Params dataclass from ``key=value`` strings, converting by field type.

    Raises
    ------
    ParamError
        Unknown key (with a suggestion), malformed item, or a value of the wrong type.
    """
    fields = {f.name: f for f in dataclasses.fields(params_cls)}
    hints = typing.get_type_hints(params_cls)
    values = {}
    for item in items or []:
        key, sep, raw = item.partition("=")
        key = key.strip().replace("-", "_")
        if not sep:
            raise ParamError(f"--param {item!r}: expected key=value")
        if key not in fields:
            known = ", ".join(fields) or "none"
            hint = suggest(key, fields)
            raise ParamError(f"unknown parameter '{key}'{hint} (accepted: {known})")
        values[key] = _convert(key, raw.strip(), hints[key])
    return check_params(params_cls(**values))


def bounded(default, *, ge=None, gt=None, le=None, lt=None):
    """A Params field with a default and a declared range (``ge`` <= value, ``gt`` <
    value, value <= ``le``, value < ``lt``; None: no bound), which :func:`check_params`
    enforces for every method alike."""
    bounds = {name: limit for name, limit in (("ge", ge), ("gt", gt), ("le", le), ("lt", lt))
              if limit is not None}
    return field(default=default, metadata={"range": bounds})


#: How each bound reads in a message, and the test it stands for.
_BOUNDS = {"ge": (">=", lambda v, b: v >= b), "gt": (">", lambda v, b: v > b),
           "le": ("<=", lambda v, b: v <= b), "lt": ("<", lambda v, b: v < b)}


def check_params(params):
    """``params`` (a Params dataclass instance) if every value passes the shared rule:
    each float finite, each number within its field's declared range (:func:`bounded`);
    :class:`ParamError` naming the first parameter that does not, otherwise."""
    if not dataclasses.is_dataclass(params):
        return params
    for f in dataclasses.fields(params):
        value = getattr(params, f.name)
        if not isinstance(value, numbers.Real) or isinstance(value, bool):
            continue
        if not math.isfinite(value):
            raise ParamError(f"parameter '{f.name}' must be a finite number, got {value}")
        bounds = f.metadata.get("range", {})
        if not all(_BOUNDS[k][1](value, b) for k, b in bounds.items()):
            wanted = " and ".join(f"{_BOUNDS[k][0]} {b:g}" for k, b in bounds.items())
            raise ParamError(f"parameter '{f.name}' must be {wanted}, got {value:g}")
    return params


def canonical_params(params_cls: type, params: dict) -> dict:
    """``params`` (name -> value as text or as typed) as one job of the method holds them:
    each value converted by its field's type, and those equal to the default left out.

    So ``qualitythr=0.50`` and ``qualitythr=0.5`` are one job, and ``qualitythr=0.3``
    when 0.3 is the default is the method with no parameters: the same record, the same
    label in results.csv and the report. Raises :class:`ParamError` as
    :func:`parse_params` does.
    """
    items = [f"{k}={param_text(v)}" for k, v in params.items()]
    parsed, defaults = parse_params(params_cls, items), params_cls()
    given = {str(k).strip().replace("-", "_") for k in params}
    return {f.name: getattr(parsed, f.name) for f in dataclasses.fields(params_cls)
            if f.name in given and getattr(parsed, f.name) != getattr(defaults, f.name)}


def method_label(name: str, params: dict) -> str:
    """``name[key=value,...]`` listing the parameters that differ from the defaults."""
    if not params:
        return name
    items = (f"{k}={param_text(v)}" for k, v in sorted(params.items()))
    return name + "[" + ",".join(items) + "]"


@functools.cache
def canonical_label(label: str) -> str:
    """``name[key=value,...]`` with its parameters as a job holds them now
    (:func:`canonical_params`: defaults left out, values in their shortest
    form); the label unchanged when it does not parse or its method is not installed."""
    from bench.core.registry import registry

    name, bracket, rest = label.partition("[")
    if not bracket or not rest.endswith("]"):
        return label
    params = {}
    for item in rest[:-1].split(","):
        key, sep, value = item.partition("=")
        if not sep:
            return label
        params[key] = value
    try:
        return method_label(name, canonical_params(registry("method").load(name).Params, params))
    except (BenchError, ImportError):
        return label


def param_text(value) -> str:
    """A parameter's value as ``--param`` takes it on the command line (``true``, not
    ``True``)."""
    return str(value).lower() if isinstance(value, bool) else str(value)


def _convert(key: str, raw: str, kind):
    origin = typing.get_origin(kind)
    if origin is typing.Literal:
        choices = typing.get_args(kind)
        if raw not in choices:
            raise ParamError(f"parameter '{key}' must be one of {', '.join(map(str, choices))}; "
                             f"got '{raw}'{suggest(raw, choices)}")
        return raw
    if kind is bool:
        lowered = raw.lower()
        if lowered in ("1", "true", "yes", "on"):
            return True
        if lowered in ("0", "false", "no", "off"):
            return False
        raise ParamError(f"parameter '{key}' expects true or false, got '{raw}'")
    if kind in (int, float, str):
        try:
            return kind(raw)
        except ValueError:
            raise ParamError(f"parameter '{key}' expects {kind.__name__}, got '{raw}'") from None
    raise ParamError(f"parameter '{key}' of type {kind} cannot be set from the command line")
