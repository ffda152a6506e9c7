"""Warming a method up before it is timed (bench.run.warmup)."""

import pytest

from bench.run import warmup
from methods.quadric import Quadric


def test_tiny_meshes_are_a_closed_sphere_and_a_textured_torus():
    plain, textured = warmup.tiny_meshes()
    assert plain.n_faces == 112 and plain.uv is None
    assert plain.welded.boundary.sum() == 0  # closed: every edge has two faces
    assert textured.uv is not None and textured.texture is not None


def test_a_method_is_warmed_up_once_per_process():
    warmup.WARM.discard((Quadric.name, repr(Quadric.Params())))
    first = warmup.warm_up(Quadric, Quadric.Params())
    assert first > 0
    assert warmup.warm_up(Quadric, Quadric.Params()) == 0.0
    # other parameters are another warm-up (they may reach other kernels)
    other = Quadric.Params(texture_weight=0.0)
    warmup.WARM.discard((Quadric.name, repr(other)))
    assert warmup.warm_up(Quadric, other) > 0


def test_a_method_that_does_not_warm_up_is_not_run(tmp_path):
    from bench.core.method import Method

    calls = []

    class Effects(Method):
        name = "effects"
        warms_up = False

        def simplify(self, mesh, target_faces, ctx=None):
            calls.append(mesh.name)
            raise AssertionError("a method that does not warm up was run by the warm-up")

    assert warmup.warm_up(Effects) == 0.0
    assert calls == []
    Effects.warms_up = True  # the same class warming up: run on both tiny meshes
    assert warmup.warm_up(Effects) > 0
    assert calls == ["warmup", "warmup-textured"]


def test_the_schedule_compiles_each_family_once_before_its_other_users():
    kernels = {"quadric": ("engine",), "image-driven": ("engine", "imaging"),
               "entropy-twin": ("engine", "imaging", "canny"), "qslim": (),
               "canny-texture": ("engine", "canny"), "(evaluation)": ()}
    order = warmup.schedule(kernels)
    # quadric builds the engine alone and starts first; image-driven builds imaging and
    # canny-texture builds canny (they need fewest families), both once the engine is
    # cached; entropy-twin waits for all three builders
    assert order == [("quadric", set()), ("(evaluation)", set()), ("qslim", set()),
                     ("canny-texture", {"quadric"}), ("image-driven", {"quadric"}),
                     ("entropy-twin", {"quadric", "image-driven", "canny-texture"})]


def test_two_families_build_side_by_side():
    kernels = {"a": ("engine",), "b": ("mt",), "c": ("engine", "mt"), "d": ("mt",)}
    order = warmup.schedule(kernels)
    assert order[:2] == [("a", set()), ("b", set())]  # each builds its own family
    assert dict(order) == {"a": set(), "b": set(), "c": {"a", "b"}, "d": {"b"}}
    kernels = {"a": ("engine",), "b": ("mt",), "d": ("mt",)}
    assert warmup.schedule(kernels) == [("a", set()), ("b", set()), ("d", {"b"})]



def test_a_split_family_compiles_its_parts_first_and_its_builder_waits_for_them():
    kernels = {"quadric": ("engine",), "image-driven": ("engine", "imaging"), "qslim": (),
               "(evaluation)": ()}
    parts = warmup.part_tasks({"engine", "imaging"})
    assert parts == {"engine": ("(engine: costing)", "(engine: collapse)")}
    order = warmup.schedule(kernels, parts)
    assert order == [("(engine: costing)", set()), ("(engine: collapse)", set()),
                     ("(evaluation)", set()), ("qslim", set()),
                     ("quadric", {"(engine: costing)", "(engine: collapse)"}),
                     ("image-driven", {"quadric"})]
    seen = set()
    for name, waits in order:
        assert waits <= seen, (name, waits)
        seen.add(name)


def test_the_engine_compiles_in_parts_and_names_an_unknown_one():
    from methods.engine.simplify import PARTS, compile_part

    assert warmup.SPLIT["engine"] == ("methods.engine.simplify", PARTS)
    plain, textured = warmup.tiny_meshes()
    for part in ("costing", "collapse"):
        compile_part(part, plain)
        compile_part(part, textured)
    with pytest.raises(ValueError, match="unknown part of the engine's kernels 'loop'"):
        compile_part("loop", plain)

def test_the_schedule_never_waits_on_a_later_task():
    kernels = {"m1": ("x", "y"), "m2": ("y",), "m3": ("x",), "m4": ("x", "y", "z"),
               "m5": ("z", "y"), "m6": ()}
    order = warmup.schedule(kernels)
    assert sorted(name for name, _ in order) == sorted(kernels)
    seen = set()
    for name, waits in order:
        assert waits <= seen, (name, waits)  # warm_up_all can always start something
        seen.add(name)
    builders = {name for name, waits in order if not waits and kernels[name]}
    assert builders == {"m2", "m3"}  # z's builder m5 needs y too, so it waits for m2


def test_warm_up_all_in_two_processes_runs_every_task_once():
    done = []
    times = warmup.warm_up_all(["qslim", "fast-simplification"], jobs=2,
                               on_done=lambda name, s: done.append(name))
    assert sorted(done) == sorted(times) == sorted(["qslim", "fast-simplification",
                                                    warmup.EVALUATION])
    assert all(s >= 0 for s in times.values())
