"""Loading and saving meshes (OBJ + MTL + texture, PLY, glTF/GLB, OFF, STL) via trimesh.

Loaders keep render vertices as the file defines them: trimesh's OBJ reader creates one
vertex per distinct (position, texture coordinate, normal) corner, which is exactly our
render-vertex model; the welded topology is recovered from equal positions.

A few problems trimesh would either hide (polygons triangulated, a texture file not
found) or report from deep inside (an index out of range) are detected by a light scan
of the file first, so the user gets one line naming the file and the problem.

**Several materials.** A mesh has one texture, which every method and renderer
understands. An OBJ with two or more ``usemtl`` materials, or a glTF whose primitives
use two or more materials, is loaded as one mesh whose materials are packed into a
texture atlas built at load time (:mod:`bench.io.atlas`): each material's texture
becomes a tile, texel for texel, with an 8-texel gutter repeating its edge (bilinear
filtering and the first three mip levels never mix materials); a textured material's
``Kd`` or base colour factor is recorded, not multiplied in, as for a file with one
material; a material with only a colour becomes a small solid tile of it; each
material's UVs are mapped affinely into its tile, and ``mesh.metadata["atlas"]`` lists
the materials in file order with their tiles. A face's material is the tile its UV centroid lies in
(:func:`bench.io.atlas.face_materials`), which survives every method, where a stored
per-face array would not. Repeating textures (UVs outside [0, 1]) are replicated in
their tile as often as the UVs span periods (no vertex is split), up to 8,192 texels a
side; beyond, loading stops with a one-line error naming the material. Faces without a
material in such a file form one more, white, material, ``default``. A file with one
material loads exactly as before (no atlas).

Writing a mesh with materials gives each material back: an OBJ gets one ``usemtl``
group per material (in the table's order, names kept) with its own texture
(``<stem>_<material>.png``) and its UVs mapped back out of the atlas, a colour-only
material its ``Kd`` and no image; a glTF/GLB gets one mesh (named after the file, or
per LOD level) with one primitive per material, each with its own named material and
texture (a colour-only one its base colour). Reading the file back gives the same
materials, faces per material and texels. Faces whose UV corners lie in two tiles (a
method mixed materials) are written with the material of their UV centroid, with a
warning. Other formats (PLY, OFF, STL) have no materials and get the atlas UVs, as
before.
"""

from __future__ import annotations

import hashlib
import io
import logging
import os
import re
import tempfile
from pathlib import Path

import numpy as np

from bench.errors import InputError
from bench.io.atlas import split_materials
from bench.io.validate import build_mesh, warn
from bench.mesh import Mesh

__all__ = ["FORMATS", "SCENE_FORMATS", "check_output_path", "load_mesh", "lod_path", "save_lods",
           "save_mesh"]

#: Supported file extensions and what they keep.
FORMATS = {
    ".obj": "positions, UVs, normals, texture (via MTL map_Kd), materials (usemtl groups)",
    ".ply": "positions, UVs, colours (no texture image)",
    ".gltf": "positions, UVs, normals, colours, base-colour texture, materials (primitives)",
    ".glb": "positions, UVs, normals, colours, base-colour texture, materials (primitives)",
    ".off": "positions, colours",
    ".stl": "positions only",
}

#: Formats that hold several named meshes in one file (an LOD chain is one file there).
SCENE_FORMATS = (".glb", ".gltf")

logging.getLogger("trimesh").setLevel(logging.ERROR)  # our own warnings say what matters


def load_mesh(path: str | os.PathLike, name: str | None = None) -> Mesh:
    """Read a mesh file into a validated :class:`Mesh`.

    Parameters
    ----------
    path : str or PathLike
        A file with one of the extensions in :data:`FORMATS`.
    name : str, optional
        Label for the mesh; defaults to the file's stem.

    Raises
    ------
    InputError
        Missing file, unknown format, unparsable content, or invalid data
        (see :mod:`bench.io.validate`).
    """
    path = Path(path)
    source = str(path)
    if not path.exists():
        raise InputError(f"{source}: no such file")
    if path.is_dir():
        raise InputError(f"{source}: is a directory, not a mesh file")
    ext = path.suffix.lower()
    if ext not in FORMATS:
        raise InputError(f"{source}: unknown mesh format '{ext or '(none)'}'; "
                         f"supported: {', '.join(FORMATS)}")

    scan = {".obj": _scan_obj, ".ply": _scan_ply}.get(ext, lambda p: {})(path)

    import trimesh

    try:
        scene = trimesh.load_scene(str(path), process=False, skip_materials=False)
        keys = _material_keys(scene, ext, scan)
        several = len(set(keys.values())) > 1 and any(k is not None for k in keys.values())
        # one material: what trimesh.load(force="mesh") returns, as always
        loaded = scene.dump() if several else scene.to_mesh()
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds; the user needs one line
        raise InputError(f"{source}: could not read as {ext[1:].upper()} "
                         f"({type(exc).__name__}: {exc})") from None
    if several:
        return _load_materials(loaded, keys, source, ext, scan, name or path.stem)
    if not isinstance(loaded, trimesh.Trimesh) or len(getattr(loaded, "faces", ())) == 0:
        raise InputError(f"{source}: the mesh has no faces (a point cloud or line set "
                         "cannot be simplified); export it with its triangles")

    if scan.get("polygons"):
        warn(f"{source}: triangulated {scan['polygons']} faces with more than 3 corners")
    if scan.get("ply_faces") is not None and len(loaded.faces) > scan["ply_faces"]:
        warn(f"{source}: triangulated polygon faces ({scan['ply_faces']} faces in the file "
             f"became {len(loaded.faces)} triangles)")

    uv, texture, colors, normals = _attributes(loaded, source, ext, scan)
    return build_mesh(loaded.vertices, loaded.faces, source=source, uv=uv, normals=normals,
                      colors=colors, texture=texture, name=name or path.stem,
                      metadata={"source": source})


def save_mesh(mesh: Mesh, path: str | os.PathLike) -> list[Path]:
    """Write ``mesh`` to ``path``; the format follows the extension.

    OBJ writes ``<stem>.mtl`` and ``<stem>.png`` beside the OBJ when the mesh is
    textured, so several results can share a folder. Returns the files written.
    """
    path = check_output_path(path)
    ext = path.suffix.lower()
    if ext == ".obj" or ext in SCENE_FORMATS:
        split = split_materials(mesh, source=str(path))
        if split is not None and ext == ".obj":
            return _save_obj_materials(mesh, split, path)
        if split is not None:
            scene, groups = _scene([(path.stem, mesh, split)], path.stem)
            return _write_export(scene, path, tree_postprocessor=_one_mesh_per_group(groups))
    tm = _to_trimesh(mesh, material_name=path.stem)
    if ext == ".obj":
        from trimesh.exchange.obj import export_obj

        text, files = export_obj(tm, include_normals=mesh.normals is not None,
                                 include_texture=True, return_texture=True,
                                 mtl_name=f"{path.stem}.mtl", digits=10)
        written = [_write_atomic(path, text.encode())]
        for fname, data in files.items():
            written.append(_write_atomic(path.parent / fname, data))
        return written
    return _write_export(tm, path)


def lod_path(path: str | os.PathLike, name: str) -> Path:
    """Where level ``name`` of an LOD chain written to ``path`` goes in a format with
    one mesh per file: ``<stem>_<name><ext>`` beside ``path`` (``out.obj`` ->
    ``out_LOD1.obj``, with ``out_LOD1.mtl`` and ``out_LOD1.png`` for a textured level).
    """
    path = Path(path)
    return path.with_name(f"{path.stem}_{name}{path.suffix}")


def save_lods(levels: list[tuple[str, Mesh]], path: str | os.PathLike) -> dict[str, list[Path]]:
    """Write an LOD chain: ``levels`` are (name, mesh) pairs, the most detailed first.

    In a format of :data:`SCENE_FORMATS` it is one file, ``path``, with one named mesh
    (and node, all at the origin) per level, as engines import LOD groups; levels that
    share a texture share one material and image. In any other format each level is a
    file of its own at :func:`lod_path` and ``path`` itself is not written.

    Returns
    -------
    dict of str to list of Path
        For each level, the files that hold it (the one scene file in a scene format).
    """
    path = check_output_path(path)
    if path.suffix.lower() not in SCENE_FORMATS:
        return {name: save_mesh(mesh, lod_path(path, name)) for name, mesh in levels}
    import trimesh

    splits = [split_materials(mesh, source=f"{path} {name}") for name, mesh in levels]
    if any(split is not None for split in splits):
        scene, groups = _scene([(name, mesh, split) for (name, mesh), split
                                in zip(levels, splits)], path.stem)
        written = _write_export(scene, path, tree_postprocessor=_one_mesh_per_group(groups))
        return {name: written for name, _ in levels}
    scene, materials = trimesh.Scene(), {}
    for name, mesh in levels:
        key = _texture_key(mesh.texture)
        tm = _to_trimesh(mesh, material_name=path.stem, material=materials.get(key))
        if mesh.uv is not None:
            materials.setdefault(key, tm.visual.material)
        scene.add_geometry(tm, geom_name=name, node_name=name)
    written = _write_export(scene, path)
    return {name: written for name, _ in levels}


def check_output_path(path: str | os.PathLike) -> Path:
    """``path`` as a Path if a mesh can be written there; InputError otherwise."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in FORMATS:
        raise InputError(f"{path}: unknown mesh format '{ext or '(none)'}'; "
                         f"supported: {', '.join(FORMATS)}")
    if not path.parent.is_dir():
        raise InputError(f"{path}: folder {path.parent} does not exist; create it first")
    if path.is_dir():
        raise InputError(f"{path}: is a directory; give a file name such as {path / 'out'}{ext}")
    return path


# -- helpers ------------------------------------------------------------------------------

def _attributes(tm, source: str, ext: str, scan: dict):
    """UV, texture, colours and (file) normals of a loaded trimesh object.

    A texture image is kept only when the file really provides one: trimesh substitutes
    a small placeholder image for textured meshes without a material, which must not
    pass for the asset's texture.
    """
    from trimesh.visual import ColorVisuals, TextureVisuals

    uv = texture = colors = normals = None
    visual = tm.visual
    if isinstance(visual, TextureVisuals):
        if visual.uv is not None and len(visual.uv) == len(tm.vertices):
            uv = np.asarray(visual.uv, dtype=np.float64)
        has_image_file = {".obj": bool(scan.get("texture_files")),
                          ".gltf": True, ".glb": True}.get(ext, False)
        image = _material_image(visual.material) if has_image_file else None
        if image is not None and uv is not None:
            texture = _image_array(image)
        if scan.get("texture_refs"):
            missing = ", ".join(scan["texture_refs"])
            warn(f"{source}: texture image not found ({missing}); loading untextured"
                 + (" (UVs kept)" if uv is not None else ""))
    elif isinstance(visual, ColorVisuals) and visual.kind == "vertex":
        colors = np.asarray(visual.vertex_colors, dtype=np.uint8)
    if "vertex_normals" in tm._cache.cache:  # present only when the file had normals
        normals = np.asarray(tm._cache.cache["vertex_normals"], dtype=np.float64)
    return uv, texture, colors, normals


def _material_keys(scene, ext: str, scan: dict) -> dict:
    """Which material each geometry of a loaded OBJ or glTF scene uses, by geometry
    name: a hashable key, or None for faces without a material. Two or more distinct
    keys make the file a multi-material asset (:func:`_load_materials`).

    In an OBJ, a material counts when a ``usemtl`` line names it (trimesh invents a
    placeholder material for faces with UVs and none). In glTF, two primitives have
    the same material when its name, texture and colour agree.
    """
    import trimesh
    from trimesh.visual import TextureVisuals

    if ext not in (".obj", ".gltf", ".glb"):
        return {}
    declared = set(scan.get("usemtl", ()))
    keys = {}
    for name, geom in scene.geometry.items():
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        visual = geom.visual
        material = visual.material if isinstance(visual, TextureVisuals) else None
        if material is None:
            keys[name] = None
        elif ext == ".obj":
            keys[name] = material.name if material.name in declared else None
        else:
            image = getattr(material, "baseColorTexture", None)
            keys[name] = (material.name, _texture_key(None if image is None
                                                      else _image_array(image)),
                          tuple(_material_color(material)))
    return keys


def _load_materials(dumped: list, keys: dict, source: str, ext: str, scan: dict,
                    name: str) -> Mesh:
    """A multi-material OBJ or glTF, its geometries ``dumped`` from trimesh's scene
    (transforms applied), as one mesh with a texture atlas (:mod:`bench.io.atlas`).
    Materials are numbered in file order (an OBJ's first ``usemtl`` of each, a glTF's
    primitives); faces without a material form one more, white, material (the suite's
    untextured albedo) named ``default``."""
    import trimesh
    from trimesh.visual import ColorVisuals, TextureVisuals

    from bench.io.atlas import Part, pack_materials

    if scan.get("polygons"):
        warn(f"{source}: triangulated {scan['polygons']} faces with more than 3 corners")
    dumped = [g for g in dumped if isinstance(g, trimesh.Trimesh)
              and g.metadata.get("name") in keys]
    order = list(dict.fromkeys(keys.values()))
    if ext == ".obj":
        usemtl = scan.get("usemtl", [])
        order.sort(key=lambda k: usemtl.index(k) if k in usemtl else len(usemtl))
    names = _material_names(order, ext)
    textures = scan.get("material_textures", {})
    parts, recoloured = [], 0
    for geom in sorted(dumped, key=lambda g: order.index(keys[g.metadata["name"]])):
        key = keys[geom.metadata["name"]]
        visual = geom.visual
        material = visual.material if isinstance(visual, TextureVisuals) else None
        uv = None
        if isinstance(visual, TextureVisuals) and visual.uv is not None \
                and len(visual.uv) == len(geom.vertices):
            uv = np.asarray(visual.uv, dtype=np.float64)
        image, texture_source, color = None, None, (255, 255, 255, 255)
        if key is not None:
            color = _material_color(material)
            if ext == ".obj":
                texture_source, exists = textures.get(key, (None, False))
                if texture_source is not None and not exists:
                    warn(f"{source}: material '{key}': texture image not found "
                         f"({texture_source}); using its colour")
                    texture_source = None
            else:
                texture_source = source
            picture = _material_image(material) if texture_source is not None else None
            image = None if picture is None else _image_array(picture)
        elif isinstance(visual, ColorVisuals) and visual.kind == "vertex":
            color = tuple(int(c) for c in np.asarray(visual.vertex_colors).mean(axis=0).round())
            recoloured += 1
        parts.append(Part(names[key], geom.vertices, geom.faces, uv=uv, image=image,
                          color=color, source=texture_source))
    if recoloured:
        warn(f"{source}: vertex colours of {recoloured} parts without a material replaced "
             "by their mean colour (a multi-material mesh keeps one colour per material)")
    return pack_materials(parts, source=source, name=name, metadata={"source": source})


def _material_names(order: list, ext: str) -> dict:
    """A unique name per material key: the file's name, ``material_<i>`` for an
    unnamed glTF material, ``default`` for faces without a material."""
    names, taken = {}, set()
    for i, key in enumerate(order):
        if key is None:
            base = "default"
        elif ext == ".obj":
            base = key
        else:
            base = key[0] or f"material_{i}"
        unique, n = base, 1
        while unique in taken:
            n += 1
            unique = f"{base}_{n}"
        taken.add(unique)
        names[key] = unique
    return names


def _material_color(material) -> tuple:
    """A trimesh material's RGBA colour (0-255): glTF's base colour factor, an MTL's
    Kd; white when the file gives none."""
    color = getattr(material, "baseColorFactor", None)
    if color is None:
        color = getattr(material, "diffuse", None)
    if color is None:
        return (255, 255, 255, 255)
    color = np.asarray(color).reshape(-1)
    if color.dtype.kind == "f":
        color = np.round(np.clip(color, 0, 1) * 255)
    rgba = [int(c) for c in color[:4]] + [255] * (4 - min(4, len(color)))
    return tuple(rgba)


def _material_image(material):
    if material is None:
        return None
    image = getattr(material, "image", None)
    if image is None:
        image = getattr(material, "baseColorTexture", None)
    return image


def _image_array(image) -> np.ndarray:
    if image.mode not in ("RGB", "RGBA"):
        image = image.convert("RGBA" if "A" in image.mode else "RGB")
    return np.asarray(image, dtype=np.uint8).copy()


def _texture_key(texture: np.ndarray | None):
    """Identifies a texture by content, so levels whose method copied the image still
    share one material (and the file one image)."""
    if texture is None:
        return None
    return texture.shape, hashlib.sha1(np.ascontiguousarray(texture).tobytes()).hexdigest()


def _write_export(tm, path: Path, **options) -> list[Path]:
    """Export a trimesh mesh or scene in the format of ``path``'s extension (``options``
    go to trimesh's exporter); the files written (a ``.gltf`` with its buffers renamed
    after ``path``)."""
    data = tm.export(file_type=path.suffix.lower()[1:], **options)
    if isinstance(data, dict):  # .gltf: the JSON plus its buffers, renamed after OUT
        gltf = data.pop("model.gltf")
        written = []
        for name, blob in data.items():
            own = f"{path.stem}_{name}"
            gltf = gltf.replace(f'"{name}"'.encode(), f'"{own}"'.encode())
            written.append(_write_atomic(path.parent / own, blob))
        return [_write_atomic(path, gltf)] + written
    return [_write_atomic(path, data if isinstance(data, bytes) else data.encode())]


def _to_trimesh(mesh: Mesh, material_name: str, material=None):
    """``mesh`` as a trimesh mesh; a textured one gets ``material`` if given (so the
    levels of a chain can share one), else a new material named ``material_name``."""
    import trimesh
    from PIL import Image

    kwargs = {}
    if mesh.normals is not None:
        kwargs["vertex_normals"] = mesh.normals
    tm = trimesh.Trimesh(mesh.positions, mesh.faces, process=False, **kwargs)
    if mesh.uv is not None:
        if material is None:
            image = Image.fromarray(mesh.texture) if mesh.texture is not None else None
            material = trimesh.visual.material.SimpleMaterial(image=image, name=material_name)
        tm.visual = trimesh.visual.TextureVisuals(uv=mesh.uv, material=material)
    elif mesh.colors is not None:
        tm.visual = trimesh.visual.ColorVisuals(tm, vertex_colors=mesh.colors)
    return tm


def _save_obj_materials(mesh: Mesh, split: list, path: Path) -> list[Path]:
    """A multi-material mesh as an OBJ with one ``usemtl`` group per material, each with
    its own texture again (``<stem>_<material>.png``) and its UVs in that texture's
    space; positions are written once per welded vertex, exactly (17 digits)."""
    from PIL import Image

    stem, welded = path.stem, mesh.welded
    lines = [f"mtllib {stem}.mtl", _rows("v", welded.positions)]
    mtl, images, vt_base, vn_base = [], {}, 1, 1
    names = _obj_names([part.material["name"] for part in split])
    for part, name in zip(split, names):
        material = part.material
        lines.append(f"usemtl {name}")
        lines.append(_rows("vt", part.uv))
        corners = [welded.vertex_of[part.vertices][part.local_faces] + 1,
                   part.local_faces + vt_base]
        if mesh.normals is not None:
            lines.append(_rows("vn", mesh.normals[part.vertices]))
            corners.append(part.local_faces + vn_base)
            vn_base += len(part.vertices)
        vt_base += len(part.vertices)
        stacked = np.stack(corners, axis=-1).reshape(len(part.local_faces), -1)
        fmt = " ".join(["/".join(["{}"] * len(corners))] * 3)
        lines.append("\n".join("f " + fmt.format(*row) for row in stacked.tolist()))
        r, g, b, a = (c / 255 for c in material["color"])
        mtl += [f"newmtl {name}", f"Kd {r:.6g} {g:.6g} {b:.6g}"]
        if a < 1:
            mtl.append(f"d {a:.6g}")
        if part.image is not None:
            image_name = f"{stem}_{name}.png"
            buffer = io.BytesIO()
            Image.fromarray(part.image).save(buffer, format="PNG")
            images[image_name] = buffer.getvalue()
            mtl.append(f"map_Kd {image_name}")
        mtl.append("")
    written = [_write_atomic(path, ("\n".join(lines) + "\n").encode()),
               _write_atomic(path.parent / f"{stem}.mtl", "\n".join(mtl).encode())]
    written += [_write_atomic(path.parent / fname, data) for fname, data in images.items()]
    return written


def _obj_names(names: list[str]) -> list[str]:
    """Material names usable in an OBJ (no whitespace), unique."""
    out, taken = [], set()
    for name in names:
        base = re.sub(r"\s+", "_", name.strip()) or "material"
        unique, n = base, 1
        while unique in taken:
            n += 1
            unique = f"{base}_{n}"
        taken.add(unique)
        out.append(unique)
    return out


def _rows(tag: str, values: np.ndarray) -> str:
    """OBJ lines ``tag x y [z]`` with every double written exactly."""
    buffer = io.StringIO()
    np.savetxt(buffer, values, fmt="%.17g", delimiter=" ", newline="\n")
    return "\n".join(f"{tag} {row}" for row in buffer.getvalue().splitlines())


def _scene(levels: list, stem: str):
    """A trimesh scene with one geometry per material of each level (one geometry for
    a level without a material table), and the groups of geometry names that make one
    glTF mesh each: ``[(level name, [geometry names])]``. Materials are shared between
    levels, so a chain's file holds each texture once."""
    import trimesh
    from PIL import Image

    scene, groups, materials = trimesh.Scene(), [], {}
    for level, mesh, split in levels:
        if split is None:
            tm = _to_trimesh(mesh, material_name=stem,
                             material=materials.get(_texture_key(mesh.texture)))
            if mesh.uv is not None:
                materials.setdefault(_texture_key(mesh.texture), tm.visual.material)
            scene.add_geometry(tm, geom_name=level, node_name=level)
            groups.append((level, [level]))
            continue
        members = []
        for i, part in enumerate(split):
            name = part.material["name"]
            key = (name, _texture_key(part.image), tuple(part.material["color"]))
            if key not in materials:
                textured = part.image is not None
                materials[key] = trimesh.visual.material.PBRMaterial(
                    name=name, baseColorTexture=Image.fromarray(part.image) if textured else None,
                    baseColorFactor=[255, 255, 255, 255] if textured else part.material["color"])
            kwargs = {}
            if mesh.normals is not None:
                kwargs["vertex_normals"] = mesh.normals[part.vertices]
            tm = trimesh.Trimesh(mesh.positions[part.vertices], part.local_faces,
                                 process=False, **kwargs)
            tm.visual = trimesh.visual.TextureVisuals(uv=part.uv, material=materials[key])
            geom = f"{level}/{i}"
            scene.add_geometry(tm, geom_name=geom, node_name=geom)
            members.append(geom)
        groups.append((level, members))
    return scene, groups


def _one_mesh_per_group(groups: list):
    """A glTF tree post-processor: each group of geometries (one per material) becomes
    one mesh with one primitive per material and one node, both named after the group
    (trimesh writes one mesh per geometry)."""
    def merge(tree: dict) -> None:
        by_name = {m["name"]: m for m in tree.get("meshes", [])}
        tree["meshes"] = [{"name": group, "primitives": [by_name[g]["primitives"][0]
                                                         for g in members]}
                          for group, members in groups]
        tree["nodes"] = [{"name": group, "mesh": i} for i, (group, _) in enumerate(groups)]
        tree["scenes"][0]["nodes"] = list(range(len(groups)))
    return merge


def _write_atomic(path: Path, data: bytes) -> Path:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.replace(tmp, path)
    return path


def _scan_obj(path: Path) -> dict:
    """Index ranges, polygon count and texture references of an OBJ, without parsing
    it fully (trimesh does that). Raises InputError on out-of-range indices."""
    data = path.read_bytes()
    n_v = polygons = 0
    max_index = 0
    worst = None
    mtllibs = []
    usemtl: dict[str, None] = {}  # material names in order of first use
    for lineno, line in enumerate(io.BytesIO(data), 1):
        head = line[:2]
        if head == b"v " or head == b"v\t":
            n_v += 1
        elif head == b"f " or head == b"f\t":
            tokens = line.split()[1:]
            if len(tokens) > 3:
                polygons += 1
            for tok in tokens:
                try:
                    idx = int(tok.split(b"/", 1)[0])
                except ValueError:
                    raise InputError(f"{path}: line {lineno}: bad face index "
                                     f"'{tok.decode(errors='replace')}'") from None
                if idx < 0:
                    resolved = n_v + idx + 1
                    if resolved < 1 and worst is None:
                        worst = (lineno, idx, n_v)
                elif idx == 0 and worst is None:
                    worst = (lineno, idx, n_v)
                elif idx > max_index:
                    max_index, max_line = idx, lineno
        elif line.startswith(b"mtllib"):
            mtllibs.extend(line.split()[1:])
        elif line.startswith(b"usemtl"):
            words = line.split()
            if len(words) > 1:
                usemtl.setdefault(words[1].decode(errors="replace"), None)
    if worst is not None:
        lineno, idx, n = worst
        raise InputError(f"{path}: line {lineno}: face index {idx} is out of range "
                         f"({n} vertices defined before it); the file is corrupt or truncated")
    if max_index > n_v:
        raise InputError(f"{path}: line {max_line}: face index {max_index} is out of range "
                         f"(the file has {n_v} vertices); the file is corrupt or truncated")
    refs, found, textures = [], [], {}
    for lib in mtllibs:
        mtl = path.parent / lib.decode(errors="replace")
        if not mtl.exists():
            refs.append(f"{mtl.name} (material file)")
            continue
        current = None
        for line in mtl.read_bytes().splitlines():
            parts = line.strip().split()
            if parts and parts[0].lower() == b"newmtl" and len(parts) > 1:
                current = parts[1].decode(errors="replace")
            elif parts and parts[0].lower() in (b"map_kd", b"map_ka") and len(parts) > 1:
                tex = parts[-1].decode(errors="replace")
                exists = (mtl.parent / tex).exists()
                (found if exists else refs).append(tex)
                if parts[0].lower() == b"map_kd" and current is not None:
                    textures[current] = (str(mtl.parent / tex), exists)
    return {"polygons": polygons, "texture_refs": refs, "texture_files": found,
            "usemtl": list(usemtl), "material_textures": textures}


def _scan_ply(path: Path) -> dict:
    """Face count from the PLY header (ASCII even in binary files), to count the faces
    trimesh triangulated."""
    with open(path, "rb") as f:
        header = f.read(4096).split(b"end_header", 1)[0]
    match = re.search(rb"element\s+face\s+(\d+)", header)
    return {"ply_faces": int(match.group(1))} if match else {}
