"""metrics.visibility: faces the protocol's views can see, on boxes with known answers,
against an independent oracle (a ray cast per pixel with trimesh)."""

import math

import numpy as np
import trimesh

from bench.core.mesh import Mesh
from metrics.views import protocol_cameras
from metrics.visibility import face_id_image, never_seen_share, seen_faces


def box(size, centre=(0.0, 0.0, 0.0)):
    b = trimesh.creation.box(extents=(size, size, size))
    return b.vertices + np.asarray(centre), b.faces


def combined(*parts, drop_outer=()):
    positions, faces, n = [], [], 0
    for i, (p, f) in enumerate(parts):
        keep = [j for j in range(len(f)) if not (i == 0 and j in drop_outer)]
        positions.append(p)
        faces.append(f[keep] + n)
        n += len(p)
    return Mesh(np.vstack(positions), np.vstack(faces).astype(np.int32), name="boxes",
                metadata={"exterior_sphere": {"centre": [0, 0, 0], "radius": 0.5}})


def test_a_box_closed_around_another_hides_it_from_every_view():
    mesh = combined(box(2.0), box(0.5))
    seen = seen_faces(mesh)
    assert seen[:12].all() and not seen[12:].any()


def test_an_opening_lets_some_view_see_inside():
    # the outer box without its two +z triangles: the inner box's +z face shows through
    p, f = box(2.0)
    top = [j for j in range(12) if np.allclose(p[f[j], 2], 1.0)]
    mesh = combined(box(2.0), box(0.5), drop_outer=top)
    seen = seen_faces(mesh)
    inner = box(0.5)
    inner_top = [12 - len(top) + j for j in range(12) if np.allclose(inner[0][inner[1][j], 2], 0.25)]
    assert seen[inner_top].all()
    inner_bottom = [12 - len(top) + j for j in range(12)
                    if np.allclose(inner[0][inner[1][j], 2], -0.25)]
    assert not seen[inner_bottom].any()


def _nearest_hits(origins, directions, tris):
    """Möller-Trumbore for every ray against every triangle: the nearest face hit, -1
    for none."""
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    d = directions[:, None, :]
    pvec = np.cross(d, e2[None])
    det = np.einsum("ij,rij->ri", e1, pvec)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tvec = origins[:, None, :] - v0[None]
    u = np.einsum("rij,rij->ri", tvec, pvec) * inv
    qvec = np.cross(tvec, e1[None])
    v = np.einsum("rij,rij->ri", d, qvec) * inv
    t = np.einsum("ij,rij->ri", e2, qvec) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    t = np.where(hit, t, np.inf)
    return np.where(hit.any(axis=1), t.argmin(axis=1), -1)


def test_face_ids_agree_with_a_ray_cast_at_every_pixel_centre():
    mesh = combined(box(2.0), box(0.5, centre=(0.3, 0.1, 0.2)), drop_outer=(0, 1))
    camera = protocol_cameras(mesh)[5]
    size = 48
    ids = face_id_image(mesh.positions, mesh.faces, camera, size)
    # the oracle: a ray through each pixel centre, its nearest hit
    inv = np.linalg.inv(camera.projection_matrix() @ camera.view_matrix())
    px, py = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    ndc = np.stack([px / size * 2 - 1, 1 - py / size * 2, np.full_like(px, -1.0),
                    np.ones_like(px)], -1).reshape(-1, 4)
    far = ndc.copy()
    far[:, 2] = 1.0
    a, b = ndc @ inv.T, far @ inv.T
    a, b = a[:, :3] / a[:, 3:], b[:, :3] / b[:, 3:]
    expected = _nearest_hits(a, b - a, mesh.positions[mesh.faces])
    # on this mesh no pixel centre falls on an edge shared by two visible faces, so the
    # two agree everywhere, on the face and on where there is none
    assert (ids.reshape(-1) == expected).all()
    assert 0.3 < (expected >= 0).mean() < 0.6


def test_never_seen_share_counts_result_faces_on_the_hidden_part():
    original = combined(box(2.0), box(0.5))
    assert never_seen_share(original, original) == 0.5
    outer_only = Mesh(original.positions, original.faces[:12], name="outer")
    assert never_seen_share(original, outer_only) == 0.0
    plain = Mesh(original.positions, original.faces, name="plain")  # no classification
    assert math.isnan(never_seen_share(plain, original))
