"""One edge collapse on the engine's arrays: faces removed, corners renamed, wedges
merged with their new attributes, quadrics summed."""

from __future__ import annotations

import numpy as np
from numba import njit

from methods.corners import corners
from methods.engine.state import QUADRIC_SIZE, WEDGE_QUADRIC_SIZE, WEDGE_TARGETS_CAP
from methods.engine.terms.quadric import _uv_minimiser
from methods.engine.terms.r5 import _r5_update
from methods.engine.topology import _compact, _edge_faces, _third
from methods.engine.wedges import (
    _count_kinds,
    _edge_parameter,
    _uv_correction,
    _wedge_pairs,
    _wedge_targets,
)


@njit(cache=True)
def _collapse(u, v, p, mesh, rules, terms, scratch, record):
    """Merge u into v at p. Returns (faces removed, changed count, wedge pairs, merged
    wedges) and fills ``scratch.efaces`` with the removed faces, ``scratch.wmap_from``/
    ``wmap_to`` with the wedge pairs and ``scratch.wq.targets`` with the merged vertex's
    distinct wedges. ``record`` is (log_changed, n_changed, kinds): the faces whose
    corner moved are appended to ``log_changed`` from ``n_changed``; ``kinds`` counts
    twin and stranded-wedge collapses (:func:`_count_kinds`). ``rules.uv_fix`` applies
    :func:`_uv_correction` last."""
    log_changed, n_changed, kinds = record
    P, Q, F, FW, falive, vhead, cnext, valive, wedge_vertex = (
        mesh.P, mesh.Q, mesh.F, mesh.FW, mesh.falive, mesh.vhead, mesh.cnext, mesh.valive,
        mesh.wedge_vertex)
    efaces, wmap_from, wmap_to = scratch.efaces, scratch.wmap_from, scratch.wmap_to
    # Pair the wedges of u and v across each removed face (same side of the edge).
    fan = (F, FW, vhead, cnext, falive)
    npairs = _wedge_pairs(u, v, fan, efaces, wmap_from, wmap_to)
    _count_kinds(u, v, fan, (wmap_from, wmap_to, npairs), kinds)
    # New texture coordinates of the merged wedges (before the topology changes).
    _merge_uvs(u, v, p, npairs, mesh, rules, terms, scratch)
    nt = _wedge_targets(u, v, fan, (wmap_from, wmap_to, npairs), scratch.wq.targets)
    k = _edge_faces(u, v, F, vhead, cnext, falive, efaces)
    for i in range(k):
        falive[efaces[i]] = False
    for i in range(k):  # the apexes of removed faces hold dead corners now
        _compact(_third(F, efaces[i], u, v), vhead, cnext, falive)
    # Rename u to v in its surviving faces; remap paired wedges; move u's other wedges.
    last = -1
    for c in corners(u, vhead, cnext):
        f = c // 3
        if falive[f]:
            j = c % 3
            F[f, j] = v
            w = FW[f, j]
            for i in range(npairs):
                if wmap_from[i] == w:
                    w = wmap_to[i]
                    break
            FW[f, j] = w
            wedge_vertex[w] = v
            log_changed[n_changed] = f
            n_changed += 1
        last = c
    if last != -1:  # append u's corner list to v's
        cnext[last] = vhead[v]
        vhead[v] = vhead[u]
    vhead[u] = -1
    valive[u] = False
    P[v] = p
    for i in range(QUADRIC_SIZE):
        Q[v, i] += Q[u, i]
    _compact(v, vhead, cnext, falive)
    return k, n_changed, npairs, nt


@njit(cache=True)
def _merge_uvs(u, v, p, npairs, mesh, rules, terms, scratch):
    """The UVs of the wedges merged by collapsing u into v at p (``npairs`` pairs in
    ``scratch.wmap_from``/``wmap_to``): Garland & Heckbert 1998's minimiser of the summed
    wedge quadrics, Lindstrom & Turk 2000's R^5 volumes, or interpolation along the edge;
    then González et al. 2008's correction (``rules.uv_fix``) where it applies."""
    P, F, FW, falive, vhead, cnext, uv, WQ = (mesh.P, mesh.F, mesh.FW, mesh.falive,
                                              mesh.vhead, mesh.cnext, mesh.uv, mesh.WQ)
    has_uv, use_r5, uv_fix = rules.has_uv, rules.use_r5, rules.uv_fix
    wmap_from, wmap_to = scratch.wmap_from, scratch.wmap_to
    n_fix = 0
    cap = WEDGE_TARGETS_CAP if uv_fix else 0  # own scratch: the UV updates use r5 and wq
    fix_t = np.empty(cap, np.int64)
    fix_uv = np.empty((cap, 2))
    fix_m = np.zeros(cap, np.int64)
    if has_uv and uv_fix:
        n_fix = _uv_correction(u, v, p, mesh, (wmap_from, wmap_to, npairs),
                               (fix_t, fix_uv, fix_m))
    t = _edge_parameter(u, v, p, P)  # for merged attributes
    if has_uv and WQ.shape[0] > 1:  # Garland-Heckbert 1998: merge, then minimise UVs
        targets = scratch.wq.targets
        nt = _wedge_targets(u, v, (F, FW, vhead, cnext, falive), (wmap_from, wmap_to, npairs),
                            targets)
        for i in range(npairs):
            for j in range(WEDGE_QUADRIC_SIZE):
                WQ[wmap_to[i], j] += WQ[wmap_from[i], j]
        best = np.empty(2)
        for i in range(nt):
            _uv_minimiser(WQ[targets[i]], p, uv[targets[i]], best)
            uv[targets[i], 0] = best[0]
            uv[targets[i], 1] = best[1]
    elif has_uv and use_r5:
        _r5_update(u, v, p, npairs, t, mesh, terms, scratch)
    elif has_uv:
        for i in range(npairs):
            a, b = wmap_from[i], wmap_to[i]
            uv[b, 0] = (1.0 - t) * uv[a, 0] + t * uv[b, 0]
            uv[b, 1] = (1.0 - t) * uv[a, 1] + t * uv[b, 1]
    for i in range(n_fix):  # González et al. 2008's correction replaces the above
        if fix_m[i] == 1:
            uv[fix_t[i], 0] = fix_uv[i, 0]
            uv[fix_t[i], 1] = fix_uv[i, 1]
