"""The engine's registered methods end to end: quadric, memoryless, canny-texture."""

import numpy as np
import pytest

from bench.core.errors import InputError
from bench.core.method import run_method, target_tolerance
from bench.core.registry import registry


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
    # the g2007 suite's claim g2007-borders reads this statistic
    assert 0 < result.stats["crossing_share_after"] < 1


def test_canny_texture_needs_a_texture():
    from bench.catalog import resolve_model

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


def _canny_faces(mesh, target, **params):
    method = registry("method").load("canny-texture")(**params)
    result = run_method(method, mesh, target)
    assert result.stop_reason is None
    return result


@pytest.mark.parametrize("units, same", [("base-cost", True), ("area", False)])
def test_canny_texture_choices_do_not_depend_on_scale(units, same, bunny_textured,
                                                      monkeypatch):
    """In the base cost's units the penalty scales as the quadrics do, so neither the
    mesh's size nor the diagonal the engine normalises to changes a collapse (scales by
    powers of two are exact, so the faces are equal to the bit). The version-4 penalty,
    the area ratio added as it is, only survives resizing the mesh, which the
    normalisation takes away; at a larger working diagonal the quadrics grow against it
    and the faces change (at a smaller one it outweighs them further, as at 1). The base is Garland-Heckbert 1997's geometric quadric
    (texture_weight=0, the paper's base method): texture quadrics mix lengths with UVs,
    so the base itself depends on the normalisation."""
    import methods.engine.simplify as engine

    params = {"texture_weight": 0.0, "canny_units": units}
    reference = _canny_faces(bunny_textured, 1000, **params)
    for factor in (1024.0, 2.0 ** -20):
        resized = bunny_textured.replace(positions=bunny_textured.positions * factor)
        got = _canny_faces(resized, 1000, **params)
        np.testing.assert_array_equal(got.mesh.faces, reference.mesh.faces)
        np.testing.assert_array_equal(got.mesh.positions, reference.mesh.positions * factor)
    unchanged = []
    for diagonal in (32.0, 1 / 32):
        monkeypatch.setattr(engine, "WORKING_DIAGONAL", diagonal)
        got = _canny_faces(bunny_textured, 1000, **params)
        unchanged.append(got.mesh.faces.shape == reference.mesh.faces.shape
                         and (got.mesh.faces == reference.mesh.faces).all()
                         and (got.mesh.uv == reference.mesh.uv).all())
    assert all(unchanged) == same, unchanged


def _measured_units(mesh):
    """The engine's inputs for canny-texture (base-cost units, texture quadrics) on
    ``mesh``, and what :func:`_canny_units` measures: (arrays, terms, scaled terms,
    statistics, initial base costs, areas of each edge's faces)."""
    from methods.engine.terms.canny import texture_borders
    from methods.engine.initial import edge_areas, first_costs
    from methods.engine.policy import Policy
    from methods.engine.simplify import (
        _canny_units,
        _image_state,
        _prepare,
        _quadrics,
        _rules,
        _terms,
    )
    from methods.engine.state import new_scratch
    policy = Policy(canny_weight=1.0, canny_units="base-cost", texture_weight=1.0)
    prep = _prepare(mesh, policy, None)
    arrays = _quadrics(mesh, policy, prep)
    rules = _rules(mesh, policy, None, prep, 1, False, None)
    terms = _terms(policy, prep, texture_borders(mesh.texture), rules)
    images = _image_state(mesh, None, arrays, prep, True)
    scaled, stats = _canny_units(arrays, rules, terms, images)
    base = rules._replace(weights=rules.weights._replace(canny=0.0))
    scratch = new_scratch(len(arrays.P))
    edges, costs, _, _ = first_costs(arrays, base, terms, scratch, images)
    areas = edge_areas(arrays, scratch, edges)
    return arrays, terms, scaled, stats, costs, areas


def test_canny_texture_penalty_is_one_mean_cost_per_mean_area(bunny_textured):
    """canny_units="base-cost": an edge of the mean face area that crosses a border
    costs the mean initial base cost more (methods.engine.simplify._canny_units)."""
    arrays, terms, scaled, stats, costs, areas = _measured_units(bunny_textured)
    # every welded edge once, as the loop queues them: an oracle from the faces alone
    F = arrays.F[arrays.falive]
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    assert len(costs) == len(areas) == len(np.unique(edges, axis=0))
    # the areas of each edge's faces sum to three times the mesh's (each face has three)
    P = arrays.P
    total = 0.5 * np.linalg.norm(np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]),
                                 axis=1).sum()
    assert areas.sum() == pytest.approx(3 * total, rel=1e-9)
    finite = np.isfinite(costs)
    assert finite.sum() == stats["canny_edges_costed"] > 0.9 * len(costs)
    assert stats["canny_base_cost"] == pytest.approx(costs[finite].mean(), rel=1e-12)
    assert scaled.canny_per_area * areas[finite].mean() == pytest.approx(
        costs[finite].mean(), rel=1e-12)
    # the version-4 unit was 1 / total area, thousands of times larger here
    assert terms.canny_per_area > 1000 * scaled.canny_per_area


def test_canny_texture_on_flat_faces_orders_by_area_ratio():
    """The crate's faces are flat with affine UVs: its base costs are rounding noise
    (some negative), which measures no scale, so the penalty is the area ratio over
    its mean, a pure number."""
    from bench.catalog import resolve_model


    crate = resolve_model("crate")
    result = _canny_faces(crate, 300)
    assert result.stats["canny_base_cost"] == 0.0
    assert result.stats["canny_cost_noise"] > 0.0
    # the penalty is r_e / r̄: an edge of the mean area that crosses a border costs 1
    _, _, scaled, stats, costs, areas = _measured_units(crate)
    assert stats["canny_base_cost"] == 0.0
    assert scaled.canny_per_area * areas[np.isfinite(costs)].mean() == pytest.approx(1.0,
                                                                                    rel=1e-12)
