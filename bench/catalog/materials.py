"""A two-material asset as engines ship them: a sphere whose halves use different
textures (two ``usemtl`` groups in an OBJ, two primitives in a glTF).

:func:`two_material_parts` gives the halves as a file holds them, each in its own UV
space with its own image; :func:`make_two_materials` packs them into one mesh with the
loaders' atlas (:func:`bench.io.atlas.pack_materials`), exactly as loading the OBJ or
GLB of the same parts does. The northern hemisphere (z ≥ 0) is material 0, ``bricks``:
warm red bricks, 256 x 256; the southern is material 1, ``waves``: blue and white
waves, 128 x 256. They meet at the equator, where both have their own render vertices
at bit-equal positions (a seam between materials); each half also has the wrap-around
seam of a longitude/latitude map and a pole where its columns meet.
"""

from __future__ import annotations

import numpy as np

from bench.core.mesh import Mesh
from bench.io.atlas import Part, pack_materials

__all__ = ["bricks_texture", "make_two_materials", "two_material_parts", "waves_texture"]


def bricks_texture(size: int = 256, seed: int = 3) -> np.ndarray:
    """(size, size, 3) uint8: red bricks in staggered rows with light mortar."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:size, 0:size] / size
    rows = 8
    row = np.minimum((y * rows).astype(int), rows - 1)
    shifted = x * 4 + 0.5 * (row % 2)
    brick = np.floor(shifted).astype(int) % 4
    tone = 0.75 + 0.25 * rng.random((rows, 4))[row, brick]
    rgb = tone[..., None] * np.array([0.78, 0.22, 0.12])
    mortar = (np.abs(y * rows - np.round(y * rows)) < 0.06) | \
        (np.abs(shifted - np.round(shifted)) < 0.03)
    rgb[mortar] = (0.85, 0.8, 0.72)
    return np.clip(rgb * 255, 0, 255).astype(np.uint8)


def waves_texture(width: int = 128, height: int = 256) -> np.ndarray:
    """(height, width, 3) uint8: white waves on a deep blue ground."""
    y, x = np.mgrid[0:height, 0:width]
    u, v = x / width, y / height
    crest = np.abs(np.sin(2 * np.pi * (6 * v + 0.15 * np.sin(2 * np.pi * 3 * u))))
    foam = np.clip((crest - 0.85) / 0.15, 0, 1)[..., None]
    blue = np.array([0.08, 0.25, 0.65]) * (0.8 + 0.2 * np.cos(2 * np.pi * u))[..., None]
    rgb = (1 - foam) * blue + foam * np.array([0.95, 0.97, 1.0])
    return np.clip(rgb * 255, 0, 255).astype(np.uint8)


def two_material_parts(around: int = 64, rows: int = 16) -> list[Part]:
    """The two hemispheres of a unit sphere (``around`` columns, ``rows`` rings from the
    equator to each pole) with their own UVs (u around, v from the equator, 0..1) and
    images: ``[bricks (north), waves (south)]``.

    Each hemisphere has ``around * (2 rows - 1)`` faces, wound outward."""
    if around < 3 or rows < 1:
        raise ValueError("two-materials needs around >= 3 and rows >= 1")
    theta = np.linspace(0.0, 2 * np.pi, around + 1)
    theta[-1] = 0.0  # bit-equal to the first column: the wrap-around is a seam
    c, s = np.cos(theta), np.sin(theta)
    c[-1], s[-1] = c[0], s[0]
    parts = []
    for north, (name, image) in ((True, ("bricks", bricks_texture())),
                                 (False, ("waves", waves_texture()))):
        phi = np.linspace(0.0, np.pi / 2, rows + 1) * (1 if north else -1)
        ring_r, ring_z = np.cos(phi), np.sin(phi)
        ring_r[0], ring_z[0] = 1.0, 0.0  # the equator: the same positions in both halves
        ring_r[-1] = 0.0  # the pole
        positions = np.stack([ring_r[:, None] * c[None, :], ring_r[:, None] * s[None, :],
                              np.broadcast_to(ring_z[:, None], (rows + 1, around + 1))],
                             axis=-1).reshape(-1, 3)
        u = np.arange(around + 1) / around
        v = np.arange(rows + 1) / rows
        uv = np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)
        pole = rows * (around + 1)
        uv[pole:pole + around, 0] += 0.5 / around  # each pole copy midway over its face
        i, j = np.meshgrid(np.arange(around), np.arange(rows - 1), indexing="xy")
        v00 = j * (around + 1) + i
        quads = np.stack([v00, v00 + 1, v00 + around + 2, v00 + around + 1], -1).reshape(-1, 4)
        cols = np.arange(around)
        top = (rows - 1) * (around + 1) + cols
        faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]],
                                np.stack([top, top + 1, pole + cols], axis=1)])
        if not north:
            faces = faces[:, ::-1]  # the south half is mirrored: flip to wind outward
        used = np.unique(faces)  # the pole's copy at u = 1 has no face
        remap = np.full(len(positions), -1)
        remap[used] = np.arange(len(used))
        # + 0.0 turns -0.0 (0 * a negative cosine at the pole) into 0.0, so the pole's
        # copies are bit-equal and weld
        parts.append(Part(name, positions[used] + 0.0, remap[faces].astype(np.int32),
                          uv=uv[used], image=image, source=f"procedural ({name}_texture)"))
    return parts


def make_two_materials(around: int = 64, rows: int = 16) -> Mesh:
    """The two-material sphere as one mesh: ``bricks`` and ``waves`` packed in one atlas
    (``metadata["atlas"]``), faces of material 0 first."""
    return pack_materials(two_material_parts(around, rows), source="two-materials",
                          name="two-materials",
                          metadata={"source": "procedural (bench.catalog.materials)"})
