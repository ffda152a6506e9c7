"""Per-node bounds of a Multi-Triangulation (Williams et al. 2003, §4 and §5.2-5.4).

:func:`preprocess` gives every node of a :class:`methods.mt.dag.MultiTriangulation`:

- a bounding sphere of the original triangles mapped to it and of its own triangles;
- a *silhouette normal cone* (§5.3): the normals of those original triangles and of
  the node's own triangles, removed and created ("a simplified surface may well
  contain sharper dihedral angles than the original");
- a *shading normal cone* (§5.4): the original's vertex normals at those triangles'
  corners (area-weighted, as the evaluation renderer's Gouraud normals);
- the luminance range ``L_min..L_max`` of the texels those triangles cover (§4, §5.2),
  or the material's gray for an untextured mesh;
- the texture deviation (§2.2) of the node's created triangles from the original.

Choices where the paper is vague:

- *Which original triangles belong to a node.* The paper rasterises the node's
  triangles into a texture pyramid holding, per texel, the original triangles mapped
  there. We follow the collapse history instead: every original triangle belongs to
  exactly one triangle of every cut, the one it was last handed to, and a node's
  original triangles are those of the triangles it removes; when the node creates its
  triangles, each original goes to the created triangle nearest to its centroid. The
  footprint is cumulative, as §5.2 demands, and no parameterisation is needed, so
  untextured meshes (the bunny) work the same way (§7 asks only for "a correspondence
  between nodes in the MT and the original triangles").
- *Texel luminance* uses the texture pyramid of §4 per original triangle: a min/max
  luminance pyramid is rasterised hierarchically (a cell inside the UV triangle gives
  its stored range; a partial cell recurses; a partial texel at the bottom counts),
  so every texel the triangle touches is covered. Luminance is Rec. 601 Y of the
  texture's sRGB values on 0..1, the protocol's luminance, without display gamma.
- *Texture deviation* is sampled, not bounded as Cohen et al. 1998 do, and has two
  parts. The parametric part, both ways between the node's created and original
  triangles: at the corners of its original triangles and at the corners, edge
  midpoints and centroids of its created ones, the distance to the point of the other
  set with the same texture coordinates. A point whose coordinates the other set does
  not contain lies in another node's part of the chart (a low-poly asset's original
  triangles are large, and a footprint holds the far corners of triangles whose
  centroid it holds) and is not sampled. A triangle whose UV triangle covers at most
  one texel shows one colour, so its UVs name no point of the surface: it contains no
  coordinates (game assets map whole solid-coloured parts to a texel or a point).
  Where UV islands overlap or mirror each other, a point may find its coordinates on
  another island than its own (the nearest point with them counts). The geometric
  part, which is all an untextured mesh has: the original vertices are handed down
  the MT as the original triangles are, each to the created triangle nearest to the
  vertex itself (at first the lowest-numbered original triangle it is a corner of),
  and a node's part is the largest distance from a vertex it hands on to its new
  triangle. A vertex always belongs to the triangle of the cut nearest to it when it
  was handed, so the corners of large original triangles do not count against a node
  that merely holds their centroid. The deviation is the larger part, made monotone (a
  node's deviation is at least its children's), so that refining never raises the
  error of the cut. Each MT triangle also keeps its own deviation, not monotone: the
  largest distance from a vertex handed to it, or its creator's parametric part. It
  is the error a cut holding the triangle has there, by which the object-space cut
  is refined (methods.mt.refine.refine_where_farthest).
- *The other bounds are each node's own*, as §4 computes them, not nested up the MT:
  a child's created triangles are shared among several parents, so a parent's
  sphere can be smaller than a child's and its cones narrower. The view errors are
  made monotone instead, by the same maximum over children as the deviation
  (methods.mt.errors says why).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from methods.mt.dag import MultiTriangulation
from metrics.shading import LUMA_B, LUMA_G, LUMA_R

__all__ = ["NodeBounds", "preprocess", "node_triangles", "node_footprints", "subtree_max",
           "texel_luminance_ranges", "luminance_pyramid"]


@dataclass
class NodeBounds:
    """Per-node bounds, each an array over the c nodes of the MT.

    Attributes
    ----------
    center : ndarray (c, 3); radius : ndarray (c,)
        Bounding sphere.
    silhouette_axis : ndarray (c, 3); silhouette_angle : ndarray (c,)
        Silhouette normal cone (half-angle in radians; π: normals in every direction).
    shading_axis : ndarray (c, 3); shading_angle : ndarray (c,)
        Shading normal cone from the original vertex normals.
    luminance : ndarray (c, 2)
        L_min, L_max of the covered texels (0..1), or the material gray twice.
    deviation : ndarray (c,)
        Texture deviation in model units, monotone up the MT.
    triangle_deviation : ndarray (nt,)
        Each MT triangle's own deviation, in model units: the largest distance from an
        original vertex its creator handed to it (the geometric part, triangle by
        triangle) or its creator's own parametric part; 0 for an original triangle.
        Not monotone: it measures the surface a cut holding the triangle has there,
        which the object-space cut refines by (methods.mt.refine).
    child_start, children : ndarray (c + 1,), (kc,) int64
        The MT's children lists (CSR): the view errors take each node's maximum over
        its children (methods.mt.errors), as the deviation does here.
    textured : bool
    seconds : float
        Wall time of the preprocessing.
    """

    center: np.ndarray
    radius: np.ndarray
    silhouette_axis: np.ndarray
    silhouette_angle: np.ndarray
    shading_axis: np.ndarray
    shading_angle: np.ndarray
    luminance: np.ndarray
    deviation: np.ndarray
    child_start: np.ndarray
    children: np.ndarray
    textured: bool
    triangle_deviation: np.ndarray | None = None
    seconds: float = 0.0


def preprocess(mt: MultiTriangulation, albedo: float = 1.0) -> NodeBounds:
    """Bounds of every node of ``mt`` (see the module docstring).

    Parameters
    ----------
    mt : MultiTriangulation
    albedo : float
        Gray material luminance of untextured meshes (the evaluation renderer's 1.0).
    """
    import time

    start_time = time.perf_counter()
    m = mt.n_original
    orig = mt.triangles[:m].astype(np.int64)
    P = mt.positions
    corners = P[orig]  # (m, 3, 3)
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area2 = np.linalg.norm(cross, axis=1)
    normals = np.divide(cross, area2[:, None], out=np.zeros_like(cross), where=area2[:, None] > 0)
    # area-weighted vertex normals over the welded original
    welded = mt.welded[orig]
    acc = np.zeros((int(mt.welded.max()) + 1, 3))
    for k in range(3):
        np.add.at(acc, welded[:, k], cross)
    length = np.linalg.norm(acc, axis=1, keepdims=True)
    vnormals = np.divide(acc, length, out=np.zeros_like(acc), where=length > 0)[welded]
    textured = mt.uv is not None and mt.texture is not None
    if textured:
        lum = texel_luminance_ranges(mt.uv[orig], mt.texture)
    else:
        lum = np.full((m, 2), float(albedo))
    tris = mt.triangles.astype(np.int64)
    # every stage reads the same two lists, built once: the node's own triangles ...
    start, split, own = node_triangles(mt)
    # ... and the original triangles mapped to it (the collapse history, handed down)
    fp_start, fp = _footprints(tris, P, m, start, split, own)
    # §2.2, §5.3: the sphere's nearest point projects the deviation to the screen and
    # culls nodes outside the view
    center, radius = _spheres(tris, P, fp_start, fp, start, own)
    # §5.3: may the node lie on the silhouette (original and simplified normals)
    sax, sang = _silhouette_cones(tris, P, normals, 0.5 * area2, fp_start, fp, start, own)
    # §5.4: the lit shading's range, from the original's vertex normals
    hax, hang = _shading_cones(vnormals, fp_start, fp)
    # §5.2: the contrast the node can induce, from the texels it covers
    lrange = _luminance_ranges(lum, fp_start, fp)
    # §2.2: how far the node moves the surface (monotone up the MT)
    child_start, children = mt.child_start.astype(np.int64), mt.children.astype(np.int64)
    moved, held = _vertex_moves(tris, P, m, start, split, own)
    parametric = _deviations(tris, P, (mt.uv if mt.uv is not None else np.zeros((1, 2)),
                                       _min_uv_det(mt)), fp_start, fp, start, split, own)
    creator = mt.creator.astype(np.int64)
    by_triangle = np.where(creator >= 0, np.maximum(held, parametric[creator]), 0.0)
    dev = np.maximum(moved, parametric)
    subtree_max(dev, child_start, children)
    return NodeBounds(center=center, radius=radius, silhouette_axis=sax,
                      silhouette_angle=sang, shading_axis=hax, shading_angle=hang,
                      luminance=lrange, deviation=dev, child_start=child_start,
                      children=children, textured=textured, triangle_deviation=by_triangle,
                      seconds=time.perf_counter() - start_time)


def _min_uv_det(mt: MultiTriangulation) -> float:
    """:func:`_deviations`'s ``min_det``: twice a texel's UV area when the MT is
    textured, 0 with UVs only, -1 without UVs."""
    if mt.uv is None:
        return -1.0
    if mt.texture is None:
        return 0.0
    height, width = mt.texture.shape[:2]
    return 2.0 / (height * width)


def node_triangles(mt: MultiTriangulation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each node's own triangles as one CSR list: removed, then created.

    Returns
    -------
    start : ndarray (c + 1,) int64
    split : ndarray (c,) int64
    own : ndarray (k,) int64
        Node i removes ``own[start[i]:split[i]]`` and creates ``own[split[i]:start[i + 1]]``
        (MT triangle indices, in the order of ``mt.removed`` and ``mt.created``).
    """
    return _node_triangles(mt.removed_start.astype(np.int64), mt.removed.astype(np.int64),
                           mt.created_start.astype(np.int64), mt.created.astype(np.int64))


def node_footprints(mt: MultiTriangulation) -> tuple[np.ndarray, np.ndarray]:
    """The original triangles mapped to each node (the module docstring's first choice).

    Returns
    -------
    fp_start : ndarray (c + 1,) int64; fp : ndarray (k,) int64
        Node i's original triangles (indices of the input's faces) are
        ``fp[fp_start[i]:fp_start[i + 1]]``.
    """
    start, split, own = node_triangles(mt)
    return _footprints(mt.triangles.astype(np.int64), mt.positions, mt.n_original,
                       start, split, own)


# -- texel luminance through a min/max pyramid (§4) -------------------------------------------

def luminance_pyramid(texture: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Min and max luminance pyramids of a texture, finest level first.

    Parameters
    ----------
    texture : ndarray of shape (h, w, 3) or (h, w) uint8

    Returns
    -------
    list of (ndarray, ndarray)
        Level l holds, per cell of 2^l × 2^l texels, the min and max of Rec. 601
        luminance on 0..1; levels halve (rounding up) down to one cell.
    """
    t = np.asarray(texture)
    if t.ndim == 3:
        y = (LUMA_R * t[..., 0] + LUMA_G * t[..., 1] + LUMA_B * t[..., 2]) / 255.0
    elif t.ndim == 2:
        y = t / 255.0
    else:
        raise ValueError(f"texture must be (h, w) or (h, w, 3), got shape {t.shape}")
    lo = hi = y.astype(np.float64)
    levels = [(lo, hi)]
    while lo.shape[0] > 1 or lo.shape[1] > 1:
        h, w = lo.shape
        ph, pw = h + (h % 2), w + (w % 2)
        lo_p = np.pad(lo, ((0, ph - h), (0, pw - w)), mode="edge")
        hi_p = np.pad(hi, ((0, ph - h), (0, pw - w)), mode="edge")
        lo = lo_p.reshape(ph // 2, 2, pw // 2, 2).min(axis=(1, 3))
        hi = hi_p.reshape(ph // 2, 2, pw // 2, 2).max(axis=(1, 3))
        levels.append((lo, hi))
    return levels


def texel_luminance_ranges(uv_triangles: np.ndarray, texture: np.ndarray) -> np.ndarray:
    """Luminance range of the texels each UV triangle touches (§4).

    Parameters
    ----------
    uv_triangles : ndarray of shape (m, 3, 2)
        Texture coordinates of each triangle's corners (origin bottom-left, as OpenGL;
        the image's row 0 is v = 1). Coordinates are clamped to [0, 1].
    texture : ndarray of shape (h, w, 3) uint8

    Returns
    -------
    ndarray of shape (m, 2)
        L_min, L_max on 0..1.
    """
    levels = luminance_pyramid(texture)
    h, w = levels[0][0].shape
    depth = len(levels)
    # pack the levels into one padded array per kind: (depth, H0, W0)
    lo = np.ones((depth, h, w))
    hi = np.zeros((depth, h, w))
    for i, (a, b) in enumerate(levels):
        lo[i, :a.shape[0], :a.shape[1]] = a
        hi[i, :b.shape[0], :b.shape[1]] = b
    shapes = np.array([a.shape for a, _ in levels], np.int64)
    xy = np.empty(uv_triangles.shape, np.float64)
    uvc = np.clip(uv_triangles, 0.0, 1.0)
    xy[..., 0] = uvc[..., 0] * w
    xy[..., 1] = (1.0 - uvc[..., 1]) * h
    return _texel_ranges(xy, lo, hi, shapes)


@njit(cache=True)
def _edge_side(ax, ay, bx, by, px, py):
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax)


@njit(cache=True)
def _classify(tri, x0, y0, x1, y1, orient):
    """0: the box [x0,x1]x[y0,y1] misses the triangle, 1: partly, 2: inside it."""
    # box axes: bounding boxes disjoint
    if (max(tri[0, 0], tri[1, 0], tri[2, 0]) <= x0 or min(tri[0, 0], tri[1, 0], tri[2, 0]) >= x1
            or max(tri[0, 1], tri[1, 1], tri[2, 1]) <= y0
            or min(tri[0, 1], tri[1, 1], tri[2, 1]) >= y1):
        return 0
    if orient == 0.0:
        return 1  # a degenerate triangle touches the texels its box overlaps
    inside_all = True
    for e in range(3):
        ax, ay = tri[e, 0], tri[e, 1]
        bx, by = tri[(e + 1) % 3, 0], tri[(e + 1) % 3, 1]
        n_in = 0
        for cx, cy in ((x0, y0), (x1, y0), (x0, y1), (x1, y1)):
            if _edge_side(ax, ay, bx, by, cx, cy) * orient > 0.0:
                n_in += 1
        if n_in == 0:
            return 0  # every corner outside this edge: a separating axis
        if n_in < 4:
            inside_all = False
    return 2 if inside_all else 1


@njit(cache=True)
def _texel_ranges(xy, lo, hi, shapes):
    m = xy.shape[0]
    depth = lo.shape[0]
    out = np.empty((m, 2))
    stack = np.empty((4 * depth * 8 + 64, 3), np.int64)
    for f in range(m):
        tri = xy[f]
        orient = _edge_side(tri[0, 0], tri[0, 1], tri[1, 0], tri[1, 1], tri[2, 0], tri[2, 1])
        bx0 = min(tri[0, 0], tri[1, 0], tri[2, 0])
        bx1 = max(tri[0, 0], tri[1, 0], tri[2, 0])
        by0 = min(tri[0, 1], tri[1, 1], tri[2, 1])
        by1 = max(tri[0, 1], tri[1, 1], tri[2, 1])
        extent = max(bx1 - bx0, by1 - by0, 1.0)
        level = min(depth - 1, int(math.ceil(math.log2(extent))))
        s = 1 << level
        lmin = 1e300
        lmax = -1e300
        n = 0
        h, w = shapes[0, 0], shapes[0, 1]
        # the cells of the start level under the triangle's box (a texel-wide margin,
        # so a triangle on a texel border still reads a texel)
        cy0 = max(0, int(math.floor(by0 - 1e-9)) // s)
        cy1 = min(shapes[level, 0] - 1, int(math.floor(by1 + 1e-9)) // s)
        cx0 = max(0, int(math.floor(bx0 - 1e-9)) // s)
        cx1 = min(shapes[level, 1] - 1, int(math.floor(bx1 + 1e-9)) // s)
        for cy in range(cy0, cy1 + 1):
            for cx in range(cx0, cx1 + 1):
                stack[n, 0] = level
                stack[n, 1] = cy
                stack[n, 2] = cx
                n += 1
        while n > 0:
            n -= 1
            lv, cy, cx = stack[n, 0], stack[n, 1], stack[n, 2]
            s = 1 << lv
            x0, y0 = cx * s, cy * s
            x1, y1 = min((cx + 1) * s, w), min((cy + 1) * s, h)
            kind = _classify(tri, x0 - 1e-9, y0 - 1e-9, x1 + 1e-9, y1 + 1e-9, orient)
            if kind == 0:
                continue
            if kind == 2 or lv == 0:
                lmin = min(lmin, lo[lv, cy, cx])
                lmax = max(lmax, hi[lv, cy, cx])
                continue
            for dy in range(2):
                for dx in range(2):
                    yy, xx = 2 * cy + dy, 2 * cx + dx
                    if yy < shapes[lv - 1, 0] and xx < shapes[lv - 1, 1]:
                        stack[n, 0] = lv - 1
                        stack[n, 1] = yy
                        stack[n, 2] = xx
                        n += 1
        if lmin > lmax:  # nothing touched (cannot happen with the margin): nearest texel
            ty = min(h - 1, max(0, int(by0)))
            tx = min(w - 1, max(0, int(bx0)))
            lmin = lo[0, ty, tx]
            lmax = hi[0, ty, tx]
        out[f, 0] = lmin
        out[f, 1] = lmax
    return out


# -- per-node bounds ---------------------------------------------------------------------------

@njit(cache=True)
def _closest_distance(p, a, b, c):
    """Distance from p to triangle abc (Ericson, Real-Time Collision Detection 5.1.5)."""
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = ab @ ap
    d2 = ac @ ap
    if d1 <= 0.0 and d2 <= 0.0:
        q = a
    else:
        bp = p - b
        d3 = ab @ bp
        d4 = ac @ bp
        if d3 >= 0.0 and d4 <= d3:
            q = b
        else:
            vc = d1 * d4 - d3 * d2
            if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
                q = a + (d1 / (d1 - d3)) * ab
            else:
                cp = p - c
                d5 = ab @ cp
                d6 = ac @ cp
                if d6 >= 0.0 and d5 <= d6:
                    q = c
                else:
                    vb = d5 * d2 - d1 * d6
                    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
                        q = a + (d2 / (d2 - d6)) * ac
                    else:
                        va = d3 * d6 - d5 * d4
                        if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
                            q = b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b)
                        else:
                            denom = 1.0 / (va + vb + vc)
                            q = a + ab * (vb * denom) + ac * (vc * denom)
    d = p - q
    return math.sqrt(d @ d)


@njit(cache=True)
def _uv_barycentric(t, a, b, c, min_det):
    """Barycentric coordinates of t in UV triangle abc; (-1, -1, -1) if degenerate:
    twice its UV area at most ``min_det``."""
    det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
    if abs(det) <= min_det:
        return -1.0, -1.0, -1.0
    l1 = ((t[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (t[1] - a[1])) / det
    l2 = ((b[0] - a[0]) * (t[1] - a[1]) - (t[0] - a[0]) * (b[1] - a[1])) / det
    return 1.0 - l1 - l2, l1, l2


@njit(cache=True)
def _cone(vectors, n, axis_out):
    """Cone around the normalised sum of vectors[:n] (already weighted); returns the
    half-angle of the unit directions (π if the sum vanishes)."""
    sx = 0.0
    sy = 0.0
    sz = 0.0
    for i in range(n):
        sx += vectors[i, 0]
        sy += vectors[i, 1]
        sz += vectors[i, 2]
    s = math.sqrt(sx * sx + sy * sy + sz * sz)
    if s < 1e-300:
        axis_out[0] = 0.0
        axis_out[1] = 0.0
        axis_out[2] = 1.0
        return math.pi
    axis_out[0] = sx / s
    axis_out[1] = sy / s
    axis_out[2] = sz / s
    min_cos = 1.0
    for i in range(n):
        ln = math.sqrt(vectors[i, 0] ** 2 + vectors[i, 1] ** 2 + vectors[i, 2] ** 2)
        if ln == 0.0:
            continue
        cs = (vectors[i, 0] * axis_out[0] + vectors[i, 1] * axis_out[1]
              + vectors[i, 2] * axis_out[2]) / ln
        min_cos = min(min_cos, cs)
    return math.acos(max(-1.0, min(1.0, min_cos)))


# The stages below share two CSR lists built once: each node's own triangles
# (``_node_triangles``) and each node's original triangles (``_footprints``). Arrays:
#
#   tris : (nt, 3) int64     every MT triangle, as MT vertex indices; the first m original
#   P : (nv, 3) float64      MT vertex positions
#   start : (c + 1,) int64   node i's own triangles are own[start[i]:start[i + 1]] ...
#   split : (c,) int64       ... the removed ones before split[i], the created ones after
#   own : (k,) int64         MT triangle indices
#   fp_start : (c + 1,) int64, fp : (kf,) int64
#                            node i's original triangles are fp[fp_start[i]:fp_start[i + 1]]


@njit(cache=True)
def _node_triangles(r_start, r_list, c_start, c_list):
    """Each node's own triangles as one CSR list: those it removes, then those it creates.

    Parameters
    ----------
    r_start, r_list : ndarray (c + 1,), (kr,) int64
        CSR: the triangles node i removes.
    c_start, c_list : ndarray (c + 1,), (kc,) int64
        CSR: the triangles node i creates.

    Returns
    -------
    start : ndarray (c + 1,) int64
    split : ndarray (c,) int64
        Where node i's created triangles begin in ``own``.
    own : ndarray (kr + kc,) int64
    """
    c = r_start.shape[0] - 1
    start = np.zeros(c + 1, np.int64)
    split = np.zeros(c, np.int64)
    own = np.empty(r_list.shape[0] + c_list.shape[0], np.int64)
    n = 0
    for i in range(c):
        for j in range(r_start[i], r_start[i + 1]):
            own[n] = r_list[j]
            n += 1
        split[i] = n
        for j in range(c_start[i], c_start[i + 1]):
            own[n] = c_list[j]
            n += 1
        start[i + 1] = n
    return start, split, own


def _footprints(tris, P, m, start, split, own):
    """Each node's original triangles (the module docstring's first choice).

    Every original triangle belongs to one triangle of the current cut, the one it was
    last handed to (at first itself). Node i collects the originals of the triangles it
    removes and hands each to its created triangle nearest to the original's centroid
    (:func:`_hand_down`).

    Parameters
    ----------
    tris : ndarray (nt, 3) int64; P : ndarray (nv, 3) float64
    m : int
        Original triangles (the first m of ``tris``).
    start, split, own : ndarray int64
        From :func:`_node_triangles`.

    Returns
    -------
    fp_start : ndarray (c + 1,) int64; fp : ndarray (kf,) int64
        CSR over nodes of original triangle indices, in collection order.
    """
    original = np.arange(m, dtype=np.int64)
    centroids = (P[tris[:m, 0]] + P[tris[:m, 1]] + P[tris[:m, 2]]) / 3.0
    fp_start, fp, _ = _hand_down(centroids, original, tris, P, start, split, own)
    return fp_start, fp


def _vertex_moves(tris, P, m, start, split, own):
    """How far each node moves the original vertices it holds (the module docstring's
    texture deviation, its geometric part).

    Every vertex of the original triangles belongs to one triangle of the current cut,
    at first the lowest-numbered original triangle it is a corner of; node i collects
    the vertices of the triangles it removes and hands each to its created triangle
    nearest to the vertex (:func:`_hand_down`).

    Returns
    -------
    moved : ndarray (c,) float64
        The largest distance from a vertex node i collects to the created triangle it
        hands it to (0 for a node that collects none or creates nothing).
    held : ndarray (nt,) float64
        The largest distance from a vertex handed to MT triangle t to t (0 for an
        original triangle, or one handed none).
    """
    corners = tris[:m].ravel()
    vertices, first = np.unique(corners, return_index=True)
    _, _, held = _hand_down(P[vertices], (first // 3).astype(np.int64), tris, P, start,
                            split, own)
    # a node hands its vertices to its created triangles only: its largest move is
    # theirs
    node = np.repeat(np.arange(len(start) - 1), np.diff(start))
    created = np.arange(len(own)) >= split[node]
    moved = np.zeros(len(start) - 1)
    np.maximum.at(moved, node[created], held[own[created]])
    return moved, held


@njit(cache=True)
def _hand_down(points, holder, tris, P, start, split, own):
    """Hand items down the MT: each item belongs to one triangle of the current cut.

    Item k (a point ``points[k]``) is held at first by MT triangle ``holder[k]``. Node
    i collects the items of the triangles it removes, in the order of its removed
    triangles (each triangle's items newest first), and hands each to its created
    triangle nearest to the item's point (Ericson's point-triangle distance; the first
    of equals wins). A node that creates nothing keeps its items but hands them on to
    no one.

    Parameters
    ----------
    points : ndarray (n, 3) float64; holder : ndarray (n,) int64
    tris, P, start, split, own : see the block comment above

    Returns
    -------
    item_start : ndarray (c + 1,) int64; items : ndarray (k,) int64
        CSR over nodes of the items each node collects.
    held : ndarray (nt,) float64
        The largest distance from an item handed to MT triangle t to t (0 if none).
    """
    c = start.shape[0] - 1
    head = np.full(tris.shape[0], -1, np.int64)  # newest item held by each MT triangle
    nxt = np.full(points.shape[0], -1, np.int64)  # next item held by the same triangle
    for k in range(points.shape[0]):
        nxt[k] = head[holder[k]]
        head[holder[k]] = k
    item_start = np.zeros(c + 1, np.int64)
    items = np.empty(max(16, 4 * points.shape[0]), np.int64)
    held = np.zeros(tris.shape[0])
    n = 0
    for i in range(c):
        first = n
        for j in range(start[i], split[i]):
            t = own[j]
            k = head[t]
            while k != -1:
                if n == items.shape[0]:
                    grown = np.empty(2 * n, np.int64)
                    grown[:n] = items
                    items = grown
                items[n] = k
                n += 1
                k = nxt[k]
            head[t] = -1
        item_start[i + 1] = n
        c0, c1 = split[i], start[i + 1]
        if c1 > c0:
            for q in range(first, n):
                k = items[q]
                best_t, best = _nearest(points[k], own[c0:c1], tris, P)
                held[best_t] = max(held[best_t], best)
                nxt[k] = head[best_t]
                head[best_t] = k
    return item_start, items[:n].copy(), held


@njit(cache=True)
def _nearest(g, candidates, tris, P):
    """The triangle of ``candidates`` nearest to the point ``g`` (the first of equals)
    and its distance."""
    best = 1e300
    best_t = -1
    for t in candidates:
        d = _closest_distance(g, P[tris[t, 0]], P[tris[t, 1]], P[tris[t, 2]])
        if d < best:
            best = d
            best_t = t
    return best_t, best


@njit(cache=True)
def _spheres(tris, P, fp_start, fp, start, own):
    """Bounding sphere of each node's original and own triangles' corners.

    The centre is the centre of their bounding box, the radius the farthest corner.

    Parameters
    ----------
    tris, P, fp_start, fp, start, own : see the block comment above

    Returns
    -------
    center : ndarray (c, 3) float64; radius : ndarray (c,) float64
    """
    c = start.shape[0] - 1
    center = np.zeros((c, 3))
    radius = np.zeros(c)
    for i in range(c):
        lo0 = lo1 = lo2 = 1e300
        hi0 = hi1 = hi2 = -1e300
        for q in range(fp_start[i], fp_start[i + 1]):
            for e in range(3):
                x = P[tris[fp[q], e]]
                lo0 = min(lo0, x[0])
                lo1 = min(lo1, x[1])
                lo2 = min(lo2, x[2])
                hi0 = max(hi0, x[0])
                hi1 = max(hi1, x[1])
                hi2 = max(hi2, x[2])
        for j in range(start[i], start[i + 1]):
            for e in range(3):
                x = P[tris[own[j], e]]
                lo0 = min(lo0, x[0])
                lo1 = min(lo1, x[1])
                lo2 = min(lo2, x[2])
                hi0 = max(hi0, x[0])
                hi1 = max(hi1, x[1])
                hi2 = max(hi2, x[2])
        cx, cy, cz = 0.5 * (lo0 + hi0), 0.5 * (lo1 + hi1), 0.5 * (lo2 + hi2)
        r2 = 0.0
        for q in range(fp_start[i], fp_start[i + 1]):
            for e in range(3):
                x = P[tris[fp[q], e]]
                r2 = max(r2, (x[0] - cx) ** 2 + (x[1] - cy) ** 2 + (x[2] - cz) ** 2)
        for j in range(start[i], start[i + 1]):
            for e in range(3):
                x = P[tris[own[j], e]]
                r2 = max(r2, (x[0] - cx) ** 2 + (x[1] - cy) ** 2 + (x[2] - cz) ** 2)
        center[i, 0] = cx
        center[i, 1] = cy
        center[i, 2] = cz
        radius[i] = math.sqrt(r2)
    return center, radius


@njit(cache=True)
def _silhouette_cones(tris, P, normals, areas, fp_start, fp, start, own):
    """Silhouette normal cone of each node (§5.3).

    The cone of the area-weighted normals of the node's original triangles and of its
    own triangles, removed and created (each own triangle's weight is its area: half
    its cross product), summed in that order.

    Parameters
    ----------
    tris, P, fp_start, fp, start, own : see the block comment above
    normals : ndarray (m, 3) float64
        Unit normals of the original triangles (zero if degenerate).
    areas : ndarray (m,) float64

    Returns
    -------
    axis : ndarray (c, 3) float64; angle : ndarray (c,) float64
    """
    c = start.shape[0] - 1
    sil_axis = np.zeros((c, 3))
    sil_angle = np.zeros(c)
    vec = np.empty((4096, 3))
    axis = np.empty(3)
    for i in range(c):
        k = fp_start[i + 1] - fp_start[i]
        n_own = start[i + 1] - start[i]
        if vec.shape[0] < k + n_own:
            vec = np.empty((2 * (k + n_own) + 16, 3))
        nvec = np.int64(0)
        for q in range(fp_start[i], fp_start[i + 1]):
            o = fp[q]
            for e in range(3):
                vec[nvec, e] = normals[o, e] * areas[o]
            nvec += 1
        for j in range(start[i], start[i + 1]):
            a = P[tris[own[j], 0]]
            b = P[tris[own[j], 1]]
            cc = P[tris[own[j], 2]]
            n = np.cross(b - a, cc - a)
            vec[nvec] = 0.5 * n
            nvec += 1
        sil_angle[i] = _cone(vec, nvec, axis)
        sil_axis[i] = axis
    return sil_axis, sil_angle


@njit(cache=True)
def _shading_cones(vnormals, fp_start, fp):
    """Shading normal cone of each node (§5.4): the original's vertex normals at the
    corners of its original triangles, summed in corner order.

    Parameters
    ----------
    vnormals : ndarray (m, 3, 3) float64
        Unit vertex normal at corner e of original triangle o (zero if undefined).
    fp_start, fp : see the block comment above

    Returns
    -------
    axis : ndarray (c, 3) float64; angle : ndarray (c,) float64
    """
    c = fp_start.shape[0] - 1
    sh_axis = np.zeros((c, 3))
    sh_angle = np.zeros(c)
    vec = np.empty((4096, 3))
    axis = np.empty(3)
    for i in range(c):
        k = fp_start[i + 1] - fp_start[i]
        if vec.shape[0] < 3 * k:
            vec = np.empty((6 * k + 16, 3))
        nvec = np.int64(0)
        for q in range(fp_start[i], fp_start[i + 1]):
            for e in range(3):
                vec[nvec] = vnormals[fp[q], e]
                nvec += 1
        sh_angle[i] = _cone(vec, nvec, axis)
        sh_axis[i] = axis
    return sh_axis, sh_angle


@njit(cache=True)
def _luminance_ranges(lum, fp_start, fp):
    """Luminance range of each node (§5.2): the union of its original triangles' texel
    ranges; (0, 0) for a node without original triangles.

    Parameters
    ----------
    lum : ndarray (m, 2) float64
        L_min, L_max per original triangle.
    fp_start, fp : see the block comment above

    Returns
    -------
    ndarray (c, 2) float64
    """
    c = fp_start.shape[0] - 1
    lrange = np.zeros((c, 2))
    for i in range(c):
        lmin = 1e300
        lmax = -1e300
        for q in range(fp_start[i], fp_start[i + 1]):
            lmin = min(lmin, lum[fp[q], 0])
            lmax = max(lmax, lum[fp[q], 1])
        if fp_start[i + 1] == fp_start[i]:
            lmin = 0.0
            lmax = 0.0
        lrange[i, 0] = lmin
        lrange[i, 1] = lmax
    return lrange


# Where a created triangle is sampled for the parametric distance: its corners, edge
# midpoints and centroid (barycentric weights).
_CREATED_SAMPLES = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0],
                             [0.5, 0.5, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5],
                             [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0]])


@njit(cache=True)
def _deviations(tris, P, texture, fp_start, fp, start, split, own):
    """Each node's own sampled parametric distance (§2.2; the module docstring's
    texture deviation, its parametric part).

    Both ways between the node's created triangles and its original triangles: at
    every corner of an original triangle, and at the corners, edge midpoints and
    centroid of every created triangle, the distance to the nearest point of the other
    set with the same texture coordinates; a point whose coordinates the other set's UV
    triangles do not contain lies in another node's part of the chart and is not
    sampled. A UV triangle that is degenerate (twice its area at most ``min_det``)
    contains no coordinates. The node's value is the largest sampled distance; 0 for a
    node that creates nothing, or a mesh without UVs.

    Parameters
    ----------
    tris, P, fp_start, fp, start, split, own : see the block comment above
    texture : (UV, min_det)
        UV, ndarray (nv, 2) float64: the MT vertex texture coordinates (ignored when
        ``min_det`` < 0). min_det, float: twice the UV area at or below which a UV
        triangle is degenerate: twice a texel's area on a textured mesh (a triangle
        within one texel shows one colour, so its UVs name no point of the surface), 0
        with UVs and no texture, -1 without UVs.

    Returns
    -------
    ndarray (c,) float64
    """
    UV, min_det = texture
    c = start.shape[0] - 1
    dev = np.zeros(c)
    if min_det < 0.0:
        return dev
    w = _CREATED_SAMPLES
    for i in range(c):
        created = own[split[i]:start[i + 1]]
        originals = fp[fp_start[i]:fp_start[i + 1]]
        for o in originals:
            for e in range(3):
                v = tris[o, e]
                d = _parametric_distance(UV[v], P[v], created, tris, P, UV, min_det)
                dev[i] = max(dev[i], d)
        for t in created:
            a, b, cc = tris[t, 0], tris[t, 1], tris[t, 2]
            for k in range(w.shape[0]):
                uv = w[k, 0] * UV[a] + w[k, 1] * UV[b] + w[k, 2] * UV[cc]
                x = w[k, 0] * P[a] + w[k, 1] * P[b] + w[k, 2] * P[cc]
                d = _parametric_distance(uv, x, originals, tris, P, UV, min_det)
                dev[i] = max(dev[i], d)
    return dev


@njit(cache=True)
def _parametric_distance(uv, x, candidates, tris, P, UV, min_det):
    """The distance from ``x`` to the nearest point with texture coordinates ``uv`` on
    the triangles ``candidates`` whose UV triangles contain them (see
    :func:`_uv_barycentric`); 0 if none does."""
    best = math.inf
    for t in candidates:
        l0, l1, l2 = _uv_barycentric(uv, UV[tris[t, 0]], UV[tris[t, 1]], UV[tris[t, 2]],
                                     min_det)
        if l0 >= -1e-9 and l1 >= -1e-9 and l2 >= -1e-9:
            y = l0 * P[tris[t, 0]] + l1 * P[tris[t, 1]] + l2 * P[tris[t, 2]]
            dd = x - y
            best = min(best, math.sqrt(dd @ dd))
    return best if best < math.inf else 0.0


@njit(cache=True)
def subtree_max(values, child_start, children):
    """Raise each node's value to its children's, in place, children first (a child's
    index is smaller): afterwards every node's value is the maximum over its subtree.

    Parameters
    ----------
    values : ndarray (c,) float64
    child_start, children : ndarray (c + 1,), (kc,) int64
        CSR: the nodes creating node i's removed triangles.
    """
    for i in range(values.shape[0]):
        for j in range(child_start[i], child_start[i + 1]):
            values[i] = max(values[i], values[children[j]])
