"""Lindstrom & Turk 2000's texture coordinates on the engine's wedges (§4.1.1).

Where a collapse moves a vertex, each wedge around it gets new UVs from the R^5
oriented volumes of its own texture patch
(:func:`methods.engine.terms.lindstrom_turk.r5_texture_coordinates`), with the patch's
texture scale κ (:func:`_face_kappa`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from methods.corners import corners
from methods.engine.terms.lindstrom_turk import ALPHA_DEG, r5_texture_coordinates, texture_kappa
from methods.engine.wedges import _mapped, _wedge_targets


@njit(cache=True)
def _r5_update(u, v, p, npairs, t_edge, mesh, terms, scratch):
    """Set the new UVs of :func:`_r5_compute`."""
    uv, targets, new_uv = mesh.uv, scratch.r5.targets, scratch.r5.new_uv
    surface = (mesh.P, mesh.F, mesh.FW, uv, mesh.falive, mesh.vhead, mesh.cnext)
    nt = _r5_compute(u, v, p, t_edge, surface, terms.face_kappa,
                     (scratch.wmap_from, scratch.wmap_to, npairs), scratch.r5)
    for ti in range(nt):
        uv[targets[ti], 0] = new_uv[ti, 0]
        uv[targets[ti], 1] = new_uv[ti, 1]


@njit(cache=True)
def _r5_compute(u, v, p, t_edge, surface, face_kappa, pairs, r5):
    """New UVs of every wedge around the vertex merged by collapsing u into v at p
    (``t_edge`` the edge parameter of p) by Lindstrom & Turk 2000's R^5 oriented volumes
    (§4.1.1), each from the triangles of its own texture patch around the edge (the
    removed ones included); a wedge whose patch profile is degenerate falls back to
    interpolation along the edge. ``surface`` is the mesh's (P, F, FW, uv, falive,
    vhead, cnext), ``face_kappa`` each face's κ, ``pairs`` the merged wedge pairs
    (wmap_from, wmap_to, npairs). Fills the targets and new UVs of ``r5``
    (methods.engine.state.R5Scratch); returns how many."""
    P, F, FW, uv, falive, vhead, cnext = surface
    wmap_from, wmap_to, npairs = pairs
    patch, targets, new_uv = r5.patch, r5.targets, r5.new_uv
    tri_a, tri_b, tri_c, uv_a, uv_b, uv_c = patch
    cap = tri_a.shape[0]
    nt = _wedge_targets(u, v, (F, FW, vhead, cnext, falive), pairs, targets)
    for ti in range(nt):
        t = targets[ti]
        n = np.int64(0)  # typed: see docs/maintainers.md, literal arguments
        kappa = 1.0
        for side in range(2):
            x = u if side == 0 else v
            for c in corners(x, vhead, cnext):
                f = c // 3
                on_edge = (F[f, 0] == u or F[f, 1] == u or F[f, 2] == u) and \
                          (F[f, 0] == v or F[f, 1] == v or F[f, 2] == v)
                if falive[f] and not (side == 1 and on_edge) and \
                        _mapped(FW[f, c % 3], wmap_from, wmap_to, npairs) == t:
                    if n == cap:
                        raise ValueError("a texture patch around a collapse has more "
                                         "triangles than PROFILE_CAP (methods.engine.state)")
                    for d in range(3):
                        tri_a[n, d] = P[F[f, 0], d]
                        tri_b[n, d] = P[F[f, 1], d]
                        tri_c[n, d] = P[F[f, 2], d]
                    for d in range(2):
                        uv_a[n, d] = uv[FW[f, 0], d]
                        uv_b[n, d] = uv[FW[f, 1], d]
                        uv_c[n, d] = uv[FW[f, 2], d]
                    kappa = face_kappa[f]
                    n += 1
        res, ok = r5_texture_coordinates(p, patch, n, kappa, ALPHA_DEG)
        if n > 0 and ok:
            new_uv[ti, 0] = res[0]
            new_uv[ti, 1] = res[1]
        else:  # interpolate along the edge when t is a merged pair, else keep
            new_uv[ti, 0] = uv[t, 0]
            new_uv[ti, 1] = uv[t, 1]
            for i in range(npairs):
                if wmap_to[i] == t:
                    a = wmap_from[i]
                    new_uv[ti, 0] = (1.0 - t_edge) * uv[a, 0] + t_edge * uv[t, 0]
                    new_uv[ti, 1] = (1.0 - t_edge) * uv[a, 1] + t_edge * uv[t, 1]
    return nt


def _face_kappa(P, F, FW, uv) -> np.ndarray:
    """(m,) the texture scale κ of each face's texture patch (Lindstrom & Turk 2000
    §4.1.1); a patch is a set of faces connected through shared wedges."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(F)
    n_w = int(FW.max()) + 1
    rows = np.repeat(np.arange(m), 3)
    graph = coo_matrix((np.ones(3 * m), (rows, m + FW.reshape(-1))), shape=(m + n_w, m + n_w))
    _, labels = connected_components(graph, directed=False)
    patch_of_face = np.unique(labels[:m], return_inverse=True)[1].reshape(-1)
    n_patches = int(patch_of_face.max()) + 1
    kappa = texture_kappa(P, F, uv[FW], patch_of_face, n_patches)
    return kappa[patch_of_face]
