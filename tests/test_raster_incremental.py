"""Tests for incremental multi-view image updates (methods.raster_incremental).

The key invariant: after any sequence of local changes (here random edge collapses),
the incrementally updated images equal a from-scratch render of the current mesh by
methods.raster.rasterize_luminance bit for bit.
"""

import time

import numpy as np
import pytest
import trimesh

from bench.mesh import Mesh
from methods.raster import face_id_buffers, rasterize_luminance
from methods.raster_incremental import ViewStack
from metrics.views import Camera, silhouette_cameras

SIZE = 64


def _sphere():
    ico = trimesh.creation.icosphere(subdivisions=3)
    return Mesh(np.asarray(ico.vertices), np.asarray(ico.faces), name="icosphere")


def _collapse(faces, positions, rng, pick=None, tries=200):
    """A random valid edge collapse (u -> v, v to the midpoint) of ``faces``.

    Returns (v, midpoint, removed rows, changed rows, new triangles of those rows), or
    None when no valid collapse was found. ``pick(u, v)`` can restrict the edges.
    """
    for _ in range(tries):
        f = faces[rng.integers(len(faces))]
        k = rng.integers(3)
        u, v = int(f[k]), int(f[(k + 1) % 3])
        if pick is not None and not pick(u, v):
            continue
        has_u = (faces == u).any(axis=1)
        has_v = (faces == v).any(axis=1)
        removed = np.flatnonzero(has_u & has_v)
        changed = np.flatnonzero(has_u & ~has_v)
        new_tris = np.where(faces[changed] == u, v, faces[changed])
        keep = np.ones(len(faces), bool)
        keep[removed] = False
        keep[changed] = False
        result = np.concatenate([faces[keep], new_tris])
        if len(result) < 4:
            continue
        if any(len(set(t)) < 3 for t in new_tris.tolist()):
            continue
        if len(np.unique(np.sort(result, axis=1), axis=0)) != len(result):
            continue  # duplicate faces
        mid = 0.5 * (positions[u] + positions[v])
        return v, mid, removed, changed, new_tris
    return None


def _apply(stack, faces, positions, op):
    """Apply a collapse to the stack (by slot) and to the reference arrays (by row)."""
    v, mid, removed, changed, new_tris = op
    slots = stack.slots
    stack.update(removed_faces=slots[removed], changed_faces=(slots[changed], new_tris),
                 new_positions=([v], [mid]))
    faces = faces.copy()
    faces[changed] = new_tris
    faces = np.delete(faces, removed, axis=0)
    positions = positions.copy()
    positions[v] = mid
    return faces, positions


@pytest.mark.parametrize("shading", ["flat", "gouraud"])
def test_collapses_match_full_render_bit_exactly(shading):
    mesh = _sphere()
    cameras = silhouette_cameras(mesh)  # fitted to the original mesh, kept fixed
    assert len(cameras) == 20
    stack = ViewStack(mesh.positions, mesh.faces, cameras, SIZE, SIZE, shading=shading,
                      tile=8)
    np.testing.assert_array_equal(
        stack.images(), rasterize_luminance(mesh, cameras, SIZE, SIZE, shading=shading))
    rng = np.random.default_rng(1)
    faces, positions = mesh.faces.copy(), mesh.positions.copy()
    done = 0
    while done < 30:
        op = _collapse(faces, positions, rng)
        assert op is not None
        faces, positions = _apply(stack, faces, positions, op)
        done += 1
        np.testing.assert_array_equal(stack.faces, faces)
        current = Mesh(positions, faces)
        expected = rasterize_luminance(current, cameras, SIZE, SIZE, shading=shading)
        assert np.array_equal(stack.images(), expected), f"mismatch after {done} collapses"
        # Each collapse re-renders a proper sub-rectangle somewhere, never nothing at all.
        assert (stack.last_rects[:, 0] <= stack.last_rects[:, 1]).any()
    np.testing.assert_array_equal(stack.face_ids(), face_id_buffers(current, cameras,
                                                                    SIZE, SIZE))


def test_added_faces_and_index_rebuild_match_full_render():
    mesh = _sphere()
    cameras = silhouette_cameras(mesh)
    stack = ViewStack(mesh.positions, mesh.faces, cameras, SIZE, SIZE, tile=4)
    rng = np.random.default_rng(7)
    faces, positions = mesh.faces.copy(), mesh.positions.copy()
    for _ in range(3):
        # Remove one face and add it back at the end (it is now drawn last), then a
        # few collapses, enough to force rebuilds of the tile index.
        row = int(rng.integers(len(faces)))
        tri = faces[row].copy()
        stack.update(removed_faces=[stack.slots[row]])
        new = stack.update(added_faces=[tri])
        assert new.shape == (1,)
        faces = np.concatenate([np.delete(faces, row, axis=0), tri[None]])
        for _ in range(100):
            faces, positions = _apply(stack, faces, positions,
                                      _collapse(faces, positions, rng))
        np.testing.assert_array_equal(stack.faces, faces)
        np.testing.assert_array_equal(
            stack.images(), rasterize_luminance(Mesh(positions, faces), cameras, SIZE, SIZE))


def test_change_outside_a_view_leaves_it_untouched():
    mesh = _sphere()
    cameras = silhouette_cameras(mesh)
    direction = np.array([1.0, 0.0, 0.0])
    # A narrow camera looking at the +x side only: points with y > 0.7 are outside.
    zoom = Camera(eye=3.0 * direction, target=direction, up=[0.0, 0.0, 1.0],
                  fov_y_deg=10.0, near=0.5, far=10.0)
    cameras = cameras + [zoom]
    stack = ViewStack(mesh.positions, mesh.faces, cameras, SIZE, SIZE, shading="gouraud")
    before = stack.images().copy()
    ids_before = stack.face_ids().copy()
    rng = np.random.default_rng(3)
    faces, positions = mesh.faces.copy(), mesh.positions.copy()
    op = _collapse(faces, positions, rng,
                   pick=lambda u, v: positions[u, 1] > 0.8 and positions[v, 1] > 0.8)
    faces, positions = _apply(stack, faces, positions, op)
    last = len(cameras) - 1
    assert stack.last_rects[last, 0] > stack.last_rects[last, 1]  # empty rectangle
    np.testing.assert_array_equal(stack.images()[last], before[last])
    ids = stack.face_ids()[last]  # rows of stack.faces; compare the stable slots
    np.testing.assert_array_equal(np.where(ids >= 0, stack.slots[ids], -1), ids_before[last])
    assert not np.array_equal(stack.images()[:last], before[:last])
    np.testing.assert_array_equal(
        stack.images(),
        rasterize_luminance(Mesh(positions, faces), cameras, SIZE, SIZE, shading="gouraud"))


def test_bunny_incremental_update_is_faster_than_full_render():
    from bench.models import BUNNY

    try:
        mesh = BUNNY.load()
    except Exception as exc:  # pragma: no cover - depends on the installed samples
        pytest.skip(f"bunny not available: {exc}")
    cameras = silhouette_cameras(mesh)
    size = 256
    stack = ViewStack(mesh.positions, mesh.faces, cameras, size, size)
    rng = np.random.default_rng(0)
    faces, positions = mesh.faces.copy(), mesh.positions.copy()
    # Warm up (numba compilation) with one collapse.
    faces, positions = _apply(stack, faces, positions, _collapse(faces, positions, rng))
    incremental = []
    for _ in range(50):
        op = _collapse(faces, positions, rng)
        v, mid, removed, changed, new_tris = op
        slots = stack.slots
        t0 = time.perf_counter()
        stack.update(removed_faces=slots[removed], changed_faces=(slots[changed], new_tris),
                     new_positions=([v], [mid]))
        incremental.append(time.perf_counter() - t0)
        faces = faces.copy()
        faces[changed] = new_tris
        faces = np.delete(faces, removed, axis=0)
        positions = positions.copy()
        positions[v] = mid
    current = Mesh(positions, faces)
    full = []
    for _ in range(5):
        t0 = time.perf_counter()
        expected = rasterize_luminance(current, cameras, size, size)
        full.append(time.perf_counter() - t0)
    np.testing.assert_array_equal(stack.images(), expected)
    inc, ful = np.median(incremental), np.median(full)
    area = (stack.last_rects[:, 1] - stack.last_rects[:, 0] + 1).clip(0) * \
        (stack.last_rects[:, 3] - stack.last_rects[:, 2] + 1).clip(0)
    print(f"\nbunny {mesh.n_faces} faces, {len(cameras)} views at {size}x{size}: "
          f"incremental update median {inc * 1e3:.2f} ms (max {max(incremental) * 1e3:.2f}),"
          f" full render median {ful * 1e3:.2f} ms, speed-up {ful / inc:.1f}x; "
          f"last update re-rendered {int(area.sum())} pixels over all views")
    assert inc < ful
