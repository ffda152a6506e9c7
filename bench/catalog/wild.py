"""Procedural analogues of real game assets (the ``wild`` suite).

The papers' shapes are single closed surfaces; the assets an engine developer has are
not. Each model here rebuilds one way real assets differ, deterministically and with
generated textures, so that anyone can run the suite's ``wild`` models without the
real files (``../shared/assets/wild/`` in the project's CI holds those):

* :func:`make_uv_sphere`: the usual UV sphere, its poles one position shared by a
  render vertex per segment (200 segments: two fans of 200 faces and 200 wedges), a
  wrap-around seam, one texture;
* :func:`make_kit`: a "kit" of many small props with flat-colour materials (six
  colours, one atlas): boxes, barrels, small bolts, a box standing on another without
  sharing vertices (touching, unwelded), and sign plates attached along a box's edge
  with their vertices on the box's (each such edge has three faces: non-manifold);
* :func:`make_vehicle`: a vehicle-like assembly: a textured body and cabin (touching,
  unwelded), four separate wheels with hubcaps of their own materials, axles.

All faces are wound outward (counter-clockwise seen from outside).
"""

from __future__ import annotations

import numpy as np

from bench.core.mesh import Mesh
from bench.io.atlas import Part, pack_materials
from bench.io.validate import build_mesh

__all__ = ["make_kit", "make_uv_sphere", "make_vehicle", "sphere_texture", "vehicle_texture"]


# -- building blocks ------------------------------------------------------------------

def _outward(positions: np.ndarray, faces: np.ndarray, centre) -> np.ndarray:
    """``faces`` with those whose normal points towards ``centre`` flipped (for convex
    pieces built without care for winding)."""
    p = positions[faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    inward = np.einsum("ij,ij->i", n, p.mean(axis=1) - np.asarray(centre)) < 0
    out = faces.copy()
    out[inward] = out[inward][:, [0, 2, 1]]
    return out


def _grid(n_u: int, n_v: int):
    """Quads of an (n_u + 1) x (n_v + 1) vertex grid as triangles, row-major."""
    i, j = np.meshgrid(np.arange(n_u), np.arange(n_v), indexing="xy")
    a = j * (n_u + 1) + i
    quads = np.stack([a, a + 1, a + n_u + 2, a + n_u + 1], -1).reshape(-1, 4)
    return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


def _box(lo, hi, n: int, uv_cells: bool = False):
    """A box from ``lo`` to ``hi``, each face an n x n grid with its own vertices (so
    its edges are seams when textured); UVs per face in a 3 x 2 layout of cells when
    ``uv_cells``. Returns (positions, faces, uv or None)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    centre = (lo + hi) / 2
    s = np.linspace(0.0, 1.0, n + 1)
    uu, vv = np.meshgrid(s, s, indexing="xy")
    uu, vv = uu.reshape(-1), vv.reshape(-1)
    positions, faces, uvs = [], [], []
    for k, (axis, side) in enumerate((a, b) for a in range(3) for b in (0, 1)):
        others = [d for d in range(3) if d != axis]
        p = np.empty((len(uu), 3))
        p[:, axis] = hi[axis] if side else lo[axis]
        # (1 - s) lo + s hi: bit-equal on the edges that two faces share
        p[:, others[0]] = (1 - uu) * lo[others[0]] + uu * hi[others[0]]
        p[:, others[1]] = (1 - vv) * lo[others[1]] + vv * hi[others[1]]
        f = _outward(p, _grid(n, n), centre) + sum(len(q) for q in positions)
        positions.append(p)
        faces.append(f)
        cell = np.array([k % 3, k // 3], float)
        uvs.append((cell + 0.05 + 0.9 * np.stack([uu, vv], -1)) / np.array([3.0, 2.0]))
    return (np.concatenate(positions), np.concatenate(faces),
            np.concatenate(uvs) if uv_cells else None)


def _cylinder(centre, radius: float, length: float, axis: int, segments: int, rings: int):
    """A closed cylinder along ``axis`` (caps as fans around a centre vertex). Returns
    (positions, faces)."""
    centre = np.asarray(centre, float)
    others = [d for d in range(3) if d != axis]
    theta = 2 * np.pi * np.arange(segments) / segments
    t = np.linspace(-length / 2, length / 2, rings + 1)
    side = np.zeros((rings + 1, segments, 3))
    side[..., others[0]] = radius * np.cos(theta)[None, :]
    side[..., others[1]] = radius * np.sin(theta)[None, :]
    side[..., axis] = t[:, None]
    positions = [side.reshape(-1, 3)]
    i, j = np.meshgrid(np.arange(segments), np.arange(rings), indexing="xy")
    a, b = j * segments + i, j * segments + (i + 1) % segments
    faces = [np.concatenate([np.stack([a, b, b + segments], -1).reshape(-1, 3),
                             np.stack([a, b + segments, a + segments], -1).reshape(-1, 3)])]
    n = (rings + 1) * segments
    for end, ring in ((0, 0), (1, rings)):
        cap = np.zeros(3)
        cap[axis] = t[ring]
        positions.append(cap[None])
        k = np.arange(segments)
        faces.append(np.stack([np.full(segments, n), ring * segments + k,
                               ring * segments + (k + 1) % segments], -1))
        n += 1
    p = np.concatenate(positions)
    return p + centre, _outward(p, np.concatenate(faces).astype(np.int64), np.zeros(3))


# -- the UV sphere ----------------------------------------------------------------------

def sphere_texture(width: int = 512, height: int = 256, seed: int = 7) -> np.ndarray:
    """(height, width, 3) uint8: a latitude/longitude map with meridian and parallel
    lines every 30 degrees over soft coloured bands."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width]
    u, v = x / width, y / height
    bands = 0.6 + 0.4 * np.sin(2 * np.pi * (3 * v + 0.2 * np.sin(2 * np.pi * 2 * u)))
    tint = rng.random((6, 3)) * 0.5 + 0.4
    rgb = bands[..., None] * tint[np.minimum((u * 6).astype(int), 5)]
    lines = (np.abs(u * 12 - np.round(u * 12)) < 0.02) | (np.abs(v * 6 - np.round(v * 6)) < 0.03)
    rgb[lines] = (0.1, 0.1, 0.12)
    return np.clip(rgb * 255, 0, 255).astype(np.uint8)


def make_uv_sphere(segments: int = 200, rings: int = 60) -> Mesh:
    """A unit UV sphere: ``rings`` bands from pole to pole, ``segments`` around.

    As modelling tools export it, each pole is one position with ``segments`` render
    vertices (u at the middle of each pole triangle), and the column u = 0 is repeated
    at u = 1 (a wrap-around seam): 2 ``segments`` (``rings`` - 1) faces."""
    if segments < 3 or rings < 2:
        raise ValueError("a UV sphere needs segments >= 3 and rings >= 2")
    theta = np.pi * np.arange(1, rings) / rings            # interior latitudes
    phi = 2 * np.pi * np.arange(segments + 1) / segments
    phi[-1] = 0.0                                           # bit-equal wrap-around column
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    ring = np.stack([st * np.cos(phi), st * np.sin(phi),
                     np.broadcast_to(ct, (rings - 1, segments + 1))], -1)
    u = np.arange(segments + 1) / segments
    ring_uv = np.stack(np.broadcast_arrays(u[None, :], 1.0 - theta[:, None] / np.pi), -1)
    k = np.arange(segments)
    north = np.tile([0.0, 0.0, 1.0], (segments, 1))
    south = np.tile([0.0, 0.0, -1.0], (segments, 1))
    pole_u = (k + 0.5) / segments
    positions = np.concatenate([ring.reshape(-1, 3), north, south])
    uv = np.concatenate([ring_uv.reshape(-1, 2), np.stack([pole_u, np.ones(segments)], -1),
                         np.stack([pole_u, np.zeros(segments)], -1)])
    width = segments + 1
    n_ring = (rings - 1) * width
    faces = [_grid(segments, rings - 2)]
    faces.append(np.stack([n_ring + k, k, k + 1], -1))                        # north fan
    last = (rings - 2) * width
    faces.append(np.stack([n_ring + segments + k, last + k + 1, last + k], -1))  # south fan
    faces = _outward(positions, np.concatenate(faces).astype(np.int64), np.zeros(3))
    return build_mesh(positions, faces, source="uv-sphere", uv=uv, texture=sphere_texture(),
                      name="uv-sphere")


# -- the kit of props -------------------------------------------------------------------

#: The kit's flat colours (name, RGBA).
KIT_COLOURS = (("red", (200, 60, 50, 255)), ("green", (70, 160, 80, 255)),
               ("blue", (60, 90, 190, 255)), ("yellow", (220, 190, 60, 255)),
               ("grey", (130, 130, 135, 255)), ("white", (235, 235, 230, 255)))


def make_kit(seed: int = 43) -> Mesh:
    """A kit of props on a 4 x 3 layout, one atlas of six flat colours.

    Boxes (6 x 6 quads a side) and barrels (24 segments) in different colours; four
    bolts (boxes of 12 faces); a box standing on another, its grid offset by 1/7 so
    the two touch without sharing a position; and two sign plates (4 x 2 quads,
    open, one-sided) whose bottom row lies on a box's top edge vertices, so the welded
    edges there have three faces (non-manifold)."""
    rng = np.random.default_rng(seed)
    parts = []

    def add(colour: int, positions, faces):
        parts.append(Part(material=KIT_COLOURS[colour][0], positions=positions,
                          faces=faces, color=KIT_COLOURS[colour][1]))

    for slot in range(12):
        x, y = 3.0 * (slot % 4), 3.0 * (slot // 4)
        colour = int(rng.integers(0, 5))
        if slot % 3 == 1:
            p, f = _cylinder((x, y, 0.8), 0.8, 1.6, 2, 24, 4)
            add(colour, p, f)
        else:
            h = 1.0 + 0.5 * (slot % 2)
            p, f, _ = _box((x - 1, y - 1, 0), (x + 1, y + 1, h), 6)
            add(colour, p, f)
            if slot == 0:  # a smaller box on top: touching, with no shared position
                p, f, _ = _box((x - 0.5 + 1 / 7, y - 0.5 + 1 / 7, h),
                               (x + 0.5 + 1 / 7, y + 0.5 + 1 / 7, h + 1), 4)
                add(4, p, f)
            if slot in (2, 5):  # a sign plate on the box's top edge y = y + 1
                s = np.linspace(0.0, 1.0, 7)[1:6]
                cols = (1 - s) * (x - 1) + s * (x + 1)  # the box's own grid positions
                zs = np.linspace(h, h + 0.8, 3)
                gx, gz = np.meshgrid(cols, zs, indexing="xy")
                p = np.stack([gx.reshape(-1), np.full(gx.size, y + 1.0), gz.reshape(-1)], -1)
                add(5, p, _grid(len(cols) - 1, len(zs) - 1))
    for b in range(4):  # bolts: the smallest parts
        x = 1.5 + 3.0 * b
        p, f, _ = _box((x - 0.1, -2.0, 0), (x + 0.1, -1.8, 0.2), 1)
        add(4, p, f)
    return pack_materials(parts, source="kit", name="kit")


# -- the vehicle ------------------------------------------------------------------------

def vehicle_texture(size: int = 256) -> np.ndarray:
    """(size, size, 3) uint8: painted panels (3 x 2 cells, one per box face) with a
    stripe, dark windows and panel lines."""
    y, x = np.mgrid[0:size, 0:size] / size
    rgb = np.empty((size, size, 3))
    rgb[:] = (0.75, 0.18, 0.15)
    cu, cv = (x * 3) % 1.0, (y * 2) % 1.0
    rgb[np.abs(cv - 0.35) < 0.05] = (0.95, 0.95, 0.9)
    windows = (cv > 0.55) & (cv < 0.85) & (np.abs(cu - 0.5) < 0.35)
    rgb[windows] = (0.12, 0.16, 0.22)
    lines = (np.abs(cu - 0.5) < 0.008) | (cu < 0.06) | (cu > 0.94) | (cv < 0.06) | (cv > 0.94)
    rgb[lines] = rgb[lines] * 0.5
    return np.clip(rgb * 255, 0, 255).astype(np.uint8)


def make_vehicle() -> Mesh:
    """A body (a box of 12 x 12 quads a side, 4 x 1.6 x 1) and a cabin on it (8 x 8,
    touching, no shared vertex) with a painted texture; four wheels (cylinders of 32
    segments, their own dark material) with hubcaps (discs, a grey material) and two
    axles (thin cylinders through the wheels), every part separate."""
    texture = vehicle_texture()
    parts = []
    p, f, uv = _box((-2, -0.8, 0.4), (2, 0.8, 1.4), 12, uv_cells=True)
    parts.append(Part(material="paint", positions=p, faces=f, uv=uv, image=texture))
    p, f, uv = _box((-1.2, -0.7, 1.4), (0.8, 0.7, 2.2), 8, uv_cells=True)
    parts.append(Part(material="paint", positions=p, faces=f, uv=uv, image=texture))
    for x in (-1.3, 1.3):
        for side in (-1, 1):
            p, f = _cylinder((x, side * 0.95, 0.45), 0.45, 0.3, 1, 32, 2)
            parts.append(Part(material="tyre", positions=p, faces=f,
                              color=(30, 30, 32, 255)))
            p, f = _cylinder((x, side * 1.12, 0.45), 0.25, 0.04, 1, 16, 1)
            parts.append(Part(material="hubcap", positions=p, faces=f,
                              color=(180, 180, 185, 255)))
        p, f = _cylinder((x, 0.0, 0.45), 0.06, 1.6, 1, 8, 2)
        parts.append(Part(material="hubcap", positions=p, faces=f,
                          color=(180, 180, 185, 255)))
    return pack_materials(parts, source="vehicle", name="vehicle")
