"""Loading and saving meshes (OBJ + MTL + texture, PLY, glTF/GLB, OFF, STL) via trimesh.

Loaders keep render vertices as the file defines them: trimesh's OBJ reader creates one
vertex per distinct (position, texture coordinate, normal) corner, which is exactly our
render-vertex model; the welded topology is recovered from equal positions.

A few problems trimesh would either hide (polygons triangulated, a texture file not
found) or report from deep inside (an index out of range) are detected by a light scan
of the file first, so the user gets one line naming the file and the problem.
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
from bench.io.validate import build_mesh, warn
from bench.mesh import Mesh

__all__ = ["FORMATS", "SCENE_FORMATS", "check_output_path", "load_mesh", "lod_path", "save_lods",
           "save_mesh"]

#: Supported file extensions and what they keep.
FORMATS = {
    ".obj": "positions, UVs, normals, texture (via MTL map_Kd)",
    ".ply": "positions, UVs, colours (no texture image)",
    ".gltf": "positions, UVs, normals, colours, base-colour texture",
    ".glb": "positions, UVs, normals, colours, base-colour texture",
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
        loaded = trimesh.load(str(path), process=False, force="mesh", skip_materials=False)
    except Exception as exc:  # trimesh raises many kinds; the user needs one line
        raise InputError(f"{source}: could not read as {ext[1:].upper()} "
                         f"({type(exc).__name__}: {exc})") from None
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


def _write_export(tm, path: Path) -> list[Path]:
    """Export a trimesh mesh or scene in the format of ``path``'s extension; the files
    written (a ``.gltf`` with its buffers renamed after ``path``)."""
    data = tm.export(file_type=path.suffix.lower()[1:])
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
    if worst is not None:
        lineno, idx, n = worst
        raise InputError(f"{path}: line {lineno}: face index {idx} is out of range "
                         f"({n} vertices defined before it); the file is corrupt or truncated")
    if max_index > n_v:
        raise InputError(f"{path}: line {max_line}: face index {max_index} is out of range "
                         f"(the file has {n_v} vertices); the file is corrupt or truncated")
    refs, found = [], []
    for lib in mtllibs:
        mtl = path.parent / lib.decode(errors="replace")
        if not mtl.exists():
            refs.append(f"{mtl.name} (material file)")
            continue
        for line in mtl.read_bytes().splitlines():
            parts = line.strip().split()
            if parts and parts[0].lower() in (b"map_kd", b"map_ka") and len(parts) > 1:
                tex = parts[-1].decode(errors="replace")
                (found if (mtl.parent / tex).exists() else refs).append(tex)
    return {"polygons": polygons, "texture_refs": refs, "texture_files": found}


def _scan_ply(path: Path) -> dict:
    """Face count from the PLY header (ASCII even in binary files), to count the faces
    trimesh triangulated."""
    with open(path, "rb") as f:
        header = f.read(4096).split(b"end_header", 1)[0]
    match = re.search(rb"element\s+face\s+(\d+)", header)
    return {"ply_faces": int(match.group(1))} if match else {}
