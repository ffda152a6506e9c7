"""The Multi-Triangulation built from the engine's collapse log (methods.mt.dag)."""

import numpy as np
import pytest

from bench.catalog.torus import make_torus
from bench.core.mesh import Mesh
from methods.engine.policy import STALL_ROTATIONS, Policy
from methods.engine.simplify import simplify_mesh
from methods.mt.dag import Cut, build_mt, from_log

# A fan of 8 triangles around vertex 4 (a flat square, y up):
#
#    0---1---2
#    | \ | / |
#    3---4---5
#    | / | \ |
#    6---7---8
#
# Collapsing 4 into 1 (a half-edge collapse, 1 stays put) removes the two triangles on
# edge 1-4 and turns the other six into a fan around 1.
FAN_POSITIONS = np.array([[x, 2 - y, 0.0] for y in range(3) for x in range(3)], float)
RING = [5, 2, 1, 0, 3, 6, 7, 8]  # counter-clockwise around 4
FAN_FACES = np.array([[4, RING[i], RING[(i + 1) % 8]] for i in range(8)], np.int32)


def fan_log(mesh):
    """The engine's log of that collapse (it names welded vertices; wedges are render
    vertices, here one per vertex: 4's wedge merges into 1's, which is the merged
    vertex's only wedge)."""
    welded = mesh.welded.vertex_of
    removed_faces = [f for f in range(8) if 1 in FAN_FACES[f]]
    return {"removed": welded[[4]], "kept": welded[[1]],
            "position": FAN_POSITIONS[[1]].copy(), "removed_faces": np.array([removed_faces]),
            "pair_start": np.array([0, 1]), "wedge_pairs": np.array([[4, 1]]),
            "wedge_start": np.array([0, 1]), "wedges": np.array([1]),
            "wedge_uv": np.zeros((1, 2))}


def test_engine_logs_wedges_as_the_fan_by_hand():
    """The engine's own log of the fan collapse has the hand-written wedge entries."""
    mesh = Mesh(FAN_POSITIONS, FAN_FACES)
    log = simplify_mesh(mesh, 6, Policy(placement="endpoints"), max_collapses=1).log
    assert len(log["removed"]) == 1
    u, v = int(log["removed"][0]), int(log["kept"][0])
    assert list(log["pair_start"]) == [0, 1] and list(log["wedge_start"]) == [0, 1]
    of = mesh.welded.vertex_of  # wedges are render vertices, one per welded vertex here
    pairs, wedges = log["wedge_pairs"], log["wedges"]
    assert pairs.shape == (1, 2)  # one or two removed faces, one distinct pair
    assert of[pairs[0]].tolist() == [u, v]
    assert of[wedges].tolist() == [v]


def test_fan_by_hand():
    mesh = Mesh(FAN_POSITIONS, FAN_FACES)
    mt = from_log(mesh, fan_log(mesh))
    assert mt.n_nodes == 1
    assert mt.n_triangles == 8 + 6
    assert mt.coarsest_faces == 6
    assert list(mt.delta) == [2]
    assert sorted(mt.node_removed(0)) == list(range(8))  # 4's star, 1 has no other face
    assert sorted(mt.node_created(0)) == list(range(8, 14))
    created = mt.triangles[mt.node_created(0)]
    assert np.all(np.any(created == 1, axis=1))  # every new face uses vertex 1
    assert not np.any(created == 4)
    assert mt.cut("finest").n_faces == 8
    coarse = mt.cut("coarsest").mesh()
    assert coarse.n_faces == 6 and np.allclose(coarse.face_normals[:, 2], 1.0)


def small_torus():
    return make_torus(16, 8, texture_size=64)


@pytest.fixture(scope="module")
def torus_mt():
    return build_mt(small_torus())


def _canonical(mesh):
    """Triangles as sorted rows of (position, uv) per corner, rotation-independent."""
    x = np.concatenate([mesh.positions[mesh.faces], mesh.uv[mesh.faces]], axis=2)
    rows = []
    for tri in x:
        k = min(range(3), key=lambda i: tuple(tri[i]))
        rows.append(np.roll(tri, -k, axis=0).reshape(-1))
    rows = np.array(rows)
    return rows[np.lexsort(rows.T[::-1])]


@pytest.mark.parametrize("texture_weight", [1.0, 0.0])
def test_coarsest_cut_is_the_engines_result(texture_weight):
    mesh = small_torus()
    mt = build_mt(mesh, texture_weight=texture_weight)
    engine = simplify_mesh(mesh, 1, Policy(placement="optimal", texture_weight=texture_weight,
                                           stall_rotations=STALL_ROTATIONS))
    coarse = mt.cut("coarsest").mesh()
    assert coarse.n_faces == engine.mesh.n_faces == mt.coarsest_faces
    np.testing.assert_allclose(_canonical(coarse), _canonical(engine.mesh), atol=1e-12)


def test_finest_cut_is_the_input(torus_mt):
    mesh = small_torus()
    fine = torus_mt.cut("finest")
    assert fine.n_faces == mesh.n_faces
    assert list(fine.triangles()) == list(range(mesh.n_faces))
    np.testing.assert_array_equal(_canonical(fine.mesh()), _canonical(mesh))


def test_arcs_point_up_the_sequence(torus_mt):
    mt = torus_mt
    for i in range(mt.n_nodes):
        assert np.all(mt.node_parents(i) > i)
        assert np.all(mt.node_children(i) < i)
    # on a closed mesh every collapse removes two faces
    assert np.all(mt.delta == 2)
    # each triangle is created once and removed once
    assert np.all(np.bincount(mt.created, minlength=mt.n_triangles)[mt.n_original:] == 1)
    assert np.all(np.bincount(mt.removed, minlength=mt.n_triangles)
                  == (mt.destroyer >= 0).astype(int))


def _assert_valid(cut):
    mesh = cut.mesh()
    assert mesh.n_faces == cut.n_faces == len(cut.triangles())
    w = mesh.welded
    assert np.all(w.edge_face_count == 2)  # closed and manifold: the torus never opens
    assert w.n_vertices - len(w.edges) + mesh.n_faces == 0  # genus 1


def test_random_cuts_are_valid_meshes(torus_mt):
    rng = np.random.default_rng(6)
    cut = torus_mt.cut("coarsest")
    for _ in range(40):
        i = int(rng.integers(torus_mt.n_nodes))
        if rng.random() < 0.6:
            cut.raise_node(int(i))
            assert not cut.applied[i]
            assert not cut.applied[torus_mt.node_parents(i)].any()
        else:
            cut.lower_node(int(i))
            assert cut.applied[i]
            assert cut.applied[torus_mt.node_children(i)].all()
        _assert_valid(cut)


def test_raise_then_lower_restores_the_cut(torus_mt):
    rng = np.random.default_rng(3)
    cut = torus_mt.cut("coarsest")
    for i in rng.integers(torus_mt.n_nodes, size=15):
        cut.raise_node(int(i))
    for i in rng.integers(torus_mt.n_nodes, size=20):
        before, faces = cut.applied.copy(), cut.n_faces
        if cut.applied[i]:
            moved = cut.raise_node(int(i))
            assert moved[-1] == i and cut.n_faces == faces + 2 * len(moved)
            for x in moved[::-1]:
                assert list(cut.lower_node(int(x))) == [x]
        else:
            moved = cut.lower_node(int(i))
            assert moved[-1] == i and cut.n_faces == faces - 2 * len(moved)
            for x in moved[::-1]:
                assert list(cut.raise_node(int(x))) == [x]
        np.testing.assert_array_equal(cut.applied, before)
        assert cut.n_faces == faces == Cut(torus_mt, cut.applied).n_faces


def test_raise_and_lower_are_inverse_on_the_frontier(torus_mt):
    cut = torus_mt.cut("coarsest")
    frontier = [i for i in range(torus_mt.n_nodes)
                if cut.applied[i] and not cut.applied[torus_mt.node_parents(i)].any()]
    before = cut.applied.copy()
    for i in frontier:
        assert list(cut.raise_node(i)) == [i]
        assert list(cut.lower_node(i)) == [i]
    np.testing.assert_array_equal(cut.applied, before)
    assert cut.n_faces == torus_mt.coarsest_faces


def test_closure_raises_every_ancestor(torus_mt):
    cut = torus_mt.cut("coarsest")
    n = len(cut.raise_node(0))  # the first collapse sits below everything built on it
    ancestors, stack = set(), [0]
    while stack:
        x = stack.pop()
        for p in torus_mt.node_parents(x):
            if p not in ancestors:
                ancestors.add(int(p))
                stack.append(int(p))
    assert n == 1 + len(ancestors)
    assert not cut.applied[list(ancestors | {0})].any()


def test_bad_cuts_and_nodes_are_rejected(torus_mt):
    applied = np.zeros(torus_mt.n_nodes, bool)
    top = torus_mt.n_nodes - 1
    assert len(torus_mt.node_children(top)) > 0
    applied[top] = True
    with pytest.raises(ValueError, match="not a cut"):
        Cut(torus_mt, applied)
    with pytest.raises(ValueError, match="shape"):
        Cut(torus_mt, np.zeros(3, bool))
    with pytest.raises(IndexError, match="out of range"):
        torus_mt.cut().raise_node(torus_mt.n_nodes)
    with pytest.raises(ValueError, match="coarsest"):
        torus_mt.cut("middle")
    with pytest.raises(ValueError, match="faces"):
        build_mt(Mesh(np.zeros((3, 3)), np.zeros((0, 3), np.int32)))
