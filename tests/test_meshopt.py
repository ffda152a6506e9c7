"""The meshoptimizer rows (meshoptimizer 1.3.0 on Node) and gltfpack.

Tiny meshes with exact expectations: a quad strip, a flat grid with a UV seam, a cube
whose six sides are six UV charts (every cube edge a seam); then the bunny and the
textured models for targets, errors and seams.
"""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from bench.catalog import BUNNY, BUNNY_TEXTURED, CRATE
from bench.core.errors import MethodError, ParamError
from bench.core.mesh import Mesh
from bench.core.method import parse_params, run_method, target_tolerance
from bench.core.registry import Registry
from methods.meshopt import (
    _WORKER,
    LIBRARY_VERSION,
    NODE_DIR,
    SCRIPT,
    VERTEX_PROTECT,
    Gltfpack,
    Meshopt,
    MeshoptAttributes,
    MeshoptPermissive,
    MeshoptSloppy,
    MeshoptUpdate,
    _node,
    node_problem,
    protected_vertices,
    uv_density_weight,
)
from metrics.topology import seam_cracks

pytestmark = pytest.mark.skipif(node_problem() is not None, reason=str(node_problem()))

VARIANTS = {"meshopt": Meshopt, "meshopt-attributes": MeshoptAttributes,
            "meshopt-update": MeshoptUpdate, "meshopt-permissive": MeshoptPermissive,
            "meshopt-sloppy": MeshoptSloppy}
#: the rows that keep every seam closed (permissive keeps those it is told to protect)
SEAM_KEEPING = ["meshopt", "meshopt-attributes", "meshopt-update"]
COLLAPSING = SEAM_KEEPING + ["meshopt-permissive"]


def strip(n: int = 5) -> Mesh:
    """A flat strip of n unit quads along x in z = 0, two triangles each, UVs (x/n, y)."""
    positions = [(i, j, 0.0) for i in range(n + 1) for j in (0, 1)]
    faces = []
    for i in range(n):
        a, b, c, d = 2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1
        faces += [(a, b, c), (a, c, d)]
    uv = [(x / n, y) for x, y, _ in positions]
    return Mesh(np.array(positions, float), np.array(faces), uv=np.array(uv),
                normals=np.tile([0.0, 0.0, 1.0], (len(positions), 1)), name="strip")


def grid(n: int = 4, seam_at: int | None = None) -> Mesh:
    """A flat n x n grid of unit squares in z = 0 with UVs (x, y) / n; with ``seam_at``
    the column x = seam_at is a UV seam: the squares right of it use their own vertices
    there and their UVs are shifted by (1, 0) (a chart elsewhere in the atlas)."""
    positions, uv, index = [], [], {}

    def vertex(i, j, right):
        key = (i, j, right and i == seam_at)
        if key not in index:
            index[key] = len(positions)
            positions.append((i, j, 0.0))
            uv.append((i / n + (1.0 if right else 0.0), j / n))
        return index[key]

    faces = []
    for i in range(n):
        for j in range(n):
            right = seam_at is not None and i >= seam_at
            a, b = vertex(i, j, right), vertex(i + 1, j, right)
            c, d = vertex(i + 1, j + 1, right), vertex(i, j + 1, right)
            faces += [(a, b, c), (a, c, d)]
    normals = np.tile([0.0, 0.0, 1.0], (len(positions), 1))
    return Mesh(np.array(positions), np.array(faces), uv=np.array(uv), normals=normals,
                name="grid")


#: The unit cube's sides: corner, then two edge vectors whose cross product points out.
SIDES = [((0, 0, 0), (0, 1, 0), (1, 0, 0)), ((0, 0, 1), (1, 0, 0), (0, 1, 0)),
         ((0, 0, 0), (1, 0, 0), (0, 0, 1)), ((0, 1, 0), (0, 0, 1), (1, 0, 0)),
         ((0, 0, 0), (0, 0, 1), (0, 1, 0)), ((1, 0, 0), (0, 1, 0), (0, 0, 1))]


def cube(n: int = 2, mirrored: tuple = ()) -> Mesh:
    """The unit cube, each side an n x n grid and its own UV chart (a tile of a 3 x 2
    atlas), so all 12 cube edges are seams: 48 faces, 54 render vertices on 26
    positions. Sides listed in ``mirrored`` have their chart mirrored in u (clockwise UV
    winding where the others wind counter-clockwise)."""
    positions, uv, faces = [], [], []
    for side, (o, a, b) in enumerate(SIDES):
        o, a, b = map(np.asarray, (o, a, b))
        base = len(positions)
        for j in range(n + 1):
            for i in range(n + 1):
                positions.append(o + a * i / n + b * j / n)
                s = 1 - i / n if side in mirrored else i / n
                uv.append(((side % 3 + 0.1 + 0.8 * s) / 3, (side // 3 + 0.1 + 0.8 * j / n) / 2))
        for j in range(n):
            for i in range(n):
                v = base + j * (n + 1) + i
                faces += [(v, v + 1, v + n + 2), (v, v + n + 2, v + n + 1)]
    return Mesh(np.array(positions, float), np.array(faces), uv=np.array(uv), name="cube")


def corners(mesh: Mesh) -> set:
    return set(map(tuple, mesh.positions.tolist()))


def area(mesh: Mesh) -> float:
    p = mesh.positions[mesh.faces]
    return float(0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
                                      axis=1).sum())


# -- tiny meshes with exact expectations --------------------------------------------------

@pytest.mark.parametrize("name", COLLAPSING)
def test_quad_strip_collapses_to_two_triangles_on_its_corners(name):
    mesh = strip()
    out = run_method(VARIANTS[name](), mesh, 2)
    assert out.mesh.n_faces == 2 and out.stop_reason is None
    assert corners(out.mesh) == {(0, 0, 0), (5, 0, 0), (0, 1, 0), (5, 1, 0)}
    assert area(out.mesh) == pytest.approx(5.0)
    # flat, with affine UVs and constant normals: the corners keep their own UVs (the
    # UVs meshopt-update solves for are those, to float32 rounding)
    np.testing.assert_allclose(sorted(map(tuple, out.mesh.uv.tolist())),
                               [(0, 0), (0, 1), (1, 0), (1, 1)],
                               atol=1e-6 if name == "meshopt-update" else 0)
    np.testing.assert_array_equal(out.mesh.normals, [[0, 0, 1]] * 4)
    # no geometric error, up to the library's float32 quadrics (measured at most 3e-4
    # of the extent); 'Regularize' adds its triangle-shape term (measured 0.058)
    if name == "meshopt-permissive":
        assert 0.01 < out.stats["library_error"] < 0.1
        unregularized = run_method(MeshoptPermissive(regularize=False), mesh, 2).stats
        assert unregularized["library_error"] == pytest.approx(0.0, abs=1e-3)
    else:
        assert out.stats["library_error"] == pytest.approx(0.0, abs=1e-3)


def test_gltfpack_takes_the_quad_strip_to_two_triangles():
    out = run_method(Gltfpack(), strip(), 2)
    assert out.mesh.n_faces == 2 and out.stop_reason is None
    assert corners(out.mesh) == {(0, 0, 0), (5, 0, 0), (0, 1, 0), (5, 1, 0)}
    assert "-si" in out.stats["gltfpack_args"] and "-noq" in out.stats["gltfpack_args"]


@pytest.mark.parametrize("name", SEAM_KEEPING)
def test_seam_grid_keeps_its_seam_and_corners(name):
    # Each chart becomes a rectangle of two triangles; the seam x = 2 stays, split.
    mesh = grid(seam_at=2)
    out = run_method(VARIANTS[name](), mesh, 4)
    assert out.mesh.n_faces == 4 and out.stop_reason is None
    assert corners(out.mesh) == {(x, y, 0) for x in (0, 2, 4) for y in (0, 4)}
    assert out.mesh.n_vertices == 8  # the seam's two ends appear once per chart
    assert out.mesh.summary()["seam_edges"] == 1
    assert seam_cracks(mesh, out.mesh) == 0
    assert area(out.mesh) == pytest.approx(16.0)


def test_cube_seams_stop_plain_simplify_at_two_triangles_a_side():
    # every side a chart: the library keeps each side's 4 corners, split per chart, and
    # cannot go below 12 faces; the note says so with the library's error
    mesh = cube()
    assert (mesh.n_faces, mesh.n_vertices, mesh.welded.n_vertices) == (48, 54, 26)
    out = run_method(Meshopt(), mesh, 4)
    assert (out.mesh.n_faces, out.mesh.n_vertices, out.mesh.welded.n_vertices) == (12, 24, 8)
    assert seam_cracks(mesh, out.mesh) == 0
    error = out.stats["result_error"]
    assert out.stop_reason == (
        "stopped at 12 faces above the target of 4: no collapse left that keeps the seams "
        f"and borders the library preserves (library error {error:.4g})")


def test_protected_vertices_on_the_cube():
    plain, mirrored = cube(), cube(mirrored=(1,))
    # charts of one orientation: nothing to protect; every seam vertex with protect=seams
    assert not protected_vertices(plain).any()
    seams = protected_vertices(plain, "seams")
    on_edges = np.isin(plain.positions, (0.0, 1.0)).sum(axis=1) >= 2  # on a cube edge
    np.testing.assert_array_equal(seams == VERTEX_PROTECT, on_edges)
    assert not protected_vertices(plain, "none").any()
    # the mirrored top (z = 1) meets its four neighbours with opposite winding: its 8
    # border positions are protected, in every chart there (8 + 4 x 3 = 20 render vertices)
    lock = protected_vertices(mirrored)
    assert np.count_nonzero(lock) == 20
    top_border = (mirrored.positions[:, 2] == 1) & on_edges
    np.testing.assert_array_equal(lock == VERTEX_PROTECT, top_border)


def test_permissive_collapses_across_an_unprotected_seam():
    # no seam protected (one UV orientation): collapses cross the seams, down to a
    # tetrahedron on four of the cube's corners, which plain simplify cannot reach
    out = run_method(MeshoptPermissive(), cube(), 4)
    assert out.mesh.n_faces == 4 and out.stop_reason is None
    assert out.mesh.welded.n_vertices == 4
    assert corners(out.mesh) <= {(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)}
    assert out.stats["protected_vertices"] == 0


def test_permissive_protect_keeps_the_seam_vertices():
    # the mirrored top's border is protected: the result keeps exactly its four corners
    # (collapses along the protected seam are allowed, across it not)
    out = run_method(MeshoptPermissive(), cube(mirrored=(1,)), 4)
    assert out.mesh.n_faces == 4 and out.stop_reason is None
    assert corners(out.mesh) == {(0, 0, 1), (1, 0, 1), (0, 1, 1), (1, 1, 1)}
    assert out.stats["protected_vertices"] == 20
    # every seam protected: permissive mode stops where plain simplify does
    every = run_method(MeshoptPermissive(protect="seams"), cube(), 4)
    assert (every.mesh.n_faces, every.mesh.n_vertices) == (12, 24)
    assert every.stats["protected_vertices"] == 48


def two_material_grid(with_table: bool = True) -> Mesh:
    """``grid(seam_at=2)`` with its two charts in two materials' tiles of an 8 x 4 atlas:
    the left chart's u in [0, 0.25] (tile u 0-0.5), the right's in [0.75, 1] (tile u
    0.5-1), one UV orientation; without the table the same UVs are one material."""
    mesh = grid(seam_at=2)
    uv = mesh.uv.copy()
    right = uv[:, 0] >= 1
    uv[:, 0] = np.where(right, 0.75 + (uv[:, 0] - 1.5) * 0.5, uv[:, 0] * 0.5)
    if not with_table:
        return mesh.replace(uv=uv)
    table = {"gutter": 8, "size": [8, 4], "materials": [
        {"name": "left", "tile": [0.0, 0.0, 0.5, 1.0]},
        {"name": "right", "tile": [0.5, 0.0, 1.0, 1.0]}]}
    return mesh.replace(uv=uv, texture=np.zeros((4, 8, 3), np.uint8),
                        metadata={"atlas": table})


@pytest.mark.parametrize("protect", ["orientation", "none"])
def test_permissive_always_protects_material_boundaries(protect):
    from bench.io.atlas import face_materials, mixed_faces

    mesh = two_material_grid()
    lock = protected_vertices(mesh, protect)
    # the seam x = 2 is a material boundary: its 5 positions, both copies of each
    assert np.count_nonzero(lock) == 10 and set(mesh.positions[lock > 0, 0]) == {2.0}
    out = run_method(MeshoptPermissive(protect=protect), mesh, 2)
    assert out.mesh.n_faces == 2
    assert {(2, 0, 0), (2, 4, 0)} <= corners(out.mesh)  # the boundary's ends stay
    assert not mixed_faces(out.mesh).any()
    assert sorted(face_materials(out.mesh).tolist()) == [0, 1]  # one face each
    # the same UVs as one material: the left chart is collapsed into the right one
    one = run_method(MeshoptPermissive(protect=protect), two_material_grid(False), 2)
    assert one.mesh.n_faces == 2 and min(x for x, _, _ in corners(one.mesh)) == 2


def test_update_writes_back_positions_and_uvs():
    mesh = BUNNY_TEXTURED.load()
    plain = run_method(MeshoptAttributes(), mesh, 1000)
    out = run_method(MeshoptUpdate(), mesh, 1000)
    # the same collapses as simplifyWithAttributes (same error), then solved vertices
    assert out.mesh.n_faces == plain.mesh.n_faces
    assert out.stats["library_error"] == plain.stats["library_error"]
    source = corners(mesh)
    moved = sum(p not in source for p in map(tuple, out.mesh.positions.tolist()))
    assert moved > out.mesh.n_vertices // 2  # measured: 962 of 1024
    assert not np.array_equal(out.mesh.uv, plain.mesh.uv)
    assert seam_cracks(mesh, out.mesh) == 0  # a seam's copies move together
    np.testing.assert_array_equal(out.mesh.texture, mesh.texture)


def test_sloppy_strip_never_exceeds_the_target():
    out = run_method(MeshoptSloppy(), grid(), 8)
    assert out.mesh.n_faces <= 8
    assert corners(out.mesh) <= corners(grid())  # clustering keeps original vertices


# -- the bunny: targets and the library's error --------------------------------------------

@pytest.fixture(scope="module")
def bunny_results():
    bunny = BUNNY.load()
    assert bunny.n_faces == 56172
    return {name: run_method(cls(), bunny, 1332) for name, cls in VARIANTS.items()}


@pytest.mark.parametrize("name", list(VARIANTS))
def test_bunny_reaches_the_target_or_records_why(bunny_results, name):
    out = bunny_results[name]
    reached = out.mesh.n_faces
    if name in COLLAPSING:  # measured: all reach it on the bunny
        assert abs(reached - 1332) <= target_tolerance(1332) and out.stop_reason is None
    else:  # sloppy lands below the target, never above, and says why
        assert reached <= 1332
        assert out.stop_reason is None or "grid sizes" in out.stop_reason
    assert len(np.unique(out.mesh.faces)) == out.mesh.n_vertices  # compacted


@pytest.mark.parametrize("name", list(VARIANTS))
def test_library_error_is_recorded_relative_and_absolute(bunny_results, name):
    stats = bunny_results[name].stats
    assert stats["result_error_units"] == "relative"
    assert 0 < stats["library_error"] < 1
    assert stats["library_error"] == stats["result_error"]
    assert stats["library_error_absolute"] == pytest.approx(
        stats["library_error"] * stats["error_scale"])
    # getScale is the mesh's largest extent (the bunny's bounding box, float32)
    extent = BUNNY.load().positions.astype(np.float32)
    assert stats["error_scale"] == pytest.approx(float(np.ptp(extent, axis=0).max()), rel=1e-6)
    assert stats["target_error"] is None  # unbounded: the face target stops it
    assert stats["library_version"] == LIBRARY_VERSION == "1.3.0"
    assert stats["backend"].startswith("meshoptimizer 1.3.0 (npm, WebAssembly on Node v")
    assert 0 < stats["library_seconds"] < stats["wall_seconds"]


def test_error_absolute_reports_model_units():
    mesh = BUNNY_TEXTURED.load()
    relative = run_method(Meshopt(), mesh, 1000).stats
    absolute = run_method(Meshopt(error_absolute=True), mesh, 1000).stats
    assert absolute["result_error_units"] == "absolute"
    assert absolute["library_error"] == pytest.approx(relative["library_error"], rel=1e-3)
    assert absolute["result_error"] == pytest.approx(relative["library_error_absolute"],
                                                     rel=1e-3)


@pytest.mark.parametrize("name", ["meshopt", "meshopt-sloppy"])
def test_bounded_error_stop_is_a_recorded_reason(name):
    mesh = BUNNY_TEXTURED.load()
    out = run_method(VARIANTS[name](bound_error=True, target_error=0.01), mesh, 200)
    assert out.mesh.n_faces > 200
    assert "target_error=0.01 allows no coarser result" in out.stop_reason
    assert f"library error {out.stats['result_error']:.4g}" in out.stop_reason
    assert out.stats["result_error"] <= 0.01
    assert out.stats["target_error"] == 0.01


# -- seams and UVs on textured models -----------------------------------------------------

@pytest.fixture(scope="module", params=[CRATE, BUNNY_TEXTURED], ids=lambda m: m.name)
def textured(request):
    return request.param.load()


@pytest.mark.parametrize("name", SEAM_KEEPING)
def test_seams_stay_closed(textured, name):
    target = round(0.10 * textured.n_faces)
    out = run_method(VARIANTS[name](), textured, target)
    assert seam_cracks(textured, out.mesh) == 0
    assert abs(out.mesh.n_faces - target) <= target_tolerance(target) or out.stop_reason


@pytest.mark.parametrize("name", ["meshopt", "meshopt-attributes", "meshopt-permissive",
                                  "meshopt-sloppy"])
def test_uvs_and_texture_survive(textured, name):
    out = run_method(VARIANTS[name](), textured, round(0.25 * textured.n_faces)).mesh
    assert out.uv.shape == (out.n_vertices, 2)
    np.testing.assert_array_equal(out.texture, textured.texture)
    # every output vertex is an input vertex, with its own position and UV
    source = {tuple(row) for row in np.hstack([textured.positions, textured.uv]).tolist()}
    assert all(tuple(row) in source for row in np.hstack([out.positions, out.uv]).tolist())


def test_gltfpack_result_is_read_back_with_its_texture(textured):
    target = round(0.25 * textured.n_faces)
    out = run_method(Gltfpack(), textured, target)
    assert abs(out.mesh.n_faces - target) <= target_tolerance(target)
    assert out.stop_reason is None
    # at 10 % gltfpack's default error limit stops it on bunny-textured, and it says so
    far = run_method(Gltfpack(), textured, round(0.10 * textured.n_faces))
    if abs(far.mesh.n_faces - round(0.10 * textured.n_faces)) > target_tolerance(1000):
        assert "within its error limit -se 0.01" in far.stop_reason
    np.testing.assert_array_equal(out.mesh.texture, textured.texture)
    assert "source" not in out.mesh.metadata or out.mesh.metadata["source"] == \
        textured.metadata.get("source")
    assert out.stats["library_version"] == "1.3.0"


def test_gltfpack_keeps_each_material_of_a_multi_material_model():
    from bench.catalog import resolve_model
    from bench.io.atlas import face_materials, materials_of, mixed_faces

    mesh = resolve_model("two-materials")
    out = run_method(Gltfpack(), mesh, 992)  # 25 %
    assert abs(out.mesh.n_faces - 992) <= target_tolerance(992) and out.stop_reason is None
    assert [m["name"] for m in materials_of(out.mesh)] == ["bricks", "waves"]
    assert [m["texture"]["source"] for m in materials_of(out.mesh)] == [
        "procedural (bricks_texture)", "procedural (waves_texture)"]
    assert not mixed_faces(out.mesh).any()
    assert np.bincount(face_materials(out.mesh)).min() > 0.4 * out.mesh.n_faces
    # gltfpack simplifies each primitive (material) alone, so their common border can
    # open (measured: 11 cracks); -slb locks it
    assert seam_cracks(mesh, out.mesh) > 0
    locked = run_method(Gltfpack(lock_border=True), mesh, 992)
    assert "-slb" in locked.stats["gltfpack_args"].split()
    assert seam_cracks(mesh, locked.mesh) == 0


def test_gltfpack_pruning_everything_is_a_clear_failure():
    # gltfpack prunes components under its error limit: at -se 0.99 the whole bunny
    # (measured) goes, which is said in one line, not as a reader's KeyError
    with pytest.raises(MethodError, match=r"gltfpack left no triangles for a target of 200 "
                                          r"faces \(with -se 0.99 its pruning removed"):
        run_method(Gltfpack(target_error=0.99), BUNNY_TEXTURED.load(), 200)


def test_gltfpack_read_back_notes_stay_in_the_stats():
    # three squares sharing one edge: gltfpack keeps the non-manifold edge, and the
    # reader's warning about it is the result's note, not a warning about a user's file
    positions, faces = [(0, 0, 0), (0, 0, 1)], []
    for dx, dy in [(1, 0), (0, 1), (-1, -1)]:
        a = len(positions)
        positions += [(dx, dy, 0), (dx, dy, 1)]
        faces += [(0, a, a + 1), (0, a + 1, 1)]
    book = Mesh(np.array(positions, float), np.array(faces), name="book")
    out = run_method(Gltfpack(), book, 5)  # pytest turns an escaping MeshWarning into an error
    assert out.mesh.n_faces == 6  # within the tolerance of 2 faces
    assert out.stats["read_back_notes"] == [
        ("gltfpack's output: 1 non-manifold edges (more than two faces); allowed, but some "
         "methods treat them as locked")]
    assert run_method(Gltfpack(), strip(), 2).stats["read_back_notes"] == []


def test_uv_weight_follows_the_readme_density_rule():
    mesh = grid()  # 32 triangles of UV area (1/4)^2 / 2 each
    assert uv_density_weight(mesh) == pytest.approx(1 / np.sqrt(1 / 32))
    stats = run_method(MeshoptAttributes(uv_weight_scale=2.0), mesh, 2).stats
    assert stats["uv_weight"] == pytest.approx(2 / np.sqrt(1 / 32))
    assert stats["normal_weight"] == 0.5


# -- parameters, determinism, failures ----------------------------------------------------

def test_params_parse_from_the_command_line():
    p = parse_params(MeshoptPermissive.Params,
                     ["bound_error=true", "target_error=0.05", "lock_border=yes",
                      "normal_weight=1", "protect=seams", "regularize=false"])
    assert (p.bound_error, p.target_error, p.lock_border, p.normal_weight, p.protect,
            p.regularize) == (True, 0.05, True, 1.0, "seams", False)
    with pytest.raises(ParamError, match="protect='edges': expected one of orientation, "
                                         "seams, none"):
        run_method(MeshoptPermissive(protect="edges"), grid(), 2)


@pytest.mark.parametrize("name", ["meshopt", "meshopt-attributes"])
def test_prune_without_an_error_bound_is_refused(name):
    with pytest.raises(ParamError, match="bound_error=true"):
        run_method(VARIANTS[name](prune=True), grid(), 2)
    out = run_method(VARIANTS[name](prune=True, bound_error=True, target_error=0.01), grid(), 2)
    assert out.mesh.n_faces == 2


def test_an_empty_result_is_a_clear_failure():
    # the cube's coarsest sloppy grid under 4 faces keeps no triangle (measured)
    with pytest.raises(MethodError, match="no triangles for a target of 4 faces"):
        run_method(MeshoptSloppy(), cube(), 4)


@pytest.mark.parametrize("name", [*VARIANTS, "gltfpack"])
def test_deterministic(name):
    """The same result twice, and with one thread or two for the job (the library runs
    in one Node process, whatever the job's thread count)."""
    from bench.run.jobs import use_threads

    cls = Gltfpack if name == "gltfpack" else VARIANTS[name]
    mesh = CRATE.load()
    before = use_threads(None)
    try:
        use_threads(1)
        a = run_method(cls(), mesh, 400)
        use_threads(2)
        b = run_method(cls(), mesh, 400)
    finally:
        use_threads(before)
    np.testing.assert_array_equal(a.mesh.faces, b.mesh.faces)
    np.testing.assert_array_equal(a.mesh.positions, b.mesh.positions)
    np.testing.assert_array_equal(a.mesh.uv, b.mesh.uv)
    assert a.stats.get("library_error") == b.stats.get("library_error")


def frame(header: dict, body: bytes) -> bytes:
    head = json.dumps({**header, "bytes": len(body)}).encode()
    return struct.pack("<I", len(head)) + head + body


def test_a_malformed_request_is_refused_in_one_line():
    # 3 floats where the header declares 3 vertices (9 floats)
    header = {"op": "simplify", "index_count": 3, "vertex_count": 3, "target_index_count": 3,
              "target_error": 1.0}
    body = np.arange(3, dtype="<u4").tobytes() + np.zeros(3, "<f4").tobytes()
    with pytest.raises(MethodError) as info:
        _WORKER.call(frame(header, body))
    assert str(info.value) == ("simplify.mjs refused the request: malformed request: the "
                               "positions need 36 bytes, the body has 12 left")
    # the worker goes on serving
    good = np.arange(3, dtype="<u4").tobytes() + np.eye(3, dtype="<f4").tobytes()
    meta, reply = _WORKER.call(frame(header, good))
    assert meta["index_count"] == 3 and np.frombuffer(reply, "<u4").tolist() == [0, 1, 2]


def test_a_request_cut_short_is_answered_before_the_script_exits():
    header = {"op": "simplify", "index_count": 3, "vertex_count": 3, "target_index_count": 3,
              "target_error": 1.0}
    whole = frame(header, np.arange(3, dtype="<u4").tobytes() + np.eye(3, dtype="<f4").tobytes())
    reply = _node([str(SCRIPT)], whole[:-5], 60)
    (size,) = struct.unpack_from("<I", reply)
    assert json.loads(reply[4:4 + size]) == {
        "refused": "truncated request: 43 bytes of body, fewer than its header declares",
        "bytes": 0}


def test_a_malformed_buffer_is_one_failed_record(tmp_path):
    from bench.records.results import records_table
    from bench.run.jobs import Job, run_job

    good, bad = grid(), grid()
    positions = bad.positions.copy()
    positions[3, 1] = np.nan  # a vertex buffer the library must not be given
    bad = bad.replace(positions=positions)
    record = run_job(Job("grid", "meshopt", 2), tmp_path / "cache", mesh=bad).record
    assert record["status"] == "failed"
    assert record["error"] == ("simplify.mjs refused the request: position component 10 is "
                               "not finite (NaN)")
    ok = run_job(Job("grid", "meshopt", 2), tmp_path / "cache", mesh=good).record
    assert ok["status"] == "ok", ok["error"]
    table = records_table([record, ok])
    assert table["library_error"].isna().tolist() == [True, False]
    assert table["library_error"].iloc[1] == ok["stats"]["library_error"]


# -- availability -------------------------------------------------------------------------

def test_rows_without_node_are_listed_unavailable_with_the_fix(monkeypatch):
    from importlib.metadata import entry_points

    monkeypatch.setenv("PATH", "/nonexistent")
    monkeypatch.delenv("BENCH_NODE", raising=False)
    eps = [ep for ep in entry_points(group="bench.methods")
           if ep.name in {*VARIANTS, "gltfpack", "qslim"}]
    methods = Registry("method", eps)
    for name in [*VARIANTS, "gltfpack"]:
        entry = methods.entry(name)
        assert not entry.available
        assert entry.problem == (
            "needs Node.js (node not found on PATH); install with: sudo apt-get install nodejs "
            f"npm && npm ci --prefix {NODE_DIR}  (or: bash scripts/setup.sh --no-run)")
    assert methods.entry("qslim").available

    from bench.commands.run import _default_methods_line
    line = _default_methods_line(methods, ["qslim"], {})
    assert "meshopt (unavailable: needs Node.js" in line


def test_a_wrong_package_version_is_unavailable(tmp_path, monkeypatch):
    import methods.meshopt as module

    fake = tmp_path / "node_modules" / "meshoptimizer"
    fake.mkdir(parents=True)
    (fake / "package.json").write_text('{"version": "0.22.0"}')
    monkeypatch.setattr(module, "NODE_DIR", tmp_path)
    assert node_problem() == ("needs meshoptimizer 1.3.0 from npm (version 0.22.0 is "
                              f"installed); install with: npm ci --prefix {tmp_path}")
    assert "(it is not installed)" in node_problem("gltfpack")


def test_a_dead_worker_is_replaced_on_the_next_call():
    run_method(Meshopt(), strip(), 2)
    first = _WORKER._proc
    first.kill()
    first.wait()
    out = run_method(Meshopt(), strip(), 2)
    assert out.mesh.n_faces == 2
    assert _WORKER._proc is not first and _WORKER._proc.poll() is None
