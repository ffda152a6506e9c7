"""The engine's registered methods end to end: quadric, memoryless, canny-texture."""

import numpy as np
import pytest

from bench.errors import InputError
from bench.method import run_method, target_tolerance
from bench.registry import registry


@pytest.mark.parametrize("name", ["quadric", "memoryless", "canny-texture"])
def test_methods_hit_the_target_and_keep_seams_closed(name, bunny_textured):
    from metrics.topology import seam_cracks

    method = registry("method").load(name)()
    result = run_method(method, bunny_textured, 1000)
    assert result.stop_reason is None
    assert abs(result.mesh.n_faces - 1000) <= target_tolerance(1000)
    assert seam_cracks(bunny_textured, result.mesh) == 0
    assert result.mesh.texture is not None and result.mesh.uv is not None
    assert result.stats["collapses"] > 0


@pytest.mark.parametrize("name", ["memoryless", "canny-texture"])
def test_a_simplified_hole_is_not_counted_as_a_crack(name, bunny_textured):
    """At 100 faces the bunny's base holes are simplified to a few chords, some passing
    nearer a seam than the original boundary (the rule before counted 1 and 2 of them
    as cracks); the engine never splits welded topology, so it opens no seam."""
    from metrics.topology import seam_cracks

    result = run_method(registry("method").load(name)(), bunny_textured, 100)
    assert result.mesh.welded.boundary.sum() > 0  # the holes are still there
    assert seam_cracks(bunny_textured, result.mesh) == 0


def test_canny_texture_shows_its_borders_and_penalised_edges(bunny_textured):
    method = registry("method").load("canny-texture")()
    result = run_method(method, bunny_textured, 2000)
    (image,) = result.artifacts.values()
    assert image.dtype == np.uint8 and image.shape == (1024, 1024, 3)
    red = (image[..., 0] > 200) & (image[..., 1] < 80)
    assert red.sum() > 0  # penalised edges drawn
    assert result.stats["crossing_edges_before"] == 249


def test_canny_texture_needs_a_texture():
    from bench.models import resolve_model

    method = registry("method").load("canny-texture")()
    tiny = resolve_model("bunny-textured").replace(texture=None)
    with pytest.raises(InputError, match="needs a texture"):
        method.simplify(tiny, 100)


@pytest.mark.parametrize("target", [100, 60])
def test_memoryless_r5_keeps_an_affine_texture_map_exact(target):
    """On a flat grid with jittered interior vertices, whose UVs are an affine function
    of position, the R^5 texture coordinates of every surviving vertex stay that
    function of its new position (Lindstrom & Turk 2000 §4.1.1). Interpolating along
    the collapsed edge does not: the placement leaves the edge's line (errors of 0.02 to
    0.05 in UV), which is what makes this test discriminate."""
    import dataclasses

    from test_engine import affine_textured_grid

    from methods.engine.simplify import simplify_mesh
    from methods.memoryless import Memoryless

    mesh, affine = affine_textured_grid()
    policy = Memoryless().policy()
    out = simplify_mesh(mesh, target, policy).mesh
    np.testing.assert_allclose(out.uv, affine(out.positions), atol=1e-12)
    plain = simplify_mesh(mesh, target, dataclasses.replace(policy, r5_uv=False)).mesh
    assert np.abs(plain.uv - affine(plain.positions)).max() > 1e-3
