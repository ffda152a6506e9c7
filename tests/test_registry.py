"""The plug-in registry, parameter parsing and face targets."""

from __future__ import annotations

import sys
import types
from dataclasses import dataclass, field
from importlib.metadata import EntryPoint
from typing import Literal

import pytest

from bench.core.errors import (
    BenchError,
    InputError,
    ParamError,
    RegistryError,
    UnavailableError,
    UnknownNameError,
)
from bench.core.method import parse_params, resolve_target, target_tolerance
from bench.core.registry import Registry, registry, suggest

PLUGINS = "bench_test_fake_plugins"


def ep(name: str, value: str, group: str = "bench.methods", dist=None) -> EntryPoint:
    point = EntryPoint(name=name, value=value, group=group)
    if dist is not None:  # what importlib.metadata does for an installed distribution
        point = point._for(types.SimpleNamespace(name=dist[0], version=dist[1]))
    return point


class Alpha:
    name = "alpha"


class Beta:
    name = "beta"


class NeedsMissing:
    name = "needs-missing"
    requires = {"no_such_module_xyz": "no-such-pkg"}


class NeedsPresent:
    requires = {"json": "json-is-stdlib"}


@pytest.fixture(autouse=True)
def fake_plugins(monkeypatch):
    """An importable module holding the plug-in objects the entry points refer to."""
    module = types.ModuleType(PLUGINS)
    for obj in (Alpha, Beta, NeedsMissing, NeedsPresent):
        setattr(module, obj.__name__, obj)
    monkeypatch.setitem(sys.modules, PLUGINS, module)
    return module


# -- loading ----------------------------------------------------------------------------------

def test_registry_loads_given_entry_points():
    reg = Registry("method", eps=[ep("beta", f"{PLUGINS}:Beta"), ep("alpha", f"{PLUGINS}:Alpha")])
    assert reg.names() == ["alpha", "beta"]
    assert len(reg) == 2
    assert "alpha" in reg and "gamma" not in reg
    assert [e.name for e in reg] == ["alpha", "beta"]
    assert reg.load("alpha") is Alpha
    entry = reg.entry("beta")
    assert entry.kind == "method"
    assert entry.target == f"{PLUGINS}:Beta"
    assert entry.origin == "(not installed)"
    assert entry.available and entry.problem is None
    assert entry.load() is Beta


def test_origin_names_the_distribution():
    reg = Registry("metric", eps=[ep("alpha", f"{PLUGINS}:Alpha", "bench.metrics",
                                     dist=("pkg-a", "1.2"))])
    assert reg.entry("alpha").origin == "pkg-a 1.2"


def test_entry_points_are_loaded_lazily():
    reg = Registry("method", eps=[ep("ghost", "no_such_plugin_module_abc:Thing")])
    entry = reg.entry("ghost")
    assert entry._loaded is False  # constructing the registry imported nothing
    assert not entry.available
    assert entry._loaded is True


def test_same_name_different_values_is_an_error():
    eps = [ep("alpha", f"{PLUGINS}:Alpha", dist=("pkg-a", "1.0")),
           ep("alpha", f"{PLUGINS}:Beta", dist=("pkg-b", "2.0"))]
    with pytest.raises(RegistryError) as info:
        Registry("method", eps=eps)
    message = str(info.value)
    assert f"method 'alpha' is registered twice: by pkg-a 1.0 ({PLUGINS}:Alpha) and by " \
           f"pkg-b 2.0 ({PLUGINS}:Beta)" in message
    assert "group 'bench.methods'" in message
    assert info.value.exit_code == 2


def test_same_name_different_values_without_distributions():
    eps = [ep("alpha", f"{PLUGINS}:Alpha"), ep("alpha", f"{PLUGINS}:Beta")]
    with pytest.raises(RegistryError, match=rf"{PLUGINS}:Alpha.*{PLUGINS}:Beta"):
        Registry("method", eps=eps)


def test_same_value_twice_is_deduplicated():
    eps = [ep("alpha", f"{PLUGINS}:Alpha"), ep("alpha", f"{PLUGINS}:Alpha")]
    reg = Registry("method", eps=eps)
    assert reg.names() == ["alpha"]
    assert reg.load("alpha") is Alpha


def test_unknown_name_suggests():
    reg = Registry("method", eps=[ep("alpha", f"{PLUGINS}:Alpha"), ep("beta", f"{PLUGINS}:Beta")])
    with pytest.raises(UnknownNameError, match=r"^unknown method 'alpah'; did you mean 'alpha'\?$"):
        reg.entry("alpah")
    with pytest.raises(UnknownNameError, match=r"unknown method 'zzz'; `bench list methods` "
                                               r"shows all"):
        reg.load("zzz")


def test_missing_module_is_listed_but_unavailable():
    reg = Registry("method", eps=[ep("ghost", "no_such_plugin_module_abc:Thing"),
                                  ep("alpha", f"{PLUGINS}:Alpha")])
    assert reg.names() == ["alpha", "ghost"]
    entry = reg.entry("ghost")
    assert not entry.available
    assert entry.problem == ("cannot import no_such_plugin_module_abc; "
                             "try: pip install no_such_plugin_module_abc")
    with pytest.raises(UnavailableError, match=r"method 'ghost' is unavailable: cannot import "
                                               r"no_such_plugin_module_abc; try: pip install"):
        reg.load("ghost")
    assert reg.load("alpha") is Alpha  # one broken plug-in does not break the others


def test_a_broken_import_inside_an_installed_module_is_not_a_missing_install(tmp_path,
                                                                          monkeypatch):
    """A plug-in whose module is there but imports a name that is not (an old copy of a
    module it needs, a typo) is unavailable with the ImportError, not with a pip command
    for a package that is installed."""
    (tmp_path / "half_edited_plugin.py").write_text("from bench.core.method import no_such_name\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    reg = Registry("method", eps=[ep("half", "half_edited_plugin:Thing")])
    problem = reg.entry("half").problem
    assert problem.startswith("failed to load half_edited_plugin:Thing: ImportError: cannot "
                              "import name 'no_such_name' from 'bench.core.method'"), problem
    assert "pip install" not in problem


def test_missing_backend_is_unavailable_with_pip_command():
    reg = Registry("model", eps=[ep("needy", f"{PLUGINS}:NeedsMissing", "bench.models")])
    entry = reg.entry("needy")
    assert not entry.available
    assert entry.problem == "missing backend; install with: pip install no-such-pkg"
    with pytest.raises(UnavailableError, match=r"model 'needy' is unavailable: missing backend; "
                                               r"install with: pip install no-such-pkg"):
        entry.load()


def test_present_backend_is_available():
    reg = Registry("method", eps=[ep("ok", f"{PLUGINS}:NeedsPresent")])
    assert reg.load("ok") is NeedsPresent


def test_missing_attribute_is_unavailable():
    reg = Registry("method", eps=[ep("nope", f"{PLUGINS}:Nope")])
    entry = reg.entry("nope")
    assert not entry.available
    assert entry.problem.startswith(f"failed to load {PLUGINS}:Nope: AttributeError")


def test_unknown_kind():
    with pytest.raises(ValueError, match="unknown registry kind 'plugin'"):
        Registry("plugin", eps=[])


def test_errors_are_bench_errors():
    for cls in (RegistryError, UnknownNameError, UnavailableError, ParamError, InputError):
        assert issubclass(cls, BenchError)
    assert str(UnknownNameError("plain message")) == "plain message"


def test_suggest():
    assert suggest("qslm", ["qslim", "qslim-texture", "fast-simplification"]) == \
        "; did you mean 'qslim'?"
    assert suggest("qualitythx", ["qualitythr", "qualityweight", "autoclean"]) == \
        "; did you mean 'qualitythr' or 'qualityweight'?"
    assert suggest("zzz", ["qslim"]) == ""
    assert suggest("x", []) == ""


# -- the installed registry -------------------------------------------------------------------

@pytest.mark.parametrize("kind, names", [
    ("method", {"qslim": "methods.baselines:QSlim",
                "qslim-texture": "methods.baselines:QSlimTexture",
                "fast-simplification": "methods.baselines:FastSimplification"}),
    ("model", {"bunny": "bench.catalog:BUNNY", "bunny-textured": "bench.catalog:BUNNY_TEXTURED",
               "torus": "bench.catalog:TORUS"}),
    ("metric", {"faces": "metrics.topology:FACES",
                "boundary_edges": "metrics.topology:BOUNDARY_EDGES"}),
])
def test_installed_registry(kind, names):
    reg = registry(kind)
    assert reg is registry(kind)  # cached per process
    for name, target in names.items():
        entry = reg.entry(name)
        assert entry.target == target
        assert entry.origin.split()[0] == "bench-simplify"
        assert entry.available, entry.problem


def test_installed_methods_load_their_classes():
    from methods.baselines import FastSimplification, QSlim, QSlimTexture

    reg = registry("method")
    assert {"qslim", "qslim-texture", "fast-simplification"} <= set(reg.names())
    for cls in (QSlim, QSlimTexture, FastSimplification):
        assert reg.load(cls.name) is cls


# -- parse_params -----------------------------------------------------------------------------

@dataclass
class P:
    flag: bool = False
    count: int = 1
    weight: float = 1.0
    label: str = "x"
    mode: Literal["fast", "slow"] = "fast"
    preserve_border: bool = False
    items: list = field(default_factory=list)


@dataclass
class Empty:
    pass


def test_parse_params_defaults():
    assert parse_params(P, None) == P()
    assert parse_params(P, []) == P()


def test_parse_params_converts_each_type():
    params = parse_params(P, ["flag=yes", "count=3", "weight=0.25", "label= hi ", "mode=slow"])
    assert params == P(flag=True, count=3, weight=0.25, label="hi", mode="slow")
    assert type(params.count) is int and type(params.weight) is float


@pytest.mark.parametrize("raw, value", [
    ("1", True), ("true", True), ("TRUE", True), ("yes", True), ("on", True),
    ("0", False), ("false", False), ("No", False), ("off", False),
])
def test_parse_params_bool_words(raw, value):
    assert parse_params(P, [f"flag={raw}"]).flag is value


def test_parse_params_hyphens_and_spaces_in_keys():
    assert parse_params(P, ["preserve-border=on", " count =2"]) == P(preserve_border=True, count=2)


def test_parse_params_later_values_win():
    assert parse_params(P, ["count=2", "count=5"]).count == 5


@pytest.mark.parametrize("item, match", [
    ("cont=3", r"^unknown parameter 'cont'; did you mean 'count'\? \(accepted: flag, count, "
               r"weight, label, mode, preserve_border, items\)$"),
    ("zzz=1", r"^unknown parameter 'zzz' \(accepted: flag, count"),
    ("count", r"^--param 'count': expected key=value$"),
    ("count=1.5", r"^parameter 'count' expects int, got '1\.5'$"),
    ("count=", r"^parameter 'count' expects int, got ''$"),
    ("weight=abc", r"^parameter 'weight' expects float, got 'abc'$"),
    ("flag=maybe", r"^parameter 'flag' expects true or false, got 'maybe'$"),
    ("mode=slo", r"^parameter 'mode' must be one of fast, slow; got 'slo'; did you mean 'slow'\?$"),
    ("mode=quick", r"^parameter 'mode' must be one of fast, slow; got 'quick'$"),
    ("items=1,2", r"^parameter 'items' of type <class 'list'> cannot be set from the command line$"),
])
def test_parse_params_errors(item, match):
    with pytest.raises(ParamError, match=match):
        parse_params(P, [item])


def test_parse_params_no_parameters_accepted():
    with pytest.raises(ParamError, match=r"unknown parameter 'x' \(accepted: none\)"):
        parse_params(Empty, ["x=1"])


def test_parse_params_on_a_real_method():
    from methods.baselines import QSlim

    params = parse_params(QSlim.Params, ["qualitythr=0.5", "preserveboundary=true"])
    assert params.qualitythr == 0.5 and params.preserveboundary is True
    assert params.autoclean is True


# -- resolve_target / target_tolerance ---------------------------------------------------------

@pytest.mark.parametrize("kwargs, match", [
    ({}, r"give exactly one of --faces N or --ratio R"),
    ({"faces": 10, "ratio": 0.5}, r"give exactly one of --faces N or --ratio R"),
    ({"ratio": 0.0}, r"--ratio must be in \(0, 1\], got 0\.0"),
    ({"ratio": -0.5}, r"--ratio must be in \(0, 1\], got -0\.5"),
    ({"ratio": 1.5}, r"--ratio must be in \(0, 1\], got 1\.5"),
    ({"faces": 0}, r"--faces must be at least 1, got 0"),
    ({"faces": -3}, r"--faces must be at least 1, got -3"),
])
def test_resolve_target_errors(kwargs, match):
    with pytest.raises(InputError, match=match):
        resolve_target(100, **kwargs)


@pytest.mark.parametrize("n, kwargs, expected", [
    (100, {"faces": 10}, 10),
    (100, {"faces": 500}, 500),  # not capped here; run_method handles targets >= input
    (9999, {"ratio": 0.2}, 2000),
    (100, {"ratio": 1.0}, 100),
    (100, {"ratio": 1e-9}, 1),
])
def test_resolve_target(n, kwargs, expected):
    assert resolve_target(n, **kwargs) == expected


@pytest.mark.parametrize("target, tol", [(1, 2), (100, 2), (599, 2), (600, 3), (1000, 5),
                                         (2000, 10), (65536, 327)])
def test_target_tolerance(target, tol):
    assert target_tolerance(target) == tol
