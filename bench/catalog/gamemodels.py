"""Game-style procedural models for the entropy-twin experiments (González et al. 2008).

Game meshes duplicate vertices wherever an attribute changes: the corners and edges of a
box with per-face texture coordinates, the joint of two sub-meshes (materials) drawn
from one vertex buffer. Both models here are built that way, deterministically, with
generated textures:

* :func:`make_crate`: a box of side 2 whose six faces are each an ``n`` × ``n`` grid
  with its own copy of the texture (UV 0..1 per face), so every vertex on a box edge
  has two render vertices and every box corner three. Texture: planks, a frame and a
  diagonal brace;
* :func:`make_barrel`: two materials in one texture atlas: the staves (left half of the
  atlas) on a cylinder, the lids (right half) on two discs. The lids' rims share their
  positions with the body's top and bottom rings but not their vertices (a seam between
  sub-meshes), and the body has a wrap-around UV seam. ``mesh.metadata["materials"]``
  names the two parts and ``metadata["material_faces"]`` says how many faces of each
  (body first, then lids).
"""

from __future__ import annotations

import numpy as np

from bench.core.mesh import Mesh

__all__ = ["make_crate", "make_barrel", "crate_texture", "barrel_texture"]


def crate_texture(size: int = 256, seed: int = 2008) -> np.ndarray:
    """(size, size, 3) uint8: horizontal planks with grain, a dark frame and a brace."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:size, 0:size] / size
    planks = 5
    plank = np.minimum((y * planks).astype(int), planks - 1)
    tone = 0.75 + 0.2 * rng.random(planks)[plank]
    grain = 0.08 * np.sin(40 * x + 6 * np.sin(7 * y + plank)) + 0.04 * rng.standard_normal(
        (size, size))
    base = np.clip(tone + grain, 0, 1)
    gap = (np.abs(y * planks - np.round(y * planks)) < 0.03)
    frame = (x < 0.1) | (x > 0.9) | (y < 0.1) | (y > 0.9)
    brace = np.abs(x - y) < 0.06
    value = np.where(gap, 0.25, base)
    value = np.where(brace, 0.55 + 0.5 * grain, value)
    value = np.where(frame, 0.45 + 0.5 * grain, value)
    colour = np.array([0.78, 0.55, 0.30])
    rgb = np.clip(value[..., None] * colour * 255, 0, 255)
    nails = ((np.hypot(x - 0.05, y - 0.05) < 0.02) | (np.hypot(x - 0.95, y - 0.05) < 0.02) |
             (np.hypot(x - 0.05, y - 0.95) < 0.02) | (np.hypot(x - 0.95, y - 0.95) < 0.02))
    rgb[nails] = (60, 60, 64)
    return rgb.astype(np.uint8)


def make_crate(n: int = 12, texture_size: int = 256) -> Mesh:
    """A box [-1, 1]^3 with each face an ``n`` × ``n`` grid of quads (two triangles
    each, 12 n² faces), faces wound outward, each face with its own UVs 0..1.

    Every face has its own (n + 1)² render vertices, so positions on the box's edges
    appear twice and the corners three times (6 (n + 1)² render vertices, 6 n² + 2
    welded ones)."""
    if n < 1:
        raise ValueError(f"crate subdivisions must be at least 1, got {n}")
    s = np.linspace(-1.0, 1.0, n + 1)
    t = np.linspace(0.0, 1.0, n + 1)
    a, b = np.meshgrid(s, s, indexing="xy")   # a along columns, b along rows
    ua, vb = np.meshgrid(t, t, indexing="xy")
    positions, uvs, faces = [], [], []
    # (axis of the normal, sign): the face's (right, up) axes so that right x up = normal
    sides = [((1, 2), 0, 1.0), ((2, 1), 0, -1.0), ((2, 0), 1, 1.0), ((0, 2), 1, -1.0),
             ((0, 1), 2, 1.0), ((1, 0), 2, -1.0)]
    for (right, up), axis, sign in sides:
        p = np.zeros((n + 1, n + 1, 3))
        p[..., right] = a
        p[..., up] = b
        p[..., axis] = sign
        base = len(positions) * (n + 1) ** 2
        positions.append(p.reshape(-1, 3))
        uvs.append(np.stack([ua, vb], axis=-1).reshape(-1, 2))
        i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
        v00 = base + j * (n + 1) + i
        quad = np.stack([v00, v00 + 1, v00 + n + 2, v00 + n + 1], axis=-1).reshape(-1, 4)
        tri = np.concatenate([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]])
        # right x up must point along the outward normal, else flip the winding
        e = np.zeros(3)
        e[right], e[up] = 1.0, 0.0
        f = np.zeros(3)
        f[up] = 1.0
        if np.cross(e, f)[axis] * sign < 0:
            tri = tri[:, ::-1]
        faces.append(tri)
    return Mesh(np.concatenate(positions), np.concatenate(faces).astype(np.int32),
                uv=np.concatenate(uvs), texture=crate_texture(texture_size), name="crate")


def barrel_texture(size: int = 256, seed: int = 2008) -> np.ndarray:
    """(size, size, 3) uint8 atlas: staves with iron hoops (left half), a metal lid
    with rings and bolts (right half)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:size, 0:size] / size
    # left half: 12 vertical staves over u in [0, 0.5), hoops at two heights
    u = np.clip(x / 0.5, 0, 1)
    stave = np.minimum((u * 12).astype(int), 11)
    tone = 0.7 + 0.25 * rng.random(12)[stave]
    grain = 0.07 * np.sin(60 * y + 3 * stave) + 0.03 * rng.standard_normal((size, size))
    wood = np.clip(tone + grain, 0, 1)[..., None] * np.array([0.72, 0.47, 0.24])
    gaps = np.abs(u * 12 - np.round(u * 12)) < 0.04
    wood[gaps] *= 0.4
    hoops = (np.abs(y - 0.2) < 0.04) | (np.abs(y - 0.8) < 0.04)
    wood[hoops] = (0.3, 0.3, 0.33)
    # right half: a lid centred at (0.75, 0.5)
    r = np.hypot((x - 0.75) / 0.25, (y - 0.5) / 0.5)
    metal = (0.55 + 0.1 * np.cos(30 * r))[..., None] * np.array([0.9, 0.92, 1.0])
    metal[np.abs(r - 0.85) < 0.04] = (0.25, 0.25, 0.28)
    angle = np.arctan2(y - 0.5, x - 0.75)
    bolt = (np.abs(r - 0.65) < 0.05) & (np.abs(np.sin(4 * angle)) < 0.15)
    metal[bolt] = (0.9, 0.8, 0.3)
    rgb = np.where((x < 0.5)[..., None], wood, metal)
    return np.clip(rgb * 255, 0, 255).astype(np.uint8)


def make_barrel(around: int = 32, rows: int = 12, rings: int = 6,
                texture_size: int = 256) -> Mesh:
    """A closed barrel: a bulging body of ``around`` × ``rows`` quads (material 0,
    "staves") and two lids of ``rings`` rings each (material 1, "lid") that share their
    rim positions with the body but not their render vertices.

    Faces: 2 · around · rows for the body, 2 · around · (2 · rings - 1) for the lids.
    """
    if around < 3 or rows < 1 or rings < 1:
        raise ValueError("barrel needs around >= 3, rows >= 1, rings >= 1")
    height, radius = 1.2, 0.5
    theta = np.linspace(0.0, 2 * np.pi, around + 1)  # the last column duplicates the first
    theta[-1] = 0.0  # bit-equal to the first, so the wrap-around is a seam, not a hole
    z = np.linspace(-height / 2, height / 2, rows + 1)
    bulge = radius * (1.0 + 0.12 * np.cos(np.pi * z / height))  # the rims keep radius
    rim_r = bulge[0]
    cols = np.arange(around + 1)
    cth, sth = np.cos(theta), np.sin(theta)
    body = np.stack([bulge[:, None] * cth[None, :], bulge[:, None] * sth[None, :],
                     np.broadcast_to(z[:, None], (rows + 1, around + 1))], axis=-1)
    body_uv = np.stack(np.meshgrid(0.5 * cols / around, np.linspace(0, 1, rows + 1)),
                       axis=-1)
    positions = [body.reshape(-1, 3)]
    uvs = [body_uv.reshape(-1, 2)]
    i, j = np.meshgrid(np.arange(around), np.arange(rows), indexing="xy")
    v00 = j * (around + 1) + i
    quad = np.stack([v00, v00 + 1, v00 + around + 2, v00 + around + 1], -1).reshape(-1, 4)
    faces = [np.concatenate([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]])]
    body_faces = len(faces[0])
    count = len(positions[0])
    for top in (False, True):
        lid, lid_uv, tris = _barrel_lid(body[-1 if top else 0, :-1], rim_r, cth[:-1],
                                        sth[:-1], rings, top)
        positions.append(lid)
        uvs.append(lid_uv)
        faces.append(tris + count)
        count += len(lid)
    lid_faces = sum(len(f) for f in faces[1:])
    mesh = Mesh(np.concatenate(positions), np.concatenate(faces).astype(np.int32),
                uv=np.concatenate(uvs), texture=barrel_texture(texture_size), name="barrel",
                metadata={"materials": ("staves", "lid"),
                          "material_faces": (int(body_faces), int(lid_faces))})
    return mesh


def _barrel_lid(rim: np.ndarray, rim_r: float, cth: np.ndarray, sth: np.ndarray,
                rings: int, top: bool):
    """A barrel's lid of ``rings`` rings inside ``rim`` (the body's end ring of radius
    ``rim_r``, which ring ``rings`` copies bit for bit; ``cth``, ``sth`` its angles'
    cosines and sines): (positions, UVs, triangles), facing up if ``top``."""
    around = len(rim)
    zc = rim[0, 2]
    # ring k = 0 is the centre, k = rings the rim
    pts = [np.array([[0.0, 0.0, zc]])]
    lid_uv = [np.array([[0.75, 0.5]])]
    for k in range(1, rings + 1):
        rr = rim_r * k / rings
        pts.append(rim.copy() if k == rings else
                   np.stack([rr * cth, rr * sth, np.full(around, zc)], axis=1))
        lid_uv.append(np.stack([0.75 + 0.24 * (k / rings) * cth,
                                0.5 + 0.48 * (k / rings) * sth], axis=1))
    tris = []
    for k in range(rings):
        inner = 0 if k == 0 else 1 + (k - 1) * around
        outer = 1 + k * around
        for c in range(around):
            c1 = (c + 1) % around
            if k == 0:
                tris.append((0, outer + c, outer + c1))
            else:
                tris.append((inner + c, outer + c, outer + c1))
                tris.append((inner + c, outer + c1, inner + c1))
    tris = np.array(tris)
    return np.concatenate(pts), np.concatenate(lid_uv), tris if top else tris[:, ::-1]
