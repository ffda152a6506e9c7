"""The edge-collapse engine on tiny hand-built meshes with exact expectations, its
invariants (lazy queue, incremental quadrics, collapse log), and its numba kernels
against slow NumPy versions."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from bench.core.mesh import Mesh
from methods.corners import corner_lists
from methods.engine.policy import Policy
from methods.engine.simplify import simplify_mesh
from methods.engine.terms.quadric import (
    _boundary_corners,
    _optimal_point,
    best_of_ends,
    face_quadrics,
    initial_quadrics,
    quadric_error,
)


def grid(n: int, z=lambda x, y: 0.0 * x):
    """An n×n grid of quads over [0, 1]², split into triangles, counter-clockwise::

        (0,1) +---+---+ (1,1)
              | / | / |
              +---+---+
              | / | / |
        (0,0) +---+---+ (1,0)
    """
    xs = np.linspace(0, 1, n + 1)
    x, y = np.meshgrid(xs, xs, indexing="ij")
    positions = np.stack([x, y, z(x, y)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).reshape(-1)
    b, c, d = a + (n + 1), a + (n + 1) + 1, a + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return positions, faces


def cube(n: int) -> Mesh:
    """A unit cube, each side an n×n grid, welded (closed, outward)."""
    positions, faces = [], []
    base, f2 = grid(n)
    for axis in range(3):
        for side in (0.0, 1.0):
            p = np.insert(base[:, :2], axis, side, axis=1)
            f = f2 if (side == 1.0) == (axis != 1) else f2[:, ::-1]
            faces.append(f + len(positions) * len(base))
            positions.append(p)
    positions = np.concatenate(positions)
    faces = np.concatenate(faces)
    # weld equal positions so the cube is one closed surface
    unique, inverse = np.unique(positions.round(12), axis=0, return_inverse=True)
    return Mesh(unique, inverse.reshape(-1)[faces])


def test_planar_grid_collapses_to_two_faces_with_zero_error():
    positions, faces = grid(4)  # 32 faces, flat
    result = simplify_mesh(Mesh(positions, faces), 2)
    assert result.stop_reason is None
    assert result.mesh.n_faces == 2
    corners = {(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)}
    got = {tuple(np.round(p[:2], 12)) for p in result.mesh.positions}
    assert got == corners
    assert np.all(result.mesh.positions[:, 2] == 0.0)


def test_cube_keeps_its_eight_corners():
    mesh = cube(3)  # 108 faces
    signed = np.einsum("ij,ij->i", mesh.positions[mesh.faces[:, 0]],
                       np.cross(mesh.positions[mesh.faces[:, 1]], mesh.positions[mesh.faces[:, 2]]))
    assert signed.sum() > 0  # outward
    result = simplify_mesh(mesh, 12)
    assert result.mesh.n_faces == 12
    got = {tuple(np.round(p, 9)) for p in result.mesh.positions}
    assert got == set(itertools.product((0.0, 1.0), repeat=3))
    assert result.mesh.welded.boundary.sum() == 0


def test_two_uv_charts_keep_both_charts_and_no_crack():
    """A flat 4×4 grid whose left and right halves are separate UV charts: the middle
    column of vertices is duplicated (a seam), left chart UVs in [0, 0.4], right chart
    in [0.6, 1]::

        +--+--+||+--+--+      || = seam (vertices stored twice)
        |  |  ||   |  |
        +--+--+||+--+--+
    """
    positions, faces = grid(4)
    x = positions[:, 0]
    right_faces = positions[faces].mean(axis=1)[:, 0] > 0.5
    seam = np.flatnonzero(np.isclose(x, 0.5))
    copies = np.arange(len(positions), len(positions) + len(seam))
    remap = np.arange(len(positions))
    remap[seam] = copies
    faces = faces.copy()
    faces[right_faces] = remap[faces[right_faces]]
    positions = np.concatenate([positions, positions[seam]])
    uv = np.where((np.arange(len(positions)) >= len(x))[:, None] | (positions[:, :1] > 0.5),
                  np.column_stack([0.6 + 0.8 * (positions[:, 0] - 0.5), positions[:, 1]]),
                  np.column_stack([0.8 * positions[:, 0], positions[:, 1]]))
    mesh = Mesh(positions, faces, uv=uv)
    assert mesh.welded.seam.sum() == 4
    result = simplify_mesh(mesh, 4)
    out = result.mesh
    w = out.welded
    assert out.n_faces == 4
    assert w.seam.sum() >= 1  # the seam survives as a seam, not a crack
    # every boundary edge lies on the outer square
    b = w.positions[w.edges[w.boundary]]
    on_outer = np.all((np.isclose(b[..., 0], 0) | np.isclose(b[..., 0], 1))
                      | (np.isclose(b[..., 1], 0) | np.isclose(b[..., 1], 1)), axis=1)
    assert on_outer.all()
    centroid_x = out.positions[out.faces].mean(axis=1)[:, 0]
    face_u = out.uv[out.faces].mean(axis=1)[:, 0]
    assert np.all(face_u[centroid_x < 0.5] <= 0.4 + 1e-12)  # left chart stays left
    assert np.all(face_u[centroid_x > 0.5] >= 0.6 - 1e-12)


def test_tetrahedron_stops_at_four_faces_and_says_why():
    """   3
         /|\\     every collapse would leave two faces sharing three vertices
        0-+-2
         \\|/
          1"""
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    faces = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    result = simplify_mesh(Mesh(positions, faces), 2)
    assert result.mesh.n_faces == 4
    assert "no valid collapse remains at 4 faces" in result.stop_reason
    assert "duplicate face" in result.stop_reason
    assert result.stats["collapses"] == 0


def test_lazy_costs_equal_fresh_costs_when_popped(bunny_textured):
    result = simplify_mesh(bunny_textured, 500, verify=True)
    assert result.stats["lazy_mismatches"] == 0
    assert result.stats["collapses"] > 2000


def test_incremental_quadrics_equal_recomputed(bunny_textured):
    policy = Policy()
    result = simplify_mesh(bunny_textured, 2000, policy)
    w = bunny_textured.welded
    lo = w.positions.min(axis=0)  # the engine works at unit diagonal
    P = (w.positions - lo) / bunny_textured.diagonal
    expected = initial_quadrics(P, w.faces.astype(np.int64), _boundary_corners(bunny_textured),
                                policy.boundary_weight)
    for removed, kept in zip(result.log["removed"], result.log["kept"]):
        expected[kept] += expected[removed]
    alive = result.vertex_alive
    np.testing.assert_allclose(result.quadrics[alive], expected[alive], rtol=1e-9, atol=1e-15)


def test_collapse_log_replays_to_the_result(bunny_textured):
    """Applying the log to the original welded faces gives the final faces."""
    result = simplify_mesh(bunny_textured, 1500)
    faces = bunny_textured.welded.faces.astype(np.int64).copy()
    alive = np.ones(len(faces), bool)
    log = result.log
    for i, (u, v) in enumerate(zip(log["removed"], log["kept"])):
        for f in log["removed_faces"][i]:
            if f >= 0:
                alive[f] = False
        for f in log["changed_faces"][log["changed_start"][i]:log["changed_start"][i + 1]]:
            faces[f][faces[f] == u] = v
    assert alive.sum() == result.mesh.n_faces
    replay = {tuple(sorted(f)) for f in faces[alive].tolist()}
    final = result.mesh.welded
    # compare by positions (welded indices are renumbered in the result)
    key = lambda pos: tuple(np.round(pos, 9))
    positions = bunny_textured.welded.positions.copy()
    for i, v in enumerate(log["kept"]):
        positions[v] = log["position"][i]
    replayed = {tuple(sorted(key(positions[j]) for j in f)) for f in replay}
    got = {tuple(sorted(key(final.positions[j]) for j in f)) for f in final.faces.tolist()}
    assert replayed == got


def test_seams_never_open_on_the_textured_bunny(bunny_textured):
    from metrics.topology import seam_cracks

    out = simplify_mesh(bunny_textured, 300).mesh
    assert seam_cracks(bunny_textured, out) == 0
    assert out.welded.non_manifold.sum() == 0


def test_boundary_lock_keeps_boundary_vertices():
    positions, faces = grid(6)
    mesh = Mesh(positions, faces)
    out = simplify_mesh(mesh, 10, Policy(boundary_lock=True))
    boundary = {tuple(p) for p in positions[np.unique(mesh.boundary_edges)]}
    got = {tuple(p) for p in out.mesh.positions}
    assert boundary <= got
    assert "boundary lock" in out.stop_reason


def test_half_edge_collapses_keep_original_positions(bunny_textured):
    out = simplify_mesh(bunny_textured, 1000, Policy(placement="endpoints")).mesh
    original = {tuple(p) for p in bunny_textured.positions}
    assert all(tuple(p) in original for p in out.positions)


def test_target_below_one_is_an_error():
    positions, faces = grid(2)
    with pytest.raises(ValueError, match="at least 1"):
        simplify_mesh(Mesh(positions, faces), 0)
    with pytest.raises(ValueError, match="unknown placement"):
        Policy(placement="best")


# -- kernels against NumPy ------------------------------------------------------------------

def _numpy_quadrics(P, F):
    Q = np.zeros((len(P), 4, 4))
    for f in F:
        n = np.cross(P[f[1]] - P[f[0]], P[f[2]] - P[f[0]])
        area = np.linalg.norm(n) / 2
        n = n / np.linalg.norm(n)
        plane = np.append(n, -n @ P[f[0]])
        for v in f:
            Q[v] += area * np.outer(plane, plane)
    return Q


def _unpack(q):
    iu = np.triu_indices(4)
    m = np.zeros((4, 4))
    m[iu] = q
    return m + np.triu(m, 1).T


def test_face_quadrics_and_error_match_numpy():
    rng = np.random.default_rng(3)
    P = rng.normal(size=(6, 3))
    F = np.array([[0, 1, 2], [2, 3, 4], [1, 4, 5], [0, 5, 3]])
    Q = face_quadrics(P, F, np.ones(len(F), bool))
    ref = _numpy_quadrics(P, F)
    for v in range(len(P)):
        np.testing.assert_allclose(_unpack(Q[v]), ref[v], rtol=1e-12, atol=1e-14)
        p = rng.normal(size=3)
        h = np.append(p, 1.0)
        assert np.isclose(quadric_error(Q[v], p), h @ ref[v] @ h, rtol=1e-12)


def test_optimal_point_matches_linear_solve_and_falls_back():
    rng = np.random.default_rng(5)
    planes = rng.normal(size=(5, 4))
    M = sum(np.outer(p, p) for p in planes)
    q = M[np.triu_indices(4)]
    out = np.empty(3)
    expected = np.linalg.solve(M[:3, :3], -M[:3, 3])
    err = _optimal_point(q, expected - 0.5, expected + 0.5, out)  # an edge around it
    np.testing.assert_allclose(out, expected, rtol=1e-9)
    assert np.isclose(err, np.append(expected, 1) @ M @ np.append(expected, 1))
    # a minimiser farther from the edge's midpoint than the edge is long is not taken
    far_a, far_b = expected + 10.0, expected + 10.1
    _optimal_point(q, far_a, far_b, out)
    assert any(np.array_equal(out, c) for c in (far_a, far_b, 0.5 * (far_a + far_b)))
    # one plane only: singular, so the best of the endpoints and the midpoint
    M1 = np.outer([0, 0, 1, -1.0], [0, 0, 1, -1.0])  # plane z = 1
    err = _optimal_point(M1[np.triu_indices(4)], np.array([0, 0, 0.0]), np.array([0, 0, 1.0]), out)
    np.testing.assert_array_equal(out, [0, 0, 1])
    assert err == 0.0


def test_best_of_ends_takes_the_lowest_error_and_the_first_of_equal_ones():
    def plane(a, b, c, d):
        return np.outer([a, b, c, d], [a, b, c, d])[np.triu_indices(4)]

    pa, pb, out = np.array([0.0, 0, 0]), np.array([2.0, 0, 0]), np.empty(3)
    # x = 1 passes through the midpoint only
    assert best_of_ends(plane(1, 0, 0, -1.0), pa, pb, out) == 0.0
    np.testing.assert_array_equal(out, [1, 0, 0])
    # x = 2 holds b
    assert best_of_ends(plane(1, 0, 0, -2.0), pa, pb, out) == 0.0
    np.testing.assert_array_equal(out, pb)
    # y = 0 holds all three: a, the first tried
    assert best_of_ends(plane(0, 1, 0, 0.0), pa, pb, out) == 0.0
    np.testing.assert_array_equal(out, pa)
    # x = 1.5: b and the midpoint 0.25 apart, a 2.25: b, tried before the midpoint
    assert best_of_ends(plane(1, 0, 0, -1.5), pa, pb, out) == 0.25
    np.testing.assert_array_equal(out, pb)


def test_corner_lists_link_every_corner_once():
    F = np.array([[0, 1, 2], [2, 1, 3], [3, 1, 0]])
    vhead, cnext = corner_lists(F, 4)
    for v in range(4):
        corners = []
        c = vhead[v]
        while c != -1:
            corners.append(c)
            c = cnext[c]
        assert sorted(corners) == sorted(np.flatnonzero(F.reshape(-1) == v).tolist())


# -- Garland-Heckbert 1998 wedge quadrics --------------------------------------------------

def test_wedge_quadric_is_area_times_squared_distance_to_the_lifted_plane():
    from methods.engine.terms.quadric import wedge_quadrics

    rng = np.random.default_rng(11)
    P = rng.normal(size=(3, 3))
    uv = rng.uniform(size=(3, 2))
    F = np.array([[0, 1, 2]])
    WQ = wedge_quadrics(P, F, F, uv, 0.7)
    corners = np.column_stack([P, 0.7 * uv])  # (3, 5)
    basis = np.linalg.qr((corners[1:] - corners[0]).T)[0]  # orthonormal (5, 2)
    area = 0.5 * np.linalg.norm(np.cross(P[1] - P[0], P[2] - P[0]))
    for _ in range(5):
        x = rng.normal(size=5)
        d = x - corners[0]
        dist2 = d @ d - np.sum((basis.T @ d) ** 2)
        A, b, c = WQ[0, :25].reshape(5, 5), WQ[0, 25:30], WQ[0, 30]
        y = x / np.array([1, 1, 1, 0.7, 0.7])  # the quadric takes plain (x, y, z, u, v)
        assert np.isclose(y @ A @ y + 2 * b @ y + c, area * dist2, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(WQ[0], WQ[1])  # each corner's wedge gets the face's quadric


def test_reduced_wedge_quadric_is_the_minimum_over_uv():
    from methods.engine.terms.quadric import _add_reduced, _uv_minimiser

    rng = np.random.default_rng(12)
    M = rng.normal(size=(6, 6))
    H = M @ M.T  # positive definite over (x, y, z, u, v, 1)
    g = np.concatenate([H[:5, :5].reshape(-1), H[:5, 5], [H[5, 5]]])
    qsum = np.zeros(10)
    _add_reduced(g, np.zeros(2), qsum)
    p = rng.normal(size=3)
    best = np.empty(2)
    assert _uv_minimiser(g, p, np.zeros(2), best)
    x = np.concatenate([p, best, [1.0]])
    np.testing.assert_allclose(quadric_error(qsum, p), x @ H @ x, rtol=1e-9)
    for _ in range(20):  # and no other (u, v) does better
        y = np.concatenate([p, best + rng.normal(scale=0.1, size=2), [1.0]])
        assert y @ H @ y >= x @ H @ x - 1e-12


def affine(p):
    """An affine texture map of positions (the planar grids' UVs)."""
    return np.column_stack([0.2 + 0.5 * p[:, 0] + 0.1 * p[:, 1],
                            0.1 - 0.2 * p[:, 0] + 0.6 * p[:, 1]])


def affine_textured_grid():
    """A flat 8x8 grid with jittered inner vertices and UVs affine in position."""
    positions, faces = grid(8)
    inner = np.all((positions[:, :2] > 0) & (positions[:, :2] < 1), axis=1)
    positions[inner, :2] += np.random.default_rng(0).uniform(-0.04, 0.04, (inner.sum(), 2))
    return Mesh(positions, faces, uv=affine(positions)), affine


def test_texture_quadrics_keep_an_affine_texture_map_exact():
    """A flat, jittered grid whose UVs are affine in position has zero 5-D quadric error
    at the true UVs, so the UVs chosen by the wedge quadrics must be exact."""
    mesh, affine = affine_textured_grid()
    out = simplify_mesh(mesh, 40, Policy(texture_weight=1.0)).mesh
    np.testing.assert_allclose(out.uv, affine(out.positions), atol=1e-9)


def test_vertex_kind_rules_do_not_depend_on_the_order_of_an_edges_ends():
    """Each rule table mirrored (ends swapped) keeps the other end: the verdict on
    (a, b) is the verdict on (b, a) with first and second exchanged."""
    from methods.engine.policy import (
        BOUNDARY_RULE,
        END_KEEP_FIRST,
        END_KEEP_SECOND,
        SEAM_RULE,
        VERTEX_BOUNDARY,
        VERTEX_INTERIOR,
        VERTEX_ORDINARY,
        VERTEX_SEAM,
    )

    swap = {END_KEEP_FIRST: END_KEEP_SECOND, END_KEEP_SECOND: END_KEEP_FIRST}
    for table in (SEAM_RULE, BOUNDARY_RULE):
        for a, b in itertools.product(range(2), repeat=2):
            assert table[b, a] == swap.get(int(table[a, b]), int(table[a, b]))
    # the prose: a seam vertex stays when joined to an ordinary one; so does a boundary one
    assert SEAM_RULE[VERTEX_SEAM, VERTEX_ORDINARY] == END_KEEP_FIRST
    assert BOUNDARY_RULE[VERTEX_INTERIOR, VERTEX_BOUNDARY] == END_KEEP_SECOND


# -- wedge quadrics through collapses: a textured box ---------------------------------------

def _lifted_face_quadric(P, uv, w):
    """Area × squared distance in R^5 to the plane of a face lifted to (x, y, z, w·u,
    w·v), as (A, b, c) in plain (x, y, z, u, v): an orthonormal basis by QR, not the
    engine's Gram–Schmidt."""
    S = np.array([1.0, 1.0, 1.0, w, w])
    Y = np.column_stack([P, w * uv])  # (3, 5)
    B = np.linalg.qr((Y[1:] - Y[0]).T)[0]
    M = np.eye(5) - B @ B.T
    area = 0.5 * np.linalg.norm(np.cross(P[1] - P[0], P[2] - P[0]))
    return area * np.concatenate([(S[:, None] * M * S[None, :]).ravel(), -S * (M @ Y[0]),
                                  [Y[0] @ M @ Y[0]]])


def _reduced(g, uv_now):
    """The 3-D quadric (10 floats) of g minimised over (u, v), by NumPy's inverse."""
    A, b, c = g[:25].reshape(5, 5), g[25:30], g[30]
    inv = np.linalg.inv(A[3:, 3:])
    App = A[:3, :3] - A[:3, 3:] @ inv @ A[3:, :3]
    bp = b[:3] - A[:3, 3:] @ inv @ b[3:]
    cc = c - b[3:] @ inv @ b[3:]
    return np.array([App[0, 0], App[0, 1], App[0, 2], bp[0], App[1, 1], App[1, 2], bp[1],
                     App[2, 2], bp[2], cc])


def _engine_state(mesh, policy):
    """The engine's arrays, rules, terms and scratch for ``mesh`` before any collapse."""
    from methods.engine.simplify import _prepare, _quadrics, _rules, _terms
    from methods.engine.state import new_scratch

    prep = _prepare(mesh, policy, None)
    arrays = _quadrics(mesh, policy, prep)
    rules = _rules(mesh, policy, None, prep, 1, False, None)
    return prep, arrays, rules, _terms(policy, prep, None, rules), new_scratch(len(prep.P))


def test_wedge_pairs_are_one_per_distinct_pair():
    """Off a seam the edge's two faces use the same two wedges: one pair. Along a box
    edge (a seam) each side merges its own wedges: two pairs. A corner's third wedge,
    on the box face the edge does not touch, is in no pair."""
    from bench.catalog.gamemodels import make_crate
    from methods.engine.wedges import _wedge_pairs

    mesh = make_crate(3)
    _, a, _, _, s = _engine_state(mesh, Policy(texture_weight=1.0))
    ones = np.sum(np.isclose(np.abs(mesh.welded.positions), 1.0), axis=1)  # 1 face, 2 edge, 3 corner
    edges = {tuple(sorted(e)) for f in a.F for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    seen = set()
    for u, v in edges:
        n = _wedge_pairs(u, v, (a.F, a.FW, a.vhead, a.cnext, a.falive), s.efaces,
                         s.wmap_from, s.wmap_to)
        pairs = set(zip(s.wmap_from[:n].tolist(), s.wmap_to[:n].tolist()))
        assert len(pairs) == n
        kinds = (int(min(ones[u], ones[v])), int(max(ones[u], ones[v])))
        on_box_edge = np.sum(np.isclose(np.abs(a.P[u] - a.P[v]), 0.0)) == 2 and \
            min(ones[u], ones[v]) >= 2
        assert n == (2 if on_box_edge else 1), (u, v, kinds)
        if kinds == (2, 3):
            corner = u if ones[u] == 3 else v
            wedges_of_corner = set(a.FW[a.F == corner].tolist())
            assert len(wedges_of_corner) == 3
            assert len(wedges_of_corner - {w for pair in pairs for w in pair}) == 1
        seen.add((kinds, n))
    # face-face and face-seam edges, box edges between edge vertices and to a corner
    assert {((1, 1), 1), ((1, 2), 1), ((2, 2), 2), ((2, 3), 2)} <= seen


def test_wedge_quadrics_through_collapses_are_sums_over_the_original_faces():
    """Replays the engine's collapses of a textured box (to 12 faces) one by one; before
    each, the edge's quadric (each merged wedge's quadric reduced over its UV) and after
    it, every wedge quadric, must equal brute-force sums over the original faces: a
    wedge's quadric is the sum of the lifted face quadrics of the original corners that
    have merged into it, each corner once. The sequence includes collapses between ends
    with unequal wedge counts (a corner's three and an edge vertex's two, an edge
    vertex's two and a face vertex's one), whose unpaired wedges keep their quadrics."""
    from bench.catalog.gamemodels import make_crate
    from methods.engine.collapse import _collapse
    from methods.engine.state import N_KINDS
    from methods.engine.terms.quadric import _edge_quadric

    mesh = make_crate(3)
    policy = Policy(texture_weight=1.0)
    log = simplify_mesh(mesh, 12, policy).log
    prep, a, rules, terms, s = _engine_state(mesh, policy)
    F0, FW0, uv0 = a.F.copy(), a.FW.copy(), a.uv.copy()
    per_face = np.array([_lifted_face_quadric(a.P[F0[f]], uv0[FW0[f]], 1.0)
                         for f in range(len(F0))])
    into = np.arange(len(a.uv))  # the wedge each original wedge has merged into

    def brute(w):
        return per_face[np.flatnonzero(into[FW0] == w) // 3].sum(axis=0)

    unequal = 0
    changed = np.empty(3 * len(F0), np.int64)
    kinds = np.zeros(N_KINDS, np.int64)
    for u, v, pos in zip(log["removed"], log["kept"], log["position"]):
        faces = [f for f in np.flatnonzero(a.falive) if u in a.F[f] and v in a.F[f]]
        pairs = set()
        for f in faces:
            wu, wv = a.FW[f][a.F[f] == u][0], a.FW[f][a.F[f] == v][0]
            if wu != wv:
                pairs.add((wu, wv))
        ring = np.isin(a.F, [u, v]) & a.falive[:, None]
        merged = dict(pairs)
        targets = {merged.get(w, w) for w in a.FW[ring].tolist()}
        unequal += len(set(a.FW[(a.F == u) & a.falive[:, None]].tolist())) != \
            len(set(a.FW[(a.F == v) & a.falive[:, None]].tolist()))
        _edge_quadric(u, v, a, s)
        expected = a.Q[u] + a.Q[v]
        for t in targets:
            group = [t] + [w for w, x in pairs if x == t]
            expected = expected + _reduced(sum(brute(w) for w in group), a.uv[t])
        # rounding is relative to the largest entry; a doubled wedge is off by its whole
        # quadric
        np.testing.assert_allclose(s.qsum, expected, rtol=1e-9,
                                   atol=1e-12 * np.abs(expected).max())
        p = (np.asarray(pos) - prep.lo) / prep.scale
        _collapse(u, v, p, a, rules, terms, s, (changed, 0, kinds))
        for w, x in pairs:
            into[into == w] = x
        live = np.unique(a.FW[a.falive])
        for w in live:
            want = brute(w)
            np.testing.assert_allclose(a.WQ[w], want, rtol=1e-9,
                                       atol=1e-12 * np.abs(want).max())
    assert int(a.falive.sum()) == 12
    assert unequal > 0


def _on_the_box(positions, faces, eps=1e-12):
    """Whether the welded ``faces`` cover the box [-1, 1]^3 exactly: every face in a box
    plane, facing out, the surface closed and consistently oriented, and the areas
    adding up to the box's 24. A closed oriented surface on the box covers each point
    of it equally often, so area 24 with every face facing out means exactly once."""
    tri = positions[faces]
    area = 0.5 * np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    outward = np.zeros(len(faces))
    for axis, side in itertools.product(range(3), (-1.0, 1.0)):
        on = np.all(np.abs(tri[:, :, axis] - side) < eps, axis=1)
        outward[on] = side * area[on, axis]
    directed = {(int(a), int(b)) for f in faces for a, b in ((f[0], f[1]), (f[1], f[2]),
                                                              (f[2], f[0]))}
    closed = len(directed) == 3 * len(faces) and all((b, a) in directed for a, b in directed)
    return bool(np.all(outward > 0) and closed and abs(outward.sum() - 24.0) < 1e-9)


def test_textured_box_keeps_its_corners_at_every_budget():
    """A subdivided box with UVs per box face (every box edge a seam): each box face is
    flat and affinely textured, so its 5-D quadrics are exact and removing a corner
    costs as much as with positions alone. At every budget down to 12 faces the
    texture quadrics keep the 8 corners and the box itself (zero Hausdorff distance
    both ways). Before wedges merged once per collapse, this box lost a corner from 224
    faces down.

    The engine's order of collapses does not depend on the budget (the budget only
    stops it), so the result at each budget is the log of one run to 12 faces replayed
    up to that budget; two budgets run on their own check that."""
    from bench.catalog.gamemodels import make_crate
    from methods.quadric import Quadric
    from metrics.geometry import hausdorff

    mesh = make_crate(7)  # 588 faces; the smallest crate that lost corners before the fix
    corners = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
    result = simplify_mesh(mesh, 12, Quadric().policy())
    assert result.mesh.n_faces == 12 and result.mesh.welded.n_vertices == 8
    log = result.log
    assert len(log["removed"]) == (mesh.n_faces - 12) // 2
    positions = mesh.welded.positions.copy()
    faces = mesh.welded.faces.astype(np.int64).copy()
    alive = np.ones(len(faces), bool)
    valive = np.ones(len(positions), bool)
    for i, (u, v) in enumerate(zip(log["removed"], log["kept"])):
        alive[log["removed_faces"][i][log["removed_faces"][i] >= 0]] = False
        for f in log["changed_faces"][log["changed_start"][i]:log["changed_start"][i + 1]]:
            faces[f][faces[f] == u] = v
        positions[v] = log["position"][i]
        valive[u] = False
        budget = int(alive.sum())
        nearest = np.linalg.norm(positions[valive][None] - corners[:, None], axis=2).min(axis=1)
        assert nearest.max() < 1e-12, (budget, nearest)  # rounding of the placement solve
        assert _on_the_box(positions, faces[alive]), budget
        if budget in (366, 100):  # the replay is the run at that budget
            run = Quadric().simplify(mesh, budget).mesh
            key = lambda p: tuple(np.round(p, 9))
            got = {tuple(sorted(key(p) for p in run.positions[f])) for f in run.faces}
            want = {tuple(sorted(key(p) for p in positions[f])) for f in faces[alive]}
            assert got == want, budget
    assert budget == 12
    d = hausdorff(mesh, result.mesh, samples=3000)  # MeshLab's single precision
    assert d["forward_max"] < 1e-6 and d["backward_max"] < 1e-6, d


# -- the move bound and the stall phases -------------------------------------------------

def test_the_move_bound_measures_the_way_off_the_faces_planes():
    """A new position far across the plane of the faces around the edge is within the
    bound; one off that plane by more than the bound is not; a dead face's plane does
    not count."""
    from collections import namedtuple

    from methods.engine.loop import _beyond_reach

    P = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, -1]], float)
    F = np.array([[0, 1, 2], [0, 2, 3], [1, 0, 4]])  # two flat faces, one tilted
    vhead, cnext = corner_lists(F, len(P))
    falive = np.array([True, True, False])
    mesh = namedtuple("Arrays", "P F vhead cnext falive")(P, F, vhead, cnext, falive)
    assert not _beyond_reach(0, 1, np.array([10.0, -3.0, 0.0]), mesh, 0.05)
    assert not _beyond_reach(0, 1, np.array([0.5, 0.0, 0.04]), mesh, 0.05)
    assert _beyond_reach(0, 1, np.array([0.5, 0.0, 0.06]), mesh, 0.05)
    assert _beyond_reach(3, 2, np.array([0.5, 0.0, -0.06]), mesh, 0.05)
    assert not _beyond_reach(0, 1, np.array([0.5, 0.0, 9.0]), mesh, np.inf)
    falive[2] = True  # the tilted face's plane now bounds the move across the flat ones
    assert _beyond_reach(0, 1, np.array([10.0, -3.0, 0.0]), mesh, 0.05)


def test_the_stall_phases_release_seams_then_widen_then_lift_the_bound():
    from methods.engine.simplify import _stall_phases
    from methods.engine.state import Rules

    rules = Rules(*([None] * len(Rules._fields)))._replace(seam_rule=True)
    policy = Policy(stall_rotations=(120.0, 180.0), stall_seams=True, max_move=0.05)
    names = [name for name, _ in _stall_phases(policy, rules)]
    assert names == ["seams released", "120 degrees", "180 degrees", "move bound lifted"]
    assert [name for name, _ in _stall_phases(policy, rules._replace(seam_rule=False))] \
        == names[1:]  # no seams to release
    assert _stall_phases(Policy(), rules) == []
    memory = Policy(stall_rotations=(120.0,), max_move=0.05, move_memory=True)
    assert [name for name, _ in _stall_phases(memory, rules)] \
        == ["120 degrees", "move memory dropped", "move bound lifted"]
    with pytest.raises(ValueError, match="max_move"):
        Policy(max_move=0.0)


def _replayed_moves(mesh, log, collapses):
    """The sum of each vertex's moves, replayed from the collapse log in plain Python:
    per collapse the largest distance from the new position to the plane of a live
    face around either end (before it), added to the larger of the two ends' sums.
    Returns the largest sum over the first ``collapses`` collapses, as a fraction of
    the diagonal."""
    positions = mesh.welded.positions.copy()
    faces = mesh.welded.faces.astype(np.int64).copy()
    alive = np.ones(len(faces), bool)
    moves = np.zeros(len(positions))
    largest = 0.0
    for i in range(collapses):
        u, v, p = int(log["removed"][i]), int(log["kept"][i]), log["position"][i]
        around = alive & ((faces == u) | (faces == v)).any(axis=1)
        tri = positions[faces[around]]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(n, axis=1)
        off = np.abs(np.einsum("fk,fk->f", n, p - tri[:, 0]))[length > 0] / length[length > 0]
        moves[v] = max(moves[u], moves[v]) + off.max(initial=0.0)
        largest = max(largest, moves[v])
        alive[log["removed_faces"][i][log["removed_faces"][i] >= 0]] = False
        for f in log["changed_faces"][log["changed_start"][i]:log["changed_start"][i + 1]]:
            faces[f][faces[f] == u] = v
        positions[v] = p
    return largest / mesh.diagonal


def test_the_move_memory_bounds_the_sum_of_a_vertexs_moves():
    """With ``move_memory`` the move bound holds for the sum of each vertex's moves
    (a slow replay of the log sums them), until the stall rule drops the memory;
    without it each collapse alone is bounded, and the sums pass the bound."""
    from bench.catalog.torus import make_torus

    mesh = make_torus(24, 12)
    bound = 0.04
    result = simplify_mesh(mesh, 120, Policy(max_move=bound, move_memory=True))
    phases = result.stats["stall_phases"]
    before = len(result.log["removed"]) - sum(result.stats["stall_collapses"])
    assert before > 0.8 * len(result.log["removed"])
    assert _replayed_moves(mesh, result.log, before) <= bound * (1 + 1e-9)
    assert result.stats["rejections"]["move bound"] > 0
    assert phases == ["move memory dropped"]  # then each collapse is bounded alone
    assert _replayed_moves(mesh, result.log, len(result.log["removed"])) > bound
    plain = simplify_mesh(mesh, 120, Policy(max_move=bound))
    assert plain.stats["stall_phases"] == []
    assert _replayed_moves(mesh, plain.log, len(plain.log["removed"])) > 2 * bound
