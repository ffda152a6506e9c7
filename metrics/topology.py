"""Counting metrics: the size and topology of a simplified mesh (L&T 2000, Plate 1 d–f).

Seam cracks
-----------
A crack is the result's boundary where the original had none: a seam opened by a
method that works on render vertices (``qslim`` moves the two copies of a seam vertex
apart, leaving a sliver gap), or a tear. A boundary of the result that descends from the
original's boundary — a hole, however simplified — is not one. Vertices move and
external methods report no provenance, so this is decided geometrically, edge by edge
(the metric's unit is edges), on the welded topology. A boundary edge of the result is a
crack unless

1. both its ends lie on the original's boundary: within :data:`RIM_BAND` times the
   longest result edge at that end of the original's boundary edges, and
2. it is not one side of an opened seam: it and another boundary edge of the result
   both lie on a seam of the original (their midpoints within :data:`SIDE_GAP` times
   their length of its seam edges) and run alongside each other (directions within
   :data:`SIDE_COS`, its midpoint within the same gap of the other edge).

An edge of the original's boundary that the result kept unchanged (same end positions)
is never a crack, so a result equal to its original has none. Without a boundary in the
original every boundary edge of the result is a crack; a closed result has none.

Why the ends and not the midpoint: a simplified hole's chords cut across the surface
near the hole, a few thousandths of the diagonal off the original boundary, as far as
cracks lie, and where a seam ends at the hole a chord's midpoint can lie nearer the seam
than the hole (the rule this one replaces, nearest-feature of the midpoint, counted
such chords as cracks on ``bunny-textured``: 5 of 17 boundary edges for
``image-driven`` at 100 faces). The chord's ends stay on the hole.

Why a band of one edge length: the placement of each collapse moves the vertices of a
simplified hole off it, by up to two thirds of the longest result edge at them (on
``bunny-textured``, over the methods that keep seams closed at budgets from 50 to 6,400
faces: at most 0.66, ``image-driven`` at 100 faces, and 0.71 for ``meshopt-sloppy``'s
grid clustering at 1,600); a vertex of an opened seam lies on the seam, more than an
edge from any hole except near where the seam meets one. There, clause 2 recovers the seam's first and last edges while its two sides are still close; a
simplified hole's boundary is a single chain with nothing running alongside it on the
seam. (Asking only the edge itself to lie on the seam is not enough: a hole squashed to
a sliver triangle whose long edge crosses a seam has its two short edges alongside it,
as ``memoryless`` leaves on ``bunny-textured`` at 50 faces. The gap has little margin:
at 0.15 of the edge length, hole edges count in 5 of the results measured there, from
``memoryless`` and ``quadric`` at 50 faces to ``image-driven`` at 1,000.)

What geometry alone cannot decide: the two sides of a seam opened wider than
:data:`SIDE_GAP` within an edge of a hole look like a notch of the hole dragged along the
seam, and are counted as the hole's; so is a tear within an edge of the boundary.
Where edges grow as long as the holes are far apart, that band covers much of the
surface around them: ``qslim`` on ``bunny-textured``, whose five holes lie close
together in its base, counts 69 cracks at 100 faces by this rule and 93 by the one
before, 557 and 577 at 1,000 faces. Conversely, a hole's vertex moved more than an edge
off it makes its edges cracks.
"""

from __future__ import annotations

import numpy as np

from bench.core.mesh import Mesh, Welded
from bench.core.metric import Metric

__all__ = [
    "BOUNDARY_EDGES",
    "FACES",
    "NON_MANIFOLD_EDGES",
    "RENDER_VERTICES",
    "RIM_BAND",
    "SEAM_CRACKS",
    "SIDE_COS",
    "SIDE_GAP",
    "WELDED_VERTICES",
    "counts",
    "crack_edges",
    "seam_cracks",
]

#: How far from the original's boundary a result vertex may lie and still be on it, in
#: units of the longest result edge at the vertex (see the module docstring).
RIM_BAND = 1.0
#: Two boundary edges are the sides of one opened seam when both midpoints lie within
#: this fraction of their length of the original's seams, that of one as near the other ...
SIDE_GAP = 0.1
#: ... and their directions are within acos(SIDE_COS) (about 26°) of each other,
#: either way round (a result's orientation is not trusted).
SIDE_COS = 0.9


def seam_cracks(original: Mesh, simplified: Mesh) -> int:
    """Number of boundary edges of ``simplified`` where ``original`` had no boundary
    (opened seams, tears; see the module docstring)."""
    return len(crack_edges(original, simplified))


def crack_edges(original: Mesh, simplified: Mesh) -> np.ndarray:
    """The cracks of ``simplified``: its welded boundary edges that do not descend from
    the boundary of ``original`` (see the module docstring).

    Returns
    -------
    ndarray of shape (c, 2) int32
        Rows of ``simplified.welded.edges``.
    """
    w, ow = simplified.welded, original.welded
    edges = w.edges[w.boundary]
    if len(edges) == 0 or not ow.boundary.any():
        return edges
    rim = ow.positions[ow.edges[ow.boundary]]
    ends = np.unique(edges)
    on_rim = np.zeros(w.n_vertices, bool)
    on_rim[ends] = (_distance_to_segments(w.positions[ends], rim)
                    <= RIM_BAND * _longest_edge(w)[ends])
    crack = ~(on_rim[edges[:, 0]] & on_rim[edges[:, 1]])

    seams = ow.positions[ow.edges[ow.seam]]
    if len(seams) and not crack.all():
        a, b = w.positions[edges[:, 0]], w.positions[edges[:, 1]]
        length = np.linalg.norm(b - a, axis=1)
        gap = SIDE_GAP * length
        on_seam = (length > 0) & (_distance_to_segments((a + b) / 2, seams) <= gap)
        ask = np.flatnonzero(~crack & on_seam)
        crack[ask[_has_side_alongside(ask, a, b, length, gap, on_seam)]] = True

    crack &= ~_kept_from(edges, w.positions, ow)
    return edges[crack]


def _longest_edge(w: Welded) -> np.ndarray:
    """ndarray of shape (k,): length of the longest welded edge at each vertex."""
    length = np.linalg.norm(w.positions[w.edges[:, 0]] - w.positions[w.edges[:, 1]], axis=1)
    longest = np.zeros(w.n_vertices)
    for end in (0, 1):
        np.maximum.at(longest, w.edges[:, end], length)
    return longest


def _has_side_alongside(ask: np.ndarray, a: np.ndarray, b: np.ndarray, length: np.ndarray,
                        gap: np.ndarray, on_seam: np.ndarray) -> np.ndarray:
    """For each boundary edge ``ask[i]`` (ends ``a``, ``b``), whether another boundary
    edge that is ``on_seam`` runs alongside it: direction within :data:`SIDE_COS` and
    the asked edge's midpoint within ``gap`` of it. Exact: a segment within ``gap`` of a
    point has its midpoint within ``gap`` + half the longest segment of it."""
    from scipy.spatial import cKDTree

    if len(ask) == 0:
        return np.zeros(0, bool)
    mid = (a + b) / 2
    radius = gap[ask] + length.max() / 2
    near = cKDTree(mid).query_ball_point(mid[ask], radius)
    i = np.repeat(np.arange(len(ask)), [len(n) for n in near])
    j = np.fromiter((k for n in near for k in n), dtype=np.int64, count=len(i))
    e = ask[i]
    keep = (j != e) & on_seam[j]
    i, j, e = i[keep], j[keep], e[keep]
    cos = np.einsum("pj,pj->p", b[e] - a[e], b[j] - a[j]) / (length[e] * length[j])
    ab = b[j] - a[j]
    t = np.clip(np.einsum("pj,pj->p", mid[e] - a[j], ab) / length[j] ** 2, 0, 1)
    distance = np.linalg.norm(mid[e] - (a[j] + t[:, None] * ab), axis=1)
    alongside = (np.abs(cos) >= SIDE_COS) & (distance <= gap[e])
    found = np.zeros(len(ask), bool)
    found[i[alongside]] = True
    return found


def _kept_from(edges: np.ndarray, positions: np.ndarray, ow: Welded) -> np.ndarray:
    """Which ``edges`` (ends at ``positions``) are boundary edges of the original kept
    unchanged: their two end positions bit-equal to those of one of its boundary edges."""
    original = set(map(bytes, _position_keys(ow.positions, ow.edges[ow.boundary])))
    return np.array([bytes(k) in original for k in _position_keys(positions, edges)], bool)


def _position_keys(positions: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """ndarray of shape (e, 6): each edge's end positions, the lexicographically smaller
    end first, so an edge has one key whichever way it is stored (-0.0 made 0.0, as
    welding merges them)."""
    p, q = positions[edges[:, 0]] + 0.0, positions[edges[:, 1]] + 0.0
    first_differs = np.argmax(p != q, axis=1)
    rows = np.arange(len(edges))
    swap = q[rows, first_differs] < p[rows, first_differs]
    return np.ascontiguousarray(np.where(swap[:, None], np.hstack([q, p]), np.hstack([p, q])))


def _distance_to_segments(points: np.ndarray, segments: np.ndarray, k: int = 8) -> np.ndarray:
    """Distance from each point (p, 3) to the nearest of the segments (s, 2, 3), exact
    over the k segments whose midpoints are nearest (the boundary of a mesh is a set of
    short segments, so the nearest one is among them)."""
    from scipy.spatial import cKDTree

    if len(segments) == 0:
        return np.full(len(points), np.inf)
    a, b = segments[:, 0], segments[:, 1]
    k = min(k, len(segments))
    _, idx = cKDTree((a + b) / 2).query(points, k=k)
    idx = idx.reshape(len(points), k)
    pa, ab = points[:, None, :] - a[idx], (b - a)[idx]
    denom = np.einsum("pkj,pkj->pk", ab, ab)
    t = np.clip(np.einsum("pkj,pkj->pk", pa, ab) / np.where(denom > 0, denom, 1), 0, 1)
    return np.linalg.norm(pa - t[..., None] * ab, axis=2).min(axis=1)


def counts(original: Mesh, simplified: Mesh) -> dict:
    """All counting metrics as a dict of ints."""
    summary = simplified.summary()
    keys = ("faces", "render_vertices", "welded_vertices", "boundary_edges",
            "non_manifold_edges")
    return {**{k: summary[k] for k in keys}, "seam_cracks": seam_cracks(original, simplified)}


def _count(key: str):
    """``compute`` of the count ``key``: read from ``ctx["topology"]`` (the protocol's
    :func:`counts`, computed once for all six metrics) or counted when absent."""
    def compute(original: Mesh, simplified: Mesh, ctx=None) -> int:
        ctx = ctx or {}
        found = ctx["topology"] if "topology" in ctx else counts(original, simplified)
        return int(found[key])

    return compute


FACES = Metric("faces", "faces", None, "triangles in the result", _count("faces"),
               needs={"topology"})
RENDER_VERTICES = Metric("render_vertices", "vertices", None,
                         "vertices as a GPU stores them (one per distinct attribute set)",
                         _count("render_vertices"), needs={"topology"})
WELDED_VERTICES = Metric("welded_vertices", "vertices", None,
                         "vertices with equal positions merged", _count("welded_vertices"),
                         needs={"topology"})
BOUNDARY_EDGES = Metric("boundary_edges", "edges", False,
                        "welded edges with one incident face (holes and cracks show here)",
                        _count("boundary_edges"), needs={"topology"})
SEAM_CRACKS = Metric("seam_cracks", "edges", False,
                     "boundary edges of the result where the original had none (opened "
                     "seams, tears)",
                     _count("seam_cracks"), needs={"topology"})
NON_MANIFOLD_EDGES = Metric("non_manifold_edges", "edges", False,
                            "welded edges with more than two incident faces",
                            _count("non_manifold_edges"), needs={"topology"})
