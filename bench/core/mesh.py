"""The one mesh value that flows through the suite.

A :class:`Mesh` stores *render vertices* ("wedges"): a vertex on a texture seam appears
once per distinct attribute set (position + UV + normal + colour), exactly as in glTF
and game engines. The welded topology, with equal positions merged, is derived from it
on demand (:attr:`Mesh.welded`) and never stored twice. Seams are then explicit: a
welded edge whose two adjacent faces use different render vertices for it.

Picture two triangles sharing the edge 1-2, where the right one uses its own copies of
the edge's vertices (a UV seam)::

    0-----1 3          render vertices 0..5, welded vertices 0..3
    |    /  /|         faces (0,1,2) and (3,5,4): positions of 3 == 1, of 4 == 2
    |  /  /  |         welded faces (0,1,2) and (1,3,2)
    2 4-----5          welded edge (1,2) is a seam, not a boundary
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

__all__ = ["Mesh", "Welded", "compact", "face_areas", "face_normals"]


@dataclass(frozen=True, eq=False)
class Welded:
    """Welded topology of a :class:`Mesh` (positions merged exactly).

    Attributes
    ----------
    vertex_of : ndarray of shape (n,) int32
        Welded vertex of each render vertex.
    positions : ndarray of shape (k, 3) float64
        One position per welded vertex.
    faces : ndarray of shape (m, 3) int32
        The mesh's faces in welded indices.
    edges : ndarray of shape (e, 2) int32
        Unique undirected welded edges, each row sorted ascending, rows sorted.
    edge_face_count : ndarray of shape (e,) int32
        Number of faces incident to each welded edge (1 boundary, 2 manifold, >2 not).
    seam : ndarray of shape (e,) bool
        True where an edge has exactly two faces and they use different render vertices
        for it.
    """

    vertex_of: np.ndarray
    positions: np.ndarray
    faces: np.ndarray
    edges: np.ndarray
    edge_face_count: np.ndarray
    seam: np.ndarray

    @property
    def n_vertices(self) -> int:
        return len(self.positions)

    @property
    def boundary(self) -> np.ndarray:
        """ndarray of shape (e,) bool: edges with exactly one incident face."""
        return self.edge_face_count == 1

    @property
    def non_manifold(self) -> np.ndarray:
        """ndarray of shape (e,) bool: edges with more than two incident faces."""
        return self.edge_face_count > 2


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh of render vertices with optional attributes.

    Parameters
    ----------
    positions : ndarray of shape (n, 3) float64
    faces : ndarray of shape (m, 3) int32
        Counter-clockwise triangles (outward normals by the right-hand rule).
    uv : ndarray of shape (n, 2) float64, optional
        Texture coordinates, origin at the bottom-left of the texture (OpenGL/OBJ).
    normals : ndarray of shape (n, 3) float64, optional
        Per-vertex normals as given by the file; ``None`` means "derive them".
    colors : ndarray of shape (n, 4) uint8, optional
        Per-vertex RGBA.
    texture : ndarray of shape (h, w, 3 or 4) uint8, optional
        The texture image, row 0 at the top (as stored in image files).
    name : str
        A label used in reports and file names.

    Notes
    -----
    Construct meshes from untrusted data with :func:`bench.io.validate.build_mesh`, which
    checks and cleans the arrays; this constructor only normalises dtypes and shapes.
    """

    positions: np.ndarray
    faces: np.ndarray
    uv: np.ndarray | None = None
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    texture: np.ndarray | None = None
    name: str = "mesh"
    metadata: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "positions", _as(self.positions, np.float64, 3, "positions"))
        set_(self, "faces", _as(self.faces, np.int32, 3, "faces"))
        n = len(self.positions)
        for attr, dtype, width in (("uv", np.float64, 2), ("normals", np.float64, 3),
                                   ("colors", np.uint8, 4)):
            value = getattr(self, attr)
            if value is not None:
                value = _as(value, dtype, width, attr)
                if len(value) != n:
                    raise ValueError(f"{attr} has {len(value)} rows for {n} vertices")
                set_(self, attr, value)
        if self.texture is not None:
            tex = np.ascontiguousarray(self.texture, dtype=np.uint8)
            if tex.ndim != 3 or tex.shape[2] not in (3, 4):
                raise ValueError(f"texture must be (h, w, 3|4) uint8, got {tex.shape}")
            set_(self, "texture", tex)

    # -- sizes ------------------------------------------------------------------------
    @property
    def n_vertices(self) -> int:
        """Number of render vertices."""
        return len(self.positions)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    @property
    def has_texture(self) -> bool:
        return self.texture is not None and self.uv is not None

    # -- derived topology ---------------------------------------------------------------
    @cached_property
    def welded(self) -> Welded:
        """The welded topology: render vertices with bit-equal positions merged."""
        return _weld(self.positions, self.faces)

    @property
    def seam_edges(self) -> np.ndarray:
        """ndarray of shape (s, 2) int32: welded edges (vertex pairs) on seams."""
        w = self.welded
        return w.edges[w.seam]

    @property
    def boundary_edges(self) -> np.ndarray:
        """ndarray of shape (b, 2) int32: welded edges with one incident face."""
        w = self.welded
        return w.edges[w.boundary]

    @cached_property
    def face_normals(self) -> np.ndarray:
        """ndarray of shape (m, 3) float64: unit face normals (zero for degenerate)."""
        return face_normals(self.positions, self.faces)

    @cached_property
    def vertex_normals(self) -> np.ndarray:
        """ndarray of shape (n, 3) float64: the file's normals, else area-weighted face
        normals accumulated over the *welded* vertex (so seams do not crease shading)."""
        if self.normals is not None:
            return self.normals
        w = self.welded
        area_normals = np.cross(*_edge_vectors(self.positions, self.faces))  # 2·area·n
        acc = np.zeros((w.n_vertices, 3))
        for corner in range(3):
            np.add.at(acc, w.faces[:, corner], area_normals)
        return _normalize(acc)[w.vertex_of]

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) corners, each ndarray of shape (3,)."""
        return self.positions.min(axis=0), self.positions.max(axis=0)

    @property
    def diagonal(self) -> float:
        """Length of the bounding-box diagonal."""
        lo, hi = self.bounding_box()
        return float(np.linalg.norm(hi - lo))

    @cached_property
    def content_hash(self) -> str:
        """SHA-1 of positions, faces, UVs and texture: identifies a model's content in
        result records and image caches."""
        h = hashlib.sha1()
        for array in (self.positions, self.faces, self.uv, self.texture):
            if array is not None:
                h.update(str(array.shape).encode())
                h.update(np.ascontiguousarray(array).tobytes())
        return h.hexdigest()

    def replace(self, **changes) -> Mesh:
        """A copy with some fields changed (derived topology is recomputed)."""
        return replace(self, **changes)

    def keep_faces(self, faces) -> Mesh:
        """The mesh made of ``faces`` alone, over only the vertices they use.

        What a simplification method returns once it knows which triangles survive:
        ``faces`` index this mesh's render vertices (a subset of its faces, or new
        triangles over its vertices); the result keeps the used vertices in their order,
        each with its UV, normal and colour, renumbers the faces onto them (see
        :func:`compact`), and keeps the texture, name and metadata.

        Parameters
        ----------
        faces : array_like of shape (k, 3) int
            Indices into this mesh's vertices.

        Returns
        -------
        Mesh

        Examples
        --------
        >>> quad = Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
        >>> half = quad.keep_faces(quad.faces[1:])
        >>> half.faces.tolist(), half.positions[:, :2].tolist()
        ([[0, 1, 2]], [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
        """
        used, renumbered = compact(faces, self.n_vertices)
        attributes = {a: getattr(self, a)[used] for a in ("uv", "normals", "colors")
                      if getattr(self, a) is not None}
        return self.replace(positions=self.positions[used], faces=renumbered, **attributes)

    def summary(self) -> dict:
        """Counts that describe the mesh, as shown by ``bench list models``."""
        w = self.welded
        return {
            "faces": self.n_faces,
            "render_vertices": self.n_vertices,
            "welded_vertices": w.n_vertices,
            "boundary_edges": int(w.boundary.sum()),
            "seam_edges": int(w.seam.sum()),
            "non_manifold_edges": int(w.non_manifold.sum()),
            "uv": self.uv is not None,
            "texture": self.texture is not None,
        }

    def __repr__(self) -> str:
        extras = [a for a in ("uv", "normals", "colors", "texture") if getattr(self, a) is not None]
        return (f"Mesh({self.name!r}, {self.n_faces} faces, {self.n_vertices} vertices"
                + (f", {'+'.join(extras)}" if extras else "") + ")")


# -- free functions ---------------------------------------------------------------------
def compact(faces, n_vertices: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The vertices ``faces`` use and ``faces`` renumbered onto them.

    Parameters
    ----------
    faces : array_like of shape (k, 3) int
        Indices into some vertex arrays.
    n_vertices : int, optional
        How many vertices there are; an index outside ``[0, n_vertices)`` is then a
        ``ValueError`` naming it.

    Returns
    -------
    used : ndarray of shape (u,) int64
        The indices ``faces`` use, ascending: index any per-vertex array with it.
    faces : ndarray of shape (k, 3) int32
        ``faces`` with each index replaced by its position in ``used``.
    """
    faces = np.asarray(faces)
    if faces.size == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3), np.int32)
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise ValueError(f"faces must be (k, 3) integers, got {faces.shape} {faces.dtype}")
    if n_vertices is not None:
        bad = faces[(faces < 0) | (faces >= n_vertices)]
        if bad.size:
            raise ValueError(f"face index {int(bad[0])} is outside the mesh's "
                             f"{n_vertices} vertices")
    used, renumbered = np.unique(faces.reshape(-1), return_inverse=True)
    return used.astype(np.int64), renumbered.reshape(-1, 3).astype(np.int32)



def face_normals(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normals of triangles, ndarray of shape (m, 3); zero rows for zero area.

    Each face's edge vectors, and then their cross product, are scaled by a power of
    two to a largest component in [0.5, 1) first, so the products neither overflow
    (coordinates of 1e200) nor underflow (1e-150) and a real triangle never passes for
    a degenerate one. Scaling by a power of two is exact: at ordinary magnitudes the
    normals are bit for bit those of the plain formula."""
    a, b = _edge_vectors(positions, faces)
    largest = np.maximum(np.abs(a).max(axis=1, initial=0), np.abs(b).max(axis=1, initial=0))
    cross = np.cross(_unit_scale(a, largest), _unit_scale(b, largest))
    return _normalize(_unit_scale(cross, np.abs(cross).max(axis=1, initial=0)))


def _unit_scale(v: np.ndarray, largest: np.ndarray) -> np.ndarray:
    """Rows of ``v`` times 2**-e, where ``largest`` (per row) is m * 2**e, 0.5 <= m < 1."""
    exponent = np.frexp(np.where(np.isfinite(largest), largest, 0.0))[1]
    return np.ldexp(v, -exponent[:, None])


def face_areas(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Triangle areas, ndarray of shape (m,)."""
    return 0.5 * np.linalg.norm(np.cross(*_edge_vectors(positions, faces)), axis=1)


def _edge_vectors(positions, faces):
    p = positions[faces]
    return p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]


def _normalize(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=1, keepdims=True)
    return np.divide(v, length, out=np.zeros_like(v), where=length > 0)


def _as(array, dtype, width: int, what: str) -> np.ndarray:
    a = np.ascontiguousarray(array, dtype=dtype)
    if a.size == 0:
        a = a.reshape(0, width)
    if a.ndim != 2 or a.shape[1] != width:
        raise ValueError(f"{what} must have shape (n, {width}), got {a.shape}")
    return a


def _weld(positions: np.ndarray, faces: np.ndarray) -> Welded:
    # Merge bit-equal positions. Seam duplicates are copies of one position, so exact
    # equality is the right test; a tolerance would also merge distinct nearby vertices.
    unique, vertex_of = np.unique(positions, axis=0, return_inverse=True)
    vertex_of = vertex_of.reshape(-1).astype(np.int32)
    wfaces = vertex_of[faces] if len(faces) else np.zeros((0, 3), np.int32)

    # Half-edges (render and welded), grouped by undirected welded edge.
    corners = np.array([[0, 1], [1, 2], [2, 0]])
    render_he = faces[:, corners].reshape(-1, 2)
    welded_he = wfaces[:, corners].reshape(-1, 2)
    # An undirected edge (a, b), a <= b, as the number a * n + b: unique in the same
    # order as the pairs, and an order of magnitude faster than unique rows.
    key = np.sort(welded_he, axis=1).astype(np.int64)
    n = max(len(unique), 1)
    codes, edge_of, count = np.unique(key[:, 0] * n + key[:, 1], return_inverse=True,
                                      return_counts=True)
    edges = np.stack([codes // n, codes % n], axis=1).astype(np.int32).reshape(-1, 2)

    # A manifold edge is a seam when its two half-edges use different render vertices.
    # Render endpoints are ordered by their welded vertex so both sides compare equal
    # when they share wedges.
    swap = welded_he[:, 0] > welded_he[:, 1]
    render_sorted = np.where(swap[:, None], render_he[:, ::-1], render_he)
    seam = np.zeros(len(edges), bool)
    manifold = count == 2
    if manifold.any():
        order = np.argsort(edge_of, kind="stable")
        starts = np.concatenate([[0], np.cumsum(count)[:-1]])
        first = render_sorted[order[starts[manifold]]]
        second = render_sorted[order[starts[manifold] + 1]]
        seam[manifold] = np.any(first != second, axis=1)
    return Welded(vertex_of=vertex_of, positions=unique, faces=wfaces.astype(np.int32),
                  edges=edges, edge_face_count=count.astype(np.int32), seam=seam)
