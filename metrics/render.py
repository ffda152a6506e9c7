"""The evaluation renderer: pyrender, headless through EGL, with our own classic shading.

Lindstrom & Turk 2000 (§3.2, §5.1) judge a simplified model by its images: 24 views of
512 × 512 pixels on a 50 % gray background, anti-aliased. This module makes those
images; :mod:`metrics.views` places the cameras.

The rendering model is fixed and classic, not pyrender's stock physically based one:

* one headlight per camera, at the eye: the light vector l at a surface point is the unit
  vector from that point towards the eye (the same as the view vector v), with no
  distance fall-off. So a surface seen edge-on receives no direct light and silhouettes
  turn dark, as the paper observes of its images (§3.2). (A light along the camera axis
  instead would light the silhouette of a sphere seen from 2r at cos 60° = 0.5.);
* colour = albedo · (ambient + diffuse · max(0, n·l)) + ks · max(0, n·h)^shininess, the
  Blinn–Phong specular term (white; h = (l + v)/|l + v| = v here) only when
  ``specular=True``; the result is clamped to [0, 1] and stored as 8-bit;
* ``flat``: per-face normals, from the screen-space derivatives of the view-space
  position in the fragment shader (dFdx × dFdy is normal to the triangle's plane);
* ``gouraud``: the lighting is computed per vertex in the vertex shader from
  ``mesh.vertex_normals`` (area-weighted over welded vertices) and interpolated;
* textured when the mesh has both a texture and UVs: albedo = texture colour, bilinear
  magnification and trilinear (mipmapped) minification, so that a texture seen small
  does not alias. Otherwise albedo is white (1.0), so luminance spans the full range;
* two-sided: nothing is culled and each side is lit with the normal facing the viewer.
  Open models (the original Stanford scan has holes in its base; pymeshlab's copy used
  here is closed) and simplifications that open cracks show their back faces; culling
  them would paint background through the mesh and lighting them with the outward normal would paint them black, both of which
  exaggerate a defect differently for different methods;
* anti-aliasing: pyrender's offscreen framebuffer is multisampled with 4 samples per
  pixel and resolved by a blit (this is pyrender's own path; no supersampling is
  needed). ``msaa=False`` switches ``GL_MULTISAMPLE`` off, so each pixel takes one
  sample at its centre, as a plain scan converter does.

How the shaders get in: pyrender asks ``renderer._renderer._program_cache`` (a
``ShaderProgramCache``) for a program by shader file name. We replace that cache by a
subclass that answers requests for pyrender's mesh shaders with our GLSL (strings in
this module), compiled through pyrender's own ``ShaderProgram``. This relies on pyrender
internals (checked against pyrender 0.1.45); ``tests/test_render.py::
test_custom_shader_is_used`` fails loudly if an upgrade bypasses the hook.

Headless: ``PYOPENGL_PLATFORM=egl`` is set (unless already set) at the top of this module,
before pyrender or PyOpenGL is imported, because PyOpenGL picks its platform once, when
``OpenGL`` is first imported. Importing pyrender or ``OpenGL.GL`` anywhere before this
module without that variable breaks rendering; the first render then raises an error
that says so (importing this module still works, e.g. for :func:`luminance`). EGL needs
the Debian packages libegl1, libegl-mesa0, libgl1, libgl1-mesa-dri and libgbm1 (Mesa
llvmpipe renders on the CPU without a display).

One renderer per process: several EGL contexts in one process break when deleted, so
every :class:`EvalRenderer` shares one process-wide ``pyrender.OffscreenRenderer`` and a
different image size is served by resizing its framebuffer.

References
----------
.. [1] P. Lindstrom and G. Turk, "Image-Driven Simplification", ACM Transactions on
   Graphics 19(3), 2000, §3.2 and §5.1.
.. [2] J. F. Blinn, "Models of light reflection for computer synthesized pictures",
   SIGGRAPH 1977 (the half-vector specular term).
"""

from __future__ import annotations

import os
import platform

# Must precede any import of pyrender or PyOpenGL (see the module docstring).
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from dataclasses import dataclass  # noqa: E402

import numpy as np  # noqa: E402
import pyrender as _pyrender  # noqa: E402
from OpenGL import GL  # noqa: E402
from pyrender.shader_program import ShaderProgram, ShaderProgramCache  # noqa: E402

from metrics.shading import (  # noqa: E402,F401
    BACKGROUND,
    DEFAULT_CONSTANTS,
    SHADINGS,
    ShadingConstants,  # (re-exported for callers)
    luminance,
)

__all__ = [
    "BACKGROUND",
    "EvalRenderer",
    "SHADINGS",
    "ShadingConstants",
    "get_renderer",
    "luminance",
    "render",
]

#: Samples per pixel of pyrender's offscreen framebuffer (hard-coded in pyrender).
PYRENDER_MSAA_SAMPLES = 4


# -- GLSL -------------------------------------------------------------------------------
# pyrender binds vertex attributes at location 0 (position) and NORMAL_LOC,
# TEXCOORD_0_LOC, ... (passed to us as defines), an instance matrix at INST_M_LOC, and
# sets the uniforms M, V, P and material.base_color_texture. Everything else is ours.

_LIGHTING_GLSL = """
uniform float ambient_k;
uniform float diffuse_k;
uniform float specular_k;
uniform float shininess;

// (albedo factor, specular term) at a point with unit normal n and unit vector v towards
// the eye. The headlight sits at the eye, so the light vector l is v itself.
vec2 classic(vec3 n, vec3 v) {
    vec3 l = v;
    float lit = ambient_k + diffuse_k * max(dot(n, l), 0.0);
    float spec = 0.0;
#ifdef SPECULAR
    vec3 h = normalize(l + v);
    spec = specular_k * pow(max(dot(n, h), 0.0), shininess);
#endif
    return vec2(lit, spec);
}
"""

_VERTEX_GLSL = """
layout(location = 0) in vec3 position;
#ifdef NORMAL_LOC
layout(location = NORMAL_LOC) in vec3 normal;
#endif
#ifdef TEXCOORD_0_LOC
layout(location = TEXCOORD_0_LOC) in vec2 texcoord_0;
#endif
layout(location = INST_M_LOC) in mat4 inst_m;

uniform mat4 M;
uniform mat4 V;
uniform mat4 P;

out vec3 view_position;
#ifdef TEXTURED
centroid out vec2 uv;
#endif
#ifdef GOURAUD
centroid out vec2 light_front;
centroid out vec2 light_back;
#endif

void main() {
    mat4 model_view = V * M * inst_m;
    vec4 p = model_view * vec4(position, 1.0);
    view_position = p.xyz;
    gl_Position = P * p;
#ifdef TEXTURED
    uv = texcoord_0;
#endif
#ifdef GOURAUD
    vec3 n = transpose(inverse(mat3(model_view))) * normal;
    float len = length(n);
    n = len > 0.0 ? n / len : n;
    vec3 v = normalize(-p.xyz);
    // Two-sided: the back side of a vertex is lit with the reversed normal.
    light_front = classic(n, v);
    light_back = classic(-n, v);
#endif
}
"""

_FRAGMENT_GLSL = """
in vec3 view_position;
#ifdef TEXTURED
centroid in vec2 uv;
struct Material { sampler2D base_color_texture; };
uniform Material material;
#else
uniform float albedo;
#endif
#ifdef GOURAUD
centroid in vec2 light_front;
centroid in vec2 light_back;
#endif

out vec4 frag_color;

void main() {
    vec3 v = normalize(-view_position);
#ifdef GOURAUD
    vec2 light = gl_FrontFacing ? light_front : light_back;
#else
    // The face normal: the position's screen-space derivatives span the face's plane.
    vec3 n = normalize(cross(dFdx(view_position), dFdy(view_position)));
    n = dot(n, v) < 0.0 ? -n : n;  // two-sided: use the side facing the viewer
    vec2 light = classic(n, v);
#endif
#ifdef TEXTURED
    vec3 base = texture(material.base_color_texture, uv).rgb;
#else
    vec3 base = vec3(albedo);
#endif
    frag_color = vec4(clamp(base * light.x + light.y, 0.0, 1.0), 1.0);
}
"""


def _program_source(stage: str, defines: dict) -> str:
    header = "#version 330 core\n" + "".join(f"#define {k} {v}\n" for k, v in defines.items())
    body = _VERTEX_GLSL if stage == "vertex" else _FRAGMENT_GLSL
    return header + _LIGHTING_GLSL + body


# -- pyrender glue ------------------------------------------------------------------------

def _check_platform() -> None:
    """Fail clearly if PyOpenGL was initialised for another platform than requested."""
    import OpenGL.platform

    wanted = os.environ.get("PYOPENGL_PLATFORM", "")
    actual = type(OpenGL.platform.PLATFORM).__module__
    if wanted == "egl" and not actual.endswith(".egl"):
        raise RuntimeError(
            f"PyOpenGL was initialised for {actual!r}, not EGL: pyrender or OpenGL was "
            "imported before metrics.render without PYOPENGL_PLATFORM=egl. Import "
            "metrics.render first or export PYOPENGL_PLATFORM=egl.")



@dataclass(frozen=True)
class _Mode:
    shading: str
    specular: bool
    msaa: bool
    constants: ShadingConstants


class _ClassicProgram(ShaderProgram):
    """A pyrender ShaderProgram whose 'files' are our GLSL sources."""

    def __init__(self, vertex_source: str, fragment_source: str, cache: _ClassicProgramCache):
        super().__init__(vertex_source, fragment_source, None, defines={})
        self._cache = cache

    def _load(self, source):  # pyrender passes what it holds as a file name
        return source

    def _bind(self):
        super()._bind()
        mode = self._cache.mode
        # pyrender enables GL_MULTISAMPLE before binding each program; this is the last
        # word before drawing, so it decides whether the 4 samples differ.
        (GL.glEnable if mode.msaa else GL.glDisable)(GL.GL_MULTISAMPLE)
        c = mode.constants
        for name, value in (("ambient_k", c.ambient), ("diffuse_k", c.diffuse),
                            ("specular_k", c.specular), ("shininess", c.shininess),
                            ("albedo", c.albedo)):
            self.set_uniform(name, float(value))


class _ClassicProgramCache(ShaderProgramCache):
    """Serves our programs for pyrender's mesh shader requests; others go to pyrender."""

    _MESH_SHADERS = ("mesh.vert", "mesh.frag")

    def __init__(self, stock: ShaderProgramCache):
        super().__init__()
        self._stock = stock
        self._programs: dict = {}
        self.mode: _Mode | None = None
        self.requests = 0  # how many mesh programs pyrender asked us for

    def get_program(self, vertex_shader, fragment_shader, geometry_shader=None,
                    defines=None):
        if self.mode is None or (vertex_shader, fragment_shader) != self._MESH_SHADERS:
            return self._stock.get_program(vertex_shader, fragment_shader,
                                           geometry_shader, defines)
        self.requests += 1
        ours = _glsl_defines(defines or {}, self.mode)
        key = tuple(sorted(ours.items()))
        if key not in self._programs:
            self._programs[key] = _ClassicProgram(_program_source("vertex", ours),
                                                  _program_source("fragment", ours), self)
        return self._programs[key]

    def clear(self):
        for program in self._programs.values():
            program.delete()
        self._programs = {}
        self._stock.clear()


def _glsl_defines(pyrender_defines: dict, mode: _Mode) -> dict:
    """Our shader's defines from pyrender's buffer layout and the shading mode."""
    ours = {k: pyrender_defines[k] for k in ("NORMAL_LOC", "TEXCOORD_0_LOC", "INST_M_LOC")
            if k in pyrender_defines}
    if "INST_M_LOC" not in ours:
        raise RuntimeError("pyrender no longer passes INST_M_LOC to its mesh shaders; the "
                           "shader hook in metrics.render needs updating")
    if "TEXCOORD_0_LOC" in ours and "HAS_BASE_COLOR_TEX" in pyrender_defines:
        ours["TEXTURED"] = 1
    if mode.shading == "gouraud":
        ours["GOURAUD"] = 1
    if mode.specular:
        ours["SPECULAR"] = 1
    return ours


class _ProtocolCamera(_pyrender.camera.Camera):
    """A pyrender camera whose projection is exactly :meth:`Camera.projection_matrix`."""

    def __init__(self, camera):
        super().__init__(znear=camera.near, zfar=camera.far)
        self.protocol_camera = camera

    def get_projection_matrix(self, width=None, height=None):
        return self.protocol_camera.projection_matrix(width / height)


# -- the renderer -----------------------------------------------------------------------

_OFFSCREEN = None  # the one pyrender.OffscreenRenderer of this process
_RENDERERS: dict = {}


def _offscreen(width: int, height: int):
    """The process-wide OffscreenRenderer, sized to (width, height), with our shaders."""
    global _OFFSCREEN
    if _OFFSCREEN is None:
        _check_platform()
        try:
            _OFFSCREEN = _pyrender.OffscreenRenderer(width, height)
        except Exception as error:
            from bench.core.errors import RenderError

            cause = str(error).strip().splitlines()
            raise RenderError(
                f"cannot create an EGL rendering context on {platform.node()} "
                f"({type(error).__name__}: {cause[-1] if cause else ''}; "
                f"PYOPENGL_PLATFORM={os.environ.get('PYOPENGL_PLATFORM')}); on Debian "
                "install libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libgbm1") from error
    # Framebuffers are resizable under EGL, so one context serves every size.
    _OFFSCREEN.viewport_width, _OFFSCREEN.viewport_height = width, height
    inner = getattr(_OFFSCREEN, "_renderer", None)
    cache = getattr(inner, "_program_cache", None)
    if not isinstance(cache, ShaderProgramCache):
        raise RuntimeError("pyrender's shader hook changed: OffscreenRenderer._renderer."
                           "_program_cache is missing; metrics.render needs updating")
    if not isinstance(cache, _ClassicProgramCache):
        inner._program_cache = _ClassicProgramCache(cache)
    return _OFFSCREEN


class EvalRenderer:
    """Renders meshes from protocol cameras (Lindstrom & Turk 2000, §3.2/§5.1).

    A thin facade over the process-wide pyrender offscreen renderer; several instances
    (of different sizes) share it. Prefer :func:`get_renderer`.

    Parameters
    ----------
    width, height : int
        Image size in pixels (the protocol uses 512 × 512).
    msaa : int
        Samples per pixel: 4 (pyrender's multisampled framebuffer) or 1 (off).
    constants : ShadingConstants, optional
        Light and material constants; the defaults are the protocol's.
    """

    def __init__(self, width: int = 512, height: int = 512, msaa: int = 4,
                 constants: ShadingConstants = DEFAULT_CONSTANTS):
        if int(width) < 1 or int(height) < 1:
            raise ValueError(f"image size must be positive, got {width} x {height}")
        if msaa not in (1, PYRENDER_MSAA_SAMPLES):
            raise ValueError(f"msaa must be 1 (off) or {PYRENDER_MSAA_SAMPLES}: pyrender's "
                             f"offscreen framebuffer has exactly {PYRENDER_MSAA_SAMPLES} "
                             f"samples, got {msaa}")
        self.width, self.height, self.msaa = int(width), int(height), int(msaa)
        self.constants = constants

    def render(self, mesh, cameras, shading: str = "flat", specular: bool = False,
               msaa: bool | None = None,
               constants: ShadingConstants | None = None) -> np.ndarray:
        """Images of ``mesh`` from each camera.

        Parameters
        ----------
        mesh : bench.core.mesh.Mesh
            Positions, faces and, if present, uv + texture are used; vertex colours are
            ignored. A mesh without faces renders as background.
        cameras : sequence of metrics.views.Camera
            Usually :func:`metrics.views.protocol_cameras` of the *original* mesh.
        shading : {"flat", "gouraud"}
        specular : bool
            Add the Blinn–Phong highlight.
        msaa : bool, optional
            Override the renderer's anti-aliasing for this call (False = one sample
            per pixel, as an aliased scan converter).
        constants : ShadingConstants, optional
            Override the renderer's constants for this call.

        Returns
        -------
        ndarray of shape (V, height, width, 3) uint8
            RGB, row 0 at the top of the image.
        """
        if shading not in SHADINGS:
            raise ValueError(f"shading must be one of {SHADINGS}, got {shading!r}")
        cameras = list(cameras)
        images = np.full((len(cameras), self.height, self.width, 3), BACKGROUND, np.uint8)
        if not cameras or mesh.n_faces == 0:
            return images
        mode = _Mode(shading, bool(specular), self.msaa > 1 if msaa is None else bool(msaa),
                     constants or self.constants)

        offscreen = _offscreen(self.width, self.height)
        cache = offscreen._renderer._program_cache
        # Render in coordinates centred on the first camera's target, so float32 keeps
        # its precision for models far from the origin.
        origin = np.asarray(cameras[0].target, dtype=np.float64)
        scene = _pyrender.Scene(bg_color=[BACKGROUND / 255.0] * 3 + [1.0],
                                ambient_light=[0.0, 0.0, 0.0])
        scene.add(_pyrender_mesh(mesh, origin, mode))
        camera_node = scene.add(_ProtocolCamera(cameras[0]))
        flags = _pyrender.RenderFlags.RGBA | _pyrender.RenderFlags.SKIP_CULL_FACES
        cache.mode = mode
        try:
            for i, camera in enumerate(cameras):
                camera_node.camera = _ProtocolCamera(camera)
                pose = camera.pose()
                pose[:3, 3] -= origin
                scene.set_pose(camera_node, pose)
                color, _ = offscreen.render(scene, flags)
                images[i] = color[:, :, :3]
            # Free the mesh's GPU buffers now rather than at the next call.
            scene.remove_node(next(iter(scene.mesh_nodes)))
            offscreen.render(scene, flags)
        finally:
            cache.mode = None
        return images


def _pyrender_mesh(mesh, origin: np.ndarray, mode: _Mode):
    """A pyrender.Mesh of ``mesh`` translated by −origin, with what the mode needs."""
    normals = mesh.vertex_normals if mode.shading == "gouraud" else None
    uv, material = None, None
    if mesh.has_texture:
        uv = mesh.uv  # origin bottom-left, as OpenGL; pyrender flips the image rows
        sampler = _pyrender.Sampler(
            magFilter=GL.GL_LINEAR,
            minFilter=GL.GL_LINEAR_MIPMAP_LINEAR if mode.constants.mipmaps else GL.GL_LINEAR)
        texture = _pyrender.Texture(source=_rgba(mesh.texture), source_channels="RGBA",
                                    sampler=sampler)
        material = _pyrender.MetallicRoughnessMaterial(baseColorTexture=texture,
                                                       doubleSided=True, alphaMode="OPAQUE")
    else:
        material = _pyrender.MetallicRoughnessMaterial(doubleSided=True, alphaMode="OPAQUE")
    primitive = _pyrender.Primitive(
        positions=(mesh.positions - origin).astype(np.float32), normals=normals,
        texcoord_0=uv, indices=mesh.faces.astype(np.uint32), material=material)
    return _pyrender.Mesh([primitive])


def _rgba(texture: np.ndarray) -> np.ndarray:
    # Four bytes per texel keeps rows 4-byte aligned (GL's default unpack alignment)
    # whatever the width; alpha is ignored by the shader.
    if texture.shape[2] == 4:
        return np.ascontiguousarray(texture)
    alpha = np.full(texture.shape[:2] + (1,), 255, np.uint8)
    return np.ascontiguousarray(np.concatenate([texture, alpha], axis=2))


def get_renderer(width: int = 512, height: int = 512, msaa: int = 4) -> EvalRenderer:
    """The shared :class:`EvalRenderer` for a size and sample count.

    All renderers share one OpenGL context (one EGL renderer per process); asking for
    another size resizes its framebuffer rather than creating a second context.
    """
    key = (int(width), int(height), int(msaa))
    if key not in _RENDERERS:
        _RENDERERS[key] = EvalRenderer(*key)
    return _RENDERERS[key]


def render(mesh, cameras, shading: str = "flat", specular: bool = False, *,
           width: int = 512, height: int = 512, msaa: int = 4) -> np.ndarray:
    """Render with the shared renderer; see :meth:`EvalRenderer.render`.

    Returns
    -------
    ndarray of shape (V, height, width, 3) uint8
    """
    return get_renderer(width, height, msaa).render(mesh, cameras, shading, specular)
