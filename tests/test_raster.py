"""Tests for the CPU scan converter (methods.imaging.raster).

The face-ID buffers are checked against a slow per-pixel NumPy reference on tiny scenes,
coverage against an analytic sphere, and the shaded luminance against the evaluation
renderer (metrics.render) with MSAA off.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.core.mesh import Mesh
from conftest import icosphere
from methods.imaging.raster import face_id_buffers, rasterize_luminance
from metrics.views import Camera, cameras_for, dodecahedron_directions, protocol_cameras

SIZE = 32
EDGE_TOL = 1e-9


# -- scenes -------------------------------------------------------------------------------

def _tetrahedron():
    positions = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float) * 0.8
    faces = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    return Mesh(positions, faces, name="tetrahedron")


def _two_triangles():
    """Two triangles that overlap on screen and cross in depth."""
    positions = np.array([[-1.0, -0.8, 0.3], [0.9, -0.5, -0.4], [-0.2, 0.9, 0.1],
                          [1.0, 0.8, 0.4], [-0.9, 0.4, -0.3], [0.3, -1.0, 0.0]])
    return Mesh(positions, np.array([[0, 1, 2], [3, 4, 5]]), name="two triangles")


def _cameras(mesh):
    extra = Camera(eye=[0.4, -0.3, 3.0], target=[0.0, 0.0, 0.0], up=[0.0, 1.0, 0.0],
                   near=1.0, far=5.0)
    return [extra] + protocol_cameras(mesh)[::5]


# -- the slow reference --------------------------------------------------------------------

def _reference(mesh, camera, width, height):
    """Face IDs by brute force: every pixel centre against every face, plus a mask of
    pixel centres within EDGE_TOL of some projected edge (where ties may go either way)."""
    mvp = camera.projection_matrix(width / height) @ camera.view_matrix()
    clip = np.c_[mesh.positions, np.ones(mesh.n_vertices)] @ mvp.T
    ndc = clip[:, :3] / clip[:, 3:]
    sx = (ndc[:, 0] + 1.0) * width / 2.0
    sy = (1.0 - ndc[:, 1]) * height / 2.0
    ids = np.full((height, width), -1, np.int32)
    near_edge = np.zeros((height, width), bool)
    for r in range(height):
        for c in range(width):
            p = np.array([c + 0.5, r + 0.5])
            best = np.inf
            for f, tri in enumerate(mesh.faces):
                a, b, d = (np.array([sx[i], sy[i]]) for i in tri)
                for u, w in ((a, b), (b, d), (d, a)):
                    t = np.clip(np.dot(p - u, w - u) / np.dot(w - u, w - u), 0.0, 1.0)
                    if np.linalg.norm(p - (u + t * (w - u))) < EDGE_TOL:
                        near_edge[r, c] = True
                m = np.array([[b[0] - a[0], d[0] - a[0]], [b[1] - a[1], d[1] - a[1]]])
                l1, l2 = np.linalg.solve(m, p - a)
                lam = np.array([1.0 - l1 - l2, l1, l2])
                if np.all(lam >= 0.0):
                    z = lam @ ndc[tri, 2]
                    if -1.0 <= z <= 1.0 and z < best:
                        best, ids[r, c] = z, f
    return ids, near_edge


@pytest.mark.parametrize("make", [_tetrahedron, _two_triangles])
def test_face_ids_match_reference(make):
    mesh = make()
    cameras = _cameras(mesh)
    ids = face_id_buffers(mesh, cameras, SIZE, SIZE)
    assert ids.shape == (len(cameras), SIZE, SIZE) and ids.dtype == np.int32
    for view, camera in enumerate(cameras):
        expected, near_edge = _reference(mesh, camera, SIZE, SIZE)
        differ = (ids[view] != expected) & ~near_edge
        assert not differ.any(), f"view {view}: {np.argwhere(differ)[:5]}"
        assert (expected >= 0).sum() > 20  # the scene is really in view
    if mesh.n_faces == 2:  # both overlapping triangles are seen somewhere
        assert set(np.unique(ids[0])) == {-1, 0, 1}


def _every_centre(x, y, z, c_lo, c_hi, r_lo, r_hi, depth, ids, fid):
    """:func:`methods.imaging.raster.scan_row`'s pixel test at every centre of the face's
    box, in the same floating-point operations, with no early end of a row."""
    x0, x1, x2 = x
    y0, y1, y2 = y
    z0, z1, z2 = z
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    if area == 0.0:
        return
    if area < 0.0:
        x1, y1, z1, x2, y2, z2 = x2, y2, z2, x1, y1, z1
        area = -area
    cmin = int(min(max(np.ceil(min(x0, x1, x2) - 0.5), float(c_lo)), c_hi + 1.0))
    cmax = int(max(min(np.floor(max(x0, x1, x2) - 0.5), float(c_hi)), c_lo - 1.0))
    rmin = int(min(max(np.ceil(min(y0, y1, y2) - 0.5), float(r_lo)), r_hi + 1.0))
    rmax = int(max(min(np.floor(max(y0, y1, y2) - 0.5), float(r_hi)), r_lo - 1.0))
    edges = ((x2 - x1, y2 - y1, x1, y1), (x0 - x2, y0 - y2, x2, y2), (x1 - x0, y1 - y0, x0, y0))
    inv_area = 1.0 / area
    for r in range(rmin, rmax + 1):
        for c in range(cmin, cmax + 1):
            e = [dx * ((r + 0.5) - ey) - dy * ((c + 0.5) - ex) for dx, dy, ex, ey in edges]
            if any(ei < 0.0 or (ei == 0.0 and not (dy < 0.0 or (dy == 0.0 and dx > 0.0)))
                   for ei, (dx, dy, _, _) in zip(e, edges)):
                continue
            zz = (e[0] * z0 + e[1] * z1 + e[2] * z2) * inv_area
            if -1.0 <= zz <= 1.0 and (zz < depth[r - r_lo, c - c_lo] or (
                    zz == depth[r - r_lo, c - c_lo] and fid < ids[r - r_lo, c - c_lo])):
                depth[r - r_lo, c - c_lo], ids[r - r_lo, c - c_lo] = zz, fid


@pytest.mark.parametrize("id_type", [np.int64, np.int32])
def test_a_row_ends_where_it_leaves_the_triangle_exactly(id_type):
    """scan_row stops a pixel row at the first centre outside the triangle after the
    inside run, and in a wide box starts it near the triangle's left edge; a test of
    every centre of the box gives the same depths and ids, bit for bit, for slivers,
    centres on edges and vertices, and both windings. With int32 ids the rows go
    through the vector pass (``_lanes``) except within LANES columns of the right edge;
    with int64 ids through the scalar loop."""
    from methods.imaging.raster import ROW, T_W, T_X, T_Y, T_Z, scan_row

    rng = np.random.default_rng(7)
    tris = [rng.uniform(-4, 36, (3, 2)) for _ in range(150)]
    tris += [np.array([[2.5, 1.5], [30.5, 1.5 + k * 1e-9], [16.5, 2.0 + k]]) for k in range(20)]
    tris += [np.floor(rng.uniform(0, 32, (3, 2))) + 0.5 for _ in range(100)]  # on centres
    tris += [np.array([[0.0, 0.0], [31.0, 30.999999999], [15.0, 15.0 + 1e-12]])]  # sliver
    t = np.zeros((1, ROW))
    depth, ids = np.full((SIZE, SIZE), np.inf), np.full((SIZE, SIZE), -1, id_type)
    want_depth, want_ids = depth.copy(), ids.copy()  # all triangles in one z-buffer
    covered = 0
    for fid, xy in enumerate(tris):
        z = rng.uniform(-0.9, 0.9, 3)
        t[0, T_X:T_X + 3], t[0, T_Y:T_Y + 3], t[0, T_Z:T_Z + 3] = xy[:, 0], xy[:, 1], z
        t[0, T_W:T_W + 3] = 1.0
        scan_row(t, 0, fid, (0, SIZE - 1, 0, SIZE - 1), False, depth, ids)
        _every_centre(xy[:, 0], xy[:, 1], z, 0, SIZE - 1, 0, SIZE - 1, want_depth,
                      want_ids, fid)
        alone, want = np.full((SIZE, SIZE), -1, id_type), np.full((SIZE, SIZE), -1, id_type)
        scan_row(t, 0, fid, (0, SIZE - 1, 0, SIZE - 1), False, np.full((SIZE, SIZE), np.inf),
                 alone)
        _every_centre(xy[:, 0], xy[:, 1], z, 0, SIZE - 1, 0, SIZE - 1,
                      np.full((SIZE, SIZE), np.inf), want, fid)
        assert np.array_equal(alone, want), f"triangle {fid}"
        covered += np.count_nonzero(want >= 0) > 0
    assert np.array_equal(ids, want_ids) and np.array_equal(depth, want_depth)
    assert covered > 200  # most triangles cover some centre


def test_sphere_covers_inscribed_disc():
    mesh = icosphere(4, name="sphere")
    camera = protocol_cameras(mesh)[0]
    ids = face_id_buffers(mesh, [camera], 256, 256)
    coverage = np.mean(ids >= 0)
    assert abs(coverage - np.pi / 4) <= 0.01 * np.pi / 4
    lum = rasterize_luminance(mesh, [camera], 256, 256)
    assert np.array_equal(lum == 128.0, ids < 0)  # lit pixels are never exactly gray
    # The sphere's centre faces the headlight: white.
    assert lum[0, 128, 128] == pytest.approx(255.0)


def test_background_is_exactly_128():
    mesh = icosphere(4, name="sphere")
    camera = protocol_cameras(mesh)[3]
    away = Camera(eye=[0.0, 0.0, 3.0], target=[0.0, 0.0, 6.0], up=[0.0, 1.0, 0.0],
                  near=0.5, far=10.0)
    for shading in ("flat", "gouraud"):
        lum = rasterize_luminance(mesh, [camera, away], 64, 48, shading)
        ids = face_id_buffers(mesh, [camera, away], 64, 48)
        assert lum.shape == (2, 48, 64) and lum.dtype == np.float64
        assert np.all(lum[ids < 0] == 128.0)
        assert np.all(lum[1] == 128.0) and np.all(ids[1] == -1)
        assert lum[0, 0, 0] == 128.0 and lum[0, -1, -1] == 128.0
    empty = Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int32))
    assert np.all(rasterize_luminance(empty, [camera], 8, 8) == 128.0)


def test_deterministic():
    mesh = _tetrahedron()
    cameras = cameras_for(mesh, dodecahedron_directions())
    for shading in ("flat", "gouraud"):
        first = rasterize_luminance(mesh, cameras, 64, 64, shading)
        second = rasterize_luminance(mesh, cameras, 64, 64, shading)
        assert np.array_equal(first, second)
    assert np.array_equal(face_id_buffers(mesh, cameras, 64, 64),
                          face_id_buffers(mesh, cameras, 64, 64))


def test_two_sided_flat_lighting():
    """A quad facing the eye is white from the front and from the back."""
    positions = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    front = Camera(eye=[0, 0, 3], target=[0, 0, 0], up=[0, 1, 0], near=1.0, far=5.0)
    back = Camera(eye=[0, 0, -3], target=[0, 0, 0], up=[0, 1, 0], near=1.0, far=5.0)
    lum = rasterize_luminance(Mesh(positions, faces), [front, back], 33, 33, "flat")
    assert lum[0, 16, 16] == pytest.approx(255.0)
    assert lum[1, 16, 16] == pytest.approx(255.0)
    # Off-centre the headlight is oblique: darker than the centre, but lit.
    assert 128.0 < lum[0, 16, 24] < 255.0
    # Gouraud lights only the corners (cos = 3 / sqrt(11)), from either side, so the
    # interpolated value is the same everywhere on the quad.
    corner = np.round(255.0 * (0.1 + 0.9 * 3.0 / np.sqrt(11.0)))
    lum = rasterize_luminance(Mesh(positions, faces), [front, back], 33, 33, "gouraud")
    assert lum[0, 16, 16] == pytest.approx(corner)
    assert lum[1, 16, 16] == pytest.approx(corner)


# -- agreement with the evaluation renderer --------------------------------------------------

def _d_rms(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)))


@pytest.mark.parametrize("shading", ["flat", "gouraud"])
def test_matches_evaluation_renderer_without_msaa(shading):
    render = pytest.importorskip("metrics.render")
    from bench.catalog import BUNNY
    from metrics.image import luminance

    mesh = BUNNY.load()
    cameras = protocol_cameras(mesh)
    try:
        images = render.get_renderer(256, 256, 4).render(mesh, cameras, shading,
                                                         msaa=False)
    except RuntimeError as error:  # no EGL on this machine
        pytest.skip(str(error))
    ours = rasterize_luminance(mesh, cameras, 256, 256, shading)
    value = _d_rms(ours, luminance(images))
    print(f"d_rms({shading}) = {value:.4f}")
    assert value <= 1.0


def test_textured_matches_evaluation_renderer_where_textures_are_not_minified():
    """bunny-textured's atlas is seen at about its own resolution, where bilinear
    sampling and the evaluation renderer's trilinear mipmaps agree (the procedural
    torus's fine 1024² texture, minified several times, does not: see the README)."""
    render = pytest.importorskip("metrics.render")
    from bench.catalog import BUNNY_TEXTURED
    from metrics.image import luminance

    mesh = BUNNY_TEXTURED.load()
    cameras = protocol_cameras(mesh)
    try:
        images = render.get_renderer(256, 256, 4).render(mesh, cameras, "flat", msaa=False)
    except RuntimeError as error:  # no EGL on this machine
        pytest.skip(str(error))
    value = _d_rms(rasterize_luminance(mesh, cameras, 256, 256, "flat"), luminance(images))
    print(f"d_rms(textured) = {value:.4f}")
    assert value <= 1.0


# -- the depth bound of a face (methods.imaging.raster.behind) -----------------------------

def _row(xs, ys, zs):
    from methods.imaging.raster import ROW, T_W, T_X, T_Y, T_Z

    t = np.zeros((1, ROW))
    t[0, T_X:T_X + 3], t[0, T_Y:T_Y + 3], t[0, T_Z:T_Z + 3] = xs, ys, zs
    t[0, T_W:T_W + 3] = 1.0
    return t


def test_a_face_is_behind_only_a_nearer_depth():
    from methods.imaging.raster import behind

    t = _row([2.0, 20.0, 5.0], [3.0, 6.0, 18.0], [0.5, 0.6, 0.7])
    assert behind(t, 0, 0.4999)
    assert not behind(t, 0, 0.5)  # a tie can go to the face
    assert not behind(t, 0, np.inf)
    sliver = _row([2.0, 20.0, 11.0], [3.0, 3.0, 3.0 + 1e-15], [0.5, 0.6, 0.7])
    assert not behind(sliver, 0, 0.4)  # S / area is not near 1: no bound


def _assert_draws_nothing_if_behind(t, far):
    """If :func:`behind` says row 0 is behind ``far``, scanning it over a buffer at
    ``far`` everywhere (ties going to the face) changes no pixel."""
    from methods.imaging.raster import behind, scan_row

    depth = np.full((48, 48), far)
    ids = np.full((48, 48), 10**9, np.int64)
    if behind(t, 0, far):
        scan_row(t, 0, 1, (0, 47, 0, 47), False, depth, ids)
        assert (ids == 10**9).all() and (depth == far).all()


coord = st.floats(-6.0, 40.0, allow_nan=False)
depth_value = st.floats(-1.0, 1.0, allow_nan=False)
# corners at one depth too: rounding then takes a pixel's depth just past the corners'
depths = st.one_of(st.tuples(depth_value, depth_value, depth_value),
                   depth_value.map(lambda z: (z, z, z)))


@settings(max_examples=400, deadline=None)
@given(st.tuples(coord, coord, coord), st.tuples(coord, coord, coord),
       depths, st.sampled_from([0.0, 1e-16, 1e-14, 1e-12, 1e-9, 1e-6, 1e-3]))
def test_a_face_behind_wins_no_pixel(xs, ys, zs, gap):
    """Whenever the bound says a face is behind depth ``far``, scan-converting it over a
    buffer at ``far`` everywhere (ties going to the face) changes no pixel."""
    t = _row(xs, ys, zs)
    far = np.nextafter(min(zs), -np.inf) if gap == 1e-16 else min(zs) - gap
    _assert_draws_nothing_if_behind(t, far)


@settings(max_examples=400, deadline=None)
@given(st.tuples(coord, coord), st.tuples(coord, coord), st.floats(0.0, 1.0),
       st.sampled_from([0.0, 1e-15, 1e-13, 1e-11, 1e-9, 1e-6, 1e-3]),
       depths, st.sampled_from([0.0, 1e-16, 1e-14, 1e-12, 1e-9]))
def test_a_sliver_behind_wins_no_pixel(a, b, s, offset, zs, gap):
    """As above for slivers: the third corner on the segment from a to b, moved off it
    by ``offset`` pixels, where rounding moves the edge functions' sum most."""
    c = (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]) + offset)
    t = _row([a[0], b[0], c[0]], [a[1], b[1], c[1]], zs)
    far = np.nextafter(min(zs), -np.inf) if gap == 1e-16 else min(zs) - gap
    _assert_draws_nothing_if_behind(t, far)


# depths past the near and far planes too: those pixels are clipped
clipped_depth = st.floats(-1.5, 1.5, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(st.tuples(coord, coord, coord), st.tuples(coord, coord, coord),
       st.one_of(depths, st.tuples(clipped_depth, clipped_depth, clipped_depth)),
       st.integers(0, 12), st.integers(0, 12), st.integers(0, 10), st.integers(0, 2**31))
def test_the_vector_pass_gives_every_centres_test(xs, ys, zs, c_lo, r_lo, extra, seed):
    """Rows scanned LANES columns at a time (int32 ids, contiguous rows) give, bit for
    bit, what testing every centre of the box gives: over a z-buffer that already holds
    depths, some equal to the face's (ties go to the lower id), in a region that starts
    anywhere and ends anywhere near the array's right edge (where the columns a pass
    would write past the array make the row go through the scalar loop), with corners
    beyond the near and far planes."""
    from methods.imaging.raster import scan_row

    rng = np.random.default_rng(seed)
    width, height = 30 - c_lo + extra, 30 - r_lo
    c_hi, r_hi = c_lo + width - 1 - extra, r_lo + height - 1
    depth = rng.choice(np.r_[np.inf, np.asarray(zs), rng.uniform(-1, 1, 3)], (height, width))
    ids = rng.integers(0, 4, (height, width)).astype(np.int32)
    want_depth, want_ids = depth.copy(), ids.copy()
    t = _row(list(xs), list(ys), list(zs))
    scan_row(t, 0, 2, (c_lo, c_hi, r_lo, r_hi), False, depth, ids)
    _every_centre(xs, ys, zs, c_lo, c_hi, r_lo, r_hi, want_depth, want_ids, 2)
    assert np.array_equal(ids, want_ids)
    assert np.array_equal(depth, want_depth)


@settings(max_examples=300, deadline=None)
@given(st.tuples(coord, coord, coord), st.tuples(coord, coord, coord),
       st.one_of(depths, st.tuples(clipped_depth, clipped_depth, clipped_depth)),
       st.integers(0, 12), st.integers(0, 12), st.integers(0, 10), st.integers(0, 2**31),
       st.sampled_from([np.int32, np.int64]), st.sampled_from([0.0, 0.5, 1.0]))
def test_a_probe_says_whether_the_scan_changes_a_pixel(xs, ys, zs, c_lo, r_lo, extra, seed,
                                                        id_type, near):
    """``wins_any`` is True exactly where testing every centre of the box changes some
    depth or id, and writes nothing: with vector passes (int32) and the scalar loop
    (int64), over z-buffers that the face wins in many pixels, in few (a share ``near``
    of the pixels nearer than any corner) or in none."""
    from methods.imaging.raster import wins_any

    rng = np.random.default_rng(seed)
    width, height = 30 - c_lo + extra, 30 - r_lo
    c_hi, r_hi = c_lo + width - 1 - extra, r_lo + height - 1
    depth = rng.choice(np.r_[np.inf, np.asarray(zs), rng.uniform(-1, 1, 3)], (height, width))
    depth[rng.random((height, width)) < near] = -1.0  # the near plane: only a tie wins it
    ids = rng.integers(0, 4, (height, width)).astype(id_type)
    want_depth, want_ids = depth.copy(), ids.copy()
    _every_centre(xs, ys, zs, c_lo, c_hi, r_lo, r_hi, want_depth, want_ids, 2)
    changed = not (np.array_equal(ids, want_ids) and np.array_equal(depth, want_depth))
    before_depth, before_ids = depth.copy(), ids.copy()
    assert wins_any(_row(list(xs), list(ys), list(zs)), 0, 2, (c_lo, c_hi, r_lo, r_hi), False,
                    depth, ids) == changed
    assert np.array_equal(depth, before_depth) and np.array_equal(ids, before_ids)


@pytest.mark.parametrize("shading,specular", [("flat", False), ("gouraud", True)])
def test_views_rendered_a_few_at_a_time_are_the_views_rendered_at_once(monkeypatch, shading,
                                                                       specular):
    """The rasterizer projects (and lights) as many views at a time as threads render
    them; any chunking gives every view bit for bit, ids and luminance, as all 24 at
    once did (a chunk of 24), whatever the number of threads."""
    from methods.imaging import raster

    mesh = icosphere(3)
    mesh = mesh.replace(positions=mesh.positions * [1.0, 0.7, 1.3] + [0.2, -0.1, 0.05])
    cameras = protocol_cameras(mesh)
    cull = [v % 5 == 0 for v in range(len(cameras))]
    rendered = {}
    for step in (24, 1, 5):
        monkeypatch.setattr(raster, "get_num_threads", lambda step=step: step)
        ids, lum = raster._render(mesh, cameras, 48, 40, shading, specular, None, cull,
                                  shade=True)
        rendered[step] = (ids, lum.view(np.int64))
    for step in (1, 5):
        assert np.array_equal(rendered[step][0], rendered[24][0])
        assert np.array_equal(rendered[step][1], rendered[24][1])
