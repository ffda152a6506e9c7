"""The ``interior`` model: a closed shell with a few openings around a highly tessellated
object — Lindstrom & Turk 2000, §5.2 (the turbine blade of Plates 2 and 3), in miniature.

The paper's blade hides most of its 1.7 M polygons in internal cavities that no exterior
view sees; a geometry-driven method keeps that detail, the image-driven method spends the
budget on the visible exterior instead. This model poses the same question on a small
scale, with every face's side known from geometry alone.

Construction (deterministic, no random numbers; all faces wound counter-clockwise seen
from outside, so normals point away from the centre):

- **shell**: a geodesic sphere of radius 1 about the origin (an icosahedron whose faces
  are split into ``shell_frequency²`` triangles, vertices projected onto the sphere),
  with :data:`OPENINGS` cut out: faces whose centroid lies within an opening's angular
  radius of its axis are removed (and so are faces left with all three corners on the
  rim), and the vertices left on each rim are moved along their great circle onto the
  rim, so every opening is a round boundary loop;
- **inner object**: a geodesic sphere of ``inner_frequency`` (far denser than the
  shell) with radius 0.5 displaced by :func:`bump_height` (bumps and dents between
  ±:data:`INNER_AMPLITUDE` of the radius), closed;
- no texture, no UVs; one connected component per part, no seams.

Classification: ``mesh.metadata["exterior_sphere"] = {"centre": [0, 0, 0], "radius":
0.7}``. A face lies on the exterior shell when its centroid is farther than 0.7 from
the centre, else on the inner object. The rule also classifies simplified meshes
(:mod:`metrics.interior` reads it): the inner object never reaches past
0.5 · (1 + :data:`INNER_AMPLITUDE`) = 0.575, and a triangle with its corners on the unit
sphere has its centroid beyond 0.7 unless its edges span more than 76° of arc — coarser than
an icosahedron's (63°).
"""

from __future__ import annotations

import numpy as np

from bench.core.mesh import Mesh, compact

__all__ = ["make_interior", "geodesic_sphere", "bump_height", "OPENINGS", "INNER_RADIUS",
           "INNER_AMPLITUDE", "EXTERIOR_RADIUS"]

#: The openings of the shell: (azimuth, elevation, angular radius), in degrees. Placed
#: irregularly, like the blade's holes; a few of the 24 protocol views (and of the 20
#: dodecahedron views) see part of the inner object through them, most see none.
OPENINGS = ((20.0, 35.0, 20.0), (145.0, -10.0, 17.0), (250.0, 28.0, 22.0),
            (320.0, -48.0, 18.0))
#: Radius of the inner object before displacement.
INNER_RADIUS = 0.5
#: Largest relative displacement of the inner object (bumps and dents).
INNER_AMPLITUDE = 0.15
#: Faces with their centroid farther than this from the centre are on the exterior.
EXTERIOR_RADIUS = 0.7


def make_interior(shell_frequency: int = 16, inner_frequency: int = 48) -> Mesh:
    """The interior model: ``20 · inner_frequency²`` inner faces plus the shell's.

    With the defaults: a 5,120-face geodesic shell less its four openings (4,543 faces
    remain) and a 46,080-face bumpy inner object: 50,623 faces and 25,373 vertices.

    Parameters
    ----------
    shell_frequency, inner_frequency : int
        Subdivision frequency of each geodesic sphere (each ≥ 2); the shell must be fine
        enough that every opening removes at least one face.
    """
    if shell_frequency < 2 or inner_frequency < 2:
        raise ValueError("interior needs a subdivision frequency of at least 2 per sphere")
    shell_pos, shell_faces = _shell_with_openings(shell_frequency)
    inner_pos, inner_faces = geodesic_sphere(inner_frequency)
    inner_radius = INNER_RADIUS * (1.0 + INNER_AMPLITUDE * bump_height(inner_pos))
    inner_pos = inner_pos * inner_radius[:, None]
    positions = np.concatenate([shell_pos, inner_pos])
    faces = np.concatenate([shell_faces, inner_faces + len(shell_pos)]).astype(np.int32)
    metadata = {
        "source": "procedural (Lindstrom & Turk 2000, §5.2)",
        "exterior_sphere": {"centre": [0.0, 0.0, 0.0], "radius": EXTERIOR_RADIUS},
        "shell_faces": int(len(shell_faces)),
        "inner_faces": int(len(inner_faces)),
        "openings": len(OPENINGS),
    }
    return Mesh(positions, faces, name="interior", metadata=metadata)


def geodesic_sphere(frequency: int) -> tuple[np.ndarray, np.ndarray]:
    """A unit geodesic sphere: every icosahedron face split into ``frequency²`` triangles.

    Vertices on the icosahedron's edges are computed once per edge, so neighbouring faces
    share them exactly (the mesh is closed and welded). Returns positions
    ``(10 f² + 2, 3)`` and faces ``(20 f², 3)``, wound counter-clockwise seen from outside.
    """
    n = int(frequency)
    if n < 1:
        raise ValueError("frequency must be at least 1")
    corners, ico_faces = _icosahedron()
    points = [c for c in corners]
    edge_points: dict[tuple[int, int], list[int]] = {}

    def edge_vertex(u: int, v: int, k: int) -> int:
        """Index of the point k/n of the way from corner u to corner v."""
        lo, hi, t = (u, v, k) if u < v else (v, u, n - k)
        if (lo, hi) not in edge_points:
            start = len(points)
            points.extend((corners[lo] * (n - s) + corners[hi] * s) / n for s in range(1, n))
            edge_points[(lo, hi)] = list(range(start, start + n - 1))
        return edge_points[(lo, hi)][t - 1]

    faces = []
    for a, b, c in ico_faces:
        index = {}
        for i in range(n + 1):
            for j in range(n + 1 - i):
                w = (n - i - j, i, j)  # barycentric weights (times n) of corners a, b, c
                if n in w:
                    index[i, j] = (a, b, c)[w.index(n)]
                elif w[0] == 0:
                    index[i, j] = edge_vertex(b, c, j)
                elif w[1] == 0:
                    index[i, j] = edge_vertex(a, c, j)
                elif w[2] == 0:
                    index[i, j] = edge_vertex(a, b, i)
                else:
                    index[i, j] = len(points)
                    points.append((corners[a] * w[0] + corners[b] * w[1] + corners[c] * w[2]) / n)
        for i in range(n):
            for j in range(n - i):
                faces.append((index[i, j], index[i + 1, j], index[i, j + 1]))
                if i + j < n - 1:
                    faces.append((index[i + 1, j], index[i + 1, j + 1], index[i, j + 1]))
    positions = np.array(points, dtype=np.float64)
    positions /= np.linalg.norm(positions, axis=1, keepdims=True)
    return positions, np.array(faces, dtype=np.int32)


def bump_height(directions: np.ndarray) -> np.ndarray:
    """Relative displacement in [-1, 1] of the inner object at unit ``directions``.

    Alternating bumps and dents (Gaussian in 1 - cos of the angle, about 12° wide)
    centred on 32 points of a Fibonacci spiral, plus a fine ripple, clipped to [-1, 1].
    """
    k = np.arange(32)
    z = 1.0 - (2 * k + 1) / 32
    azimuth = k * np.pi * (3.0 - np.sqrt(5.0))
    centres = np.stack([np.sqrt(1 - z**2) * np.cos(azimuth), np.sqrt(1 - z**2) * np.sin(azimuth),
                        z], axis=1)
    signs = np.where(k % 2 == 0, 1.0, -0.7)
    cosines = directions @ centres.T
    height = (signs * np.exp(-(1.0 - cosines) / 0.022)).sum(axis=1)
    x, y, zz = directions.T
    ripple = np.sin(11 * x + 0.5) * np.sin(11 * y + 1.5) * np.sin(11 * zz + 2.5)
    return np.clip(0.8 * height + 0.2 * ripple, -1.0, 1.0)


def _icosahedron() -> tuple[np.ndarray, list[tuple[int, int, int]]]:
    """The 12 unit vertices and 20 outward-wound faces of a regular icosahedron."""
    phi = (1.0 + np.sqrt(5.0)) / 2.0
    corners = np.array([[-1, phi, 0], [1, phi, 0], [-1, -phi, 0], [1, -phi, 0],
                        [0, -1, phi], [0, 1, phi], [0, -1, -phi], [0, 1, -phi],
                        [phi, 0, -1], [phi, 0, 1], [-phi, 0, -1], [-phi, 0, 1]])
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    return corners / np.linalg.norm(corners, axis=1, keepdims=True), faces


def _opening_axes() -> np.ndarray:
    az, el = (np.radians([o[k] for o in OPENINGS]) for k in (0, 1))
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)


def _shell_with_openings(frequency: int) -> tuple[np.ndarray, np.ndarray]:
    """The unit geodesic sphere with :data:`OPENINGS` cut out and their rims made round."""
    positions, faces = geodesic_sphere(frequency)
    axes = _opening_axes()
    radii = np.radians([o[2] for o in OPENINGS])
    centroids = positions[faces].mean(axis=1)
    centroids /= np.linalg.norm(centroids, axis=1, keepdims=True)
    inside = (centroids @ axes.T) > np.cos(radii)  # (faces, openings)
    if not inside.any(axis=0).all():
        raise ValueError(f"shell frequency {frequency} is too coarse for the openings")
    faces = faces[~inside.any(axis=1)]
    # A face with all three corners on a rim would lie flat in the rim's plane once the
    # rim is made round (and turn over); such "ears" go with the opening.
    while True:
        on_rim = np.isin(faces, _boundary_vertices(faces)).all(axis=1)
        if not on_rim.any():
            break
        faces = faces[~on_rim]

    # Move each rim vertex along the great circle through the opening's axis onto the rim.
    # Each rim vertex belongs to exactly one opening (the openings are far apart).
    used, faces = compact(faces)
    positions = positions[used]
    rim = _boundary_vertices(faces)
    p = positions[rim]
    nearest = (p @ axes.T).argmax(axis=1)
    axis, radius = axes[nearest], radii[nearest]
    tangent = p - (p * axis).sum(axis=1, keepdims=True) * axis
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    positions[rim] = np.cos(radius)[:, None] * axis + np.sin(radius)[:, None] * tangent

    normals = np.cross(positions[faces[:, 1]] - positions[faces[:, 0]],
                       positions[faces[:, 2]] - positions[faces[:, 0]])
    if ((normals * positions[faces].mean(axis=1)).sum(axis=1) <= 0).any():
        raise ValueError(f"shell frequency {frequency}: rounding the openings turned faces "
                         "over; use a finer shell")
    return positions, faces


def _boundary_vertices(faces: np.ndarray) -> np.ndarray:
    """Vertices on edges used by exactly one face."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    unique, count = np.unique(edges, axis=0, return_counts=True)
    return np.unique(unique[count == 1])
