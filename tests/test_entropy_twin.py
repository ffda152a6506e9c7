"""Tests for entropy-twin (González et al. 2008) and the viewpoint-entropy term.

Each against an independent computation or a count made by hand:

* the entropy of hand-made face-id buffers (log 2, log 3, with and without background),
  by the NumPy oracle and by the numba kernels of the engine's state;
* the incrementally kept pixel counts and entropies equal those of a from-scratch
  render after K collapses, and the NumPy entropy of a fresh
  :func:`methods.imaging.raster.face_id_buffers` render of the extracted mesh;
* the cost of a collapse is the brute-force sum over views of |H_v after - H_v before|;
* no seam opens on the crate, the two-material barrel and the textured bunny;
* the twin, fake and translated collapses of Algorithm 2 on the crate, counted by hand
  (a known collapse sequence) and by a NumPy replay of the collapse log;
* the α, β texture-coordinate correction reproduces an affine texture map exactly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.catalog.gamemodels import make_barrel, make_crate
from bench.core.errors import ParamError
from bench.core.mesh import Mesh
from conftest import blob
from methods.engine.policy import Policy
from methods.engine.simplify import simplify_mesh
from methods.engine.wedges import barycentric_uv
from methods.entropy_twin import EntropyTwin, entropy_term, rebuild_normals, viewpoint_entropy
from methods.imaging.entropy import entropy_init, view_entropy
from methods.imaging.raster import face_id_buffers
from methods.imaging.state import entropy_state
from metrics.topology import seam_cracks

RES = 48
HALF_EDGE = Policy(placement="endpoints", quadric_weight=0.0, boundary_weight=0.0,
                   seam_rule=False, boundary_rule=True)


def _kernel_entropy(ids, background):
    """Entropies by the engine's numba kernels (entropy_init + view_entropy)."""
    ids = np.asarray(ids, np.int64)
    ent = entropy_state(len(ids), int(ids.max()) + 1, True, background, False)
    entropy_init(ids, ent)
    return np.array([view_entropy(s, float(a)) for s, a in zip(ent.sums, ent.totals)])


# -- the entropy of hand-made configurations -------------------------------------------

#: view 0: faces 0 and 1, four pixels each, no background
#: view 1: face 0 on the top row, background on the bottom row
#: view 2: faces 0, 1, 2 and the background, two pixels each
#: view 3: background only
HAND = np.array([[[0, 0, 1, 1], [0, 0, 1, 1]],
                 [[0, 0, 0, 0], [-1, -1, -1, -1]],
                 [[0, 0, 1, 1], [2, 2, -1, -1]],
                 [[-1, -1, -1, -1], [-1, -1, -1, -1]]])


@pytest.mark.parametrize("entropy", [viewpoint_entropy, _kernel_entropy])
def test_entropy_of_hand_made_configurations(entropy):
    with_bg = entropy(HAND, background=True)
    without = entropy(HAND, background=False)
    assert with_bg == pytest.approx([math.log(2), math.log(2), math.log(4), 0.0], abs=1e-12)
    assert without == pytest.approx([math.log(2), 0.0, math.log(3), 0.0], abs=1e-12)


# -- incremental entropy ------------------------------------------------------------------

def _run(mesh, background, collapses, target=4):
    term = entropy_term(mesh, resolution=RES, background=background)
    return term, simplify_mesh(mesh, target, HALF_EDGE, verify=True, image=term,
                               max_collapses=collapses)


@pytest.mark.parametrize("background", [True, False])
def test_incremental_entropy_equals_a_fresh_render(background):
    mesh = blob()
    term, result = _run(mesh, background, collapses=150)
    s = result.stats
    assert s["collapses"] == 150
    assert s["face_id_mismatched_pixels"] == 0 and s["depth_mismatched_pixels"] == 0
    assert s["entropy_count_mismatches"] == 0  # the per-face pixel counts, exactly
    assert s["entropy_max_error"] < 1e-9
    assert "image_mismatched_pixels" not in s  # luminance is not kept in entropy mode
    assert result.images is None  # nor returned
    # an independent render of the extracted mesh in world coordinates; rounding of the
    # projection may move a few edge pixels
    oracle = viewpoint_entropy(face_id_buffers(result.mesh, term.cameras, RES, RES),
                               background)
    assert np.asarray(s["view_entropy"]) == pytest.approx(oracle, abs=0.02)
    assert oracle != pytest.approx(viewpoint_entropy(
        face_id_buffers(mesh, term.cameras, RES, RES), background), abs=0.02)


@pytest.mark.parametrize("background", [True, False])
def test_cost_is_the_sum_of_absolute_entropy_changes(background):
    mesh = blob()
    for k in (0, 9, 40):
        _, before = _run(mesh, background, collapses=k)
        _, after = _run(mesh, background, collapses=k + 1)
        brute = np.abs(np.subtract(after.stats["view_entropy"],
                                   before.stats["view_entropy"])).sum()
        assert after.log["cost"][k] == pytest.approx(brute, rel=1e-7, abs=1e-12)
        assert brute > 0


# -- duplicated vertices: no seam opens ---------------------------------------------------

def _boundary_follows_the_original(original, result):
    """Every boundary edge of the result joins two vertices of one boundary loop of the
    original (half-edge collapses keep positions, so vertices are matched exactly)."""
    ow, rw = original.welded, result.welded
    edges = ow.edges[ow.boundary]
    loop = np.arange(ow.n_vertices)
    for _ in range(ow.n_vertices):  # label propagation along boundary edges
        lo = np.minimum(loop[edges[:, 0]], loop[edges[:, 1]])
        if np.array_equal(loop[edges[:, 0]], lo) and np.array_equal(loop[edges[:, 1]], lo):
            break
        np.minimum.at(loop, edges[:, 0], lo)
        np.minimum.at(loop, edges[:, 1], lo)
    on_boundary = np.zeros(ow.n_vertices, bool)
    on_boundary[edges.reshape(-1)] = True
    index = {tuple(p): i for i, p in enumerate(ow.positions)}
    for a, b in rw.edges[rw.boundary]:
        i, j = index[tuple(rw.positions[a])], index[tuple(rw.positions[b])]
        if not (on_boundary[i] and on_boundary[j] and loop[i] == loop[j]):
            return False
    return True


@pytest.mark.parametrize("make,target", [(make_crate, 100), (make_barrel, 100)])
def test_no_seam_opens_on_game_meshes(make, target):
    mesh = make()
    result = EntropyTwin(resolution=64).simplify(mesh, target)
    assert result.mesh.n_faces in (target - 1, target)
    summary = result.mesh.summary()
    assert summary["boundary_edges"] == 0 and summary["non_manifold_edges"] == 0
    assert seam_cracks(mesh, result.mesh) == 0
    s = result.stats
    assert s["twin_collapses"] > 0  # seam edges went with their twins
    # each kind is a subset of the collapses, and a fake collapse translates at least
    # one duplicate
    assert s["twin_collapses"] <= s["collapses"] and s["fake_collapses"] <= s["collapses"]
    assert s["fake_collapses"] <= s["translated_duplicates"]


def test_no_seam_opens_on_the_textured_bunny(bunny_textured):
    result = EntropyTwin(resolution=64).simplify(bunny_textured, 1000)
    assert result.mesh.n_faces in (999, 1000)
    assert seam_cracks(bunny_textured, result.mesh) == 0
    assert _boundary_follows_the_original(bunny_textured, result.mesh)
    s = result.stats
    assert 0 < s["fake_collapses"] <= s["translated_duplicates"]
    assert "fake_vertices" not in s and "real_collapses" not in s  # no constant stats


def test_a_mesh_without_duplicates_has_no_twin_or_fake_collapses():
    result = EntropyTwin(resolution=RES, normals_angle=-1).simplify(blob(), 100)
    assert result.stats["twin_collapses"] == 0 and result.stats["fake_collapses"] == 0
    assert result.mesh.normals is None
    assert result.stats["presimplified_faces"] == 320  # below 20 x the target: untouched


def test_the_move_bound_is_a_multiple_of_the_target_face_size():
    """move_bound x sqrt(surface area / target faces), as a fraction of the diagonal:
    a unit square in two triangles (area 1, diagonal sqrt 2) at a target of 4 faces has
    faces of size 1/2."""
    square = Mesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float),
                  np.array([[0, 1, 2], [0, 2, 3]]))
    assert EntropyTwin().max_move(square, 4) == pytest.approx(0.7 * 0.5 / math.sqrt(2))
    twice = EntropyTwin(move_bound=1.4)
    assert twice.max_move(square, 1) == pytest.approx(1.4 / math.sqrt(2))
    assert twice.policy(False, 0.25).max_move == 0.25


def test_a_mesh_without_area_has_no_move_bound():
    """Its faces have no size to bound a move by: it simplifies as without the bound
    (as version 3 did: stopped at 2 faces), not with an error about max_move."""
    line = Mesh(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], float),
                np.array([[0, 1, 2], [1, 2, 3]]))
    assert EntropyTwin().max_move(line, 1) == math.inf
    result = EntropyTwin(resolution=RES).simplify(line, 1)
    assert result.mesh.n_faces == 2 and "no valid collapse" in result.stop_reason


def test_large_meshes_are_presimplified_to_twenty_times_the_target():
    mesh = blob(3)  # 1,280 faces
    result = EntropyTwin(resolution=RES).simplify(mesh, 40)
    assert result.stats["presimplified_faces"] in (799, 800)
    assert result.mesh.n_faces in (39, 40)
    off = EntropyTwin(resolution=RES, presimplify_faces=-1).simplify(mesh, 40)
    assert off.stats["presimplified_faces"] == 1280


# -- twin and translated collapses, counted by hand --------------------------------------

def _kinds_by_replay(mesh, log):
    """Algorithm 2's kinds of every logged collapse, by replaying the log on the input's
    faces in NumPy (an oracle for the engine's counters).

    For a collapse of u into v: the faces holding both are removed, and each gives the
    pair (u's wedge, v's wedge) in it; the collapse is a *twin* one when there are two
    distinct pairs (the real edge and its twin). A wedge of u in a surviving face that
    is no pair's first is *translated* onto v (a *fake* collapse in the paper's words).
    Paired wedges of u become v's; the rest keep their identity.

    Returns
    -------
    ndarray of shape (collapses, 3) int
        Per collapse: twin (0/1), fake (0/1), translated wedges.
    """
    F = mesh.welded.faces.astype(np.int64).copy()
    FW = mesh.faces.astype(np.int64).copy()
    alive = np.ones(len(F), bool)
    out = []
    for k, (u, v) in enumerate(zip(log["removed"], log["kept"])):
        has_u = alive & (F == u).any(axis=1)
        both = has_u & (F == v).any(axis=1)
        removed = log["removed_faces"][k]
        assert set(removed[removed >= 0]) == set(np.flatnonzero(both))
        pairs = {}
        for f in np.flatnonzero(both):
            pair = (FW[f][F[f] == u][0], FW[f][F[f] == v][0])
            pairs.setdefault(pair, None)
        to = {}
        for a, b in pairs:
            to.setdefault(a, b)
        moved = np.flatnonzero(has_u & ~both)
        translated = {FW[f][F[f] == u][0] for f in moved} - set(to)
        out.append((int(len(pairs) >= 2), int(bool(translated)), len(translated)))
        alive[both] = False
        for f in moved:
            e = np.flatnonzero(F[f] == u)[0]
            F[f, e] = v
            FW[f, e] = to.get(FW[f, e], FW[f, e])
    return np.array(out, np.int64).reshape(-1, 3)


#: make_crate(2), one corner of the box with its three faces unfolded (each box face a
#: 2 x 2 grid and its own UV chart, so the box edges are seams)::
#:
#:              C-----m-----C
#:              |     |     |       C  box corner: 3 render vertices (one per chart)
#:              m-----o-----m  +z   m  box-edge midpoint: 2 (one per chart)
#:              |     |     |       o  face centre: 1
#:        C-----m-----C-----m-----C
#:        |     |     |     |     |
#:        m--o--m  -y |  +x m--o--m
#:        |     |     |     |     |
#:        C-----m-----C-----m-----C
#:
#: 8 corners, 12 midpoints, 6 centres: 26 welded and 54 render vertices, 48 faces.
QUADRIC_HALF_EDGE = Policy(placement="endpoints", max_normal_rotation=180.0, seam_rule=False)


def test_collapse_kinds_on_the_crate_by_hand():
    """make_crate(2) to 10 faces by half-edge collapses under the plain quadric: 19
    collapses, of which 13 twin, 1 fake, 1 duplicate translated.

    The hand count. A centre's quadric holds one plane (its box face), a midpoint's the
    two planes of its box edge, a corner's three; so the collapses of zero cost are a
    centre into any neighbour (all in its chart) and a midpoint along its box edge into
    a corner, and every other collapse costs more. The engine takes these 18 first, in
    some order; each leaves the others' zero cost intact (48 - 2 * 18 = 12 faces: the
    cube of make_crate(1)):

    - a centre (1 wedge) into v: its faces are all in one chart, so one wedge pair, no
      twin, and nothing left at u: (0, 0, 0), six times;
    - a midpoint m into a corner along the box edge between charts A and B: the two
      removed faces are one of A and one of B, so the pairs (m_A, C_A) and (m_B, C_B)
      are distinct, a twin collapse; both of m's wedges are paired: (1, 0, 0), twelve
      times.

    The 19th is a corner u into a corner v along a box edge (it leaves one plane of u;
    across a face diagonal it would leave two): a twin as above, and u's wedge on the
    third box face, where v is not, has no partner and is translated: (1, 1, 1).
    """
    mesh = make_crate(2)
    s = mesh.summary()
    assert (s["faces"], s["welded_vertices"], s["render_vertices"]) == (48, 26, 54)
    result = simplify_mesh(mesh, 10, QUADRIC_HALF_EDGE)
    stats, log = result.stats, result.log
    assert stats["collapses"] == 19 and result.mesh.n_faces == 10
    assert (stats["twin_collapses"], stats["stranded_collapses"],
            stats["stranded_wedges"]) == (13, 1, 1)
    # which vertex went, by its place on the box: the count of its coordinates at +-1
    on_box = (np.abs(mesh.welded.positions[log["removed"]]) == 1.0).sum(axis=1)
    assert sorted(on_box[:18]) == [1] * 6 + [2] * 12 and on_box[18] == 3
    assert np.all(log["cost"][:18] < 1e-12) and log["cost"][18] > 1e-6
    kinds = _kinds_by_replay(mesh, log)
    expected = {1: (0, 0, 0), 2: (1, 0, 0), 3: (1, 1, 1)}
    assert [tuple(k) for k in kinds] == [expected[n] for n in on_box]


@pytest.mark.parametrize("n,target", [(2, 6), (3, 30)])
def test_engine_counts_collapse_kinds_as_the_replay_does(n, target):
    """Down to a few faces the crate's corners collapse across faces too (fake collapses
    with two translated wedges): the engine's counters equal the NumPy replay's sums."""
    mesh = make_crate(n)
    result = simplify_mesh(mesh, target, QUADRIC_HALF_EDGE)
    kinds = _kinds_by_replay(mesh, result.log)
    s = result.stats
    assert len(kinds) == s["collapses"]
    assert tuple(kinds.sum(axis=0)) == (s["twin_collapses"], s["stranded_collapses"],
                                        s["stranded_wedges"])


def test_entropy_twin_reports_the_kinds_of_its_one_collapse():
    """entropy-twin takes the cube make_crate(1) from 12 to 10 faces: one collapse.

    The hand count. Each of the 8 corners has 3 render vertices (one per box face, 24 in
    all), and every edge is a box edge (two charts) or a face diagonal (one chart):

    - a box edge u -> v between charts A and B removes a face of A and one of B: two
      distinct wedge pairs, a twin collapse; u's wedge on the third face (where v is not)
      is translated: twin 1, fake 1, translated 1; v's position then holds 3 + 1
      render vertices, 22 in all;
    - a face diagonal u -> v in chart A removes two faces of A: one pair, no twin; u's
      wedges on its two other faces are translated: twin 0, fake 1, translated 2; v's
      position holds 3 + 2 render vertices, 23 in all.

    The engine's choice is read from the output: the position with more than three
    render vertices is v.
    """
    mesh = make_crate(1)
    assert (mesh.n_faces, mesh.n_vertices, mesh.welded.n_vertices) == (12, 24, 8)
    result = EntropyTwin(resolution=RES, normals_angle=-1).simplify(mesh, 10)
    out, s = result.mesh, result.stats
    assert s["collapses"] == 1 and out.n_faces == 10
    _, per_position = np.unique(out.positions, axis=0, return_counts=True)
    assert len(per_position) == 7
    extra = int(per_position.max()) - 3
    assert sorted(per_position) == [3] * 6 + [3 + extra]
    assert out.n_vertices == 21 + extra
    hand = {1: (1, 1, 1), 2: (0, 1, 2)}  # box edge, face diagonal
    assert extra in hand
    assert (s["twin_collapses"], s["fake_collapses"], s["translated_duplicates"]) == hand[extra]


# -- texture-coordinate correction ----------------------------------------------------------

def test_barycentric_uv_is_exact_inside_a_planar_textured_triangle():
    rng = np.random.default_rng(7)
    A, t = rng.standard_normal((2, 3)), rng.standard_normal(2)  # an affine texture map
    tri = rng.standard_normal((3, 3))
    uv = tri @ A.T + t
    normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    out = np.empty(2)
    for w in rng.dirichlet(np.ones(3), size=20):
        q = w @ tri
        depth = barycentric_uv(q, tri[0], tri[1], tri[2], uv[0], uv[1], uv[2], out)
        assert out == pytest.approx(q @ A.T + t, abs=1e-12)
        assert depth == pytest.approx(w.min(), abs=1e-12)
        # the offset along the normal (γ) is dropped
        barycentric_uv(q + 0.3 * normal, tri[0], tri[1], tri[2], uv[0], uv[1], uv[2], out)
        assert out == pytest.approx(q @ A.T + t, abs=1e-12)
    outside = 1.5 * tri[1] - 0.5 * tri[0]
    assert barycentric_uv(outside, tri[0], tri[1], tri[2], uv[0], uv[1], uv[2], out) < 0
    flat = np.array([tri[0], tri[0], tri[1]])
    assert barycentric_uv(q, flat[0], flat[1], flat[2], uv[0], uv[1], uv[2], out) == -np.inf


def _two_charts(n=12):
    """A flat n x n grid in z = 0 cut along x = 0.5 into two UV charts with different
    affine maps; the seam's vertices are duplicated (one render vertex per chart)."""
    s = np.linspace(0.0, 1.0, n + 1)
    x, y = np.meshgrid(s, s, indexing="xy")
    grid = np.stack([x, y, np.zeros_like(x)], -1).reshape(-1, 3)
    maps = (np.array([[0.4, 0.1], [-0.1, 0.5]]), np.array([[-0.3, 0.2], [0.25, 0.6]]))
    shifts = (np.array([0.05, 0.1]), np.array([0.9, 0.2]))
    positions, uvs, faces = [], [], []
    for chart in (0, 1):
        base = len(positions) and sum(len(p) for p in positions)
        positions.append(grid)
        uvs.append(grid[:, :2] @ maps[chart].T + shifts[chart])
        i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
        keep = (i < n // 2) if chart == 0 else (i >= n // 2)
        v = (j * (n + 1) + i)[keep]
        quad = np.stack([v, v + 1, v + n + 2, v + n + 1], -1) + base
        faces.append(np.concatenate([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]]))
    mesh = Mesh(np.concatenate(positions), np.concatenate(faces).astype(np.int32),
                uv=np.concatenate(uvs))
    used = np.unique(mesh.faces)
    remap = np.full(len(mesh.positions), -1)
    remap[used] = np.arange(len(used))
    mesh = Mesh(mesh.positions[used], remap[mesh.faces].astype(np.int32), uv=mesh.uv[used])
    return mesh, maps, shifts


def _chart_error(mesh, maps, shifts):
    """Per face, the largest UV error of its corners under the better of the two maps."""
    p, uv = mesh.positions[mesh.faces][..., :2], mesh.uv[mesh.faces]
    errors = [np.abs(uv - (p @ M.T + t)).max(axis=(1, 2)) for M, t in zip(maps, shifts)]
    return np.minimum(*errors)


def test_uv_correction_keeps_an_affine_texture_map_exact():
    mesh, maps, shifts = _two_charts()
    assert mesh.summary()["seam_edges"] == 12 and _chart_error(mesh, maps, shifts).max() < 1e-12
    fixed = EntropyTwin(resolution=RES, normals_angle=-1).simplify(mesh, 60)
    plain = EntropyTwin(resolution=RES, normals_angle=-1, uv_correction=False).simplify(mesh, 60)
    assert fixed.stats["fake_collapses"] > 0  # seam duplicates were translated
    assert _chart_error(fixed.mesh, maps, shifts).max() < 1e-9
    assert _chart_error(plain.mesh, maps, shifts).max() > 1e-3


# -- normals (Algorithm 3) -----------------------------------------------------------------

def test_normals_rebuilt_with_an_angle_threshold():
    box = trimesh.creation.box()
    cube = Mesh(box.vertices, box.faces.astype(np.int32))
    hard = rebuild_normals(cube, 60.0)
    assert hard.n_vertices == 24  # every corner split into its three faces' normals
    corner_normals = hard.normals[hard.faces]
    assert np.allclose(corner_normals, hard.face_normals[:, None, :])
    smooth = rebuild_normals(cube, 180.0)
    assert smooth.n_vertices == 8
    sphere = trimesh.creation.icosphere(2)
    ball = rebuild_normals(Mesh(sphere.vertices, sphere.faces.astype(np.int32)))
    assert ball.n_vertices == len(sphere.vertices)
    assert np.einsum("ij,ij->i", ball.normals, sphere.vertices).min() > 0.99
    crate = rebuild_normals(make_crate(2))
    assert np.allclose(crate.normals[crate.faces], crate.face_normals[:, None, :])
    with pytest.raises(ValueError, match="normals angle"):
        rebuild_normals(cube, 200.0)


# -- models and parameters ---------------------------------------------------------------------

def test_game_models_duplicate_vertices_where_attributes_change():
    crate = make_crate(12)
    s = crate.summary()
    assert (s["faces"], s["render_vertices"], s["welded_vertices"]) == (1728, 1014, 866)
    assert s["seam_edges"] == 12 * 12 and s["boundary_edges"] == 0  # 12 box edges
    barrel = make_barrel(32, 12, 6)
    s = barrel.summary()
    assert s["faces"] == 2 * 32 * 12 + 2 * 32 * 11 and s["boundary_edges"] == 0
    # the two lid rims (32 edges each) and the body's wrap-around line (12 edges)
    assert s["seam_edges"] == 2 * 32 + 12
    assert barrel.metadata["material_faces"] == (768, 704)
    assert np.array_equal(make_barrel().texture, barrel.texture)


@pytest.mark.parametrize("params,message", [
    ({"views": 0}, "views"), ({"resolution": 4}, "resolution"),
    ({"normals_angle": 181}, "normals_angle"), ({"canny_weight": -1}, "canny_weight"),
    ({"max_normal_rotation": 0}, "max_normal_rotation"),
    ({"presimplify_faces": -2}, "presimplify_faces")])
def test_bad_parameters_are_clear_errors(params, message):
    with pytest.raises(ParamError, match=message):
        EntropyTwin(**params).simplify(blob(1), 40)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31), st.integers(0, 30), st.integers(0, 30), st.integers(1, 34),
       st.integers(1, 20), st.booleans())
def test_a_rectangles_entropy_change_is_the_recounted_one(seed, c0, r0, cols, rows,
                                                          background):
    """``_entropy_change`` over a rectangle gives the change of the viewpoint entropy
    recounted from both whole images, and with ``commit`` leaves the counts of the new
    image."""
    from methods.imaging.entropy import _entropy_change, entropy_init
    from methods.imaging.state import entropy_state

    rng = np.random.default_rng(seed)
    m, size = 12, 64
    before = rng.integers(-1, m, (2, size, size)).astype(np.int32)
    before[1] = before[0][::-1]
    c1, r1 = min(c0 + cols, size) - 1, min(r0 + rows, size) - 1
    ids = np.full((size, size), -7, np.int32)  # rectangle-relative; the rest unused
    region = before[1, r0:r1 + 1, c0:c1 + 1].copy()
    change = rng.random(region.shape) < rng.choice([0.0, 0.05, 0.5])
    region[change] = rng.integers(-1, m, np.count_nonzero(change))
    ids[:r1 - r0 + 1, :c1 - c0 + 1] = region
    after = before.copy()
    after[1, r0:r1 + 1, c0:c1 + 1] = region
    ent = entropy_state(2, m, on=True, background=background)
    entropy_init(before, ent)
    rect = np.array([c0, c1, r0, r1])
    dh = _entropy_change(1, rect, ids, before, ent, True)
    old, new = viewpoint_entropy(before, background), viewpoint_entropy(after, background)
    assert dh == pytest.approx(new[1] - old[1], abs=1e-12)
    again = entropy_state(2, m, on=True, background=background)
    entropy_init(after, again)
    assert np.array_equal(ent.counts, again.counts)
    assert np.array_equal(ent.totals, again.totals)
