"""The textured torus of Lindstrom & Turk 2000, §5.4 (Plate 12), rebuilt procedurally.

The paper's model was "constructed with a highly non-linear texture parameterization
... by sweeping and spinning an ellipse around a circle to form a torus", with a texture
of "randomly colored square blocks on a white background, with a number of straight
black lines and several rows of text". It had 65,536 triangles.

Our choices where the paper is silent (each is deterministic for a seed):

- geometry: major radius 1; an ellipse with semi-axes 0.42 and 0.18 is swept around the
  circle while spinning about the sweep direction, two full turns per revolution;
- grid: 256 × 128 quads split into 65,536 triangles; the grid lines are placed at
  *warped* angles, θ = 2π(s + 0.06 sin 4πs) and φ = 2π(t + 0.09 sin 2πt) for uniform
  s, t, while texture coordinates stay (s, t) — so the texture is stretched and
  compressed non-linearly over the surface;
- UV seams where s and t wrap (vertices duplicated with u = 0 and u = 1, v likewise),
  as a game engine would store it;
- texture: 1024², white, 90 random squares (random colours), 14 straight black lines,
  6 rows of text in Pillow's default font.
"""

from __future__ import annotations

import numpy as np

from bench.core.mesh import Mesh

__all__ = ["make_torus", "torus_texture"]


def make_torus(major_segments: int = 256, minor_segments: int = 128, seed: int = 2000,
               texture_size: int = 1024) -> Mesh:
    """The procedural torus; ``2 * major_segments * minor_segments`` faces.

    Parameters
    ----------
    major_segments, minor_segments : int
        Grid resolution around the big circle and around the ellipse (each ≥ 3).
    seed : int
        Seed of the texture's random blocks and lines.
    texture_size : int
        Width and height of the texture image in pixels.
    """
    if major_segments < 3 or minor_segments < 3:
        raise ValueError("torus needs at least 3 segments in each direction")
    s = np.linspace(0.0, 1.0, major_segments + 1)  # includes the wrap duplicate
    t = np.linspace(0.0, 1.0, minor_segments + 1)
    theta = 2 * np.pi * (s + 0.06 * np.sin(4 * np.pi * s))  # warped, still monotone
    phi = 2 * np.pi * (t + 0.09 * np.sin(2 * np.pi * t))
    th, ph = np.meshgrid(theta, phi, indexing="ij")

    spin = 2.0 * th  # the ellipse turns twice about the sweep direction per revolution
    a, b, radius = 0.42, 0.18, 1.0
    ex, ey = a * np.cos(ph), b * np.sin(ph)  # ellipse in its own frame
    radial = ex * np.cos(spin) - ey * np.sin(spin)  # rotate it in the (radial, z) plane
    height = ex * np.sin(spin) + ey * np.cos(spin)
    r = radius + radial
    positions = np.stack([r * np.cos(th), r * np.sin(th), height], axis=-1).reshape(-1, 3)
    # The wrap duplicates must be bit-identical to their partners so they weld.
    grid = positions.reshape(major_segments + 1, minor_segments + 1, 3)
    grid[-1] = grid[0]
    grid[:, -1] = grid[:, 0]

    uu, vv = np.meshgrid(s, t, indexing="ij")
    uv = np.stack([uu, vv], axis=-1).reshape(-1, 2)

    cols = minor_segments + 1
    i, j = np.meshgrid(np.arange(major_segments), np.arange(minor_segments), indexing="ij")
    v00 = (i * cols + j).reshape(-1)
    v10, v01, v11 = v00 + cols, v00 + 1, v00 + cols + 1
    # Outward orientation: d/dθ × d/dφ points out of the tube for this layout.
    faces = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
    faces = faces.reshape(2, -1, 3).transpose(1, 0, 2).reshape(-1, 3)  # quad halves adjacent
    return Mesh(grid.reshape(-1, 3), faces.astype(np.int32), uv=uv,
                texture=torus_texture(texture_size, seed), name="torus",
                metadata={"source": "procedural (Lindstrom & Turk 2000, §5.4)", "seed": seed})


def torus_texture(size: int = 1024, seed: int = 2000) -> np.ndarray:
    """Random coloured squares, straight black lines and rows of text on white.

    Returns
    -------
    ndarray of shape (size, size, 3) uint8
    """
    from PIL import Image, ImageDraw, ImageFont

    rng = np.random.default_rng(seed)
    image = Image.new("RGB", (size, size), "white")
    draw = ImageDraw.Draw(image)
    for _ in range(90):
        side = int(rng.integers(size // 40, size // 10))
        x, y = rng.integers(0, size - side, 2)
        colour = tuple(int(c) for c in rng.integers(0, 230, 3))
        draw.rectangle([int(x), int(y), int(x) + side, int(y) + side], fill=colour)
    width = max(2, size // 256)
    for _ in range(14):
        if rng.random() < 0.5:  # horizontal or vertical line across the whole image
            y = int(rng.integers(0, size))
            draw.line([(0, y), (size, y)], fill="black", width=width)
        else:
            x = int(rng.integers(0, size))
            draw.line([(x, 0), (x, size)], fill="black", width=width)
    font = ImageFont.load_default(size=max(8, size // 24))
    words = ["IMAGE", "DRIVEN", "SIMPLIFICATION", "TORUS", "TEXTURE", "LUMINANCE", "QSLIM"]
    for row in range(6):
        text = " ".join(words[int(k)] for k in rng.integers(0, len(words), 4))
        y = int((row + 0.5) * size / 6)
        draw.text((size // 32, y), text, fill="black", font=font)
    return np.asarray(image, dtype=np.uint8).copy()
