"""Parts and materials a result lost: ``components_lost``, ``components_lost_area`` and
``materials_lost``.

A game asset is many parts and materials; a wheel or a decal that vanishes is seen
from every distance, though it moves the image error little. These metrics say what
went: the connected components of the original (welded, positions merged) and its
materials (:func:`bench.io.atlas.face_materials`; a mesh without a material table is
one material) of which no face is left.

Results do not carry face ids back to the original (most methods build new meshes), so
the correspondence is geometric: each face of the result is given to the original face
nearest to its centroid (among four points per original face: its centroid and the
midpoints between the centroid and each corner), and each connected component of the
result to the original component it lies closest to on average (:func:`parts_lost`).
A component or material that nothing of the result was given to is lost. A part
simplified in place stays near its own surface; one that is gone leaves nothing there.
Parts closer to each other than the result's own error can be confused, as any
geometric correspondence would.
"""

from __future__ import annotations

import numpy as np

from bench.core.mesh import Mesh, face_areas
from bench.core.metric import Metric
from bench.io.atlas import face_materials


def welded_components(mesh: Mesh) -> np.ndarray:
    """(m,) int: the connected component of each face in the welded mesh (faces that
    share a position are connected), numbered in order of first face."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    w = mesh.welded
    m, nv = mesh.n_faces, w.n_vertices
    rows = np.repeat(np.arange(m), 3)
    graph = coo_matrix((np.ones(3 * m), (rows, m + w.faces.reshape(-1).astype(np.int64))),
                       shape=(m + nv, m + nv))
    _, labels = connected_components(graph, directed=False)
    _, first, inverse = np.unique(labels[:m], return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    return rank[inverse.reshape(-1)]


def face_samples(original: Mesh):
    """(points (4m, 3), the face of ``original`` each lies on (4m,), a KD-tree of the
    points): per face its centroid and the midpoints between the centroid and each
    corner."""
    from scipy.spatial import cKDTree

    corners = original.positions[original.faces]            # (m, 3, 3)
    centroid = corners.mean(axis=1)
    points = np.concatenate([centroid[:, None], (corners + centroid[:, None]) / 2],
                            axis=1).reshape(-1, 3)
    return points, np.repeat(np.arange(original.n_faces), 4), cKDTree(points)


def nearest_original_faces(original: Mesh, simplified: Mesh, samples=None) -> np.ndarray:
    """(k,) int: for each face of ``simplified``, the face of ``original`` nearest to its
    centroid (see the module's docstring); ``samples``: :func:`face_samples` of
    ``original``, when the caller has them."""
    if simplified.n_faces == 0:
        return np.zeros(0, np.int64)
    _, owner, tree = samples or face_samples(original)
    _, nearest = tree.query(simplified.positions[simplified.faces].mean(axis=1))
    return owner[nearest]


def parts_lost(original: Mesh, simplified: Mesh) -> dict:
    """``{"components": lost components, "area": their share of the original's area,
    "materials": lost materials}``.

    A component of the original is kept when a face of the result is nearest to it
    (:func:`nearest_original_faces`) or when a connected component of the result is
    matched with it (:func:`_matched_components`: a part simplified to a few faces can
    lie nearer to a larger neighbour's faces than to its own, face by face, but the
    neighbour is matched with its own simplified self). A material is kept when a face
    of the result is nearest to one of its faces.

    Returns the counts as ints and the area share as a float."""
    components = welded_components(original)
    materials = face_materials(original)
    if materials is None:
        materials = np.zeros(original.n_faces, np.int64)
    samples = face_samples(original)
    nearest = nearest_original_faces(original, simplified, samples)
    kept_components = set(np.unique(components[nearest]).tolist())
    if len(kept_components) <= int(components.max()):  # some not yet found: match them
        kept_components |= _matched_components(samples, components, simplified)
    lost_c = np.setdiff1d(np.unique(components), np.array(sorted(kept_components), np.int64))
    lost_m = np.setdiff1d(np.unique(materials), np.unique(materials[nearest]))
    areas = face_areas(original.positions, original.faces)
    total = float(areas.sum())
    share = float(areas[np.isin(components, lost_c)].sum()) / total if total > 0 else 0.0
    return {"components": len(lost_c), "area": share, "materials": len(lost_m)}


def _matched_components(samples, components: np.ndarray, simplified: Mesh) -> set:
    """The original components matched one to one with the connected components of
    ``simplified`` (:func:`scipy.optimize.linear_sum_assignment` over the mean distance
    from a result component's vertices and face centroids to an original component's
    sample points; the candidates of a result component are the owners of the
    :data:`CANDIDATES` samples nearest to each of its points)."""
    from scipy.optimize import linear_sum_assignment
    from scipy.spatial import cKDTree

    if simplified.n_faces == 0:
        return set()
    sample_points, face, everything = samples
    owner = components[face]
    trees: dict = {}
    result = welded_components(simplified)
    n_result, n_original = int(result.max()) + 1, int(components.max()) + 1
    cost = np.full((n_result, n_original), _UNMATCHED)
    for r in range(n_result):
        faces = simplified.faces[result == r]
        points = np.concatenate([simplified.positions[np.unique(faces)],
                                 simplified.positions[faces].mean(axis=1)])
        _, near = everything.query(points, k=min(CANDIDATES, len(sample_points)))
        for c in np.unique(owner[near]):
            if c not in trees:
                trees[c] = cKDTree(sample_points[owner == c])
            cost[r, c] = float(trees[c].query(points)[0].mean())
    rows, cols = linear_sum_assignment(cost)
    return {int(c) for r, c in zip(rows, cols) if cost[r, c] < _UNMATCHED}


#: Nearest samples per point whose components are a result component's candidates.
CANDIDATES = 16
_UNMATCHED = 1e300


def _lost(key: str):
    def compute(original: Mesh, simplified: Mesh, ctx) -> float:
        return float(ctx["parts"][key])
    return compute


COMPONENTS_LOST = Metric(
    "components_lost", "components", False,
    "connected components of the original with no face left", _lost("components"),
    needs=frozenset({"parts"}))
COMPONENTS_LOST_AREA = Metric(
    "components_lost_area", "fraction of area", False,
    "the lost components' share of the original's surface area", _lost("area"),
    needs=frozenset({"parts"}))
MATERIALS_LOST = Metric(
    "materials_lost", "materials", False,
    "materials of the original with no face left", _lost("materials"),
    needs=frozenset({"parts"}))
