"""Warming a method up before it is timed (bench.harness.warmup)."""

from bench.harness import warmup
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
