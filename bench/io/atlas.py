"""Several materials in one mesh: a texture atlas built at load time.

A :class:`~bench.core.mesh.Mesh` has one texture image, which is what every method and the
renderers understand. An asset as engines ship it has several materials (an OBJ's
``usemtl`` groups, a glTF mesh's primitives), each with its own texture or only a
colour. :func:`pack_materials` turns such parts into one mesh:

* each material becomes a *tile* of one atlas image: its texture as is, texel for
  texel, or, for a material with only a colour, a small solid tile of that colour;
* each tile is surrounded by a gutter of :data:`GUTTER` texels that repeat its edge
  texels, and every tile starts at a multiple of :data:`GUTTER` texels, so bilinear
  filtering and the first three mip levels (blocks of up to 8 x 8 texels) never mix two
  materials' texels;
* each material's UVs are mapped affinely into its tile; a colour-only material's
  corners all sit at its tile's centre;
* ``mesh.metadata["atlas"]`` records, per material in file order, its name, its tile,
  its texture's source and size, its colour and how its UVs were mapped (see
  :func:`pack_materials`), so writers can give each material its own texture and UVs
  back (:func:`split_materials`).

Per-face material ids are derived from the UVs rather than stored
(:func:`face_materials`): methods return new meshes built from the surviving render
vertices, so a stored per-face array would go stale, while UVs travel through every
method. Tiles are disjoint rectangles, so a face's UV centroid lies in exactly one of
them (or, after a method moved a UV into a gutter, nearest to one of them).

Seams between materials come for free: two materials never share a render vertex
(their UVs differ), so where they meet the welded mesh has a seam, and the engine's
seam rule keeps each material's UVs inside its tile. :func:`mixed_faces` finds faces
whose corners lie in two tiles, which is how a method that mixes materials shows.

Repeating textures (UVs outside [0, 1]) cannot sit in a tile as they are: the tile
holds the texture replicated as many times as the material's UVs span periods (u from
-1.5 to 2 is four periods wide), and the UVs are mapped onto the replicated tile. This
keeps the mesh's topology (no vertex is split) and its look (the period boundaries
inside the tile filter as a repeating texture does). A material whose replicated tile
would exceed :data:`MAX_TILE` texels on a side is refused with a one-line error naming
it; mirrored repeats are not modelled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.core.errors import InputError
from bench.core.mesh import Mesh
from bench.io.validate import build_mesh, warn

__all__ = [
    "GUTTER",
    "MAX_ATLAS",
    "MAX_TILE",
    "SOLID",
    "MaterialMesh",
    "Part",
    "corner_materials",
    "face_materials",
    "material_image",
    "materials_of",
    "mixed_faces",
    "pack_materials",
    "split_materials",
    "tiles_of",
    "wedge_tiles",
]

#: Gutter around each tile, in texels; tiles also start at multiples of it.
GUTTER = 8
#: Side of the solid tile of a colour-only material, in texels.
SOLID = 8
#: Largest side of one material's (replicated) tile, in texels.
MAX_TILE = 8192
#: Largest side of the atlas, in texels (a common GPU limit).
MAX_ATLAS = 16384
#: UVs within this of an integer count as on it when counting a repeat's periods, so
#: rounding noise (u = 1.0000001) does not double a texture.
_PERIOD_EPS = 1e-5
#: The metadata key of the material table.
KEY = "atlas"


@dataclass
class Part:
    """One material's share of an asset, as a file holds it.

    Attributes
    ----------
    material : str
        The material's name; parts with the same name share one tile.
    positions : ndarray of shape (n, 3)
    faces : ndarray of shape (m, 3) int
    uv : ndarray of shape (n, 2), optional
        In the material's own UV space (origin bottom-left).
    normals : ndarray of shape (n, 3), optional
    image : ndarray of shape (h, w, 3 or 4) uint8, optional
        The material's texture, row 0 at the top; None for a colour-only material.
    color : sequence of 4 ints
        The material's RGBA colour (0-255): the tile of a colour-only material.
    source : str, optional
        Where the texture came from (a file path), for the record.
    """

    material: str
    positions: np.ndarray
    faces: np.ndarray
    uv: np.ndarray | None = None
    normals: np.ndarray | None = None
    image: np.ndarray | None = None
    color: tuple = (255, 255, 255, 255)
    source: str | None = None


@dataclass
class MaterialMesh:
    """One material of a mesh with its own texture and UVs again (for writers).

    Attributes
    ----------
    material : dict
        The material's entry of ``metadata["atlas"]["materials"]``.
    faces : ndarray of shape (k,) int
        Indices of the mesh's faces with this material.
    vertices : ndarray of shape (n,) int
        The mesh's render vertices these faces use.
    local_faces : ndarray of shape (k, 3) int32
        The faces in indices into ``vertices``.
    uv : ndarray of shape (n, 2)
        UVs in the material's own space (inverse of the atlas mapping).
    image : ndarray of shape (h, w, c) uint8 or None
        The material's texture cut out of the atlas (one period), None when colour-only.
    """

    material: dict
    faces: np.ndarray
    vertices: np.ndarray
    local_faces: np.ndarray
    uv: np.ndarray
    image: np.ndarray | None


def pack_materials(parts: list[Part], *, source: str, name: str,
                   metadata: dict | None = None) -> Mesh:
    """One validated :class:`Mesh` holding ``parts``, their materials packed in an atlas.

    Parameters
    ----------
    parts : list of Part
        In file order; materials are numbered by their first part.
    source : str
        What to name in messages (the file).
    name : str
        The mesh's label.
    metadata : dict, optional
        Extra metadata; ``"atlas"`` is added.

    Returns
    -------
    Mesh
        Faces in part order. ``metadata["atlas"]`` is ``{"gutter", "size": [w, h],
        "materials": [...]}``; each material is ``{"name", "tile": [u0, v0, u1, v1]``
        (its interior in atlas UVs), ``"rect": [x, y, w, h]`` (the same in atlas
        texels, row 0 at the top, one period wide and high), ``"repeat": [nu, nv]``
        and ``"offset": [ou, ov]`` (its UV range [ou, ou + nu] x [ov, ov + nv] fills
        the tile), ``"texture": {"source", "size": [w, h]}`` or None when colour-only,
        ``"color": [r, g, b, a]}``.

    Raises
    ------
    InputError
        A repeating texture too large to replicate, or an atlas beyond
        :data:`MAX_ATLAS`.
    """
    if not parts:
        raise InputError(f"{source}: the mesh has no faces (a point cloud or line set "
                         "cannot be simplified); export it with its triangles")
    order: dict[str, list[Part]] = {}
    for part in parts:
        order.setdefault(part.material, []).append(part)
    materials, tiles = [], []
    for mat_name, members in order.items():
        material, tile = _material_tile(mat_name, members, source)
        materials.append(material)
        tiles.append(tile)
    texture, rects, size = _pack(tiles, source)
    for material, (x, y, w, h) in zip(materials, rects):
        nu, nv = material["repeat"]
        material["rect"] = [x, y, w // nu, h // nv]  # one period
        material["tile"] = _tile_uv(material["rect"], material["repeat"], size)
    index = {n: i for i, n in enumerate(order)}
    positions, faces, uvs, normals = _joined(parts, [materials[index[p.material]]
                                                     for p in parts], source)
    meta = dict(metadata or {})
    meta[KEY] = {"gutter": GUTTER, "size": list(size), "materials": materials}
    return build_mesh(positions, faces, source=source, uv=uvs, normals=normals,
                      texture=texture, name=name, metadata=meta)


def _joined(parts: list[Part], materials: list[dict], source: str):
    """The parts as one mesh's (positions, faces, atlas UVs, normals or None), each
    part's UVs moved into its material's tile (``materials``: each part's)."""
    positions, faces, uvs, normals = [], [], [], []
    offset = 0
    for part, material in zip(parts, materials):
        positions.append(np.asarray(part.positions, dtype=np.float64))
        faces.append(np.asarray(part.faces, dtype=np.int64) + offset)
        uvs.append(_to_atlas(material, part.uv, len(part.positions)))
        normals.append(part.normals)
        offset += len(part.positions)
    if any(n is None for n in normals):
        if any(n is not None for n in normals):
            warn(f"{source}: normals are given for some materials only; all normals are "
                 "derived from the geometry")
        normal_array = None
    else:
        normal_array = np.concatenate(normals)
    return np.concatenate(positions), np.concatenate(faces), np.concatenate(uvs), normal_array


def materials_of(mesh: Mesh) -> list[dict] | None:
    """The material table of a mesh made by :func:`pack_materials`, or None.

    The table is trusted only while the mesh still carries the atlas it describes (a
    method that replaced the texture leaves a stale table, which is ignored)."""
    table = mesh.metadata.get(KEY)
    if not isinstance(table, dict) or mesh.texture is None or mesh.uv is None:
        return None
    h, w = mesh.texture.shape[:2]
    if list(table.get("size", ())) != [w, h]:
        return None
    return table["materials"]


def tiles_of(materials: list[dict]) -> np.ndarray:
    """ndarray of shape (k, 4): each material's tile [u0, v0, u1, v1]."""
    return np.array([m["tile"] for m in materials], dtype=np.float64).reshape(-1, 4)


def corner_materials(mesh: Mesh) -> np.ndarray | None:
    """ndarray of shape (m, 3) int: the tile each face corner's UV lies in (nearest
    tile for a UV in a gutter); None for a mesh without a material table."""
    materials = materials_of(mesh)
    if materials is None:
        return None
    return _nearest_tile(mesh.uv[mesh.faces].reshape(-1, 2), tiles_of(materials)).reshape(-1, 3)


def wedge_tiles(mesh: Mesh) -> np.ndarray | None:
    """ndarray of shape (n, 4): the tile [u0, v0, u1, v1] each render vertex's UV lies
    in (or is nearest to); None for a mesh without a material table. On a loaded mesh
    this is the vertex's material's tile, which a simplifier keeps its UV inside."""
    materials = materials_of(mesh)
    if materials is None:
        return None
    tiles = tiles_of(materials)
    return tiles[_nearest_tile(mesh.uv, tiles)]


def face_materials(mesh: Mesh) -> np.ndarray | None:
    """ndarray of shape (m,) int: each face's material, the tile its UV centroid lies in
    (or is nearest to); None for a mesh without a material table."""
    materials = materials_of(mesh)
    if materials is None:
        return None
    return _nearest_tile(mesh.uv[mesh.faces].mean(axis=1), tiles_of(materials))


def mixed_faces(mesh: Mesh) -> np.ndarray | None:
    """ndarray of shape (m,) bool: faces whose UV corners lie in two or more tiles (a
    method merged two materials' UVs); None for a mesh without a material table."""
    corners = corner_materials(mesh)
    if corners is None:
        return None
    return (corners[:, 0] != corners[:, 1]) | (corners[:, 1] != corners[:, 2])


def material_image(mesh: Mesh, material: dict) -> np.ndarray | None:
    """A material's own texture cut out of ``mesh``'s atlas (one period of a repeat);
    None for a colour-only material."""
    if material.get("texture") is None:
        return None
    x, y, w, h = material["rect"]
    return mesh.texture[y:y + h, x:x + w].copy()


def split_materials(mesh: Mesh, source: str | None = None) -> list[MaterialMesh] | None:
    """``mesh`` cut into its materials, each with its own UVs and texture again; None
    when the mesh has no material table.

    A face goes to the material its UV centroid lies in. Faces whose corners lie in
    two tiles (a method mixed materials) are counted in a warning: their corners'
    UVs fall outside [0, 1] of their material's texture.
    """
    materials = materials_of(mesh)
    if materials is None:
        return None
    of_face = face_materials(mesh)
    mixed = int(mixed_faces(mesh).sum())
    if mixed:
        warn(f"{source or mesh.name}: {mixed} faces have UV corners in two materials' tiles "
             "(the method mixed materials); each is written with the material its UV "
             "centroid lies in")
    out = []
    for k, material in enumerate(materials):
        faces = np.flatnonzero(of_face == k)
        if len(faces) == 0:
            continue
        vertices, local = np.unique(mesh.faces[faces].reshape(-1), return_inverse=True)
        out.append(MaterialMesh(material, faces, vertices,
                                local.reshape(-1, 3).astype(np.int32),
                                _from_atlas(material, mesh.uv[vertices]),
                                material_image(mesh, material)))
    return out


# -- helpers ------------------------------------------------------------------------------

def _material_tile(name: str, members: list[Part], source: str):
    """A material's table entry (without its place) and its tile's interior image."""
    color = [int(c) for c in members[0].color]
    image = members[0].image
    material = {"name": name, "texture": None, "color": color, "repeat": [1, 1],
                "offset": [0.0, 0.0]}
    if image is not None and any(p.uv is None for p in members):
        warn(f"{source}: material '{name}' has a texture but its faces have no UVs; "
             "using its colour")
        image = None
    if image is None:
        tile = np.empty((SOLID, SOLID, 4 if color[3] < 255 else 3), np.uint8)
        tile[:] = color[:tile.shape[2]]
        return material, tile
    image = np.ascontiguousarray(image, dtype=np.uint8)
    used = np.concatenate([np.asarray(p.uv, dtype=np.float64)[np.unique(p.faces)]
                           for p in members])
    if not np.isfinite(used).all():
        raise InputError(f"{source}: material '{name}' has NaN or infinite UVs; fix its "
                         "texture coordinates")
    lo = np.floor(used.min(axis=0) + _PERIOD_EPS)
    hi = np.ceil(used.max(axis=0) - _PERIOD_EPS)
    repeat = np.maximum(hi - lo, 1).astype(np.int64)
    h, w = image.shape[:2]
    if w * repeat[0] > MAX_TILE or h * repeat[1] > MAX_TILE:
        raise InputError(
            f"{source}: material '{name}' repeats its {w} x {h} texture {repeat[0]} x "
            f"{repeat[1]} times (UVs u {used[:, 0].min():.3g}..{used[:, 0].max():.3g}, "
            f"v {used[:, 1].min():.3g}..{used[:, 1].max():.3g}); replicated in the atlas "
            f"that exceeds {MAX_TILE} texels; scale its UVs into fewer periods or bake "
            "the texture")
    material.update(texture={"source": members[0].source, "size": [int(w), int(h)]},
                    repeat=[int(r) for r in repeat], offset=[float(o) for o in lo])
    return material, np.tile(image, (int(repeat[1]), int(repeat[0]), 1))


def _pack(tiles: list[np.ndarray], source: str):
    """Shelf-pack the tiles (with gutters) into one image; returns it, each tile's
    interior [x, y, w, h] (texels, row 0 at the top) and the size (w, h)."""
    channels = max(t.shape[2] for t in tiles)  # RGBA as soon as one material has alpha
    boxes = [(_ceil_to(t.shape[1] + 2 * GUTTER), _ceil_to(t.shape[0] + 2 * GUTTER))
             for t in tiles]
    order = sorted(range(len(tiles)), key=lambda i: (-boxes[i][1], -boxes[i][0], i))
    # Shelves (rows of tiles, tallest first) for a few widths: the widest tile, a square
    # of the total area, each prefix of the row order; the smallest atlas wins, then the
    # squarest, then the narrowest (deterministic).
    area = sum(bw * bh for bw, bh in boxes)
    widths = {max(bw for bw, _ in boxes), _ceil_to(math.ceil(math.sqrt(area)))}
    widths.update(np.cumsum([boxes[i][0] for i in order]).tolist())
    best = None
    for width in sorted(w for w in widths if w >= max(bw for bw, _ in boxes)):
        places, height = _shelves(order, boxes, width)
        rank = (width * height, abs(width - height), width)
        if best is None or rank < best[0]:
            best = (rank, width, height, places)
    _, width, height, places = best
    if width > MAX_ATLAS or height > MAX_ATLAS:
        raise InputError(f"{source}: the materials' textures need a {width} x {height} "
                         f"atlas, more than {MAX_ATLAS} texels on a side; reduce their "
                         "resolution")
    atlas = np.zeros((height, width, channels), np.uint8)
    rects = []
    for i, tile in enumerate(tiles):
        x, y = places[i]
        bw, bh = boxes[i]
        th, tw = tile.shape[:2]
        pixels = _channels(tile, channels)
        atlas[y:y + bh, x:x + bw] = np.pad(pixels, ((GUTTER, bh - th - GUTTER),
                                                    (GUTTER, bw - tw - GUTTER), (0, 0)),
                                           mode="edge")
        rects.append([int(x + GUTTER), int(y + GUTTER), int(tw), int(th)])
    return atlas, rects, (width, height)


def _shelves(order: list[int], boxes: list, width: int):
    """Tiles placed left to right in rows no wider than ``width``, in ``order``;
    returns {tile: (x, y)} and the total height."""
    places, x, y, shelf = {}, 0, 0, 0
    for i in order:
        bw, bh = boxes[i]
        if x + bw > width:
            x, y, shelf = 0, y + shelf, 0
        places[i] = (x, y)
        x, shelf = x + bw, max(shelf, bh)
    return places, y + shelf


def _tile_uv(rect, repeat, size) -> list[float]:
    """The tile [u0, v0, u1, v1] of a rect (one period) repeated ``repeat`` times."""
    x, y, w, h = rect
    width, height = size
    tw, th = w * repeat[0], h * repeat[1]
    return [x / width, (height - y - th) / height, (x + tw) / width, (height - y) / height]


def _to_atlas(material: dict, uv, n: int) -> np.ndarray:
    """A part's UVs in the atlas: affinely onto its material's tile; the tile's centre
    for a colour-only material."""
    u0, v0, u1, v1 = material["tile"]
    lo, span = np.array([u0, v0]), np.array([u1 - u0, v1 - v0])
    if material["texture"] is None:
        return np.broadcast_to(lo + span / 2, (n, 2)).copy()
    offset, repeat = np.array(material["offset"]), np.array(material["repeat"], np.float64)
    return lo + (np.asarray(uv, dtype=np.float64) - offset) / repeat * span


def _from_atlas(material: dict, uv: np.ndarray) -> np.ndarray:
    """The inverse of :func:`_to_atlas`: atlas UVs back in the material's own space
    ((0.5, 0.5) for a colour-only material, whose UVs carry nothing)."""
    if material["texture"] is None:
        return np.full((len(uv), 2), 0.5)
    u0, v0, u1, v1 = material["tile"]
    lo, span = np.array([u0, v0]), np.array([u1 - u0, v1 - v0])
    offset, repeat = np.array(material["offset"]), np.array(material["repeat"], np.float64)
    return offset + (uv - lo) / span * repeat


def _nearest_tile(points: np.ndarray, tiles: np.ndarray) -> np.ndarray:
    """Index of the tile each UV point lies in, or is nearest to (tiles are disjoint)."""
    dx = np.maximum(np.maximum(tiles[None, :, 0] - points[:, None, 0], 0),
                    points[:, None, 0] - tiles[None, :, 2])
    dy = np.maximum(np.maximum(tiles[None, :, 1] - points[:, None, 1], 0),
                    points[:, None, 1] - tiles[None, :, 3])
    return np.argmin(dx * dx + dy * dy, axis=1)


def _channels(image: np.ndarray, channels: int) -> np.ndarray:
    if image.shape[2] == channels:
        return image
    if channels == 3:
        return image[..., :3]
    alpha = np.full(image.shape[:2] + (1,), 255, np.uint8)
    return np.concatenate([image, alpha], axis=2)


def _ceil_to(n: int, step: int = GUTTER) -> int:
    return -(-int(n) // step) * step
