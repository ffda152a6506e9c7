"""Tests for the evaluation renderer (metrics.render, Lindstrom & Turk 2000 §3.2/§5.1).

The scenes are tiny and analytic: a unit icosphere framed by a protocol camera (its
silhouette just fills the frame), and a 2 × 2 quad seen from (0, 0, 3)::

    (-1, 1) 3-------2 (1, 1)       faces (0, 1, 2) and (0, 2, 3), counter-clockwise
            |     / |              seen from +z; uv = (x + 1) / 2, (y + 1) / 2, so
            |   /   |              uv (0, 0) is the bottom-left corner
    (-1,-1) 0-------1 (1, -1)
"""

import os
import subprocess
import sys

import numpy as np
import pytest

from bench.core.mesh import Mesh
from conftest import icosphere
from metrics.render import (
    BACKGROUND,
    DEFAULT_CONSTANTS,
    EvalRenderer,
    ShadingConstants,
    get_renderer,
    luminance,
    render,
)
from metrics.views import Camera, protocol_cameras

#: Constants that paint every covered sample white: coverage = (Y − 128) / 127.
WHITE = ShadingConstants(ambient=1.0, diffuse=0.0)
FRONT = Camera(eye=[0.0, 0.0, 3.0], target=[0.0, 0.0, 0.0], up=[0.0, 1.0, 0.0],
               near=1.0, far=5.0)
CENTRE = (256, 256)  # a pixel whose ray is within half a pixel of the optical axis


def _quad(tilt_deg=0.0, reverse=False, texture=None):
    positions = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    uv = (positions[:, :2] + 1.0) / 2.0
    t = np.radians(tilt_deg)  # rotate about x: the normal leans away by tilt_deg
    rotation = np.array([[1, 0, 0], [0, np.cos(t), -np.sin(t)], [0, np.sin(t), np.cos(t)]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    if reverse:
        faces = faces[:, ::-1]
    return Mesh(positions @ rotation.T, faces, uv=uv if texture is not None else None,
                texture=texture)


@pytest.fixture(scope="module")
def sphere():
    return icosphere(5)  # 20480 faces, vertices on |x| = 1


@pytest.fixture(scope="module")
def renderer():
    return get_renderer(512, 512, 4)


# -- framing and background -------------------------------------------------------------

def test_sphere_covers_pi_over_four_of_the_frame(sphere, renderer):
    # The sphere (radius r) seen from 2r subtends asin(1/2) = 30°, half the 60° field of
    # view: its silhouette is the disc inscribed in the square image, area share π/4.
    # The icosphere is inscribed in the unit sphere with edges a ≈ 0.038, so its outline
    # lies inside the circle by at most the sagitta a²/6 ≈ 2.4e-4 (≤ 5e-4 in area); 4×
    # MSAA quantises coverage along the ~1600 edge pixels to 1/4, an error ~1e-5.
    images = renderer.render(sphere, protocol_cameras(sphere)[:3], constants=WHITE)
    coverage = (luminance(images) - BACKGROUND) / (255 - BACKGROUND)
    for share in coverage.mean(axis=(1, 2)):
        assert share == pytest.approx(np.pi / 4, rel=1e-3)
        assert share <= np.pi / 4


def test_background_is_exactly_128(sphere, renderer):
    images = renderer.render(sphere, protocol_cameras(sphere)[:4])
    for row, col in ((0, 0), (0, -1), (-1, 0), (-1, -1)):
        assert np.all(images[:, row, col] == BACKGROUND)


def test_sphere_silhouette_is_dark_and_centre_white(sphere, renderer):
    # The headlight sits at the eye: the centre faces it (white), the rim is edge-on.
    y = luminance(renderer.render(sphere, protocol_cameras(sphere)[:1], "gouraud"))[0]
    assert y[CENTRE] == pytest.approx(255.0, abs=1.0)
    rim = y[256, 2:6]  # just inside the disc's left edge
    assert np.all(rim < 255 * (DEFAULT_CONSTANTS.ambient + 0.35 * DEFAULT_CONSTANTS.diffuse))


# -- shading ----------------------------------------------------------------------------

def test_flat_and_gouraud_differ_on_a_sphere(sphere, renderer):
    cameras = protocol_cameras(sphere)[:2]
    flat = renderer.render(sphere, cameras, "flat").astype(int)
    gouraud = renderer.render(sphere, cameras, "gouraud").astype(int)
    difference = np.abs(flat - gouraud)
    assert difference.mean() > 0.2
    assert np.count_nonzero(difference) > 0.2 * flat.size


def test_flat_lights_per_pixel_and_gouraud_per_vertex(renderer):
    # A plane facing the eye. Flat: the face normal is lit per pixel, so the centre,
    # where l = v = n, is white. Gouraud: the four corners are lit, each at
    # cos = 3/√11 from the eye at (0, 0, 3), and that value is interpolated everywhere.
    c = DEFAULT_CONSTANTS
    flat = luminance(renderer.render(_quad(), [FRONT], "flat"))[0]
    gouraud = luminance(renderer.render(_quad(), [FRONT], "gouraud"))[0]
    assert flat[CENTRE] == pytest.approx(255 * (c.ambient + c.diffuse), abs=1.0)
    corner = 255 * (c.ambient + c.diffuse * 3 / np.sqrt(11))
    inside = np.s_[160:352, 160:352]
    assert np.abs(gouraud[inside] - corner).max() <= 1.0
    assert np.all(flat[inside] >= gouraud[inside] - 1.0)


def test_headlight_follows_lambert_cosine(renderer):
    # At the centre pixel the light and view vectors are the optical axis, so a plane
    # tilted by θ gets ambient + diffuse·cos θ; one facing the eye gets ambient + diffuse.
    c = ShadingConstants(ambient=0.15, diffuse=0.7)
    facing = luminance(renderer.render(_quad(), [FRONT], "flat", constants=c))[0][CENTRE]
    tilted = luminance(renderer.render(_quad(60.0), [FRONT], "flat", constants=c))[0][CENTRE]
    assert facing == pytest.approx(255 * (c.ambient + c.diffuse), abs=1.0)
    assert tilted == pytest.approx(255 * (c.ambient + c.diffuse * 0.5), abs=1.0)
    assert tilted / facing == pytest.approx((c.ambient + 0.5 * c.diffuse)
                                            / (c.ambient + c.diffuse), abs=2 / 255)


@pytest.mark.parametrize("shading", ["flat", "gouraud"])
def test_back_faces_are_lit_like_front_faces(shading, renderer):
    # Two-sided lighting, no culling: reversing the winding changes nothing.
    front = renderer.render(_quad(30.0), [FRONT], shading)
    back = renderer.render(_quad(30.0, reverse=True), [FRONT], shading)
    assert np.abs(front.astype(int) - back).max() <= 1
    assert np.count_nonzero(front != BACKGROUND) > 10000


def test_specular_adds_a_highlight(sphere, renderer):
    c = ShadingConstants(ambient=0.1, diffuse=0.4, specular=0.3, shininess=32.0)
    # At the centre of a plane facing the eye n = l = v = h: 0.1 + 0.4 + 0.3 = 0.8 → 204.
    plain = luminance(renderer.render(_quad(), [FRONT], constants=c))[0]
    shiny = luminance(renderer.render(_quad(), [FRONT], specular=True, constants=c))[0]
    assert shiny[CENTRE] == pytest.approx(204.0, abs=1.0)
    assert plain[CENTRE] == pytest.approx(127.5, abs=1.0)
    # The highlight only adds light, and cos^32 has faded near a sphere's rim.
    cameras = protocol_cameras(sphere)[:1]
    for shading in ("flat", "gouraud"):
        plain = luminance(renderer.render(sphere, cameras, shading, constants=c))[0]
        shiny = luminance(renderer.render(sphere, cameras, shading, True, constants=c))[0]
        assert np.all(shiny >= plain)
        assert shiny[CENTRE] > plain[CENTRE] + 60
        assert np.abs(shiny[256, 10:20] - plain[256, 10:20]).max() <= 1.0


def test_custom_shader_is_used(renderer):
    # Our shading makes a white plane facing the headlight exactly ambient + diffuse:
    # 0.25 + 0.35 = 0.6 → 153. pyrender's stock PBR shader (no lights in the scene,
    # sRGB output) cannot produce this value.
    c = ShadingConstants(ambient=0.25, diffuse=0.35)
    image = renderer.render(_quad(), [FRONT], "flat", constants=c)[0]
    got = image[250:262, 250:262]
    assert np.all(got == 153), (
        "pyrender's shader hook changed: the evaluation renderer no longer draws with "
        "metrics.render's GLSL (expected gray 153 at the image centre, got "
        f"{np.unique(got)}). Check pyrender.renderer.Renderer._program_cache and "
        "ShaderProgramCache.get_program in the installed pyrender.")


# -- textures ---------------------------------------------------------------------------

QUADRANTS = {  # image quadrant -> texture colour (texture row 0 is the top)
    "top-left": (220, 40, 30),
    "top-right": (30, 200, 40),
    "bottom-left": (40, 30, 210),
    "bottom-right": (230, 210, 20),
}


def _checker_texture():
    tex = np.zeros((4, 4, 3), np.uint8)
    tex[:2, :2], tex[:2, 2:] = QUADRANTS["top-left"], QUADRANTS["top-right"]
    tex[2:, :2], tex[2:, 2:] = QUADRANTS["bottom-left"], QUADRANTS["bottom-right"]
    return tex


@pytest.mark.parametrize("shading", ["flat", "gouraud"])
def test_textured_quad_keeps_its_orientation(shading, renderer):
    # uv (0, 0) is the texture's bottom-left, and image row 0 is the top: the quad must
    # show the texture upright. Quadrant centres of the quad, (±0.5, ±0.5, 0), project
    # 0.5 / (3 tan 30°) · 256 ≈ 74 pixels from the image centre; bilinear filtering
    # there mixes texels of one colour only.
    image = renderer.render(_quad(texture=_checker_texture()), [FRONT], shading,
                            constants=WHITE)[0]
    offset = int(round(0.5 / (3 * np.tan(np.radians(30))) * 256))
    where = {"top-left": (256 - offset, 256 - offset), "top-right": (256 - offset, 256 + offset),
             "bottom-left": (256 + offset, 256 - offset),
             "bottom-right": (256 + offset, 256 + offset)}
    for quadrant, (row, col) in where.items():
        assert tuple(image[row, col]) == QUADRANTS[quadrant], quadrant


def test_rgba_texture_and_odd_width(renderer):
    # A 3-texel-wide RGB texture has rows of 9 bytes (not 4-byte aligned); RGBA input
    # takes the same path. Both must upload without shearing.
    rgb = np.zeros((2, 3, 3), np.uint8)
    rgb[:, :] = (10, 200, 100)
    for texture in (rgb, np.concatenate([rgb, np.full((2, 3, 1), 255, np.uint8)], 2)):
        image = renderer.render(_quad(texture=texture), [FRONT], constants=WHITE)[0]
        assert tuple(image[CENTRE]) == (10, 200, 100)


# -- anti-aliasing, sizes, determinism ----------------------------------------------------

def test_msaa_blends_edges_and_can_be_switched_off(sphere):
    cameras = protocol_cameras(sphere)[:1]
    smooth = get_renderer().render(sphere, cameras, constants=WHITE)
    hard = get_renderer().render(sphere, cameras, constants=WHITE, msaa=False)
    # With 4 samples a pixel's coverage is 0, 1/4, ..., 1: exactly five gray levels.
    levels = np.unique(smooth)
    assert len(levels) == 5 and levels[0] == 128 and levels[-1] == 255
    np.testing.assert_allclose(levels, 128 + 127 * np.arange(5) / 4, atol=0.5)
    assert set(np.unique(hard)) == {128, 255}
    also_hard = get_renderer(512, 512, 1).render(sphere, cameras, constants=WHITE)
    assert np.array_equal(hard, also_hard)


def test_renderers_share_one_context_and_resize(sphere):
    from metrics import render as module

    assert get_renderer() is get_renderer(512, 512, 4)
    small = get_renderer(64, 48).render(sphere, protocol_cameras(sphere)[:2])
    assert small.shape == (2, 48, 64, 3) and small.dtype == np.uint8
    shared = module._OFFSCREEN
    direct = EvalRenderer(32, 32).render(sphere, protocol_cameras(sphere)[:1])
    assert direct.shape == (1, 32, 32, 3)
    assert module._OFFSCREEN is shared
    assert get_renderer().render(sphere, protocol_cameras(sphere)[:1]).shape == (1, 512, 512, 3)


def test_empty_inputs_render_background(sphere, renderer):
    assert renderer.render(sphere, []).shape == (0, 512, 512, 3)
    empty = Mesh(np.zeros((0, 3)), np.zeros((0, 3), int))
    images = renderer.render(empty, protocol_cameras(sphere)[:2])
    assert images.shape == (2, 512, 512, 3) and np.all(images == BACKGROUND)


def test_bad_arguments_are_rejected(sphere, renderer):
    with pytest.raises(ValueError, match="shading must be one of"):
        renderer.render(sphere, protocol_cameras(sphere)[:1], shading="phong")
    with pytest.raises(ValueError, match="exactly 4 samples"):
        EvalRenderer(msaa=2)
    with pytest.raises(ValueError, match="positive"):
        EvalRenderer(0, 512)


def test_module_level_render_uses_the_shared_renderer(sphere):
    cameras = protocol_cameras(sphere)[:1]
    assert np.array_equal(render(sphere, cameras), get_renderer().render(sphere, cameras))


@pytest.mark.slow
def test_bunny_24_views_are_deterministic(renderer):
    from bench.catalog import BUNNY

    bunny = BUNNY.load()
    cameras = protocol_cameras(bunny)
    first = renderer.render(bunny, cameras)
    second = renderer.render(bunny, cameras)
    assert first.shape == (24, 512, 512, 3) and first.dtype == np.uint8
    assert np.array_equal(first, second)
    covered = np.mean(np.any(first != BACKGROUND, axis=-1), axis=(1, 2))
    assert np.all(covered > 0.05)  # the bunny is in every view


# -- luminance and import order -----------------------------------------------------------

def test_luminance_weights():
    rgb = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], np.uint8)
    y = luminance(rgb[None])
    assert y.shape == (1, 2, 2) and y.dtype == np.float64
    np.testing.assert_allclose(y[0], [[0.299 * 255, 0.587 * 255], [0.114 * 255, 255.0]])
    with pytest.raises(ValueError, match="RGB in the last axis"):
        luminance(np.zeros((2, 2, 4)))


def test_importing_pyrender_first_without_egl_fails_clearly():
    env = {k: v for k, v in os.environ.items() if k != "PYOPENGL_PLATFORM"}
    env.pop("DISPLAY", None)
    code = ("import pyrender, numpy as np\n"
            "from metrics.render import luminance, render\n"
            "from metrics.views import cameras_for, dodecahedron_directions\n"
            "luminance(np.zeros((1, 3), np.uint8))  # importing still works\n"
            "points = np.eye(3)\n"
            "from bench.core.mesh import Mesh\n"
            "render(Mesh(points, [[0, 1, 2]]), cameras_for(points, dodecahedron_directions()))")
    result = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode != 0
    assert "PYOPENGL_PLATFORM=egl" in result.stderr


def test_protocol_with_the_representative_view_evaluates_that_view_alone(sphere):
    """One view, the 24-view protocol's REPRESENTATIVE_VIEW pixel for pixel; d_rms and
    FLIP over that view (FLIP's 6-view subset belongs to the 24 views)."""
    from metrics.protocol import Protocol, evaluate, render_views
    from metrics.views import REPRESENTATIVE_VIEW

    every = Protocol("gouraud", specular=True, resolution=64, msaa=1, hausdorff_samples=500)
    one = Protocol("gouraud", specular=True, resolution=64, msaa=1, hausdorff_samples=500,
                   views="representative")
    coarse = icosphere(2)
    images = render_views(coarse, sphere, one)
    assert images.shape == (1, 64, 64, 3)
    np.testing.assert_array_equal(images[0], render_views(coarse, sphere, every)[REPRESENTATIVE_VIEW])
    ev = evaluate(sphere, coarse, one)
    assert len(ev.per_view["d_rms"]) == 1 and len(ev.per_view["flip"]) == 1
    assert ev.metrics["d_rms"] > 0 and ev.images.shape == (1, 64, 64, 3)
