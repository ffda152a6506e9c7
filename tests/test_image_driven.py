"""Tests for image-driven simplification (methods.imaging.region, methods.image_driven).

The invariants of Lindstrom & Turk 2000 §4.2, each against an independent computation:

* the images kept up to date collapse by collapse equal a from-scratch render of the
  current mesh, bit for bit (flat, gouraud with specular, textured, interior views);
* the cost of a collapse (equation 8 over the affected rectangles) equals the
  brute-force difference of the summed squared error over whole images before and
  after the collapse;
* the engine's images agree with :func:`methods.imaging.raster.rasterize_luminance` of the
  extracted mesh (world coordinates, a different set-up path).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bench.core.errors import ParamError
from conftest import blob
from methods.engine.policy import Policy
from methods.engine.simplify import simplify_mesh
from methods.image_driven import ImageDriven
from methods.imaging.raster import face_id_buffers, rasterize_luminance
from methods.imaging.state import ImageTerm
from methods.imaging.views import interior_mask, view_directions
from metrics.views import dodecahedron_directions, silhouette_cameras

RES = 48
PLACEMENT = Policy(placement="memoryless", quadric_weight=0.0, memoryless_weight=0.0,
                   boundary_weight=0.0)
#: Half-edge collapses: the kept vertex stays, so a commit re-scans only the faces that
#: held the removed one (methods.imaging.region.commit_geometry).
HALF_EDGE = dataclasses.replace(PLACEMENT, placement="endpoints")


def _term(mesh, shading="flat", specular=False, cull=None, res=RES):
    cameras = silhouette_cameras(mesh)
    reference = rasterize_luminance(mesh, cameras, res, res, shading=shading,
                                    specular=specular, cull_front=cull)
    return ImageTerm(tuple(cameras), reference, shading=shading, specular=specular,
                     cull_front=None if cull is None else tuple(cull))


def _run(mesh, term, collapses, target=4, policy=PLACEMENT):
    return simplify_mesh(mesh, target, policy, verify=True, image=term,
                         max_collapses=collapses)


@pytest.mark.parametrize("shading,specular", [("flat", False), ("gouraud", True)])
def test_incremental_images_equal_a_full_render(shading, specular):
    mesh = blob()
    result = _run(mesh, _term(mesh, shading, specular), collapses=120)
    assert result.stats["collapses"] == 120
    # bit for bit: the same kernels and per-vertex functions, faces in the same order
    assert result.stats["image_mismatched_pixels"] == 0
    assert result.stats["face_id_mismatched_pixels"] == 0
    assert result.stats["image_evaluations"] > 120


def test_incremental_images_with_texture_and_interior_views(small_torus):
    cull = interior_mask(20, 10)
    result = _run(small_torus, _term(small_torus, cull=cull), collapses=60, target=100)
    assert result.stats["collapses"] == 60
    assert result.stats["image_mismatched_pixels"] == 0
    assert result.stats["face_id_mismatched_pixels"] == 0
    assert result.mesh.uv is not None


@pytest.mark.parametrize("shading,specular", [("flat", False), ("gouraud", True)])
def test_half_edge_collapses_keep_the_images_exact(shading, specular):
    """The kept vertex's other faces keep their pixels at a commit and are re-shaded
    where their normals change."""
    mesh = blob()
    result = _run(mesh, _term(mesh, shading, specular), collapses=120, policy=HALF_EDGE)
    assert result.stats["collapses"] == 120
    assert result.stats["image_mismatched_pixels"] == 0
    assert result.stats["face_id_mismatched_pixels"] == 0
    assert result.stats["depth_mismatched_pixels"] == 0


def test_half_edge_collapses_keep_textured_images_exact(small_torus):
    """Textured, with the UV correction: the commits of half-edge collapses keep the
    images exact too."""
    result = _run(small_torus, _term(small_torus), collapses=60, target=100,
                  policy=dataclasses.replace(HALF_EDGE, uv_correction=True))
    assert result.stats["collapses"] == 60
    assert result.stats["image_mismatched_pixels"] == 0
    assert result.stats["face_id_mismatched_pixels"] == 0


@pytest.mark.parametrize("shading", ["flat", "gouraud"])
def test_cost_is_the_brute_force_change_of_the_squared_error(shading):
    """f(e, k) = SSE(Y0, Y^{k+1}) - SSE(Y0, Y^k) over whole images (equation 8 before
    restricting it to the rectangles)."""
    mesh = blob()
    term = _term(mesh, shading)
    for k in (0, 7, 30):
        before = _run(mesh, term, collapses=k)
        after = _run(mesh, term, collapses=k + 1)
        assert after.stats["image_mismatched_pixels"] == 0
        brute = after.stats["image_sse"] - before.stats["image_sse"]
        cost = after.log["cost"][k]
        assert cost == pytest.approx(brute, rel=1e-9, abs=1e-6)


def test_engine_images_match_the_public_rasterizer():
    """Rendering in the engine's normalised frame agrees with rendering the extracted
    mesh in world coordinates (rounding of the projection may move a few edge pixels)."""
    mesh = blob()
    term = _term(mesh)
    result = _run(mesh, term, collapses=150)
    again = rasterize_luminance(result.mesh, term.cameras, RES, RES)
    same = np.mean(again == result.images)
    assert same > 0.995
    assert np.sqrt(np.mean((again - result.images) ** 2)) < 1.0


def test_interior_views_cull_front_faces():
    mesh = blob(1)
    cameras = silhouette_cameras(mesh)[:4]
    ids = face_id_buffers(mesh, cameras, RES, RES, cull_front=[False, True, False, True])
    centroids = mesh.positions[mesh.faces].mean(axis=1)
    normals = mesh.face_normals
    for h, cam in enumerate(cameras):
        seen = np.unique(ids[h][ids[h] >= 0])
        facing = np.einsum("ij,ij->i", normals[seen], np.asarray(cam.eye) - centroids[seen])
        if h % 2:  # culled views see only faces turned away from the eye (the inside)
            assert np.all(facing < 0)
        else:
            assert np.all(facing > 0)


def test_view_directions_and_interior_mask():
    assert np.allclose(view_directions(20), dodecahedron_directions())
    d = view_directions(7)
    assert d.shape == (7, 3) and np.allclose(np.linalg.norm(d, axis=1), 1.0)
    mask = interior_mask(20, 10)
    assert mask.sum() == 10 and list(np.flatnonzero(mask)) == list(range(0, 20, 2))
    assert interior_mask(20, 0).sum() == 0 and interior_mask(20, 20).all()


def test_method_reaches_the_target_and_is_deterministic():
    mesh = blob()
    method = ImageDriven(resolution=RES, presimplify_faces=200)
    first = method.simplify(mesh, 80)
    second = method.simplify(mesh, 80)
    assert first.mesh.n_faces in (79, 80)
    assert first.stats["presimplified_faces"] == 200
    assert np.array_equal(first.mesh.positions, second.mesh.positions)
    assert np.array_equal(first.mesh.faces, second.mesh.faces)
    assert 0 < first.stats["rasterizer_share"] < 1


@pytest.mark.parametrize("params,message", [
    ({"shading": "phong"}, "shading"), ({"resolution": 4}, "resolution"),
    ({"views": 0}, "views"), ({"interior_views": 21}, "interior_views"),
    ({"presimplify_faces": -1}, "presimplify_faces")])
def test_bad_parameters_are_clear_errors(params, message):
    with pytest.raises(ParamError, match=message):
        ImageDriven(**params).simplify(blob(1), 40)
