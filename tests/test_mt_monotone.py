"""perceptual-mt's view errors are monotone up the MT (each node's is the largest of its
subtree), so the cut at a budget does not depend on the cut refinement starts from.

The MTs come from the real pipeline (the engine's collapse log, methods.mt.dag) on
small random meshes: jittered, randomly textured tori and jittered icospheres.
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.catalog.torus import make_torus
from conftest import blob
from methods.mt.bounds import preprocess
from methods.mt.dag import build_mt
from methods.mt.errors import ERRORS, LIGHTINGS, node_errors
from methods.mt.refine import Refiner, refine
from methods.perceptual_mt import PerceptualMT
from metrics.views import Camera, protocol_cameras

SETTINGS = settings(max_examples=12, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


def random_mesh(kind: str, seed: int):
    """A small mesh for the engine: a torus (textured, with UV seams) or an icosphere
    (untextured), its welded vertices jittered by a seeded amount."""
    rng = np.random.default_rng(seed)
    if kind == "torus":
        mesh = make_torus(int(rng.integers(6, 13)), int(rng.integers(4, 9)), seed=seed,
                          texture_size=16)
        texture = rng.integers(0, 256, (16, 16, 3), dtype=np.uint8)
        mesh = mesh.replace(texture=texture)
    else:
        mesh = blob(int(rng.integers(1, 3)), seed=seed)
    vertex_of = mesh.welded.vertex_of
    jitter = 0.03 * rng.standard_normal((int(vertex_of.max()) + 1, 3))
    return mesh.replace(positions=mesh.positions + jitter[vertex_of], name=f"{kind}-{seed}")


def with_bounds(kind: str, seed: int):
    mesh = random_mesh(kind, seed)
    mt = build_mt(mesh)
    return mesh, mt, preprocess(mt)


def arcs(mt):
    """(parent, child) node indices of every arc of the MT."""
    parent = np.repeat(np.arange(mt.n_nodes), np.diff(mt.child_start))
    return parent, mt.children.astype(np.int64)


def random_cameras(mesh, rng, n):
    """n cameras around and inside the mesh: eyes from 0.2 to 4 bounding radii from
    the centre (inside the nodes' spheres too), looking near the centre, random fields
    of view."""
    lo, hi = mesh.positions.min(0), mesh.positions.max(0)
    centre, radius = 0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo)
    cams = []
    for _ in range(n):
        d = rng.standard_normal(3)
        eye = centre + radius * rng.uniform(0.2, 4.0) * d / np.linalg.norm(d)
        target = centre + 0.5 * radius * rng.uniform(-1, 1, 3)
        forward = (target - eye) / np.linalg.norm(target - eye)
        up = np.cross(np.cross(forward, rng.standard_normal(3)), forward)
        cams.append(Camera(eye=eye, target=target, up=up / np.linalg.norm(up),
                           fov_y_deg=float(rng.uniform(20, 100)), near=0.01 * radius,
                           far=10 * radius))
    return cams


def ranked_cut(mt, err, budget):
    """The cut the refinement must end on (methods.mt.refine): refine the nodes in the
    order of (error, index), highest first, while the budget holds."""
    applied = np.ones(mt.n_nodes, bool)
    faces = mt.coarsest_faces
    for i in sorted(range(mt.n_nodes), key=lambda i: (err[i], i), reverse=True):
        if faces + mt.delta[i] > budget:
            break
        faces += mt.delta[i]
        applied[i] = False
    return applied


def random_cut(mt, rng):
    """A valid cut: random nodes raised (with their ancestors) from the coarsest."""
    cut = mt.cut("coarsest")
    for i in rng.choice(mt.n_nodes, size=rng.integers(0, mt.n_nodes + 1), replace=True):
        cut.raise_node(int(i))
    return cut


# -- the view errors ----------------------------------------------------------------------------

def descendants(mt):
    """Each node's subtree (itself and every node below it), by search."""
    out = []
    for i in range(mt.n_nodes):
        seen, stack = {i}, [i]
        while stack:
            for ch in mt.node_children(stack.pop()):
                if int(ch) not in seen:
                    seen.add(int(ch))
                    stack.append(int(ch))
        out.append(np.array(sorted(seen)))
    return out


@SETTINGS
@given(kind=st.sampled_from(["torus", "blob"]), seed=st.integers(0, 2 ** 16))
def test_a_nodes_error_is_the_largest_of_its_subtree_in_every_view(kind, seed):
    mesh, mt, b = with_bounds(kind, seed)
    p, c = arcs(mt)
    below = descendants(mt)
    rng = np.random.default_rng(seed)
    cams = protocol_cameras(mesh)[::4] + random_cameras(mesh, rng, 6)
    for cam in cams:
        for error in ERRORS:
            for lighting in LIGHTINGS:
                for specular in (True, False):
                    err, status = node_errors(b, cam, 256, error, lighting, specular)
                    own, own_status = node_errors(b, cam, 256, error, lighting, specular,
                                                  subtree_max=False)
                    expected = np.array([own[d].max() for d in below])
                    np.testing.assert_array_equal(err, expected)
                    # so a parent's error is never below a child's, and a node has
                    # error 0 (invisible, or below threshold) only if its whole
                    # subtree has; the status stays each node's own test
                    assert np.all(err[p] >= err[c]) and np.all(err >= 0)
                    np.testing.assert_array_equal(status, own_status)


# -- refinement ---------------------------------------------------------------------------------

@SETTINGS
@given(kind=st.sampled_from(["torus", "blob"]), seed=st.integers(0, 2 ** 16),
       share=st.floats(0.0, 1.0))
def test_refinement_reaches_the_same_cut_from_any_start(kind, seed, share):
    mesh, mt, b = with_bounds(kind, seed)
    rng = np.random.default_rng(seed)
    budget = mt.coarsest_faces + round(share * (mesh.n_faces - mt.coarsest_faces))
    cams = protocol_cameras(mesh)[::6] + random_cameras(mesh, rng, 2)
    for error in ERRORS:
        r = Refiner(mt, b, error, lighting="gouraud", specular=True)
        for cam in cams:
            err, _ = r.errors(cam, 256)
            expected = ranked_cut(mt, err, budget)
            starts = {"coarsest": mt.cut("coarsest"), "finest": mt.cut("finest"),
                      "random": random_cut(mt, rng), "previous view": r.cut}
            for name, cut in starts.items():
                refine(cut, err, budget)
                assert np.array_equal(cut.applied, expected), (error, name)
                assert cut.n_faces == len(cut.triangles()) <= max(budget, mt.coarsest_faces)


def test_equal_errors_are_ranked_by_node_index():
    """With every error 0 (a view in which nothing is visible) the heaps meet nothing
    but ties; the ranking by index still makes one cut, from every start."""
    mesh, mt, _ = with_bounds("torus", 7)
    err = np.zeros(mt.n_nodes)
    rng = np.random.default_rng(7)
    for budget in range(mt.coarsest_faces, mesh.n_faces + 1, 7):
        expected = ranked_cut(mt, err, budget)
        # refined: the nodes from the last collapse down, as far as the budget allows
        k = np.count_nonzero(~expected)
        assert np.all(~expected[mt.n_nodes - k:]) and np.all(expected[:mt.n_nodes - k])
        for cut in (mt.cut("coarsest"), mt.cut("finest"), random_cut(mt, rng)):
            refine(cut, err, budget)
            np.testing.assert_array_equal(cut.applied, expected)


@pytest.mark.parametrize("kind", ["torus", "blob"])
def test_the_views_cuts_do_not_depend_on_their_order(kind):
    """End to end through the method: imaging the protocol views in reverse order (so
    that each starts from a different cut) gives every view the same mesh. (With each
    node's own error and ties in heap order, as in version 1, 14 of the 24 views of
    the torus and 22 of the blob differ at this budget.)"""
    from metrics.protocol import Protocol

    mesh = random_mesh(kind, 0)
    protocol = Protocol(shading="gouraud", specular=True)
    cams = protocol_cameras(mesh)
    view_cuts = PerceptualMT().simplify(mesh, mesh.n_faces // 2).view_cuts
    forward = view_cuts(cams, protocol)
    backward = view_cuts(cams[::-1], protocol)  # view 23 first, from view 23's own cut
    for a, b in zip(forward, backward[::-1]):
        np.testing.assert_array_equal(a.faces, b.faces)
        np.testing.assert_array_equal(a.positions, b.positions)
