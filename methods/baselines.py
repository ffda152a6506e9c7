"""External baselines: QSlim as implemented by MeshLab (pymeshlab) and fast-simplification.

These wrap other people's implementations unchanged, so the suite's own methods are
compared against the tools engine developers actually use.

pymeshlab remembers the last values passed to a filter as its new defaults, even
across MeshSets; every call here therefore passes every parameter explicitly.
"""

from __future__ import annotations

import tempfile
from dataclasses import asdict, dataclass
from importlib.metadata import version
from pathlib import Path

import numpy as np

from bench.core.errors import InputError
from bench.core.mesh import Mesh, compact
from bench.core.method import Method, SimplifyResult, bounded

__all__ = ["FastSimplification", "QSlim", "QSlimTexture", "fewest_faces"]


@dataclass
class QSlimParams:
    """Parameters of MeshLab's quadric edge collapse (names as in pymeshlab)."""

    qualitythr: float = bounded(0.3, ge=0, le=1)
    preserveboundary: bool = False
    boundaryweight: float = bounded(1.0, ge=0)
    preservenormal: bool = False
    preservetopology: bool = False
    optimalplacement: bool = True
    planarquadric: bool = False
    planarweight: float = bounded(0.001, ge=0)
    qualityweight: bool = False
    autoclean: bool = True


@dataclass
class QSlimTextureParams:
    """Parameters of MeshLab's quadric edge collapse with texture (names as in pymeshlab)."""

    qualitythr: float = bounded(0.3, ge=0, le=1)
    extratcoordw: float = bounded(1.0, ge=0)
    preserveboundary: bool = False
    boundaryweight: float = bounded(1.0, ge=0)
    optimalplacement: bool = True
    preservenormal: bool = False
    planarquadric: bool = False


class QSlim(Method):
    """Garland–Heckbert quadric edge collapse, MeshLab's implementation.

    Works on the render vertices as given: a texture seam is two boundaries to it, so
    seams may open (this is what an engine gets from running QSlim on its unwelded
    vertex buffers). Per-vertex UVs and colours of surviving vertices are carried along
    and the texture is kept.
    """

    name = "qslim"
    version = "1"
    summary = "QSlim quadric edge collapse on render vertices (pymeshlab)"
    reference = "Garland & Heckbert, Surface simplification using quadric error metrics, SIGGRAPH 1997"
    requires = {"pymeshlab": "pymeshlab>=2023.12"}
    Params = QSlimParams

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        result, reason = fewest_faces(lambda t: self._decimate(mesh, t), target_faces, mesh)
        return SimplifyResult(result, {"backend": _pymeshlab_version()}, stop_reason=reason)

    def _decimate(self, mesh: Mesh, target_faces: int) -> Mesh:
        import pymeshlab

        kwargs = {}
        if mesh.uv is not None:
            kwargs["v_tex_coords_matrix"] = mesh.uv
        if mesh.colors is not None:
            kwargs["v_color_matrix"] = mesh.colors.astype(np.float64) / 255.0
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=mesh.positions, face_matrix=mesh.faces, **kwargs))
        ms.meshing_decimation_quadric_edge_collapse(
            targetfacenum=int(target_faces), targetperc=0.0, selected=False, **asdict(self.params))
        ms.meshing_remove_unreferenced_vertices()
        out = ms.current_mesh()
        uv = out.vertex_tex_coord_matrix() if mesh.uv is not None else None
        colors = None
        if mesh.colors is not None:
            colors = np.clip(np.rint(out.vertex_color_matrix() * 255), 0, 255).astype(np.uint8)
        return mesh.replace(positions=out.vertex_matrix(), faces=out.face_matrix(), uv=uv,
                            colors=colors, normals=None)


class QSlimTexture(Method):
    """Garland–Heckbert 1998 quadrics over position and texture coordinates, MeshLab's
    implementation.

    The input is welded (equal positions merged) and its UVs passed per wedge (face
    corner), so MeshLab sees seams as attribute discontinuities, not boundaries. The
    output's wedges are split back into render vertices: one per distinct
    (vertex, UV) pair.
    """

    name = "qslim-texture"
    version = "1"
    summary = "QSlim with texture-coordinate quadrics on wedges (pymeshlab)"
    reference = ("Garland & Heckbert, Simplifying surfaces with color and texture using "
                 "quadric error metrics, IEEE Visualization 1998")
    requires = {"pymeshlab": "pymeshlab>=2023.12"}
    needs_uv = True
    Params = QSlimTextureParams

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        import pymeshlab

        if mesh.uv is None:
            raise InputError(f"{mesh.name}: qslim-texture needs texture coordinates and the "
                             "mesh has none; use --method qslim")
        ms = pymeshlab.MeshSet()
        with tempfile.TemporaryDirectory(prefix="bench-qslim-") as tmp:
            ms.load_new_mesh(_write_wedge_obj(mesh, Path(tmp)))
        ms.meshing_decimation_quadric_edge_collapse_with_texture(
            targetfacenum=int(target_faces), targetperc=0.0, selected=False, **asdict(self.params))
        out = ms.current_mesh()
        positions, faces, uv = split_wedges(out.vertex_matrix(), out.face_matrix(),
                                            out.wedge_tex_coord_matrix())
        result = mesh.replace(positions=positions, faces=faces, uv=uv, normals=None, colors=None)
        return SimplifyResult(result, {"backend": _pymeshlab_version()})


class FastSimplification(Method):
    """Quadric decimation by the fast-simplification package (Fast-Quadric-Mesh-
    Simplification by Sven Forstmann, wrapped for Python).

    Positions only: it cannot carry UVs, normals or colours, so its output is
    untextured. With ``weld`` (the default) seams are merged first so they cannot
    open; without it the render vertices are used as given.
    """

    name = "fast-simplification"
    version = "1"
    summary = "Forstmann's fast quadric decimation, positions only (fast-simplification)"
    reference = "S. Forstmann, Fast-Quadric-Mesh-Simplification (software), 2014"
    requires = {"fast_simplification": "fast-simplification>=0.1.7"}

    @dataclass
    class Params:
        agg: float = bounded(7.0, ge=0)
        weld: bool = True
        preserve_border: bool = False

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        result, reason = fewest_faces(lambda t: self._decimate(mesh, t), target_faces, mesh)
        return SimplifyResult(result, {"backend": "fast-simplification",
                                       "attributes_dropped": mesh.uv is not None},
                              stop_reason=reason)

    def _decimate(self, mesh: Mesh, target_faces: int) -> Mesh:
        import fast_simplification

        p = self.params
        if p.weld:
            positions, faces = mesh.welded.positions, mesh.welded.faces
        else:
            positions, faces = mesh.positions, mesh.faces
        points, tris = fast_simplification.simplify(
            positions, faces, target_count=int(target_faces), agg=float(p.agg), verbose=False,
            return_collapses=False, lossless=False, preserve_border=bool(p.preserve_border))
        points, tris = _drop_unreferenced(points, tris)
        return Mesh(points, tris, name=mesh.name, metadata=dict(mesh.metadata))


def fewest_faces(decimate, target: int, mesh: Mesh) -> tuple[Mesh, str | None]:
    """``decimate(target)``, and a stop reason when the backend leaves no face there.

    QSlim and fast-simplification go down to an empty mesh when asked for fewer faces
    than the surface can keep (1 face of a closed mesh). Then the target is raised
    (by 1, 2, 4, ... faces, below the input's count) until a result has faces, which is
    returned with the reason; when none has, the input itself is. An empty result is
    never returned.
    """
    result = decimate(target)
    if result.n_faces > 0:
        return result, None
    step, tried = 1, target
    while target + step < mesh.n_faces:
        tried = target + step
        result = decimate(tried)
        if result.n_faces > 0:
            return result, (f"the backend leaves no faces at a target of {target}; stopped at "
                            f"{result.n_faces} faces, the fewest it leaves (target {tried})")
        step *= 2
    return mesh, (f"the backend leaves no faces at any target from {target} to {tried}; "
                  f"returned the input's {mesh.n_faces} faces")


def split_wedges(positions: np.ndarray, faces: np.ndarray, wedge_uv: np.ndarray):
    """Turn per-corner UVs into render vertices: one per distinct (vertex, UV) pair.

    Parameters
    ----------
    positions : ndarray of shape (k, 3)
    faces : ndarray of shape (m, 3) int
    wedge_uv : ndarray of shape (3m, 2)
        UV of corner ``j`` of face ``i`` at row ``3i + j``.

    Returns
    -------
    positions : ndarray of shape (n, 3)
    faces : ndarray of shape (m, 3) int32
    uv : ndarray of shape (n, 2)
    """
    corners = faces.reshape(-1)
    key = np.column_stack([corners.astype(np.float64), wedge_uv])
    unique, inverse = np.unique(key, axis=0, return_inverse=True)
    return positions[unique[:, 0].astype(np.int64)], inverse.reshape(-1, 3).astype(np.int32), unique[:, 1:]


def _pymeshlab_version() -> str:
    return f"pymeshlab {version('pymeshlab')}"


def _write_wedge_obj(mesh: Mesh, folder: Path) -> str:
    """The welded mesh with per-corner UVs as an OBJ that MeshLab reads with texture
    indices set. (pymeshlab's Mesh constructor takes wedge UVs but leaves the faces
    without a texture index, which the texture-aware filter rejects.)"""
    welded = mesh.welded
    lines = ["mtllib wedges.mtl", "usemtl tex"]
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in welded.positions.tolist()]
    lines += [f"vt {u!r} {v!r}" for u, v in mesh.uv.tolist()]
    pv, pt = welded.faces + 1, mesh.faces + 1  # corner i: welded vertex, render UV
    lines += [f"f {a}/{d} {b}/{e} {c}/{f}" for (a, b, c), (d, e, f) in zip(pv.tolist(), pt.tolist())]
    (folder / "wedges.obj").write_text("\n".join(lines) + "\n")
    (folder / "wedges.mtl").write_text("newmtl tex\nmap_Kd tex.png\n")
    from PIL import Image

    Image.new("RGB", (1, 1), "white").save(folder / "tex.png")  # the filter reads UVs only
    return str(folder / "wedges.obj")


def _drop_unreferenced(points: np.ndarray, tris: np.ndarray):
    used, tris = compact(tris)
    return points[used], tris
