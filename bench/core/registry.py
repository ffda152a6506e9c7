"""Plug-in registry: methods, metrics and models found through entry points.

The suite's own methods, metrics and models are registered in its ``pyproject.toml``
under the same entry-point groups a third-party package would use::

    [project.entry-points."bench.methods"]
    my-method = "my_package.module:MyMethod"

Entries are loaded lazily (importing a method must not import every backend). A
plug-in object may declare ``requires = {"import_name": "pip requirement"}``; when one
is missing the entry stays listed, marked unavailable, with the pip command that fixes
it; a plug-in whose backend is not a Python package may define a callable
``unavailable_reason()`` returning why it cannot run and the fix (None when it can).
Two distributions registering one name is an error naming both.

For trying a plug-in without packaging it, ``BENCH_PLUGINS`` adds entries from the
environment (worker processes inherit it)::

    BENCH_PLUGINS="method:my-method=my_module:MyMethod,metric:gap=my_module:GAP"
"""

from __future__ import annotations

import difflib
import importlib.util
import os
from dataclasses import dataclass, field
from importlib.metadata import EntryPoint, entry_points

from bench.core.errors import RegistryError, UnavailableError, UnknownNameError

__all__ = ["GROUPS", "Entry", "Registry", "registry", "suggest"]

#: kind -> entry-point group
GROUPS = {"method": "bench.methods", "metric": "bench.metrics", "model": "bench.models"}


def suggest(name: str, candidates) -> str:
    """'; did you mean 'x'?' for the closest candidate, or '' when none is close."""
    close = difflib.get_close_matches(name, list(candidates), n=3, cutoff=0.6)
    if not close:
        return ""
    return "; did you mean " + " or ".join(f"'{c}'" for c in close) + "?"


def _installed(module: str) -> bool:
    """Whether ``module``'s top-level package can be found (an ImportError naming it is
    then a broken import inside it, not a missing install)."""
    try:
        return importlib.util.find_spec(module.split(".", 1)[0]) is not None
    except (ImportError, ValueError):
        return False


@dataclass
class Entry:
    """One registered plug-in, not yet imported."""

    kind: str
    name: str
    target: str  #: "module:attribute"
    origin: str  #: "distribution version" that registered it
    entry_point: EntryPoint | None = field(default=None, repr=False)
    _object: object = field(default=None, repr=False)
    _problem: str | None = field(default=None, repr=False)
    _loaded: bool = field(default=False, repr=False)

    def _load(self) -> None:
        if self._loaded:
            return
        self._loaded = True
        try:
            self._object = self.entry_point.load()
        except ImportError as exc:
            module = getattr(exc, "name", None) or str(exc)
            if _installed(module):  # it is there but fails inside: no pip command helps
                self._problem = f"failed to load {self.target}: ImportError: {exc}"
            else:
                self._problem = f"cannot import {module}; try: pip install {module}"
            return
        except SystemExit as exc:  # sys.exit() on import must not end bench (with code 0)
            self._problem = (f"failed to load {self.target}: it called sys.exit({exc.code!r}) "
                             "on import")
            return
        except KeyboardInterrupt:
            raise
        except BaseException as exc:  # noqa: BLE001 - a broken plug-in must not break bench
            self._problem = (f"failed to load {self.target}: {type(exc).__name__}: "
                             f"{' '.join(str(exc).split())}")
            return
        missing = [pip for mod, pip in getattr(self._object, "requires", {}).items()
                   if importlib.util.find_spec(mod) is None]
        if missing:
            self._problem = "missing backend; install with: pip install " + " ".join(missing)
            return
        # a backend outside Python (a program, an npm package) says itself what is missing
        check = getattr(self._object, "unavailable_reason", None)
        if callable(check):
            self._problem = check()

    @property
    def available(self) -> bool:
        self._load()
        return self._problem is None

    @property
    def problem(self) -> str | None:
        """Why the entry is unavailable, with the fix; None when it is available."""
        self._load()
        return self._problem

    def definition(self):
        """The registered object even when a backend it runs on is missing, for what it
        declares (a metric's unit and direction); UnavailableError when it could not be
        imported at all."""
        self._load()
        if self._object is None:
            raise UnavailableError(f"{self.kind} '{self.name}' cannot be loaded: {self._problem}")
        return self._object

    def load(self):
        """The registered object; raises UnavailableError with the fix if it cannot run."""
        self._load()
        if self._problem is not None:
            raise UnavailableError(f"{self.kind} '{self.name}' is unavailable: {self._problem}")
        return self._object


class Registry:
    """All entries of one kind ('method', 'metric' or 'model').

    Parameters
    ----------
    kind : str
        A key of :data:`GROUPS`.
    eps : iterable of EntryPoint, optional
        Entry points to use instead of the installed ones (for tests and embedding).
    """

    def __init__(self, kind: str, eps=None):
        if kind not in GROUPS:
            raise ValueError(f"unknown registry kind {kind!r}; expected one of {list(GROUPS)}")
        self.kind = kind
        self._entries: dict[str, Entry] = {}
        found = entry_points(group=GROUPS[kind]) if eps is None else eps
        for ep in found:
            self._add(ep)
        if eps is None:
            for ep in _environment_entry_points(kind):
                self._add(ep, origin="$BENCH_PLUGINS")

    def _add(self, ep: EntryPoint, origin: str | None = None) -> None:
        dist = getattr(ep, "dist", None)
        if origin is None:
            origin = f"{dist.name} {dist.version}" if dist is not None else "(not installed)"
        entry = Entry(self.kind, ep.name, ep.value, origin, ep)
        old = self._entries.get(ep.name)
        if old is not None:
            if old.target == entry.target:  # the same distribution seen twice on sys.path
                return
            raise RegistryError(
                f"{self.kind} '{ep.name}' is registered twice: by {old.origin} "
                f"({old.target}) and by {entry.origin} ({entry.target}); uninstall one "
                f"of them or rename the entry point in group '{GROUPS[self.kind]}'")
        self._entries[ep.name] = entry

    def names(self) -> list[str]:
        return sorted(self._entries)

    def __iter__(self):
        return iter(self._entries[n] for n in self.names())

    def __contains__(self, name: str) -> bool:
        return name in self._entries

    def __len__(self) -> int:
        return len(self._entries)

    def entry(self, name: str) -> Entry:
        """The entry called ``name``; UnknownNameError with suggestions otherwise."""
        try:
            return self._entries[name]
        except KeyError:
            hint = suggest(name, self._entries) or f"; `bench list {self.kind}s` shows all"
            raise UnknownNameError(f"unknown {self.kind} '{name}'{hint}") from None

    def load(self, name: str):
        """The object registered as ``name`` (imported on first use)."""
        return self.entry(name).load()


def _environment_entry_points(kind: str) -> list[EntryPoint]:
    """Entry points of ``kind`` listed in ``$BENCH_PLUGINS`` (see the module docstring)."""
    out = []
    for item in os.environ.get("BENCH_PLUGINS", "").split(","):
        item = item.strip()
        if not item:
            continue
        head, sep, value = item.partition("=")
        item_kind, colon, name = head.partition(":")
        if not (sep and colon and ":" in value):
            raise RegistryError(f"BENCH_PLUGINS entry {item!r} is not KIND:NAME=module:attribute")
        if item_kind not in GROUPS:
            raise RegistryError(f"BENCH_PLUGINS entry {item!r}: kind must be one of "
                                f"{', '.join(GROUPS)}")
        if item_kind == kind:
            out.append(EntryPoint(name.strip(), value.strip(), GROUPS[kind]))
    return out


_cache: dict[str, Registry] = {}


def registry(kind: str) -> Registry:
    """The process-wide registry of installed plug-ins of ``kind``."""
    if kind not in _cache:
        _cache[kind] = Registry(kind)
    return _cache[kind]
