"""Geometric error, Metro-style: sampled Hausdorff distances between two surfaces.

Metro (Cignoni, Rocchini & Scopigno 1998), which Lindstrom & Turk 2000 use in §5.1,
samples one surface at its vertices, along its edges and over its faces, and measures
each sample's distance to the closest point of the other surface. Done both ways, the
largest distance is the two-sided Hausdorff distance; the mean and RMS describe the
typical error.

The closest-point queries are MeshLab's (pymeshlab ``get_hausdorff_distance``), but the
samples are drawn here, so they are reproducible: the filter has no seed parameter and
its face sampling draws from a random generator that lives for the whole process, so two
identical calls give different numbers. The samples are handed to the filter as a point
cloud whose every vertex it measures.

Direction, as in Metro: *forward* samples the ORIGINAL and measures the distance to the
simplified mesh (how far the original's surface is from the result: parts that were cut
away); *backward* samples the simplified mesh and measures the distance to the original
(parts of the result that stray from the original). All distances are fractions of the
original's bounding-box diagonal.

The :class:`~bench.core.metric.Metric` constants :data:`HAUSDORFF_MEAN` and
:data:`HAUSDORFF_MAX` are called as ``compute(original, simplified, ctx)`` with ``ctx`` a
dict that may hold ``"hausdorff_samples"`` (int) or a ``"protocol"`` whose
``hausdorff_samples`` is used; the result of :func:`hausdorff` is cached in it under
``"hausdorff"``, so both metrics share one computation. They need ``"hausdorff"``
(:data:`bench.core.metric.NEEDS`): :func:`metrics.protocol.evaluate` puts that result in
``ctx`` before any metric runs, so the distances are sampled once per evaluation.
"""

from __future__ import annotations

import numpy as np

from bench.core.mesh import Mesh, face_areas
from bench.core.metric import Metric

__all__ = ["hausdorff", "sample_surface", "distance_to_surface", "HAUSDORFF_SAMPLES",
           "HAUSDORFF_MEAN", "HAUSDORFF_MAX"]

#: Default number of edge samples and, separately, of face samples on each surface
#: (every vertex is a sample too), as the protocol's ≥ 200k requires.
HAUSDORFF_SAMPLES = 200_000

# MeshLab drops samples farther than ``maxdist`` from the target, silently shrinking the
# statistics. No distance between two meshes exceeds the diagonal of the box enclosing
# both, so ``maxdist`` is that diagonal, with a margin for MeshLab's float32 arithmetic.
_MAXDIST_MARGIN = 1.01


def hausdorff(original: Mesh, simplified: Mesh, samples: int = HAUSDORFF_SAMPLES,
              seed: int = 0) -> dict[str, float]:
    """Metro-style distances between two surfaces, both ways.

    Parameters
    ----------
    original, simplified : Mesh
        Both with at least one face; ``original`` must have a bounding box of nonzero
        diagonal (the unit of the results).
    samples : int
        Samples per direction, at least 1: every vertex of the sampled surface, and the
        rest split evenly between its edges and faces (at least one of each; see
        :func:`sample_surface`). MeshLab's ``samplenum`` likewise counts all kinds.
    seed : int
        Seed of the face samples; the same seed gives the same numbers.

    Returns
    -------
    dict of str to float
        ``forward_mean``, ``forward_rms``, ``forward_max``: distances from samples of
        ``original`` to the surface of ``simplified``; ``backward_mean``,
        ``backward_rms``, ``backward_max``: from samples of ``simplified`` to
        ``original``; ``symmetric_max``: the larger maximum (the two-sided Hausdorff
        distance); ``hausdorff_mean``: the mean of the two directions' means. All are
        fractions of ``original.diagonal``.

    References
    ----------
    .. [1] Cignoni, P., Rocchini, C. & Scopigno, R. Metro: measuring error on simplified
       surfaces. Computer Graphics Forum 17(2), 1998.
    .. [2] Lindstrom, P. & Turk, G. Image-driven simplification. ACM TOG 19(3), 2000,
       §5.1 (Figure 5: Metro's mean error in units of the bounding-box diagonal).
    """
    _check_mesh(original, "original")
    _check_mesh(simplified, "simplified")
    samples = _check_samples(samples)
    diagonal = original.diagonal
    if not diagonal > 0:
        raise ValueError("the original's bounding box has zero diagonal (all vertices "
                         "coincide), so distances relative to it are undefined")

    bound = _enclosing_diagonal(original, simplified)
    # Different seeds per direction keep the two sample sets independent.
    forward = distance_to_surface(sample_surface(original, _per_kind(original, samples), seed),
                                  simplified, bound)
    backward = distance_to_surface(
        sample_surface(simplified, _per_kind(simplified, samples), seed + 1), original, bound)
    result = {}
    for side, distances in (("forward", forward), ("backward", backward)):
        result[f"{side}_mean"] = float(distances.mean() / diagonal)
        result[f"{side}_rms"] = float(np.sqrt(np.mean(distances ** 2)) / diagonal)
        result[f"{side}_max"] = float(distances.max() / diagonal)
    result["symmetric_max"] = max(result["forward_max"], result["backward_max"])
    result["hausdorff_mean"] = 0.5 * (result["forward_mean"] + result["backward_mean"])
    return result


def _per_kind(mesh: Mesh, samples: int) -> int:
    """Edge samples (and, separately, face samples) that bring the total to ``samples``."""
    return max(1, -(-(samples - mesh.welded.n_vertices) // 2))


def sample_surface(mesh: Mesh, samples: int = HAUSDORFF_SAMPLES, seed: int = 0) -> np.ndarray:
    """Metro-style sample points of a surface: vertices, edges and faces.

    The samples are, in this order, every welded vertex; ``samples`` points spread
    evenly along the welded edges (at equal arc-length steps over all edges laid end to
    end, so longer edges get proportionally more; no randomness); and ``samples`` points
    drawn uniformly over the area (a face chosen with probability proportional to its
    area, then a uniform point in it). A mesh of zero total area gets no face samples.

    Parameters
    ----------
    mesh : Mesh
    samples : int
        Number of edge samples and, separately, of face samples; at least 1.
    seed : int
        Seed of the face samples.

    Returns
    -------
    ndarray of shape (k + 2·samples, 3) float64
        k is the number of welded vertices (k + samples when the area is zero).
    """
    _check_mesh(mesh, "mesh")
    samples = _check_samples(samples)
    w = mesh.welded
    parts = [w.positions, _edge_samples(w.positions, w.edges, samples)]
    areas = face_areas(w.positions, w.faces)
    if areas.sum() > 0:
        parts.append(_face_samples(w.positions, w.faces, areas, samples, seed))
    return np.concatenate(parts)


def distance_to_surface(points: np.ndarray, mesh: Mesh,
                        max_distance: float | None = None) -> np.ndarray:
    """Unsigned distance from each point to the closest point of a mesh's surface.

    MeshLab's closest-point search (pymeshlab ``get_hausdorff_distance`` with the points
    as the sampled mesh and only its vertices sampled). Every filter parameter is passed,
    because pymeshlab remembers the last values given as the defaults of later calls.

    Parameters
    ----------
    points : ndarray of shape (p, 3) float
    mesh : Mesh
        At least one face.
    max_distance : float, optional
        An upper bound on every distance; defaults to the diagonal of the box enclosing
        the points and the mesh, which bounds all of them.

    Returns
    -------
    ndarray of shape (p,) float64
        Computed in MeshLab's single precision (relative error about 1e-7).
    """
    import pymeshlab

    points = np.ascontiguousarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        raise ValueError(f"points must have shape (p, 3) with p >= 1, got {points.shape}")
    if not np.isfinite(points).all():
        raise ValueError("points contain NaN or infinite coordinates; drop them first")
    _check_mesh(mesh, "mesh")
    if max_distance is None:
        both = np.concatenate([points, mesh.positions])
        max_distance = float(np.linalg.norm(both.max(axis=0) - both.min(axis=0)))
    # A positive bound even when every point lies on one spot of a flat mesh.
    max_distance = max(max_distance, np.finfo(np.float32).tiny) * _MAXDIST_MARGIN

    w = mesh.welded
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=points))                         # id 0
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=w.positions, face_matrix=w.faces))  # id 1
    result = ms.get_hausdorff_distance(
        sampledmesh=0, targetmesh=1, savesample=True,
        samplevert=True, sampleedge=False, samplefauxedge=False, sampleface=False,
        samplenum=len(points),  # >= the vertex count: every vertex, in order, no sampling
        maxdist=pymeshlab.PureValue(max_distance))
    if result["n_samples"] != len(points):
        raise RuntimeError(f"MeshLab measured {result['n_samples']} of {len(points)} "
                           f"points within {max_distance:g}; pass a larger max_distance")
    # savesample adds the closest points (id 2) and the samples (id 3); the closest
    # points carry each sample's distance as their vertex quality.
    closest = ms.mesh(2)
    if closest.vertex_number() != len(points):
        raise RuntimeError("pymeshlab returned an unexpected sample layout; "
                           "check the installed pymeshlab version")
    return closest.vertex_scalar_array().astype(np.float64)


# -- sampling stages ---------------------------------------------------------------------

def _edge_samples(positions: np.ndarray, edges: np.ndarray, count: int) -> np.ndarray:
    """``count`` points at equal arc-length steps along the edges laid end to end,
    each at the middle of its step, shape (count, 3)."""
    a, b = positions[edges[:, 0]], positions[edges[:, 1]]
    lengths = np.linalg.norm(b - a, axis=1)
    ends = np.cumsum(lengths)
    total = ends[-1]
    if not total > 0:  # every edge degenerate: the surface is a single point
        return np.repeat(a[:1], count, axis=0)
    s = (np.arange(count) + 0.5) * (total / count)
    edge = np.minimum(np.searchsorted(ends, s, side="right"), len(edges) - 1)
    start = ends[edge] - lengths[edge]
    t = np.clip((s - start) / np.where(lengths[edge] > 0, lengths[edge], 1.0), 0.0, 1.0)
    return a[edge] + t[:, None] * (b[edge] - a[edge])


def _face_samples(positions: np.ndarray, faces: np.ndarray, areas: np.ndarray, count: int,
                  seed: int) -> np.ndarray:
    """``count`` points uniform over the area, shape (count, 3)."""
    rng = np.random.default_rng(seed)
    ends = np.cumsum(areas)
    face = np.minimum(np.searchsorted(ends, rng.random(count) * ends[-1], side="right"),
                      len(faces) - 1)
    # Uniform point in a triangle: with u, v uniform on [0, 1), s = √u, the weights
    # (1 − s, s(1 − v), s·v) are uniform over it (Osada et al., Shape distributions,
    # ACM TOG 2002, §4.2).
    u, v = rng.random(count), rng.random(count)
    s = np.sqrt(u)
    p = positions[faces[face]]
    return ((1 - s)[:, None] * p[:, 0] + (s * (1 - v))[:, None] * p[:, 1]
            + (s * v)[:, None] * p[:, 2])


# -- validation --------------------------------------------------------------------------

def _check_mesh(mesh, what: str) -> None:
    if not isinstance(mesh, Mesh):
        raise ValueError(f"{what} must be a bench.core.mesh.Mesh, got {type(mesh).__name__}; "
                         "build one with bench.io.validate.build_mesh")
    if mesh.n_faces == 0:
        raise ValueError(f"{what} has no faces; a surface distance needs at least one "
                         "triangle")
    if not np.isfinite(mesh.positions).all():
        raise ValueError(f"{what} has NaN or infinite vertex positions; clean it with "
                         "bench.io.validate.build_mesh")


def _check_samples(samples) -> int:
    if isinstance(samples, bool) or int(samples) != samples or samples < 1:
        raise ValueError(f"samples must be a positive integer, got {samples!r}")
    return int(samples)


def _enclosing_diagonal(a: Mesh, b: Mesh) -> float:
    lo = np.minimum(a.positions.min(axis=0), b.positions.min(axis=0))
    hi = np.maximum(a.positions.max(axis=0), b.positions.max(axis=0))
    return float(np.linalg.norm(hi - lo))


# -- registered metrics ------------------------------------------------------------------

def _distances(original, simplified, ctx) -> dict[str, float]:
    """:func:`hausdorff` of the pair, computed once per ``ctx`` dict (see the module
    docstring)."""
    if ctx is None:
        ctx = {}
    if "hausdorff" not in ctx:
        default = getattr(ctx.get("protocol"), "hausdorff_samples", HAUSDORFF_SAMPLES)
        ctx["hausdorff"] = hausdorff(original, simplified,
                                     samples=ctx.get("hausdorff_samples", default))
    return ctx["hausdorff"]


def _compute_mean(original, simplified, ctx=None) -> float:
    return _distances(original, simplified, ctx)["hausdorff_mean"]


def _compute_max(original, simplified, ctx=None) -> float:
    return _distances(original, simplified, ctx)["symmetric_max"]


HAUSDORFF_MEAN = Metric("hausdorff_mean", "fraction of bbox diagonal", False,
                        "Metro mean surface distance, average of both directions",
                        _compute_mean, requires={"pymeshlab": "pymeshlab>=2023.12"},
                        needs={"hausdorff"})
HAUSDORFF_MAX = Metric("hausdorff_max", "fraction of bbox diagonal", False,
                       "two-sided Hausdorff distance (Metro maximum of both directions)",
                       _compute_max, requires={"pymeshlab": "pymeshlab>=2023.12"},
                       needs={"hausdorff"})
