"""Every engine method on the wild suite's hardest cases: a 200-segment UV sphere, the
real capsule (skipped without shared/assets), and the vehicle's atlas (slow; apart from
tests/test_wild.py so that another test worker takes them)."""

from __future__ import annotations

import pytest
from test_wild import ENGINE_METHODS, asset, quiet_load

from bench.core.registry import registry
from bench.io.atlas import face_materials
from metrics.parts import parts_lost

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("method", ENGINE_METHODS)
def test_every_engine_method_runs_through_a_200_segment_uv_sphere(method):
    mesh = quiet_load("uv-sphere")
    for target in (708, 100):
        result = registry("method").load(method)().simplify(mesh, target, None)
        assert result.mesh.n_faces <= 1.1 * target, result.stop_reason


@pytest.mark.parametrize("method", ENGINE_METHODS)
def test_every_engine_method_runs_through_the_capsule(method):
    mesh = quiet_load(asset("capsule/capsule.obj"))
    for ratio in (0.1, 0.03):
        target = round(mesh.n_faces * ratio)
        result = registry("method").load(method)().simplify(mesh, target, None)
        assert result.mesh.n_faces <= 1.1 * target, result.stop_reason


@pytest.mark.parametrize("method", ENGINE_METHODS)
def test_no_atlas_cell_bleeds_into_its_neighbour(method):
    """On the vehicle (a painted body, tyres and hubcaps in one atlas) every face of the
    result keeps its corners in one material's tile, each UV inside its tile, and no
    material is lost."""
    from bench.io.atlas import materials_of, mixed_faces, tiles_of

    mesh = quiet_load("vehicle")
    tiles = tiles_of(materials_of(mesh))
    for ratio in (0.1, 0.03):
        out = registry("method").load(method)().simplify(
            mesh, round(mesh.n_faces * ratio), None).mesh
        assert not mixed_faces(out).any()
        corner_tile = tiles[face_materials(out)]                     # (k, 4) per face
        uv = out.uv[out.faces]                                        # (k, 3, 2)
        assert (uv >= corner_tile[:, None, :2] - 1e-12).all()
        assert (uv <= corner_tile[:, None, 2:] + 1e-12).all()
        assert parts_lost(mesh, out)["materials"] == 0
