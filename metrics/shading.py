"""The protocol's shading model as constants: a leaf both renderers import.

The evaluation renderer (:mod:`metrics.render`, pyrender and GLSL) and the suite's own
numba scan converter (:mod:`methods.imaging.raster`) shade with the same classic model
and the same numbers; they take them from here, so a simplification process never has
to load pyrender or OpenGL to know them. This module imports NumPy only.

colour = albedo · (ambient + diffuse · max(0, n·l)) + ks · max(0, n·h)^shininess, the
headlight at the eye, clamped to [0, 1] and stored as 8 bits; luminance
Y = 0.299 R + 0.587 G + 0.114 B on 0..255 (ITU-R BT.601, as Lindstrom & Turk 2000 use
for equation 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BACKGROUND", "SHADINGS", "ShadingConstants", "DEFAULT_CONSTANTS",
           "LUMA_WEIGHTS", "LUMA_R", "LUMA_G", "LUMA_B", "luminance"]

#: Background colour: 50 % gray as an 8-bit value (Lindstrom & Turk 2000, §3.2).
BACKGROUND = 128
#: Shading modes: per-face normals, or lighting per vertex interpolated (Gouraud).
SHADINGS = ("flat", "gouraud")
#: Weights of R, G and B in the luminance Y (ITU-R BT.601, as in L&T 2000 §3.1).
LUMA_R, LUMA_G, LUMA_B = 0.299, 0.587, 0.114
LUMA_WEIGHTS = np.array([LUMA_R, LUMA_G, LUMA_B])


@dataclass(frozen=True)
class ShadingConstants:
    """Material and light constants of the classic shading model.

    The defaults sum ambient + diffuse to 1, so a white surface facing the headlight is
    exactly white and one seen edge-on keeps 10 % (silhouettes stay dark but distinct
    from black holes); ``specular`` adds a highlight that may clip at white.

    Parameters
    ----------
    ambient : float
        Light reaching every surface regardless of orientation.
    diffuse : float
        Lambert weight of max(0, n·l).
    albedo : float
        Gray reflectance of untextured meshes (textured meshes use the texture colour).
    specular : float
        Blinn–Phong weight ks, used when rendering with ``specular=True``.
    shininess : float
        Blinn–Phong exponent.
    mipmaps : bool
        Trilinear (mipmapped) texture minification; False gives plain bilinear.
    """

    ambient: float = 0.1
    diffuse: float = 0.9
    albedo: float = 1.0
    specular: float = 0.3
    shininess: float = 32.0
    mipmaps: bool = True


DEFAULT_CONSTANTS = ShadingConstants()


def luminance(images: np.ndarray) -> np.ndarray:
    """Luminance Y = 0.299 R + 0.587 G + 0.114 B of RGB pixels, on 0..255.

    Parameters
    ----------
    images : ndarray of shape (..., 3) uint8
        RGB pixels.

    Returns
    -------
    ndarray of shape (...) float64

    References
    ----------
    .. [1] Lindstrom, P. & Turk, G. Image-driven simplification. ACM TOG 19(3), 2000,
       §3.1 (the luminance weights of ITU-R BT.601).
    """
    images = np.asarray(images)
    if images.ndim == 0 or images.shape[-1] != 3:
        raise ValueError(f"images must have RGB in the last axis, shape (..., 3), got "
                         f"{images.shape}; drop an alpha channel with images[..., :3]")
    if images.dtype != np.uint8:
        raise ValueError(f"images must be uint8 (0..255), got {images.dtype}; convert float "
                         "images in 0..1 with (255 * x).round().astype(np.uint8)")
    return images @ LUMA_WEIGHTS
