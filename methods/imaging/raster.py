"""A CPU scan converter with the shading model of the evaluation renderer.

Image-driven simplification (Lindstrom & Turk 2000, §4.2) renders a model from the 20
dodecahedron views many times. This module does it on the CPU, without anti-aliasing,
with the same cameras (:mod:`metrics.views`) and the same classic shading as
:mod:`metrics.render` with ``msaa=False``:

* a headlight at the eye: at a surface point ``p`` the light vector is
  ``l = normalize(eye - p)`` (equal to the view vector), no fall-off;
* ``colour = albedo * (ambient + diffuse * max(0, n.l)) [+ ks * max(0, n.l)^shininess]``,
  clamped to [0, 1] and quantised to 8 bits per channel, as the framebuffer stores it;
* two-sided: nothing is culled; ``flat`` flips the face normal towards the viewer,
  ``gouraud`` lights each vertex for both sides and picks the side by the triangle's
  winding on screen (``gl_FrontFacing``: counter-clockwise in y-up window coordinates);
* ``flat``: the unit face normal with ``l`` evaluated at every pixel's surface point
  (the GLSL evaluates the lighting per fragment with a per-face normal);
* ``gouraud``: lighting per vertex from ``mesh.vertex_normals``, interpolated with
  perspective-correct barycentrics (GLSL's default ``smooth`` interpolation);
* textured meshes (texture and uv): albedo from the texture, bilinear with repeat
  wrapping. The evaluation renderer uses trilinear mipmaps for minification, so
  textures seen small differ (the untextured path is exact up to rounding);
* background 128.

Rasterisation conventions
-------------------------
Vertices go through ``P @ V`` of each camera to clip space and are divided by ``w``;
window coordinates are ``x = (x_ndc + 1) W / 2`` and ``y = (1 - y_ndc) H / 2`` (y
downwards, so row 0 is the top of the image, as in the evaluation renderer's output).
A pixel (row r, column c) is sampled once at its centre ``(c + 0.5, r + 0.5)``. A
centre exactly on an edge belongs to the triangle if the edge is a *top* edge
(horizontal, interior below it) or a *left* edge (interior to its right), so pixels on
an edge shared by two triangles are drawn exactly once. Depth is the NDC ``z``, affine
in screen space, tested with ``<`` (the first face drawn wins a tie, as ``GL_LESS`` with
faces drawn in index order) and clipped to [-1, 1] per pixel (the near and far planes).
Triangles with a vertex at or behind the eye plane (``w <= 0``) are skipped rather
than clipped; protocol cameras never produce them (the model lies in [r, 3r] of depth).

The per-triangle set-up (transforms, per-vertex lighting) is vectorised in NumPy; the
per-pixel work runs in numba kernels, parallel over views (each view is independent,
so the result does not depend on the number of threads). A row's centres are tested
eight at a time in vector registers where the arrays allow it (:func:`_lanes`), with
the scalar loop's operations, so with its bits.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from llvmlite import ir
from numba import get_num_threads, njit, prange, types
from numba.extending import intrinsic, overload

from bench.core.numba_cache import lock_cache_writes
from metrics.shading import BACKGROUND, DEFAULT_CONSTANTS, LUMA_B, LUMA_G, LUMA_R, SHADINGS

lock_cache_writes()  # several processes compile at once (bench.core.numba_cache)

__all__ = ["BACKGROUND", "SHADINGS", "face_id_buffers", "rasterize_luminance"]

#: The shading settings as the kernels see them: floats ``ambient``, ``diffuse``, ``ks``
#: (specular coefficient), ``shininess``, ``albedo``, and booleans ``specular`` (add the
#: highlight), ``gouraud`` (per-vertex lighting; else flat) and ``textured`` (albedo from
#: the texture). Made by :func:`shading_constants`.
Shading = namedtuple("Shading", "ambient diffuse ks shininess albedo specular gouraud textured")



def vertex_light(positions, normals, eyes, ambient, diffuse, ks, shininess, specular):
    """Per-vertex headlight terms for gouraud shading, lit from both sides.

    Parameters
    ----------
    positions, normals : ndarray of shape (n, 3)
    eyes : ndarray of shape (V, 3)

    Returns
    -------
    ndarray of shape (V, n, 4)
        (diffuse+ambient, specular) for the front side, then for the back side.
    """
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    n = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0.0)
    to_eye = eyes[:, None, :] - positions[None]
    to_eye /= np.linalg.norm(to_eye, axis=2, keepdims=True)
    dot = np.einsum("vnk,nk->vn", to_eye, n)
    light = np.empty(dot.shape + (4,))
    for k, side in ((0, dot), (2, -dot)):
        cos = np.maximum(side, 0.0)
        light[..., k] = ambient + diffuse * cos
        light[..., k + 1] = ks * cos ** shininess if specular else 0.0
    return light


# -- set-up in NumPy ----------------------------------------------------------------------

def _project(positions: np.ndarray, cameras, width: int, height: int, origin=None):
    """Screen coordinates of every vertex in every view.

    Parameters
    ----------
    positions : ndarray of shape (n, 3) float64
    cameras : sequence of V metrics.views.Camera
    width, height : int
    origin : ndarray of shape (3,), optional
        The point the sums are taken relative to (default: the first camera's target).
        A view's coordinates depend on it and on its own camera only, bit for bit.

    Returns
    -------
    screen : ndarray of shape (V, n, 4) float64
        Columns x, y (pixels, y down), z (NDC depth) and w (clip w).
    """
    aspect = width / height
    mvp = np.stack([c.projection_matrix(aspect) @ c.view_matrix() for c in cameras])
    # Relative to the first target, like the evaluation renderer, for well-scaled sums.
    origin = np.asarray(cameras[0].target if origin is None else origin, dtype=np.float64)
    mvp = mvp.copy()
    mvp[:, :, 3] += mvp[:, :, :3] @ origin  # so that mvp @ (p - origin) == old mvp @ p
    rel = positions - origin
    clip = np.einsum("vij,nj->vni", mvp[:, :, :3], rel) + mvp[:, None, :, 3]
    w = clip[..., 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_w = np.where(w > 0.0, 1.0 / np.where(w > 0.0, w, 1.0), 0.0)
    screen = np.empty(clip.shape)
    screen[..., 0] = (clip[..., 0] * inv_w + 1.0) * (0.5 * width)
    screen[..., 1] = (1.0 - clip[..., 1] * inv_w) * (0.5 * height)
    screen[..., 2] = clip[..., 2] * inv_w
    screen[..., 3] = w
    return np.ascontiguousarray(screen)


# -- the per-face set-up table ------------------------------------------------------------
# Every face to draw in a view is first written as one row of a table: screen
# coordinates of its corners, its normal, its corners' positions, per-corner lighting
# and texture coordinates. The scan converter and the shader read only the table, so
# the same two kernels serve whole images (:func:`rasterize_luminance`) and the small
# regions that image-driven simplification re-renders per candidate collapse, whatever
# produced the rows (per-vertex arrays here, wedges and a simulated collapse in
# :mod:`methods.imaging.region`).

T_X, T_Y, T_Z, T_W = 0, 3, 6, 9  # x, y (pixels, y down), z (NDC) and clip w of corners 0-2
T_N = 12  # unit face normal (flat shading)
T_P = 15  # corner positions, 3 x 3
T_L = 24  # corner lighting, 3 x 4: (lit front, spec front, lit back, spec back)
T_UV = 36  # corner texture coordinates, 3 x 2
ROW = 42

#: 0 and -1 (no vertex) as int64 values, not literals: numba compiles a kernel once more
#: for every literal constant it is called with, and once more again while it types a
#: counter that starts at a literal (``n = 0`` ... ``n += 1``); docs/maintainers.md.
ZERO = np.int64(0)
NO_VERTEX = np.int64(-1)


#: The smallest positive double (a subnormal): ``e < TINY`` is ``e <= 0`` for any e.
TINY = 5e-324

#: Boxes at least this many columns wide start each row near the triangle's left edge
#: (:func:`_row_start`); narrower ones at the box's left.
WIDE_BOX = 8


@njit(cache=True, inline="always")
def _threshold(dx, dy):
    """The threshold ``q`` of the edge along (dx, dy): a centre fails it where its edge
    function e < q. That is e < 0, or e == 0 off a top-left edge (dy < 0, or dy == 0
    and dx > 0), in one comparison: no double lies between 0 and TINY, and NaN passes."""
    return 0.0 if dy < 0.0 or (dy == 0.0 and dx > 0.0) else TINY


@njit(cache=True, inline="always")
def _fails(px, py, xa, ya, dx, dy, q):
    """Whether the centre (px, py) is outside the edge from (xa, ya) along (dx, dy),
    whose threshold is ``q`` (:func:`_threshold`)."""
    return dx * (py - ya) - dy * (px - xa) < q


@njit(cache=True, inline="always")
def _row_start(py, cmin, cmax, edges, slopes):
    """The column where :func:`scan_row` starts row ``py``: every centre left of it is
    outside the triangle. ``edges`` are :func:`_scan`'s (dx, dy, q, xa, ya) of the
    three edges, ``slopes`` their dx/dy where their function grows along the row
    (dy < 0), else NaN."""
    # the rightmost crossing of the row by such an edge, with that edge
    best, xa, ya, dx, dy, q = -np.inf, 0.0, 0.0, 0.0, 0.0, 0.0
    (dx0, dy0, q0, xa0, ya0), (dx1, dy1, q1, xa1, ya1), (dx2, dy2, q2, xa2, ya2) = edges
    for s, xe, ye, dxe, dye, qe in ((slopes[0], xa0, ya0, dx0, dy0, q0),
                                    (slopes[1], xa1, ya1, dx1, dy1, q1),
                                    (slopes[2], xa2, ya2, dx2, dy2, q2)):
        if s == s:  # not NaN
            x = xe + s * (py - ye)  # where the edge crosses the row
            if x > best:
                best, xa, ya, dx, dy, q = x, xe, ye, dxe, dye, qe
    if best == -np.inf:  # no such edge
        return cmin
    g = int(min(np.ceil(best - 0.5), cmax + 2.0)) - 1  # at most cmax + 1: an empty row
    if g <= cmin:
        return cmin
    # the centre of column g - 1 must fail that edge
    return g if _fails(g - 0.5, py, xa, ya, dx, dy, q) else cmin


#: Columns of a row tested at once (:func:`_lanes`): 8 doubles fill a 512-bit vector
#: register.
LANES = 8


def _lane_types(depth, ids):
    """Whether ``depth`` holds float64 and ``ids`` int32, the types :func:`_lanes` reads
    and writes (decided when numba compiles the caller)."""
    return depth.dtype == np.float64 and ids.dtype == np.int32


@overload(_lane_types)
def _lane_types_numba(depth, ids):
    ok = depth.dtype == types.float64 and ids.dtype == types.int32
    return lambda depth, ids: ok


def _lane_pass(store):
    """The intrinsic :func:`_lanes` (``store``) or :func:`_lanes_probe` (no stores)."""

    def lanes(typingctx, dptr, gptr, n, lo, a0, a1, a2, dy0, dy1, dy2, xa0, xa1, xa2, q0,
              q1, q2, z0, z1, z2, inv_area, fid):
        return _lane_code(store)

    lanes.__name__ = "_lanes" if store else "_lanes_probe"
    lanes.__doc__ = _lane_code.__doc__
    return intrinsic(lanes)


def _lane_code(store):
    """Depth-test the centres of columns lo, lo + 1, ..., lo + n (n < :data:`LANES`) of a
    row in one vector pass, into the ``LANES`` depths at address ``dptr`` (float64) and
    face ids at ``gptr`` (int32) that start at column lo; the columns past lo + n get
    their own values back, so no other thread may write those columns meanwhile. Returns
    the centres inside the face as bits (bit j: column lo + j).

    Column c's edge function i is ``a_i - dy_i * (c + 0.5 - xa_i)``, with
    ``a_i = dx_i * (py - ya_i)`` of the row: :func:`scan_row`'s arithmetic, operation for
    operation, so each lane gives the scalar loop's bits (numba compiles without
    fast-math flags, so no product is fused into an addition; ``tests/test_raster.py``
    compares with Python's arithmetic). LLVM does not vectorise this loop
    from Python, as it may not move one column's loads above the previous column's
    stores into the other array, so the vector code is written out here.

    Without ``store`` (:func:`_lanes_probe`) nothing is written, and the columns whose
    (depth, id) the face would win come back too, as bits LANES.. of the result."""
    sig = types.int64(types.intp, types.intp, types.int64, types.int64,
                      *([types.float64] * 16), types.int64)

    def codegen(context, builder, signature, args):
        (dptr, gptr, n, lo, a0, a1, a2, dy0, dy1, dy2, xa0, xa1, xa2, q0, q1, q2, z0, z1, z2,
         inv_area, fid) = args
        f64, i32, i64 = ir.DoubleType(), ir.IntType(32), ir.IntType(64)
        vd, vi, vl = (ir.VectorType(f64, LANES), ir.VectorType(i32, LANES),
                      ir.VectorType(i64, LANES))

        def splat(x, vt):
            return _splat(builder, x, vt)

        steps = ir.Constant(vl, list(range(LANES)))
        cols = builder.add(splat(lo, vl), steps)
        px = builder.fadd(builder.sitofp(cols, vd), splat(ir.Constant(f64, 0.5), vd))
        out, z = _lane_edges(builder, px, ((a0, dy0, xa0, q0), (a1, dy1, xa1, q1),
                                           (a2, dy2, xa2, q2)), (z0, z1, z2, inv_area))
        dp = builder.inttoptr(dptr, vd.as_pointer())
        gp = builder.inttoptr(gptr, vi.as_pointer())
        d = builder.load(dp, align=8)
        g = builder.load(gp, align=4)
        live = builder.icmp_signed("<=", steps, splat(n, vl))
        inside = builder.and_(live, builder.not_(out))  # NaN fails no edge, as in scan_row
        near = builder.fcmp_ordered(">=", z, splat(ir.Constant(f64, -1.0), vd))
        far = builder.fcmp_ordered("<=", z, splat(ir.Constant(f64, 1.0), vd))
        win = builder.and_(inside, builder.and_(near, far))
        tie = builder.and_(builder.fcmp_ordered("==", z, d),
                           builder.icmp_signed("<", splat(fid, vl), builder.sext(g, vl)))
        win = builder.and_(win, builder.or_(builder.fcmp_ordered("<", z, d), tie))
        bits = builder.zext(builder.bitcast(inside, ir.IntType(LANES)), i64)
        if not store:
            won = builder.zext(builder.bitcast(win, ir.IntType(LANES)), i64)
            return builder.or_(bits, builder.shl(won, ir.Constant(i64, LANES)))
        builder.store(builder.select(win, z, d), dp, align=8)
        builder.store(builder.select(win, splat(builder.trunc(fid, i32), vi), g), gp, align=4)
        return bits

    return sig, codegen


def _splat(builder, x, vt):
    """The scalar ``x`` in every lane of the vector type ``vt`` (LLVM IR)."""
    undef = ir.Constant(vt, ir.Undefined)
    v = builder.insert_element(undef, x, ir.Constant(ir.IntType(32), 0))
    return builder.shuffle_vector(v, undef, ir.Constant(ir.VectorType(ir.IntType(32), LANES),
                                                        [0] * LANES))


def _lane_edges(builder, px, edges, depths):
    """:func:`_lane_code`'s edge functions at the columns' centres ``px`` (LLVM IR):
    (the lanes failing an edge, the lanes' depths). ``edges`` holds each edge's
    (a, dy, xa, q), ``depths`` (z0, z1, z2, 1 / area)."""
    vd = px.type
    values, out = [], None
    for a, dy, xa, q in edges:
        e = builder.fsub(_splat(builder, a, vd),
                         builder.fmul(_splat(builder, dy, vd),
                                      builder.fsub(px, _splat(builder, xa, vd))))
        fails = builder.fcmp_ordered("<", e, _splat(builder, q, vd))
        out = fails if out is None else builder.or_(out, fails)
        values.append(e)
    z0, z1, z2, inv_area = (_splat(builder, x, vd) for x in depths)
    z = builder.fadd(builder.fmul(values[0], z0), builder.fmul(values[1], z1))
    return out, builder.fmul(builder.fadd(z, builder.fmul(values[2], z2)), inv_area)


_lanes = _lane_pass(True)
_lanes_probe = _lane_pass(False)


@njit(cache=True, _nrt=False)
def scan_row(t, k, fid, rect, cull_front, depth, ids, spans=None):
    """Z-buffer row ``k`` of table ``t``, a face with id ``fid``, into the region
    ``rect`` = (c_lo, c_hi, r_lo, r_hi), rows r_lo..r_hi and columns c_lo..c_hi
    (inclusive); with ``spans`` (rows, 2), only columns
    ``spans[r, 0]..spans[r, 1]`` of each row ``r`` (none where the first is larger).

    ``depth`` and ``ids`` are indexed from (r_lo, c_lo). A pixel goes to the face with
    the smaller (depth, id): equal depths go to the lower id, which is what drawing
    faces in increasing id with a ``<`` depth test gives (``GL_LESS``), whatever order
    the faces are scanned in. Returns the number of pixel centres tested.
    """
    return _scan(t, k, fid, rect, cull_front, (depth, ids), spans, False)


@njit(cache=True, _nrt=False)
def wins_any(t, k, fid, rect, cull_front, depth, ids):
    """Whether :func:`scan_row` of the same arguments would change any pixel of
    ``depth`` and ``ids``, which it leaves as they are: it stops at the first pixel
    the face wins."""
    return _scan(t, k, fid, rect, cull_front, (depth, ids), None, True) != 0


@njit(cache=True, inline="always")
def _scan(t, k, fid, rect, cull_front, zbuffer, spans, probe):
    """:func:`scan_row` (``zbuffer`` its (depth, ids)); with ``probe``,
    :func:`wins_any` (1 at the first pixel won, else 0)."""
    (c_lo, c_hi, r_lo, r_hi), (depth, ids) = rect, zbuffer
    drawn, tri, area = _facing(t, k, cull_front)
    if not drawn:
        return 0
    x0, y0, z0, x1, y1, z1, x2, y2, z2 = tri
    cmin, cmax = _centres(x0, x1, x2, c_lo, c_hi)
    rmin, rmax = _centres(y0, y1, y2, r_lo, r_hi)
    if cmin > cmax or rmin > rmax:
        return 0
    # Edge i is opposite vertex i; a centre fails it where e_i < q_i.
    dx0, dy0 = x2 - x1, y2 - y1
    dx1, dy1 = x0 - x2, y0 - y2
    dx2, dy2 = x1 - x0, y1 - y0
    q0, q1, q2 = _threshold(dx0, dy0), _threshold(dx1, dy1), _threshold(dx2, dy2)
    edges = ((dx0, dy0, q0, x1, y1), (dx1, dy1, q1, x2, y2), (dx2, dy2, q2, x0, y0))
    depths = (z0, z1, z2, 1.0 / area)
    # Along a row each edge function is monotone in the column (every operation of it is
    # a correctly rounded monotone function of px), so the centres inside all three
    # edges form one run: the row ends where it is left. Not for values so large that
    # the products could overflow (inf - inf is NaN, which is not monotone).
    bounded = max(abs(x0), abs(x1), abs(x2), abs(y0), abs(y1), abs(y2)) < 1e150
    # For the same reason the centres left of a row's run fail one of the edges whose
    # function grows along the row (dy < 0): in a wide box a row starts a column before
    # the first centre right of the rightmost of their crossings, when the centre left
    # of that start is checked to fail its edge (then so do all centres left of it),
    # else at the box's left.
    skip = bounded and cmax - cmin >= WIDE_BOX
    s0 = dx0 / dy0 if dy0 < 0.0 else np.nan
    s1 = dx1 / dy1 if dy1 < 0.0 else np.nan
    s2 = dx2 / dy2 if dy2 < 0.0 else np.nan
    # Rows go through :func:`_lanes`, LANES columns at a time, when they can: it reads and
    # writes LANES columns from its first, which must lie in contiguous rows of the arrays.
    vector = (_lane_types(depth, ids) and cmax - c_lo + LANES <= depth.shape[1]
              and depth.strides[1] == 8 and ids.strides[1] == 4)
    narrow = cmax - cmin < LANES
    dbase = depth.ctypes.data + (-c_lo) * 8
    gbase = ids.ctypes.data + (-c_lo) * 4
    for r in range(rmin, rmax + 1):
        lo, hi = cmin, cmax
        if spans is not None:
            lo, hi = max(cmin, spans[r, 0]), min(cmax, spans[r, 1])
            if lo > hi:
                continue
        py = r + 0.5
        start = lo
        if skip:
            start = max(lo, _row_start(py, cmin, cmax, edges, (s0, s1, s2)))
        if vector:
            i = r - r_lo
            won = _lanes_row((dbase + i * depth.strides[0], gbase + i * ids.strides[0]),
                             (start, hi, py), edges, depths, fid, narrow, bounded, probe)
        else:
            won = _scalar_row((depth, ids, r - r_lo, c_lo), (start, hi, py), edges, depths,
                              fid, bounded, probe)
        if won:
            return 1
    return 0 if probe else (rmax - rmin + 1) * (cmax - cmin + 1)


@njit(cache=True, inline="always")
def _centres(a, b, c, lo, hi):
    """The first and last pixel (columns or rows ``lo..hi``) whose centre lies within
    the coordinates a, b, c (first > last: none)."""
    # clamped as floats first, so that far-away vertices cannot overflow the integers
    first = int(min(max(np.ceil(min(a, b, c) - 0.5), float(lo)), hi + 1.0))
    last = int(max(min(np.floor(max(a, b, c) - 0.5), float(hi)), lo - 1.0))
    return first, last


@njit(cache=True, inline="always")
def _facing(t, k, cull_front):
    """Row ``k`` of ``t`` as a triangle to scan: (drawn, its corners (x, y, z) x 3 wound
    positively, its doubled area). Not drawn: a corner behind the eye, no area (or
    NaN), or a front face culled."""
    nothing = (False, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), 0.0)
    if t[k, T_W] <= 0.0 or t[k, T_W + 1] <= 0.0 or t[k, T_W + 2] <= 0.0:
        return nothing
    x0, y0, z0 = t[k, T_X], t[k, T_Y], t[k, T_Z]
    x1, y1, z1 = t[k, T_X + 1], t[k, T_Y + 1], t[k, T_Z + 1]
    x2, y2, z2 = t[k, T_X + 2], t[k, T_Y + 2], t[k, T_Z + 2]
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    if not area != 0.0:  # zero or NaN
        return nothing
    if area < 0.0:  # y-down clockwise: the GL front face
        if cull_front:
            return nothing
        x1, y1, z1, x2, y2, z2 = x2, y2, z2, x1, y1, z1  # make the winding positive
        area = -area
    return True, (x0, y0, z0, x1, y1, z1, x2, y2, z2), area


@njit(cache=True, inline="always")
def _lanes_row(row, span, edges, depths, fid, narrow, bounded, probe):
    """Columns ``start..hi`` of one row (``span``: start, hi and the row's centre ``py``)
    through :func:`_lanes` (:func:`_lanes_probe` with ``probe``), from the addresses of
    its column 0 in the depths and ids (``row``); ``edges`` and ``depths`` as
    :func:`_scan` makes them. Returns True when a probe wins a pixel."""
    dp, gp = row
    start, hi, py = span
    (dx0, dy0, q0, x1, y1), (dx1, dy1, q1, x2, y2), (dx2, dy2, q2, x0, y0) = edges
    z0, z1, z2, inv_area = depths
    a0, a1, a2 = dx0 * (py - y1), dx1 * (py - y2), dx2 * (py - y0)
    if narrow:  # the whole row at once
        if probe:
            return _lanes_probe(dp + start * 8, gp + start * 4, hi - start, start, a0, a1,
                                a2, dy0, dy1, dy2, x1, x2, x0, q0, q1, q2, z0, z1, z2,
                                inv_area, fid) >> LANES != 0
        _lanes(dp + start * 8, gp + start * 4, hi - start, start, a0, a1, a2, dy0, dy1, dy2,
               x1, x2, x0, q0, q1, q2, z0, z1, z2, inv_area, fid)
        return False
    entered = False
    c = start
    while c <= hi:
        n = min(hi - c, LANES - 1)
        if probe:
            inside = _lanes_probe(dp + c * 8, gp + c * 4, n, c, a0, a1, a2, dy0, dy1, dy2,
                                  x1, x2, x0, q0, q1, q2, z0, z1, z2, inv_area, fid)
            if inside >> LANES:
                return True
        else:
            inside = _lanes(dp + c * 8, gp + c * 4, n, c, a0, a1, a2, dy0, dy1, dy2, x1, x2,
                            x0, q0, q1, q2, z0, z1, z2, inv_area, fid)
        entered = entered or inside != 0
        if entered and bounded and not (inside >> n) & 1:
            break  # the run of centres inside ended in these columns
        c += LANES
    return False


@njit(cache=True, inline="always")
def _scalar_row(row, span, edges, depths, fid, bounded, probe):
    """Columns ``start..hi`` of one row (``span``: start, hi and the row's centre
    ``py``), a centre at a time, into row ``i`` of ``depth`` and ``ids`` (indexed from
    column ``c_lo``; ``row``: depth, ids, i, c_lo); ``edges`` and ``depths`` as
    :func:`_scan` makes them. Returns whether a probe won a pixel."""
    depth, ids, i, c_lo = row
    start, hi, py = span
    (dx0, dy0, q0, x1, y1), (dx1, dy1, q1, x2, y2), (dx2, dy2, q2, x0, y0) = edges
    z0, z1, z2, inv_area = depths
    entered = False
    px = start - 0.5  # the centre's column, stepped exactly (k + 0.5 for integer k)
    for c in range(start, hi + 1):
        px += 1.0
        e0 = dx0 * (py - y1) - dy0 * (px - x1)
        if e0 < q0:
            if entered and bounded:
                break
            continue
        e1 = dx1 * (py - y2) - dy1 * (px - x2)
        if e1 < q1:
            if entered and bounded:
                break
            continue
        e2 = dx2 * (py - y0) - dy2 * (px - x0)
        if e2 < q2:
            if entered and bounded:
                break
            continue
        entered = True
        z = (e0 * z0 + e1 * z1 + e2 * z2) * inv_area
        if z < -1.0 or z > 1.0:
            continue
        d = depth[i, c - c_lo]
        if z < d or (z == d and fid < ids[i, c - c_lo]):
            if probe:
                return True
            depth[i, c - c_lo] = z
            ids[i, c - c_lo] = fid
    return False


#: Relative rounding error of a double (2^-52).
EPS = 2.0 ** -52


@njit(cache=True)
def behind(t, k, far):
    """Whether :func:`scan_row` of row ``k`` can win no pixel whose current depth is at
    most ``far``: a lower bound of every depth it computes inside the face is above
    ``far``. Inside the face each edge function e_i is >= 0 and their sum S is the
    face's doubled area up to rounding, so the depth (sum e_i z_i) / area lies within
    the corners' z scaled by S / area; the bound takes the rounding of the edge
    functions (a few units of the largest products, over the face's box) and of the sum
    into account, and gives up (False) on slivers, where S / area is not near 1."""
    if not far < np.inf:
        return False
    z0, z1, z2 = t[k, T_Z], t[k, T_Z + 1], t[k, T_Z + 2]
    zmin = min(z0, z1, z2)
    if not zmin > far:  # also NaN
        return False
    x0, x1, x2 = t[k, T_X], t[k, T_X + 1], t[k, T_X + 2]
    y0, y1, y2 = t[k, T_Y], t[k, T_Y + 1], t[k, T_Y + 2]
    area = abs((x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0))
    xspan = max(x0, x1, x2) - min(x0, x1, x2) + 1.0
    yspan = max(y0, y1, y2) - min(y0, y1, y2) + 1.0
    dx = abs(x2 - x1) + abs(x0 - x2) + abs(x1 - x0)
    dy = abs(y2 - y1) + abs(y0 - y2) + abs(y1 - y0)
    err = 16.0 * EPS * (dx * yspan + dy * xspan)
    if not (area > 0.0 and err < 0.5 * area and np.isfinite(err)):
        return False
    r = err / area
    zabs = max(abs(z0), abs(z1), abs(z2))
    lower = min(zmin * (1.0 - r), zmin * (1.0 + r)) - 16.0 * EPS * zabs * (1.0 + r)
    return lower > far


@njit(cache=True, inline="always")
def shade_pixel(t, k, px, py, eye, shading, texture):
    """Luminance (0..255) of table row ``k`` at pixel centre (px, py) under ``shading``
    (:data:`Shading`)."""
    ambient, diffuse, ks, shininess, albedo = (shading.ambient, shading.diffuse, shading.ks,
                                               shading.shininess, shading.albedo)
    specular, gouraud, textured = shading.specular, shading.gouraud, shading.textured
    x0, y0, w0 = t[k, T_X], t[k, T_Y], t[k, T_W]
    x1, y1, w1 = t[k, T_X + 1], t[k, T_Y + 1], t[k, T_W + 1]
    x2, y2, w2 = t[k, T_X + 2], t[k, T_Y + 2], t[k, T_W + 2]
    # perspective-correct barycentrics
    e0 = (x2 - x1) * (py - y1) - (y2 - y1) * (px - x1)
    e1 = (x0 - x2) * (py - y2) - (y0 - y2) * (px - x2)
    e2 = (x1 - x0) * (py - y0) - (y1 - y0) * (px - x0)
    q0, q1, q2 = e0 / w0, e1 / w1, e2 / w2
    total = q0 + q1 + q2
    b0, b1, b2 = q0 / total, q1 / total, q2 / total
    if gouraud:
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        s = 0 if area < 0.0 else 2  # y-down clockwise == GL front face
        lit = (b0 * t[k, T_L + s] + b1 * t[k, T_L + 4 + s] + b2 * t[k, T_L + 8 + s])
        spec = (b0 * t[k, T_L + s + 1] + b1 * t[k, T_L + 5 + s] + b2 * t[k, T_L + 9 + s])
    else:
        qx = b0 * t[k, T_P] + b1 * t[k, T_P + 3] + b2 * t[k, T_P + 6]
        qy = b0 * t[k, T_P + 1] + b1 * t[k, T_P + 4] + b2 * t[k, T_P + 7]
        qz = b0 * t[k, T_P + 2] + b1 * t[k, T_P + 5] + b2 * t[k, T_P + 8]
        lx, ly, lz = eye[0] - qx, eye[1] - qy, eye[2] - qz
        norm = np.sqrt(lx * lx + ly * ly + lz * lz)
        d = abs(t[k, T_N] * lx + t[k, T_N + 1] * ly + t[k, T_N + 2] * lz) / norm
        lit = ambient + diffuse * d
        spec = ks * d ** shininess if specular else 0.0
    if textured:
        tu = b0 * t[k, T_UV] + b1 * t[k, T_UV + 2] + b2 * t[k, T_UV + 4]
        tv = b0 * t[k, T_UV + 1] + b1 * t[k, T_UV + 3] + b2 * t[k, T_UV + 5]
        return _texel_luma(texture, tu, tv, lit, spec)
    return _luma(albedo, albedo, albedo, lit, spec)


@njit(cache=True)
def shade_region(t, ids, rect, eye, shading, texture, background, out):
    """Luminance of every pixel of the region ``rect`` = (c_lo, c_hi, r_lo, r_hi) from
    ``ids`` (row of ``t`` or -1) into ``out`` (indexed from (r_lo, c_lo), like ``ids``)."""
    c_lo, c_hi, r_lo, r_hi = rect
    for r in range(r_lo, r_hi + 1):
        py = r + 0.5
        for c in range(c_lo, c_hi + 1):
            k = ids[r - r_lo, c - c_lo]
            if k < 0:
                out[r - r_lo, c - c_lo] = background
            else:
                out[r - r_lo, c - c_lo] = shade_pixel(t, k, c + 0.5, py, eye, shading, texture)


@njit(cache=True)
def _texel_luma(tex, u, v, lit, spec):
    """Bilinear, repeat-wrapped texture colour (uv origin bottom-left, texture row 0 at
    the top), lit, quantised, as luminance."""
    h, w = tex.shape[0], tex.shape[1]
    x = u * w - 0.5
    y = (1.0 - v) * h - 0.5
    fx, fy = np.floor(x), np.floor(y)
    ax, ay = x - fx, y - fy
    c0, r0 = int(fx) % w, int(fy) % h
    c1, r1 = (c0 + 1) % w, (r0 + 1) % h
    return _luma(_bilerp(tex, r0, c0, r1, c1, ax, ay, 0), _bilerp(tex, r0, c0, r1, c1, ax, ay, 1),
                 _bilerp(tex, r0, c0, r1, c1, ax, ay, 2), lit, spec)


@njit(cache=True)
def _bilerp(tex, r0, c0, r1, c1, ax, ay, k):
    top = tex[r0, c0, k] * (1.0 - ax) + tex[r0, c1, k] * ax
    bottom = tex[r1, c0, k] * (1.0 - ax) + tex[r1, c1, k] * ax
    return (top * (1.0 - ay) + bottom * ay) / 255.0


@njit(cache=True)
def _luma(r, g, b, lit, spec):
    """8-bit quantised colour (r, g, b) * lit + spec, then its luminance on 0..255."""
    y = np.floor(min(max(r * lit + spec, 0.0), 1.0) * 255.0 + 0.5) * LUMA_R
    y += np.floor(min(max(g * lit + spec, 0.0), 1.0) * 255.0 + 0.5) * LUMA_G
    y += np.floor(min(max(b * lit + spec, 0.0), 1.0) * 255.0 + 0.5) * LUMA_B
    return y


@njit(cache=True)
def _fill_rows(t, s, surface, light, shading, shade):
    """Table rows of all faces of ``surface`` (positions, faces, face normals, uv) in
    one view from per-vertex arrays: screen ``s`` (n, 4), ``light`` (n, 4) (gouraud) and
    uv (n, 2) (textured); screen coordinates only unless ``shade``."""
    positions, faces, face_normals, uv = surface
    gouraud, textured = shading.gouraud, shading.textured
    for f in range(faces.shape[0]):
        for j in range(3):
            i = faces[f, j]
            t[f, T_X + j] = s[i, 0]
            t[f, T_Y + j] = s[i, 1]
            t[f, T_Z + j] = s[i, 2]
            t[f, T_W + j] = s[i, 3]
            if not shade:
                continue
            for d in range(3):
                t[f, T_P + 3 * j + d] = positions[i, d]
            if gouraud:
                for d in range(4):
                    t[f, T_L + 4 * j + d] = light[i, d]
            if textured:
                t[f, T_UV + 2 * j] = uv[i, 0]
                t[f, T_UV + 2 * j + 1] = uv[i, 1]
        if shade and not gouraud:
            for d in range(3):
                t[f, T_N + d] = face_normals[f, d]


@njit(cache=True, parallel=True)
def _render_kernel(views, surface, texture, shading, size, background, shade):
    """Face index per pixel (-1 empty) and, with ``shade``, luminance, for every view.

    views : (screen (V, n, 4), light (V, n, 4) (gouraud only), eyes (V, 3), cull_front
    (V,) bool); surface : (positions (n, 3), faces (m, 3) int32, face normals (m, 3),
    uv (n, 2)); size : (width, height). Views run in parallel; each is independent, so
    the result does not depend on the number of threads.
    """
    screen, light, eyes, cull_front = views
    faces, (width, height) = surface[1], size
    n_views, m = screen.shape[0], faces.shape[0]
    gouraud = shading.gouraud
    ids = np.full((n_views, height, width), -1, np.int32)
    lum = np.full((n_views if shade else 0, height, width), background)
    for v in prange(n_views):
        t = np.empty((m, ROW))
        _fill_rows(t, screen[v], surface, light[v] if gouraud and shade else light[0], shading,
                   shade)
        depth = np.full((height, width), np.inf)
        for k in range(m):
            scan_row(t, k, k, (ZERO, width - 1, ZERO, height - 1), cull_front[v], depth,
                     ids[v])
        if shade:
            shade_region(t, ids[v], (ZERO, width - 1, ZERO, height - 1), eyes[v], shading,
                         texture, background, lum[v])
    return ids, lum


# -- public API ---------------------------------------------------------------------------

def _render(mesh, cameras, width, height, shading, specular, constants, cull_front, shade):
    if shading not in SHADINGS:
        raise ValueError(f"shading must be one of {SHADINGS}, got {shading!r}")
    cameras = list(cameras)
    width, height = int(width), int(height)
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive, got {width} x {height}")
    cull = np.zeros(len(cameras), np.bool_)
    if cull_front is not None:
        cull[:] = np.asarray(cull_front, dtype=np.bool_).reshape(-1)
    if constants is None:
        constants = DEFAULT_CONSTANTS
    if not cameras or mesh.n_faces == 0:
        ids = np.full((len(cameras), height, width), -1, np.int32)
        return ids, np.full(ids.shape if shade else (0, height, width), float(BACKGROUND))
    positions = np.ascontiguousarray(mesh.positions, dtype=np.float64)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int32)
    eyes = np.stack([np.asarray(c.eye, dtype=np.float64) for c in cameras])
    gouraud = shading == "gouraud"
    textured = bool(mesh.has_texture)
    shading = shading_constants(constants, specular, gouraud, textured)
    face_n = (np.ascontiguousarray(mesh.face_normals, dtype=np.float64)
              if not gouraud and shade else np.zeros((1, 3)))
    if textured and shade:
        uv = np.ascontiguousarray(mesh.uv, dtype=np.float64)
        texture = np.ascontiguousarray(mesh.texture[:, :, :3])
    else:
        uv, texture = np.zeros((1, 2)), np.zeros((1, 1, 3), np.uint8)
        shading = shading._replace(textured=False)
    # As many views at a time as threads render them: the screen coordinates (and vertex
    # light) of all 24 views of a large mesh at once would take gigabytes. Each view's
    # image depends on its own camera only, so the chunks change no pixel.
    ids = np.empty((len(cameras), height, width), np.int32)
    lum = np.empty((len(cameras) if shade else 0, height, width))
    origin = np.asarray(cameras[0].target, dtype=np.float64)
    step = max(1, get_num_threads())
    normals = (np.asarray(mesh.vertex_normals, dtype=np.float64) if gouraud and shade
               else None)
    for first in range(0, len(cameras), step):
        views = slice(first, first + step)
        screen = _project(positions, cameras[views], width, height, origin)
        light = (np.zeros((1, 1, 4)) if normals is None else
                 vertex_light(positions, normals, eyes[views], shading.ambient,
                              shading.diffuse, shading.ks, shading.shininess, specular))
        ids[views], chunk = _render_kernel((screen, light, eyes[views], cull[views]),
                                           (positions, faces, face_n, uv), texture, shading,
                                           (width, height), float(BACKGROUND), shade)
        if shade:
            lum[views] = chunk
    return ids, lum


def shading_constants(constants, specular: bool, gouraud: bool, textured: bool) -> Shading:
    """The :data:`Shading` of :func:`shade_pixel` (every coefficient a float64)."""
    return Shading(ambient=float(np.float64(constants.ambient)),
                   diffuse=float(np.float64(constants.diffuse)),
                   ks=float(np.float64(constants.specular)),
                   shininess=float(np.float64(constants.shininess)),
                   albedo=float(np.float64(constants.albedo)), specular=bool(specular),
                   gouraud=bool(gouraud), textured=bool(textured))


def face_id_buffers(mesh, cameras, width: int = 256, height: int = 256,
                    cull_front=None) -> np.ndarray:
    """The index of the face seen at each pixel centre, for each camera.

    Parameters
    ----------
    mesh : bench.core.mesh.Mesh
        Positions (n, 3) and faces (m, 3) are used.
    cameras : sequence of V metrics.views.Camera
    width, height : int
        Image size in pixels.
    cull_front : sequence of V bool, optional
        Views that skip front faces (front-face culling), e.g. to see interiors.

    Returns
    -------
    ndarray of shape (V, height, width) int32
        Face indices into ``mesh.faces``, -1 where no face covers the pixel centre; row
        0 is the top of the image. Same rasterisation as :func:`rasterize_luminance`.
    """
    ids, _ = _render(mesh, cameras, width, height, "flat", False, DEFAULT_CONSTANTS,
                     cull_front, shade=False)
    return ids


def rasterize_luminance(mesh, cameras, width: int = 256, height: int = 256,
                        shading: str = "flat", specular: bool = False,
                        constants=None, cull_front=None) -> np.ndarray:
    """Luminance images of ``mesh``, shaded as the evaluation renderer without MSAA.

    Parameters
    ----------
    mesh : bench.core.mesh.Mesh
        Positions (n, 3), faces (m, 3); ``vertex_normals`` for gouraud; ``uv`` (n, 2)
        and ``texture`` (h, w, 3|4) uint8 for the albedo when both are present.
    cameras : sequence of V metrics.views.Camera
    width, height : int
        Image size in pixels.
    shading : {"flat", "gouraud"}
    specular : bool
        Add the Blinn-Phong highlight ``ks * max(0, n.h)^shininess`` (h = l here).
    constants : metrics.render.ShadingConstants, optional
        Ambient, diffuse, albedo, specular and shininess; the defaults are the
        protocol's (ambient 0.1, diffuse 0.9, albedo 1).
    cull_front : sequence of V bool, optional
        Views that skip front faces (Lindstrom & Turk 2000 §5.2's interior views).

    Returns
    -------
    ndarray of shape (V, height, width) float64
        Y = 0.299 R + 0.587 G + 0.114 B of the 8-bit colour on 0..255; 128 where no
        face covers the pixel centre; row 0 at the top.
    """
    _, lum = _render(mesh, cameras, width, height, shading, specular, constants, cull_front,
                     shade=True)
    return lum
