"""``torus-puzzle``: the lit, textured torus of Williams et al. 2003 (Plate 1, Figure 4d).

The paper shows "a textured and lit torus ... at full resolution with 57,660
triangles" carrying a jigsaw puzzle texture (credited to Greg Turk). Neither the
torus's proportions nor the texture are given; our choices (deterministic):

- geometry: the swept-ellipse torus of :mod:`bench.catalog.torus` (the suite's torus, so its
  non-linear parameterisation and UV seams are shared), on a 310 × 93 grid:
  2 · 310 · 93 = 57,660 triangles, exactly the paper's count; the grid's aspect follows
  the tube's (the big circle is about 3.3 times the ellipse's circumference);
- texture: 1024², a 16 × 8 grid of jigsaw pieces, each a random colour (saturated and
  pale ones mixed, so the texture has both high- and low-contrast regions), with a
  round tab on every edge between two pieces pointing into a random neighbour, and
  dark outlines three texels wide. The piece grid wraps like the UVs, so the seams
  of the torus do not cut through a piece's outline.
"""

from __future__ import annotations

import numpy as np

from bench.core.mesh import Mesh

__all__ = ["make_torus_puzzle", "puzzle_texture"]


def make_torus_puzzle(major_segments: int = 310, minor_segments: int = 93, seed: int = 2003,
                      texture_size: int = 1024) -> Mesh:
    """The puzzle torus; ``2 * major_segments * minor_segments`` faces (57,660)."""
    from bench.catalog.torus import make_torus

    torus = make_torus(major_segments, minor_segments, seed=seed, texture_size=64)
    return torus.replace(texture=puzzle_texture(texture_size, seed=seed), name="torus-puzzle",
                         metadata={"source": "procedural (Williams et al. 2003, Plate 1)",
                                   "seed": seed})


def puzzle_texture(size: int = 1024, pieces: tuple[int, int] = (16, 8),
                   seed: int = 2003) -> np.ndarray:
    """A jigsaw puzzle texture that tiles periodically.

    Parameters
    ----------
    size : int
        Width and height in texels (at least 8 per piece).
    pieces : (int, int)
        Pieces across (u) and down (v), each at least 2.
    seed : int

    Returns
    -------
    ndarray of shape (size, size, 3) uint8
    """
    nx, ny = pieces
    if nx < 2 or ny < 2:
        raise ValueError(f"a puzzle needs at least 2 x 2 pieces, got {pieces}")
    if size < 8 * max(nx, ny):
        raise ValueError(f"texture size {size} is too small for {pieces} pieces "
                         "(at least 8 texels per piece)")
    rng = np.random.default_rng(seed)
    cw, ch = size / nx, size / ny
    ys, xs = np.mgrid[0:size, 0:size] + 0.5
    col = np.floor(xs / cw).astype(int) % nx
    row = np.floor(ys / ch).astype(int) % ny
    piece = row * nx + col
    fx, fy = xs / cw - np.floor(xs / cw), ys / ch - np.floor(ys / ch)  # position in cell
    radius, reach = 0.17, 0.12  # tab radius and how far its centre lies past the edge
    # Each cell's right and bottom edges carry one round tab; the flag says whether it
    # sticks out of the cell (into the next one) or into it (from the next one).
    right = rng.random((ny, nx)) < 0.5
    down = rng.random((ny, nx)) < 0.5
    out = piece.copy()
    for dx, dy, flag in ((1, 0, right), (0, 1, down)):
        prev_col, prev_row = (col - dx) % nx, (row - dy) % ny
        next_col, next_row = (col + dx) % nx, (row + dy) % ny
        # a tab of the previous cell sticking into this one, near this cell's left/top
        cx, cy = (reach, 0.5) if dx else (0.5, reach)
        tab_in = flag[prev_row, prev_col] & ((fx - cx) ** 2 + (fy - cy) ** 2 < radius ** 2)
        out = np.where(tab_in, prev_row * nx + prev_col, out)
        # a tab of the next cell sticking back into this one, near its right/bottom
        cx, cy = (1.0 - reach, 0.5) if dx else (0.5, 1.0 - reach)
        tab_back = ~flag[row, col] & ((fx - cx) ** 2 + (fy - cy) ** 2 < radius ** 2)
        out = np.where(tab_back, next_row * nx + next_col, out)
    pale = rng.random(nx * ny) < 0.5
    base = rng.integers(0, 256, (nx * ny, 3))
    colours = np.where(pale[:, None], 170 + base // 3, base).astype(np.uint8)
    image = colours[out]
    edge = np.zeros((size, size), bool)
    for axis in (0, 1):
        for shift in (1, -1):
            edge |= out != np.roll(out, shift, axis=axis)
    edge = edge | np.roll(edge, 1, 0) | np.roll(edge, 1, 1)
    image[edge] = (25, 25, 25)
    return np.ascontiguousarray(image)
