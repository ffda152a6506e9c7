"""Warming a method up before it is timed (bench.run.warmup)."""

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
