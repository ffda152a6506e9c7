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
import math
import os
import re
import stat
from pathlib import Path

import numpy as np

from bench.core.errors import InputError
from bench.core.mesh import Mesh
from bench.io.atlas import split_materials
from bench.io.atomic import write_atomic
from bench.io.cache import cached_read, file_identity
from bench.io.cache import named_files as cached_named_files
from bench.io.ply import ply_bytes
from bench.io.validate import UV_LIMIT, build_mesh, check_uv, warn

__all__ = ["FORMATS", "SCENE_FORMATS", "apply_texture", "check_not_inputs", "check_output_path",
           "glb_bytes", "input_files", "load_mesh", "lod_path", "save_lods", "save_mesh"]

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


def load_mesh(path: str | os.PathLike, name: str | None = None, *,
              texture_file: str | os.PathLike | None = None) -> Mesh:
    """Read a mesh file into a validated :class:`Mesh`.

    Parameters
    ----------
    path : str or PathLike
        A file with one of the extensions in :data:`FORMATS`.
    name : str, optional
        Label for the mesh; defaults to the file's stem.
    texture_file : str or PathLike, optional
        An image to use as the mesh's texture, in place of the file's own (an OBJ
        with UVs and no ``mtllib`` names none): see :func:`apply_texture`.

    Raises
    ------
    InputError
        Missing file, unknown format, unparsable content, or invalid data
        (see :mod:`bench.io.validate`).
    """
    path = Path(path)
    source = str(path)
    ext = _mesh_format(path, source)
    return cached_read(path, name, texture_file,
                       lambda: _read_mesh(path, source, ext, name, texture_file),
                       lambda: _named_files(path, ext))


def _read_mesh(path: Path, source: str, ext: str, name: str | None, texture_file) -> Mesh:
    """:func:`load_mesh` without the cache."""
    scan = {".obj": _scan_obj_once, ".ply": _scan_ply, ".off": _scan_off, ".gltf": _scan_gltf,
            ".glb": _scan_gltf}.get(ext, lambda p: {})(path)

    import trimesh

    loaded, keys, several = _read_scene(path, source, ext, scan)
    if several:
        mesh = _load_materials(loaded, keys, source, ext, scan, name or path.stem)
        return mesh if texture_file is None else apply_texture(mesh, texture_file)
    if not isinstance(loaded, trimesh.Trimesh) or len(getattr(loaded, "faces", ())) == 0:
        raise InputError(f"{source}: the mesh has no faces (a point cloud or line set "
                         "cannot be simplified); export it with its triangles")

    _warn_faces(source, scan)
    _check_counts(loaded, source, scan)
    uv, texture, colors, normals = _attributes(loaded, source, ext, scan)
    if uv is not None:
        _check_file_uv(uv, source, path if ext == ".obj" else None)
    if uv is not None and texture_file is None and ext == ".obj" and not scan.get("mtllib"):
        _warn_no_material(path)
    mesh = build_mesh(loaded.vertices, loaded.faces, source=source, uv=uv, normals=normals,
                      colors=colors, texture=texture, name=name or path.stem,
                      metadata={"source": source, **_surface(loaded.visual)})
    return mesh if texture_file is None else apply_texture(mesh, texture_file)


def _mesh_format(path: Path, source: str) -> str:
    """The extension of ``path``, a readable regular file of a format :data:`FORMATS`
    names whose first bytes look like that format; an InputError otherwise."""
    if not path.exists():
        raise InputError(f"{source}: no such file")
    if path.is_dir():
        raise InputError(f"{source}: is a directory, not a mesh file")
    ext = path.suffix.lower()
    if ext not in FORMATS:
        raise InputError(f"{source}: unknown mesh format '{ext or '(none)'}'; "
                         f"supported: {', '.join(FORMATS)}")
    _check_readable(path, source)
    _check_signature(path, ext, source)
    return ext


def _read_scene(path: Path, source: str, ext: str, scan: dict):
    """The file read by trimesh: ``(loaded, keys, several)``, with ``keys`` each
    geometry's material key and ``several`` whether there is more than one material
    (then ``loaded`` is the scene's meshes, else one mesh)."""
    import trimesh

    try:
        if scan.get("text") is not None:  # re-encoded as UTF-8, or polygons ear-clipped
            scene = trimesh.load_scene(io.BytesIO(scan["text"].encode("utf-8")),
                                       file_type=scan.get("file_type", "obj"),
                                       resolver=_TextResolver(str(path),
                                                              scan.get("texture_aliases")),
                                       process=False, skip_materials=False)
        else:  # the resolver opens regular files only (a named pipe would block)
            scene = trimesh.load_scene(str(path), process=False, skip_materials=False,
                                       resolver=_TextResolver(str(path),
                                                              scan.get("texture_aliases")))
        keys = _material_keys(scene, ext, scan)
        several = len(set(keys.values())) > 1 and any(k is not None for k in keys.values())
        # one material: what trimesh.load(force="mesh") returns, as always
        loaded = scene.dump() if several else scene.to_mesh()
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds; the user needs one line
        raise InputError(f"{source}: could not read as {ext[1:].upper()} "
                         f"({type(exc).__name__}: {exc})") from None
    return loaded, keys, several


def _check_counts(loaded, source: str, scan: dict) -> None:
    """InputError when fewer vertices or faces were read than a PLY header declares; a
    warning for each face dropped or split."""
    if scan.get("ply_vertices") is not None and len(loaded.vertices) < scan["ply_vertices"]:
        raise InputError(f"{source}: only {len(loaded.vertices)} of the "
                         f"{scan['ply_vertices']} vertices its header declares could be read; "
                         "the file is corrupt or truncated")
    if scan.get("ply_faces") is not None and len(loaded.faces) < _ply_expected(scan):
        raise InputError(f"{source}: only {len(loaded.faces)} of the {scan['ply_faces']} faces "
                         "its header declares could be read; the file is corrupt or truncated")
    if "ply_polygons" in scan:  # every face counted: each dropped or split one is named
        _warn_ply_faces(source, scan)
    elif scan.get("ply_faces") is not None and len(loaded.faces) > scan["ply_faces"]:
        concave = scan.get("concave", 0)
        warn(f"{source}: triangulated polygon faces ({scan['ply_faces']} faces in the file "
             f"became {len(loaded.faces)} triangles"
             + (f"; {concave} concave, by ear clipping)" if concave else ")"))


#: Extensions of the image files an OBJ's texture may be (for :func:`_warn_no_material`).
_IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tga", ".bmp", ".tif", ".tiff", ".webp")


def _warn_no_material(path: Path) -> None:
    """The warning for an OBJ with texture coordinates and no ``mtllib`` line (so no
    texture), when an image beside it looks like its texture: one with the OBJ's stem,
    else the folder's only image. Said how to give it (``PATH::texture=IMAGE``)."""
    images = sorted(p for p in path.parent.iterdir()
                    if p.suffix.lower() in _IMAGE_EXTENSIONS and p.is_file())
    same = [p for p in images if p.stem == path.stem]
    likely = same[0] if same else images[0] if len(images) == 1 else None
    if likely is None:
        return
    warn(f"{path}: has texture coordinates but no material file (no mtllib line), so it "
         f"loads untextured; {likely.name} beside it looks like its texture: give it as "
         f"{path}::texture={likely} (bench simplify: --texture {likely})")


def apply_texture(mesh: Mesh, texture_file: str | os.PathLike) -> Mesh:
    """``mesh`` with the image ``texture_file`` as its texture (replacing its own), for
    a model given as ``PATH::texture=IMAGE`` or with ``bench simplify --texture``; the
    image's path is kept in ``metadata["texture"]`` (never written over). A relative
    path is taken from the current folder. InputError for a missing or unreadable
    image, a mesh without texture coordinates, or one with several materials (each has
    its own texture)."""
    texture_file = Path(texture_file)
    source = mesh.metadata.get("model") or mesh.metadata.get("source") or mesh.name
    if not texture_file.is_file():
        beside = Path(source).parent / texture_file
        hint = (f"; relative paths are from the current folder: did you mean {beside}?"
                if not texture_file.is_absolute() and beside.is_file() else "")
        what = "is a directory, not an image" if texture_file.is_dir() else \
            "is not a regular file (a named pipe or device), not an image" \
            if texture_file.exists() else "no such texture image"
        raise InputError(f"{texture_file}: {what} (the texture given for {source}){hint}")
    if mesh.uv is None:
        raise InputError(f"{source}: has no texture coordinates, so the texture "
                         f"{texture_file} cannot be applied to it; give a mesh with UVs")
    atlas = mesh.metadata.get("atlas")
    if atlas:
        raise InputError(f"{source}: has {len(atlas['materials'])} materials, each with its "
                         f"own texture; a texture ({texture_file}) can be given only for a "
                         "mesh with one material")
    from PIL import Image

    try:
        with Image.open(texture_file) as image:
            image.load()
            pixels = _image_array(image)
    except Exception:  # noqa: BLE001 - PIL raises many kinds; one line for the user
        raise InputError(f"{texture_file}: texture image {_unreadable(texture_file)}") from None
    return mesh.replace(texture=pixels, metadata={**mesh.metadata, "texture": str(texture_file)})


def save_mesh(mesh: Mesh, path: str | os.PathLike, *, inputs: list | None = None,
              force: bool = False) -> list[Path]:
    """Write ``mesh`` to ``path``; the format follows the extension.

    OBJ writes ``<stem>.mtl`` and ``<stem>.png`` beside the OBJ when the mesh is
    textured, so several results can share a folder. Returns the files written.

    ``inputs`` are the files the mesh was read from (:func:`input_files`): none of them
    is overwritten unless ``force``, and a texture among them never is (InputError,
    before anything is written). Texture coordinates that are not finite or beyond
    :data:`~bench.io.validate.UV_LIMIT` are refused too.
    """
    path = check_output_path(path)
    return _commit(_mesh_files(mesh, path), inputs, force)


def glb_bytes(mesh: Mesh, name: str = "mesh") -> bytes:
    """``mesh`` as a binary glTF file (GLB), in memory, exactly as :func:`save_mesh`
    writes ``<name>.glb``: positions, UVs, normals and colours, its texture embedded
    (or one primitive per material, each with its own texture). The run writes its
    meshes this way for the report's 3D view. Raises InputError where :func:`save_mesh`
    would (coordinates beyond 32-bit floats, UVs out of range)."""
    (_, data), = _mesh_files(mesh, Path(f"{name}.glb"))
    return data


def _mesh_files(mesh: Mesh, path: Path) -> list[tuple[Path, bytes]]:
    """The files (path, content) that hold ``mesh`` written to ``path``."""
    if mesh.uv is not None:
        check_uv(mesh.uv, str(path))
    ext = path.suffix.lower()
    split = None
    if ext == ".obj" or ext in SCENE_FORMATS:
        split = split_materials(mesh, source=str(path))
        if split is not None and ext == ".obj":
            return _obj_material_files(mesh, split, path)  # exact digits
    _check_storable(mesh, path, str(path))
    if ext == ".ply":
        return [(path, ply_bytes(mesh))]
    if split is not None:
        scene, groups = _scene([(path.stem, mesh, split)], path.stem)
        return _export_files(scene, path, tree_postprocessor=_one_mesh_per_group(groups))
    tm = _to_trimesh(mesh, material_name=path.stem)
    if ext == ".obj":
        from trimesh.exchange.obj import export_obj

        text, files = export_obj(tm, include_normals=mesh.normals is not None,
                                 include_texture=True, return_texture=True,
                                 mtl_name=f"{path.stem}.mtl", digits=10)
        return [(path, text.encode())] + [(path.parent / fname, data)
                                          for fname, data in files.items()]
    return _export_files(tm, path)


#: How each format stores a coordinate: PLY, STL and glTF as 32-bit floats, OBJ and OFF as
#: text with 10 decimals (an OBJ with several materials is written exactly).
_STORAGE = {".ply": "32-bit floats", ".stl": "32-bit floats", ".glb": "32-bit floats",
            ".gltf": "32-bit floats", ".obj": "10 decimals", ".off": "10 decimals"}


def _check_storable(mesh: Mesh, path: Path, source: str) -> None:
    """InputError when ``path``'s format cannot hold ``mesh``'s coordinates: they would
    become infinite (beyond 3.4e38 in 32-bit floats) or every face would collapse to
    zero area (coordinates too small for the format's precision); a warning with the
    count when some faces would. Ordinary meshes pass."""
    from bench.core.mesh import face_normals

    _check_finite(mesh, source)
    ext = path.suffix.lower()
    with np.errstate(over="ignore", under="ignore"):
        if _STORAGE[ext] == "32-bit floats":
            stored = mesh.positions.astype(np.float32).astype(np.float64)
        else:
            # at 4.5e5 and beyond a double has no bit below 1e-10 (and rounding there
            # would overflow at 1e298)
            small = np.abs(mesh.positions) < 1e6
            stored = np.where(small, np.round(np.where(small, mesh.positions, 0), 10),
                              mesh.positions)
    name = ext[1:].upper()
    if not np.isfinite(stored).all():
        big = float(np.abs(mesh.positions).max())
        raise InputError(f"{source}: coordinates up to {big:g} do not fit the {_STORAGE[ext]} "
                         f"{name} is written with; write .obj or .off, or scale the mesh")
    if np.array_equal(stored, mesh.positions):
        return
    before = face_normals(mesh.positions, mesh.faces).any(axis=1)
    lost = before & ~face_normals(stored, mesh.faces).any(axis=1)
    if lost.all():
        raise InputError(f"{source}: all {len(lost)} faces would collapse to zero area in "
                         f"the {_STORAGE[ext]} {name} is written with (coordinates too "
                         "small for them); scale the mesh first")
    if lost.any():
        warn(f"{source}: {int(lost.sum())} faces collapse to zero area in the "
             f"{_STORAGE[ext]} {name} is written with")


def _check_finite(mesh: Mesh, source: str) -> None:
    """InputError when a mesh to be written has coordinates that are not finite: a
    method's arithmetic overflowed on coordinates near the largest double (squares
    overflow beyond about 1e154), which no output format can help."""
    finite = np.isfinite(mesh.positions)
    if finite.all():
        return
    big = float(np.abs(mesh.positions[finite]).max(initial=0.0))
    raise InputError(f"{source}: {int((~finite.all(axis=1)).sum())} vertices of the result "
                     f"have coordinates that are not finite: coordinates this large (up to "
                     f"{big:g}) overflow floating-point arithmetic; scale the mesh down and "
                     "simplify again")


def input_files(source: str | os.PathLike | None) -> list[tuple[Path, str]]:
    """The files a mesh file ``source`` is made of, each with its kind: the file itself
    (``"mesh"``), an OBJ's material files (``"material"``) and the images they name
    (``"texture"``), a glTF's buffers (``"buffer"``) and images (``"texture"``). Only
    those that exist; none for a ``source`` that is not a file (a procedural model)."""
    if source is None or not Path(source).is_file():
        return []
    path = Path(source)
    return [(p, kind) for p, kind in _named_files(path, path.suffix.lower()) if p.is_file()]


def _named_files(path: Path, ext: str) -> list[tuple[Path, str]]:
    """The files a mesh file is made of or names, whether they exist or not (those of
    its cache entry when it was just read from there, else from the file)."""
    known = cached_named_files(path)
    if known is not None:
        return known
    if ext == ".obj":
        return list(_scan_obj_once(path)["files"])
    files = [(path, "mesh"), *(_gltf_files(path) if ext == ".gltf" else [])]
    if any(not p.is_file() for p, _ in files):  # trimesh looks for the bare name there
        files.append((path.parent, "folder"))
    return files


def _gltf_files(path: Path) -> list[tuple[Path, str]]:
    """The files a ``.gltf`` names (buffers and images, by URI), whether they exist or
    not; none for a file that is not glTF JSON."""
    import json
    from urllib.parse import unquote

    if path.suffix.lower() != ".gltf":
        return []
    try:
        tree = json.loads(path.read_bytes())
    except (ValueError, OSError, RecursionError):
        tree = {}
    files = []
    for key, kind in (("buffers", "buffer"), ("images", "texture")):
        for item in tree.get(key, []) if isinstance(tree, dict) else []:
            uri = item.get("uri") if isinstance(item, dict) else None
            if isinstance(uri, str) and not uri.startswith("data:"):
                files.append((path.parent / unquote(uri), kind))
    return files


def check_not_inputs(targets: list[Path], inputs: list | None, force: bool) -> None:
    """InputError if one of ``targets`` is one of ``inputs`` (:func:`input_files`):
    always for a texture, else unless ``force``. Files are compared as the file system
    sees them (a link or another spelling of the path is the same file)."""
    taken = {}
    for source, kind in inputs or ():
        try:
            st = os.stat(source)
        except OSError:
            continue
        taken[(st.st_dev, st.st_ino)] = (source, kind)
    for target in targets:
        try:
            st = os.stat(target)
        except OSError:
            continue
        hit = taken.get((st.st_dev, st.st_ino))
        if hit is None:
            continue
        source, kind = hit
        if kind == "texture":
            raise InputError(f"{target}: is the input's texture ({source}), which is never "
                             "written over, not even with --force; choose another output "
                             "name (textures are named after it)")
        if not force:
            raise InputError(f"{target}: is the input's {kind} file ({source}); choose "
                             "another output name, or give --force to replace it")


def _commit(files: list[tuple[Path, bytes]], inputs: list | None, force: bool) -> list[Path]:
    """Write ``files`` (each atomically) after :func:`check_not_inputs`; the paths
    written, in order, once each."""
    unique = list(dict.fromkeys(p for p, _ in files))
    check_not_inputs(unique, inputs, force)
    for target, data in files:
        try:
            write_atomic(target, data)
        except OSError as exc:
            raise InputError(f"{target}: cannot write it ({exc.strerror or exc}); give an "
                             "output in a folder you can write to") from None
    return unique


def lod_path(path: str | os.PathLike, name: str) -> Path:
    """Where level ``name`` of an LOD chain written to ``path`` goes in a format with
    one mesh per file: ``<stem>_<name><ext>`` beside ``path`` (``out.obj`` ->
    ``out_LOD1.obj``, with ``out_LOD1.mtl`` and ``out_LOD1.png`` for a textured level).
    """
    path = Path(path)
    return path.with_name(f"{path.stem}_{name}{path.suffix}")


def save_lods(levels: list[tuple[str, Mesh]], path: str | os.PathLike, *,
              inputs: list | None = None, force: bool = False) -> dict[str, list[Path]]:
    """Write an LOD chain: ``levels`` are (name, mesh) pairs, the most detailed first.

    In a format of :data:`SCENE_FORMATS` it is one file, ``path``, with one named mesh
    (and node, all at the origin) per level, as engines import LOD groups; levels that
    share a texture share one material and image. In any other format each level is a
    file of its own at :func:`lod_path` and ``path`` itself is not written.

    ``inputs`` and ``force`` are as in :func:`save_mesh`; nothing is written when a
    level's file would land on an input.

    Returns
    -------
    dict of str to list of Path
        For each level, the files that hold it (the one scene file in a scene format).
    """
    path = check_output_path(path)
    if path.suffix.lower() not in SCENE_FORMATS:
        per_level = {name: _mesh_files(mesh, check_output_path(lod_path(path, name)))
                     for name, mesh in levels}
        _commit([f for files in per_level.values() for f in files], inputs, force)
        return {name: list(dict.fromkeys(p for p, _ in files))
                for name, files in per_level.items()}
    import trimesh

    for name, mesh in levels:
        if mesh.uv is not None:
            check_uv(mesh.uv, f"{path} {name}")
        _check_storable(mesh, path, f"{path} {name}")

    splits = [split_materials(mesh, source=f"{path} {name}") for name, mesh in levels]
    if any(split is not None for split in splits):
        scene, groups = _scene([(name, mesh, split) for (name, mesh), split
                                in zip(levels, splits)], path.stem)
        written = _commit(_export_files(scene, path,
                                        tree_postprocessor=_one_mesh_per_group(groups)),
                          inputs, force)
        return {name: written for name, _ in levels}
    scene, materials = trimesh.Scene(), {}
    for name, mesh in levels:
        key = _texture_key(mesh.texture)
        tm = _to_trimesh(mesh, material_name=path.stem, material=materials.get(key))
        if mesh.uv is not None:
            materials.setdefault(key, tm.visual.material)
        scene.add_geometry(tm, geom_name=name, node_name=name)
    written = _commit(_export_files(scene, path), inputs, force)
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
        kept = " (UVs kept)" if uv is not None else ""
        if scan.get("texture_refs"):
            missing = ", ".join(scan["texture_refs"])
            warn(f"{source}: texture image not found ({missing}); loading untextured{kept}")
        if scan.get("texture_unreadable"):
            warn(f"{source}: texture image unreadable ({', '.join(scan['texture_unreadable'])}); "
                 f"loading untextured{kept}")
        elif has_image_file and image is None and ext == ".obj":
            reasons = ", ".join(f"{name} {_unreadable(where)}"
                                for name, where in scan["texture_files"])
            warn(f"{source}: texture image unreadable ({reasons}); loading untextured{kept}")
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

    _warn_faces(source, scan)
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
            _check_file_uv(uv, source, Path(source) if ext == ".obj" else None)
        image, texture_source, color = None, None, (255, 255, 255, 255)
        if key is not None:
            image, texture_source, color = _material_look(material, key, ext, textures,
                                                          source)
        elif isinstance(visual, ColorVisuals) and visual.kind == "vertex":
            color = tuple(int(c) for c in np.asarray(visual.vertex_colors).mean(axis=0).round())
            recoloured += 1
        parts.append(Part(names[key], geom.vertices, geom.faces, uv=uv, image=image,
                          color=color, source=texture_source))
    if recoloured:
        warn(f"{source}: vertex colours of {recoloured} parts without a material replaced "
             "by their mean colour (a multi-material mesh keeps one colour per material)")
    return pack_materials(parts, source=source, name=name, metadata={"source": source})


def _material_look(material, key: str, ext: str, textures: dict, source: str):
    """A material's (texture image or None, its source or None, RGBA colour); a texture
    an OBJ names but that is missing or unreadable is warned of, and its colour used."""
    color = _material_color(material)
    if ext == ".obj":
        texture_source, problem = textures.get(key, (None, None))
        if texture_source is not None and problem is not None:
            what = "not found" if problem == "not found" else "unreadable"
            detail = texture_source if problem == "not found" else \
                f"{texture_source} {problem}"
            warn(f"{source}: material '{key}': texture image {what} "
                 f"({detail}); using its colour")
            texture_source = None
    else:
        texture_source = source
    picture = _material_image(material) if texture_source is not None else None
    image = None if picture is None else _image_array(picture)
    if image is not None and ext == ".obj" and "kd" not in getattr(material, "kwargs", {}):
        color = (255, 255, 255, 255)  # no Kd: white, not trimesh's 0.4 grey
    if picture is None and texture_source is not None and ext == ".obj":
        warn(f"{source}: material '{key}': texture image unreadable "
             f"({_unreadable(Path(texture_source))}); using its colour")
    return image, texture_source, color


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
    """A PIL image as an 8-bit RGB or RGBA array. A 16-bit (or 32-bit integer) grey
    image is scaled to 8 bits (65535 -> 255), where PIL's conversion would clip every
    value above 255 to white."""
    if image.mode.startswith("I"):  # I;16, I;16B, I;16L, I: grey, more than 8 bits
        values = np.asarray(image).astype(np.float64)
        top = 65535.0 if image.mode.startswith("I;16") or values.max(initial=0) <= 65535 \
            else float(2**32 - 1)
        grey = np.rint(np.clip(values, 0, top) * (255.0 / top)).astype(np.uint8)
        return np.repeat(grey[..., None], 3, axis=-1)
    if image.mode not in ("RGB", "RGBA"):
        image = image.convert("RGBA" if "A" in image.mode else "RGB")
    return np.asarray(image, dtype=np.uint8).copy()


def _unreadable(path: Path) -> str:
    """Why an image file that exists gave no texture: what PIL says of it."""
    from PIL import Image

    if path.is_dir():
        return "is a directory"
    if path.stat().st_size == 0:
        return "is empty"
    try:
        with Image.open(path) as image:
            image.load()
    except Exception as exc:  # noqa: BLE001 - PIL raises many kinds; one line for the user
        return f"cannot be read as an image: {' '.join(str(exc).split()) or type(exc).__name__}"
    return "could not be loaded"


def _warn_faces(source: str, scan: dict) -> None:
    """The loader's warnings about an OBJ's faces: polygons triangulated (the concave
    ones by ear clipping), faces with fewer than 3 corners left out."""
    if scan.get("polygons"):
        concave = scan.get("concave", 0)
        warn(f"{source}: triangulated {scan['polygons']} faces with more than 3 corners"
             + (f" ({concave} concave, by ear clipping)" if concave else ""))
    if scan.get("short"):
        warn(f"{source}: ignored {scan['short']} faces with fewer than 3 corners (first on "
             f"line {scan['first_short']})")


def _check_file_uv(uv: np.ndarray, source: str, obj: Path | None) -> None:
    """:func:`~bench.io.validate.check_uv` for a file's UVs; for an OBJ (``obj``) the
    error names the first ``vt`` line at fault."""
    try:
        check_uv(uv, source)
    except InputError:
        if obj is None:
            raise
        for lineno, line in enumerate(io.BytesIO(obj.read_bytes()), 1):
            if line[:3] not in (b"vt ", b"vt\t"):
                continue
            try:
                values = [float(x) for x in line.split()[1:3]]
            except ValueError:
                continue
            if not all(abs(x) <= UV_LIMIT for x in values):
                raise InputError(f"{source}: line {lineno}: texture coordinate "
                                 f"{' '.join(f'{x:g}' for x in values)} is not finite or "
                                 f"beyond {UV_LIMIT:g} in magnitude; the file is corrupt") \
                    from None
        raise


class _TextResolver:
    """trimesh's file resolver for a mesh file: a material file that is not UTF-8 is
    handed over re-encoded from Latin-1 (trimesh decodes only UTF-8). A texture trimesh
    asks for by the whole rest of its ``map_Kd`` line, options included, is read from
    the file name in it (``aliases``, from :func:`_scan_obj`). A file that is not a
    regular file (a named pipe, a device, a directory) is never opened: it is refused
    as missing (opening a named pipe would block until something writes)."""

    def __new__(cls, source: str, aliases: dict | None = None):
        from trimesh.resolvers import FilePathResolver

        class Resolver(FilePathResolver):
            def get(self, name: str):
                name = (aliases or {}).get(name, name)
                for candidate in (name.strip(), name.strip().lstrip("/"),
                                  os.path.split(name)[-1]):
                    try:
                        where = self.absolute(candidate)
                    except ValueError:
                        continue
                    if where.exists() and not _regular(where):
                        raise FileNotFoundError(f"{name}: not a regular file")
                data = super().get(name)
                if isinstance(data, bytes) and name.lower().endswith(".mtl"):
                    data = _decode(data)[0].encode("utf-8")
                return data

        return Resolver(source)


def _regular(path: Path) -> bool:
    """Whether ``path`` is a regular file (following links), by ``stat`` alone."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return False


def _not_regular(path: Path) -> str:
    """What a texture path that is neither a regular file nor a directory is: "not
    found", or "is not a regular file" (a named pipe, a device), found by ``stat``."""
    return "is not a regular file" if path.exists() else "not found"


def _check_readable(path: Path, source: str) -> None:
    """InputError unless ``path`` is a regular file that can be read: a named pipe or a
    device is refused without being opened (reading a pipe blocks), and a file the
    user may not read, or whose read fails, is named with the reason."""
    if not _regular(path):
        raise InputError(f"{source}: is not a regular file (a named pipe, device or "
                         "socket); give a mesh file")
    try:
        with open(path, "rb") as f:
            f.read(1)
    except OSError as exc:
        raise InputError(f"{source}: cannot read it ({exc.strerror or exc}); check that "
                         "the file is readable") from None


def _check_signature(path: Path, ext: str, source: str) -> None:
    """InputError for an OFF or STL file that is none (garbage, another format), said
    as such, before trimesh, which would reach for a character-set detector it may not
    have (and name that module as the problem): an OFF is text beginning with its
    header, an STL binary (80 bytes, a triangle count, 50 bytes per triangle) or
    UTF-8 text."""
    if ext not in (".off", ".stl"):
        return
    if ext == ".off":
        with open(path, "rb") as f:  # the header, after any comments
            text = f.read(1 << 16).removeprefix(b"\xef\xbb\xbf").decode("latin-1")
        if not re.match(r"\s*(#[^\n]*\n\s*)*[A-Za-z0-9]*OFF\b", text):
            raise InputError(f"{source}: not an OFF file (it does not begin with an OFF "
                             "header); check the file and its extension")
        return
    size = os.stat(path).st_size
    with open(path, "rb") as f:
        head = f.read(84)
    count = int.from_bytes(head[80:84], "little") if size >= 84 else None
    if count is not None and size == 84 + 50 * count:
        return  # binary
    try:
        path.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        size = "shorter than a binary STL's 84-byte header" if count is None else \
            f"{size} bytes where a binary STL of {count} triangles has {84 + 50 * count}"
        raise InputError(f"{source}: not an STL file (not ASCII STL text, and {size}); "
                         "the file is corrupt or of another format") from None


def _scan_gltf(path: Path) -> dict:
    """A glTF or GLB with sparse accessors as glTF JSON with them applied
    (:mod:`bench.io.gltf_sparse`; trimesh ignores them); {} for any other."""
    from bench.io.gltf_sparse import dense_gltf

    text = dense_gltf(path)
    scan = {} if text is None else {"text": text, "file_type": "gltf"}
    odd = [f"{p.name} is not a regular file" for p, kind in _gltf_files(path)
           if kind == "texture" and p.exists() and not _regular(p)]
    if odd:  # never opened (_TextResolver); trimesh drops such an image without a word
        scan["texture_unreadable"] = odd
    return scan


def _texture_key(texture: np.ndarray | None):
    """Identifies a texture by content, so levels whose method copied the image still
    share one material (and the file one image)."""
    if texture is None:
        return None
    return texture.shape, hashlib.sha1(np.ascontiguousarray(texture).tobytes()).hexdigest()


def _export_files(tm, path: Path, **options) -> list[tuple[Path, bytes]]:
    """Export a trimesh mesh or scene in the format of ``path``'s extension (``options``
    go to trimesh's exporter); the files to write, (path, content) (a ``.gltf`` with its
    buffers renamed after ``path``)."""
    data = tm.export(file_type=path.suffix.lower()[1:], **options)
    if isinstance(data, dict):  # .gltf: the JSON plus its buffers, renamed after OUT
        gltf = data.pop("model.gltf")
        written = []
        for name, blob in data.items():
            own = f"{path.stem}_{name}"
            gltf = gltf.replace(f'"{name}"'.encode(), f'"{own}"'.encode())
            written.append((path.parent / own, blob))
        return [(path, gltf)] + written
    return [(path, data if isinstance(data, bytes) else data.encode())]


def _to_trimesh(mesh: Mesh, material_name: str, material=None):
    """``mesh`` as a trimesh mesh; a textured one gets ``material`` if given (so the
    levels of a chain can share one), else a new material named ``material_name``
    (:func:`_plain_material`)."""
    import trimesh
    from PIL import Image

    kwargs = {}
    if mesh.normals is not None:
        kwargs["vertex_normals"] = mesh.normals
    tm = trimesh.Trimesh(mesh.positions, mesh.faces, process=False, **kwargs)
    if mesh.uv is not None:
        if material is None:
            image = Image.fromarray(mesh.texture) if mesh.texture is not None else None
            material = _plain_material(image, material_name, _roughness(mesh.metadata))
        tm.visual = trimesh.visual.TextureVisuals(uv=mesh.uv, material=material)
    elif mesh.colors is not None:
        tm.visual = trimesh.visual.ColorVisuals(tm, vertex_colors=mesh.colors)
    return tm


def _surface(visual) -> dict:
    """``{"material": {"roughness": r}}`` when a loaded file's one material states its
    roughness, else ``{}`` (:func:`_roughness` then gives 1): glTF's roughness factor;
    an MTL's ``Pr``, else its specular exponent ``Ns`` mapped as Blender maps it,
    ``1 - sqrt(Ns / 1000)``. Kept so that a written result has the input's roughness."""
    material = getattr(visual, "material", None)
    roughness = getattr(material, "roughnessFactor", None)
    stated = getattr(material, "kwargs", None) or {}
    try:
        if roughness is None and stated.get("pr"):
            roughness = float(np.ravel(stated["pr"])[0])
        elif roughness is None and stated.get("ns") is not None:
            ns = float(np.ravel(stated["ns"])[0])
            roughness = 1 - math.sqrt(min(max(ns, 0.0), 1000.0) / 1000)
    except (TypeError, ValueError):
        roughness = None
    if roughness is None or not math.isfinite(roughness):
        return {}
    return {"material": {"roughness": min(max(float(roughness), 0.0), 1.0)}}


def _roughness(metadata: dict) -> float:
    """The roughness a mesh is written with: its input's (:func:`_surface`), else 1
    (glTF's default; a fully rough, diffuse surface, as the protocol renders it)."""
    return float((metadata.get("material") or {}).get("roughness", 1.0))


def _plain_material(image, name: str, roughness: float):
    """The material of a mesh written with one texture (or none): base colour white, so
    that the texture alone is the colour, as the protocol renders it; not metallic; the
    given roughness. A glTF gets them as its metallic-roughness factors, an MTL as
    ``Kd 1 1 1``, ``Ks 0 0 0``, ``Ns`` (Blender's mapping, ``1000 (1 - r)^2``) and the
    PBR lines ``Pr`` and ``Pm 0``. (trimesh's default is a 0.4 grey, and glTF reads a
    missing metallic factor as fully metallic: a dull, dark result in PBR viewers.)"""
    from trimesh.visual.material import PBRMaterial, SimpleMaterial

    class Plain(SimpleMaterial):
        def to_pbr(self):
            return PBRMaterial(baseColorTexture=self.image, baseColorFactor=[255] * 4,
                               metallicFactor=0.0, roughnessFactor=roughness)

        def to_obj(self, name=None):
            data, name = super().to_obj(name)
            data[f"{name}.mtl"] += f"\nPr {roughness:.6g}\nPm 0".encode()
            return data, name

    return Plain(image=image, name=name, diffuse=[255] * 4, ambient=[255] * 4,
                 specular=[0, 0, 0, 255], glossiness=1000 * (1 - roughness) ** 2)


def _obj_material_files(mesh: Mesh, split: list, path: Path) -> list[tuple[Path, bytes]]:
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
    return [(path, ("\n".join(lines) + "\n").encode()),
            (path.parent / f"{stem}.mtl", "\n".join(mtl).encode())] + \
        [(path.parent / fname, data) for fname, data in images.items()]


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
                    baseColorFactor=[255, 255, 255, 255] if textured else part.material["color"],
                    metallicFactor=0.0, roughnessFactor=_roughness(mesh.metadata))
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


def _decode(data: bytes) -> tuple[str, str]:
    """A text file's content and encoding: UTF-8 (ASCII included), else Latin-1, which
    every byte sequence is (exporters on Windows write it)."""
    try:
        return data.decode("utf-8"), "utf-8"
    except UnicodeDecodeError:
        return data.decode("latin-1"), "latin-1"


_INDEX_KINDS = ("face index", "texture coordinate index", "normal index")
_INDEX_UNITS = ("vertices", "texture coordinates", "normals")


#: The last OBJ scanned, as (file identity, scan): loading a mesh and listing its input
#: files (``bench simplify``) read and scan it once, not twice.
_LAST_OBJ_SCAN: list = [None, None]


def _scan_obj_once(path: Path) -> dict:
    """:func:`_scan_obj`, kept while the OBJ and every file the scan lists (material
    files and images, found or not, and the folder when it counts) are unchanged, until
    another OBJ is scanned. Treat the result as read-only."""
    known, scan = _LAST_OBJ_SCAN
    if known is not None and known == _scan_identity(path, scan):
        return scan
    scan = _scan_obj(path)
    _LAST_OBJ_SCAN[:] = [_scan_identity(path, scan), scan]
    return scan


def _scan_identity(path: Path, scan: dict) -> tuple:
    """What the scan of ``path`` depends on: the path and its files' identities."""
    return (str(path), *(file_identity(p) for p, _ in scan["files"]))


def _scan_obj(path: Path) -> dict:
    """Index ranges, face sizes, encoding and texture references of an OBJ, without
    parsing it fully (trimesh does that). Raises InputError on an index out of range
    (of a vertex, texture coordinate or normal) and on an unreadable index.

    Faces with more than 3 corners are checked for convexity; the concave ones are
    ear-clipped here (``text``, the file as trimesh is to read it), since trimesh cuts
    every polygon into a fan, which covers the wrong area when the polygon is concave.
    """
    data = path.read_bytes()
    _, encoding = _decode(data)
    lines = _ObjLines.triangles(path, data, encoding)
    if lines is None:  # not the common case: line by line, with the line of any error
        lines = _ObjLines()
        for lineno, line in enumerate(io.BytesIO(data), 1):
            lines.read(path, lineno, line, encoding)
        lines.check_ranges(path)
    mtl = _scan_mtls(path, lines.mtllibs, encoding)
    # The folder is one of the things the mesh is read from when a file it names is
    # missing (trimesh then looks for its bare name there) or, with UVs and no material
    # file, when the images in it decide a warning (_warn_no_material).
    missing = any(not p.is_file() for p, _ in mtl["files"])
    folder = [(path.parent, "folder")] if missing or (lines.counts[1] and not lines.mtllibs) \
        else []
    text, concave = _ear_clip(data.decode(encoding), lines.big) if lines.big else (None, 0)
    if concave == 0 and encoding == "utf-8" and "latin-1" not in mtl["encodings"]:
        text = None  # trimesh reads the file itself, as it always has
    elif text is None:
        text = data.decode(encoding)
    return {"polygons": lines.polygons, "concave": concave, "short": lines.short,
            "first_short": lines.first_short, "texture_refs": mtl["refs"],
            "texture_files": mtl["found"], "texture_unreadable": mtl["unreadable"],
            "usemtl": list(lines.usemtl), "material_textures": mtl["textures"],
            "files": [(path, "mesh"), *mtl["files"], *folder], "encoding": encoding,
            "text": text, "texture_aliases": mtl["aliases"], "mtllib": bool(lines.mtllibs)}


#: The line heads an OBJ's vertex data starts with, and their kind (v, vt, vn).
_OBJ_HEADS = {b"v ": 0, b"v\t": 0, b"vt": 1, b"vn": 2}


#: What :meth:`_ObjLines.triangles` reads: face lines (their corners), a corner's form
#: with every number as 1 -> (a pattern for such corners, with indices of at most 17
#: digits, which an int64 holds; the index kinds in it), the heads of v, vt and vn
#: lines, and mtllib and usemtl lines.
_FACE_LINE = re.compile(rb"^f[ \t]([^\n]*)", re.M)
_CORNER_SHAPE = re.compile(rb"[0-9]+")
_INDEX = rb"[0-9]{1,17}"
_CORNER_FORMS = {b"1": (_INDEX, (0,)), b"1/1": (_INDEX + b"/" + _INDEX, (0, 1)),
                 b"1//1": (_INDEX + b"//" + _INDEX, (0, 2)),
                 b"1/1/1": (_INDEX + b"/" + _INDEX + b"/" + _INDEX, (0, 1, 2))}
_VERTEX_HEADS = ((b"v ", b"v\t"), (b"vt ", b"vt\t"), (b"vn ", b"vn\t"))
_MATERIAL_LINE = re.compile(rb"^(?:mtllib|usemtl)[^\n]*\n?", re.M)


class _ObjLines:
    """What :func:`_scan_obj` gathers from an OBJ's lines, one line at a time."""

    def __init__(self):
        self.counts = [0, 0, 0]  # v, vt, vn lines so far
        self.polygons = self.short = 0
        self.first_short = None
        self.big: list[tuple[int, list[bytes], int]] = []  # (line, corners, v lines before)
        self.maxima = [(0, 0), (0, 0), (0, 0)]  # per kind: (largest index, its line)
        self.worst = [None, None, None]  # per kind: first index <= 0 out of range
        self.mtllibs = []
        self.usemtl: dict[str, None] = {}  # material names in order of first use

    @classmethod
    def triangles(cls, path: Path, data: bytes, encoding: str) -> _ObjLines | None:
        """The common case read as a whole: every face a triangle whose corners all have
        the same form (``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``), every index positive
        and defined. None otherwise: :meth:`read`, line by line, then finds what is
        different, and the line of any error. Both read the same lines the same way."""
        faces = _FACE_LINE.findall(data)
        first = faces[0].split()[:1] if faces else None
        form = _CORNER_FORMS.get(_CORNER_SHAPE.sub(b"1", first[0])) if first else None
        if form is None:
            return None
        corner, kinds = form
        triangle = re.compile(rb"^[ \t]*%s[ \t]+%s[ \t]+%s[ \t\r]*$" % ((corner,) * 3), re.M)
        tails = b"\n".join(faces)
        if len(triangle.findall(tails)) != len(faces):
            return None
        indices = np.fromstring(tails.replace(b"/", b" ").replace(b"\r", b" "),
                                dtype=np.int64, sep=" ")
        indices = indices.reshape(len(faces) * 3, len(kinds))
        lines = cls()
        lines.counts = [sum(data.startswith(head) + data.count(b"\n" + head)
                            for head in heads) for heads in _VERTEX_HEADS]
        for column, kind in enumerate(kinds):
            if indices[:, column].min() < 1 or indices[:, column].max() > lines.counts[kind]:
                return None
        if b"mtllib" in data or b"usemtl" in data:
            for match in _MATERIAL_LINE.finditer(data):
                lines.read(path, 0, match.group(0), encoding)
        return lines

    def read(self, path: Path, lineno: int, line: bytes, encoding: str) -> None:
        head = line[:2]
        if head in _OBJ_HEADS:
            kind = _OBJ_HEADS[head]
            if kind == 0 or line[2:3] in (b" ", b"\t"):
                self.counts[kind] += 1
        elif head == b"f " or head == b"f\t":
            tokens = line.split()[1:]
            if len(tokens) < 3:
                self.short += 1
                self.first_short = self.first_short or lineno
            elif len(tokens) > 3:
                self.polygons += 1
                self.big.append((lineno, tokens, self.counts[0]))
            for tok in tokens:
                self._corner(path, lineno, tok)
        elif line.startswith(b"mtllib"):
            whole = line[len(b"mtllib"):].strip()  # one name with spaces, or several
            named = whole and (path.parent / whole.decode(encoding)).is_file()
            self.mtllibs.extend([whole] if named else line.split()[1:])
        elif line.startswith(b"usemtl"):
            words = line.split()
            if len(words) > 1:
                self.usemtl.setdefault(words[1].decode(encoding), None)

    def _corner(self, path: Path, lineno: int, tok: bytes) -> None:
        """One face corner (``v``, ``v/vt``, ``v//vn``, ``v/vt/vn``): its indices read
        and the largest and the first impossible one of each kind noted."""
        for kind, part in enumerate(tok.split(b"/")[:3]):
            if kind and not part:  # v//vn, or v/ : no such index
                continue
            try:
                idx = int(part)
            except ValueError:
                raise InputError(f"{path}: line {lineno}: bad {_INDEX_KINDS[kind]} "
                                 f"'{tok.decode(errors='replace')}'") from None
            if idx < 0:
                if self.counts[kind] + idx + 1 < 1 and self.worst[kind] is None:
                    self.worst[kind] = (lineno, idx, self.counts[kind])
            elif idx == 0:
                if self.worst[kind] is None:
                    self.worst[kind] = (lineno, idx, self.counts[kind])
            elif idx > self.maxima[kind][0]:
                self.maxima[kind] = (idx, lineno)

    def check_ranges(self, path: Path) -> None:
        """InputError for the first index of each kind that points at no line."""
        for kind in range(3):
            if self.worst[kind] is not None:
                lineno, idx, n = self.worst[kind]
                raise InputError(f"{path}: line {lineno}: {_INDEX_KINDS[kind]} {idx} is out "
                                 f"of range ({n} {_INDEX_UNITS[kind]} defined before it); the "
                                 "file is corrupt or truncated")
            top, lineno = self.maxima[kind]
            if top > self.counts[kind]:
                raise InputError(f"{path}: line {lineno}: {_INDEX_KINDS[kind]} {top} is out "
                                 f"of range (the file has {self.counts[kind]} "
                                 f"{_INDEX_UNITS[kind]}); the file is corrupt or truncated")


def _scan_mtls(path: Path, mtllibs: list[bytes], encoding: str) -> dict:
    """The texture references of an OBJ's material files: the files named, found or not
    (``files``), textures missing (``refs``, with material files missing), found
    (``found``: name and path) and unreadable, each material's diffuse texture
    (``textures``), the names trimesh will look for instead of the file's (``aliases``)
    and the files' encodings."""
    refs, found, unreadable, textures, files = [], [], [], {}, []
    encodings, aliases = [], {}
    for lib in mtllibs:
        mtl = path.parent / lib.decode(encoding)
        if not mtl.is_file():
            refs.append(f"{mtl.name} (material file)")
            files.append((mtl, "material"))  # named, missing: input_files leaves it out
            continue
        files.append((mtl, "material"))
        mtl_text, mtl_encoding = _decode(mtl.read_bytes())
        encodings.append(mtl_encoding)
        current = None
        for line in mtl_text.splitlines():
            parts = line.strip().split()
            key = parts[0].lower() if parts else ""
            if key == "newmtl" and len(parts) > 1:
                current = parts[1]
            elif (key.startswith("map_") or key in ("bump", "disp", "decal", "norm")) \
                    and len(parts) > 1:
                tex = _map_file(line)
                if not tex:
                    continue
                files.append((mtl.parent / tex, "texture"))
                if key not in ("map_kd", "map_ka"):
                    continue
                if key == "map_kd":  # trimesh's name for it: the rest of the line
                    said = line.strip()[len("map_kd"):].strip()
                    if said != tex:
                        aliases[said] = tex
                where = mtl.parent / tex
                problem = None if where.is_file() else \
                    "is a directory" if where.is_dir() else _not_regular(where)
                if problem is None:
                    found.append((tex, where))
                elif problem == "not found":
                    refs.append(tex)
                else:
                    unreadable.append(f"{tex} {problem}")
                if key == "map_kd" and current is not None:
                    textures[current] = (str(where), problem)
    return {"refs": refs, "found": found, "unreadable": unreadable, "textures": textures,
            "files": files, "encodings": encodings, "aliases": aliases}


#: Options of an MTL texture statement (``map_Kd -s 1 1 1 -clamp on file.png``) and how
#: many values each takes; ``-o``, ``-s`` and ``-t`` take one to three numbers.
_MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1,
                "-imfchan": 1, "-mm": 2, "-texres": 1, "-type": 1, "-o": 3, "-s": 3, "-t": 3}


def _map_file(line: str) -> str:
    """The file name of an MTL texture statement: what follows the keyword and its
    options, to the end of the line, inner spaces included (``map_Kd -s 2 2 fuze uv.jpg``
    -> ``fuze uv.jpg``); empty when there is none."""
    words = list(re.finditer(r"\S+", line))[1:]  # after the keyword
    i = 0
    while i < len(words) and words[i].group().lower() in _MAP_OPTIONS:
        option, i = words[i].group().lower(), i + 1
        for n in range(_MAP_OPTIONS[option]):
            if i >= len(words):
                break
            if option in ("-o", "-s", "-t") and n > 0:  # the optional 2nd and 3rd value
                try:
                    float(words[i].group())
                except ValueError:
                    break
            i += 1
    return line[words[i].start():].strip() if i < len(words) else ""


def _ear_clip(text: str, big: list) -> tuple[str | None, int]:
    """``text`` with each concave polygon of ``big`` (line, corner tokens, vertex lines
    before it) replaced by the triangles of ear clipping, and how many there were.
    Convex polygons are left to trimesh's fan, which is right for them."""
    positions = []
    for line in text.split("\n"):
        if line[:2] in ("v ", "v\t"):
            values = line.split()[1:4]
            try:
                positions.append([float(x) for x in values] + [0.0] * (3 - len(values)))
            except ValueError:
                positions.append([np.nan] * 3)
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    lines = text.split("\n")
    concave = 0
    for lineno, tokens, before in big:
        corners = []
        for tok in tokens:
            idx = int(tok.split(b"/", 1)[0])
            corners.append(before + idx if idx < 0 else idx - 1)
        triangles = _triangulate_polygon(positions[corners])
        if triangles is None:
            continue
        concave += 1
        names = [tok.decode("latin-1") for tok in tokens]
        lines[lineno - 1] = "\n".join("f " + " ".join(names[i] for i in tri)
                                        for tri in triangles)
    return "\n".join(lines), concave


def _triangulate_polygon(points: np.ndarray) -> list[tuple[int, int, int]] | None:
    """Ear clipping of one polygon (its corners in order, shape (k, 3)) in the plane of
    its Newell normal: triangles as corner numbers in the polygon's winding, or None
    when the polygon is convex (or degenerate, or not finite), where a fan is right."""
    if not np.isfinite(points).all():
        return None
    q = points - points.mean(axis=0)
    scale = np.abs(q).max()
    if scale == 0:
        return None
    q = np.ldexp(q, -np.frexp(scale)[1])  # into [-1, 1] by a power of two: no overflow
    normal = np.cross(q, np.roll(q, -1, axis=0)).sum(axis=0)
    if not normal.any():
        return None
    axis = int(np.argmax(np.abs(normal)))
    u, v = [(1, 2), (2, 0), (0, 1)][axis]
    flat = q[:, [u, v]].copy()
    if normal[axis] < 0:  # counter-clockwise seen from the normal's side
        flat[:, 1] *= -1
    prev, nxt = np.roll(flat, 1, axis=0), np.roll(flat, -1, axis=0)
    turns = _cross2(flat - prev, nxt - flat)
    if (turns >= 0).all():
        return None

    remaining = list(range(len(flat)))
    triangles = []
    while len(remaining) > 3:
        n = len(remaining)
        for j in range(n):
            a, b, c = remaining[j - 1], remaining[j], remaining[(j + 1) % n]
            if _cross2(flat[b] - flat[a], flat[c] - flat[b]) <= 0:
                continue  # reflex or flat corner: not an ear
            others = [k for k in remaining if k not in (a, b, c)]
            if others and _inside(flat[others], flat[a], flat[b], flat[c]).any():
                continue
            triangles.append((a, b, c))
            del remaining[j]
            break
        else:  # no ear (a self-intersecting polygon): a fan over what is left
            triangles += [(remaining[0], remaining[i], remaining[i + 1])
                          for i in range(1, len(remaining) - 1)]
            return triangles
    triangles.append(tuple(remaining))
    return triangles


def _cross2(a: np.ndarray, b: np.ndarray):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _inside(p: np.ndarray, a, b, c) -> np.ndarray:
    """Which points ``p`` lie in the counter-clockwise triangle abc or on its edges."""
    return ((_cross2(b - a, p - a) >= 0) & (_cross2(c - b, p - b) >= 0)
            & (_cross2(a - c, p - c) >= 0))


def _clip_face_lines(lines: list[str], rows, positions: np.ndarray) -> tuple[int, int, int]:
    """Replace each concave polygon among the face lines ``lines[i]`` (``i`` in ``rows``,
    each "k i1 ... ik [extra]" as OFF and ASCII PLY write them) by the triangles of ear
    clipping, any extra values (a face colour) kept on each; returns (polygons, concave
    ones, triangles added). Raises ValueError for an index out of range (the caller
    leaves such a file to trimesh, whose error or the index check says what is wrong)."""
    polygons = concave = added = 0
    for i in rows:
        tokens = lines[i].split()
        k = int(tokens[0])
        if k <= 3:
            continue
        polygons += 1
        corners = [int(t) for t in tokens[1:1 + k]]
        if min(corners) < 0 or max(corners) >= len(positions):
            raise ValueError("face index out of range")
        triangles = _triangulate_polygon(positions[corners])
        if triangles is None:
            continue
        concave += 1
        added += len(triangles) - 1
        extra = " ".join(tokens[1 + k:])
        lines[i] = "\n".join(f"3 {' '.join(str(corners[j]) for j in tri)} {extra}".rstrip()
                             for tri in triangles)
    return polygons, concave, added


def _scan_off(path: Path) -> dict:
    """An ASCII OFF's polygons, with the concave ones ear-clipped in ``text`` (trimesh
    cuts every polygon into a fan, which covers the wrong area when it is concave).
    Anything this does not parse (another header, a binary or malformed file) is left
    to trimesh as it is."""
    text, encoding = _decode(path.read_bytes())
    lines = text.split("\n")
    entries = [(i, line.split("#", 1)[0].split()) for i, line in enumerate(lines)]
    entries = [(i, tokens) for i, tokens in entries if tokens]
    if not entries or entries[0][1][0] != "OFF":
        return {}
    try:
        if len(entries[0][1]) > 1:  # the counts on the header's line
            count_line, counts, first = entries[0][0], entries[0][1][1:], 1
        else:
            count_line, counts, first = entries[1][0], entries[1][1], 2
        nv, nf = int(counts[0]), int(counts[1])
        vertices = entries[first:first + nv]
        faces = entries[first + nv:first + nv + nf]
        if len(vertices) != nv or len(faces) != nf:
            return {}
        positions = np.array([[float(x) for x in tokens[:3]] for _, tokens in vertices])
        polygons, concave, added = _clip_face_lines(lines, [i for i, _ in faces], positions)
        short = [i for i, tokens in faces if int(tokens[0]) < 3]  # trimesh leaves them out
    except (ValueError, IndexError):
        return {}
    if concave:
        header = lines[count_line].split("#", 1)[0].split()
        numbers = header[1:] if header[0] == "OFF" else header
        numbers[1] = str(nf + added)
        lines[count_line] = " ".join((["OFF"] if header[0] == "OFF" else []) + numbers)
    return {"text": "\n".join(lines) if concave or encoding != "utf-8" else None,
            "file_type": "off",
            "polygons": polygons, "concave": concave, "short": len(short),
            "first_short": short[0] + 1 if short else None}


def _scan_ply(path: Path) -> dict:
    """Vertex and face counts from the PLY header (ASCII even in binary files), to count
    the faces trimesh triangulated and to tell a truncated file. An ASCII file must have
    a line per element its header declares, the last one complete."""
    with open(path, "rb") as f:
        head = f.read(4096)
    header = head.split(b"end_header", 1)[0]
    scan = {}
    for key, name in (("ply_vertices", b"vertex"), ("ply_faces", b"face")):
        match = re.search(rb"element\s+" + name + rb"\s+(\d+)", header)
        if match:
            scan[key] = int(match.group(1))
    if re.search(rb"format\s+ascii", header) and b"end_header" in head:
        body = path.read_bytes().split(b"end_header", 1)[1].split(b"\n", 1)[-1]
        rows = [row for row in body.splitlines() if row.strip()]
        elements = re.findall(rb"element\s+(\S+)\s+(\d+)", header)
        declared = sum(int(n) for _, n in elements)
        if len(rows) < declared:
            raise InputError(f"{path}: {len(rows)} data lines where its header declares "
                             f"{declared} elements; the file is truncated")
        last = header.rsplit(b"element", 1)[-1]
        if rows and re.search(rb"property\s+list\s+\S+\s+\S+\s+\S+", last) \
                and last.count(b"property") == 1:
            tokens = rows[declared - 1].split()
            try:
                complete = len(tokens) >= 1 + int(float(tokens[0]))
            except (ValueError, IndexError):
                complete = False
            if not complete:
                raise InputError(f"{path}: its last element (line {declared} of the data) "
                                 "is incomplete; the file is truncated")
        scan.update(_ply_ear_clip(head.split(b"end_header", 1)[0], path.read_bytes()))
        scan.update(_ply_face_sizes(path.read_bytes()))
    elif re.search(rb"format\s+binary_(little|big)_endian", header) and b"end_header" in head:
        text = _ply_binary_as_ascii(path.read_bytes())
        if text is not None:  # not all triangles: clip and count as in ASCII
            ascii_header = text.split(b"end_header", 1)[0]
            scan.update(_ply_ear_clip(ascii_header, text))
            scan.update(_ply_face_sizes(text))
    return scan


def _ply_face_sizes(data: bytes) -> dict:
    """The corner counts of an ASCII PLY's faces (a vertex and a face element, one index
    list per face): ``ply_polygons`` faces of more than 3 corners and the
    ``ply_polygon_triangles`` they become (k - 2 each), ``ply_short`` faces of fewer
    than 3 (trimesh leaves them out) and the number of the first; {} for any other
    layout, or a file this cannot read (left to trimesh and the checks after it)."""
    header, _, body = data.partition(b"end_header")
    elements = re.findall(rb"element\s+(\S+)\s+(\d+)((?:\s*property[^\n]*)*)", header)
    if [e[0] for e in elements] != [b"vertex", b"face"] or \
            len(re.findall(rb"property", elements[1][2])) != 1 or \
            not re.search(rb"property\s+list", elements[1][2]):
        return {}
    nv, nf = int(elements[0][1]), int(elements[1][1])
    rows = [row for row in body.split(b"\n", 1)[-1].splitlines() if row.strip()]
    try:
        sizes = np.array([int(float(row.split()[0])) for row in rows[nv:nv + nf]], np.int64)
    except (ValueError, IndexError):
        return {}
    short = np.flatnonzero(sizes < 3)
    big = sizes[sizes > 3]
    return {"ply_polygons": len(big), "ply_polygon_triangles": int((big - 2).sum()),
            "ply_short": len(short), "ply_first_short": int(short[0]) if len(short) else None}


def _ply_expected(scan: dict) -> int:
    """The triangles a PLY gives when none is lost: its declared faces, less those of
    fewer than 3 corners, with each polygon counted as its k - 2 triangles (when
    :func:`_ply_face_sizes` could count them)."""
    return (scan["ply_faces"] - scan.get("ply_short", 0) - scan.get("ply_polygons", 0)
            + scan.get("ply_polygon_triangles", 0))


def _warn_ply_faces(source: str, scan: dict) -> None:
    """The warnings about a PLY's faces, each kind counted on its own: polygons
    triangulated (the faces of 3 or more corners and the triangles they became; the
    concave ones by ear clipping), faces of 1 or 2 corners left out."""
    if scan["ply_polygons"]:
        concave = scan.get("concave", 0)
        kept = scan["ply_faces"] - scan["ply_short"]
        warn(f"{source}: triangulated polygon faces ({kept} faces in the file became "
             f"{_ply_expected(scan)} triangles"
             + (f"; {concave} concave, by ear clipping)" if concave else ")"))
    if scan["ply_short"]:
        warn(f"{source}: ignored {scan['ply_short']} faces with fewer than 3 corners (first: "
             f"face {scan['ply_first_short']} of the file, counting from 0)")


#: PLY scalar types and their NumPy codes.
_PLY_TYPES = {b"char": "i1", b"int8": "i1", b"uchar": "u1", b"uint8": "u1", b"short": "i2",
              b"int16": "i2", b"ushort": "u2", b"uint16": "u2", b"int": "i4",
              b"int32": "i4", b"uint": "u4", b"uint32": "u4", b"float": "f4",
              b"float32": "f4", b"double": "f8", b"float64": "f8"}


def _ply_binary_as_ascii(data: bytes) -> bytes | None:
    """A binary PLY of a vertex and a face element (scalar vertex properties, one index
    list per face) that has a face of other than 3 corners, as the same PLY in ASCII, so
    :func:`_ply_ear_clip` can clip its concave polygons and :func:`_ply_face_sizes`
    count every face; None for a triangle mesh, any
    other layout or a file too short for its header (all left to trimesh)."""
    header, sep, body = data.partition(b"end_header")
    if not sep:
        return None
    body = body[2:] if body.startswith(b"\r\n") else body[1:]
    order = "<" if b"binary_little_endian" in header else ">"
    elements = re.findall(rb"element\s+(\S+)\s+(\d+)((?:\s*property[^\n]*)*)", header)
    if [e[0] for e in elements] != [b"vertex", b"face"]:
        return None
    vprops = [line.split() for line in elements[0][2].splitlines() if line.strip()]
    if any(len(w) != 3 or w[1] not in _PLY_TYPES for w in vprops):
        return None
    fprops = [line.split() for line in elements[1][2].splitlines() if line.strip()]
    if len(fprops) != 1 or len(fprops[0]) != 5 or fprops[0][1] != b"list" or \
            fprops[0][2] not in _PLY_TYPES or fprops[0][3] not in _PLY_TYPES:
        return None
    nv, nf = int(elements[0][1]), int(elements[1][1])
    vtype = np.dtype([(w[2].decode("ascii", "replace"), order + _PLY_TYPES[w[1]])
                      for w in vprops])
    ctype = np.dtype(order + _PLY_TYPES[fprops[0][2]])
    itype = np.dtype(order + _PLY_TYPES[fprops[0][3]])
    if len(body) < nv * vtype.itemsize:
        return None
    vertices = np.frombuffer(body, vtype, nv)
    at, faces = nv * vtype.itemsize, []
    triangles = np.dtype([("n", ctype), ("i", itype, 3)])
    if len(body) - at == nf * triangles.itemsize:  # a triangle mesh, read in one go
        counts = np.frombuffer(body, triangles, nf, at)["n"]
        if (counts == 3).all():
            return None
    for _ in range(nf):
        if at + ctype.itemsize > len(body):
            return None
        n = int(np.frombuffer(body, ctype, 1, at)[0])
        at += ctype.itemsize
        if n < 0 or at + n * itype.itemsize > len(body):
            return None
        faces.append(np.frombuffer(body, itype, n, at))
        at += n * itype.itemsize
    if all(len(f) == 3 for f in faces):
        return None
    lines = [re.sub(rb"format\s+binary_\w+", b"format ascii", header).rstrip() +
             b"\nend_header"]
    lines += [" ".join(repr(v.item()) for v in row).encode() for row in vertices]
    lines += [" ".join(str(int(i)) for i in (len(f), *f)).encode() for f in faces]
    return b"\n".join(lines) + b"\n"


def _ply_ear_clip(header: bytes, data: bytes) -> dict:
    """An ASCII PLY of a vertex and a face element (x, y, z among the vertex's scalar
    properties, one index list per face) with its concave polygons ear-clipped, as
    ``text`` and ``concave``; {} for any other layout (left to trimesh's fan)."""
    elements = re.findall(rb"element\s+(\S+)\s+(\d+)((?:\s*property[^\n]*)*)", header)
    if [e[0] for e in elements] != [b"vertex", b"face"]:
        return {}
    vertex_props = [line.split() for line in elements[0][2].splitlines() if line.strip()]
    if any(len(words) != 3 for words in vertex_props):  # a list property, or malformed
        return {}
    names = [words[2] for words in vertex_props]
    face_props = re.findall(rb"property\s+list\s+\S+\s+\S+\s+\S+", elements[1][2])
    if len(face_props) != 1 or elements[1][2].count(b"property") != 1 \
            or not all(n in names for n in (b"x", b"y", b"z")):
        return {}
    text, _ = _decode(data)
    head, body = text.split("end_header", 1)
    first, rest = body.split("\n", 1) if "\n" in body else (body, "")
    lines = rest.split("\n")
    rows = [i for i, line in enumerate(lines) if line.strip()]
    nv, nf = int(elements[0][1]), int(elements[1][1])
    xyz = [names.index(n) for n in (b"x", b"y", b"z")]
    try:
        positions = np.array([[float(lines[i].split()[j]) for j in xyz] for i in rows[:nv]])
        _, concave, added = _clip_face_lines(lines, rows[nv:nv + nf], positions)
    except (ValueError, IndexError):
        return {}
    if not concave:
        return {}
    head = re.sub(r"element\s+face\s+\d+", f"element face {nf + added}", head)
    return {"text": head + "end_header" + first + "\n" + "\n".join(lines),
            "file_type": "ply", "concave": concave}
