"""perceptual-mt's view errors are monotone up the MT: each node's is the largest of its
subtree.

The MTs come from the real pipeline (the engine's collapse log, methods.mt.dag) on
small random meshes: jittered, randomly textured tori and jittered icospheres.
"""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.models.torus import make_torus
from conftest import blob
from methods.mt.bounds import preprocess
from methods.mt.dag import build_mt
from methods.mt.errors import ERRORS, LIGHTINGS, node_errors
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
