"""Parts and materials are kept (the rule "last faces of a part").

An asset as engines ship it is many parts (a vehicle's wheels, a kit's props) and
many materials. Edge collapses never join two connected components, but they can
remove a small one whole (an open part of two triangles goes with one collapse), and a
material's few faces can disappear inside a larger part. Either loss is visible from
every distance, whatever its cost says.

With ``Policy.keep_parts`` every face belongs to a *group*: the pair (connected
component of the welded mesh, material). The loop keeps each group's live face count
and rejects a collapse that would empty a group; the rejection is counted as "last
faces of a part". A part can still shrink to the smallest shape the other rules allow
(a closed part to a tetrahedron, an open one to a triangle). When the target cannot be
reached without dropping parts, the run stops above it and says so (the stop reason
lists this rule's rejections): parts are not dropped by size.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from methods.engine.topology import _edge_faces


def face_groups(F: np.ndarray, nv: int, materials: np.ndarray | None):
    """(group of each face (m,) int64, live faces of each group (g,) int64): the groups
    are the distinct (welded component, material) pairs, numbered in order of first
    face. ``F`` (m, 3) welded faces; ``materials`` (m,) material ids or None."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(F)
    if m == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    rows = np.repeat(np.arange(m), 3)
    graph = coo_matrix((np.ones(3 * m), (rows, m + F.reshape(-1))), shape=(m + nv, m + nv))
    _, labels = connected_components(graph, directed=False)
    component = labels[:m].astype(np.int64)
    material = np.zeros(m, np.int64) if materials is None else np.asarray(materials, np.int64)
    pairs = component * (int(material.max()) + 1) + material
    _, first, group = np.unique(pairs, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")  # number groups by first face
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    group = rank[group.reshape(-1)].astype(np.int64)
    return group, np.bincount(group, minlength=len(order)).astype(np.int64)


@njit(cache=True, _nrt=False)
def empties_a_part(u, v, mesh, scratch):
    """True when removing the faces of edge (u, v) would leave one of their groups with
    no live face (:func:`face_groups`)."""
    k = _edge_faces(u, v, mesh.F, mesh.vhead, mesh.cnext, mesh.falive, scratch.efaces)
    for i in range(min(k, scratch.efaces.shape[0])):
        g = mesh.group[scratch.efaces[i]]
        removed = 0
        for j in range(min(k, scratch.efaces.shape[0])):
            if mesh.group[scratch.efaces[j]] == g:
                removed += 1
        if mesh.group_live[g] <= removed:
            return True
    return False


@njit(cache=True, _nrt=False)
def faces_removed(mesh, faces, n):
    """Count the removal of ``faces[:n]`` in their groups' live faces."""
    for i in range(n):
        mesh.group_live[mesh.group[faces[i]]] -= 1
