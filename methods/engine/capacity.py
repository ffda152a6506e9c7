"""Whether a collapse fits the engine's fixed workspaces (the capacity rule).

The kernels work in scratch arrays of fixed size, each a named constant:
:data:`~methods.engine.state.WEDGE_TARGETS_CAP` distinct wedges of the merged vertex,
:data:`~methods.engine.state.PROFILE_CAP` triangles of a texture patch (R^5 UVs),
:data:`~methods.engine.state.LOG_CHANGED_HEADROOM` faces renamed by one collapse, and
with a rendered term :data:`methods.imaging.region.MAX_RING` vertices whose normal
changes, :data:`~methods.imaging.region.AFFECTED_CAP` faces re-rendered and
:data:`~methods.imaging.rows.NORMAL_FACES_CAP` faces around one vertex. Ordinary
meshes never come near them, but a UV sphere's pole is one position shared by a render
vertex per segment (a hundred wedges and faces around one welded vertex).

A collapse that would exceed one of them is not evaluated: its cost is infinite and the
loop rejects it under the rule ``capacity`` (counted like every other rule). Such a
fan shrinks as its neighbours collapse, and the collapse is tried again when an
endpoint changes. A result therefore never depends on a capacity being large enough,
only on this rule; and a mesh whose collapses fit (every mesh that simplified before
the rule existed) gets the same collapses as before, because :func:`over_capacity`
answers False without looking further while the merged vertex has at most
``WEDGE_TARGETS_CAP`` corners (and the ring fits, with a rendered term).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from methods.corners import corners
from methods.engine.state import LOG_CHANGED_HEADROOM, PROFILE_CAP, WEDGE_TARGETS_CAP, renders
from methods.engine.wedges import _mapped, _wedge_pairs
from methods.imaging.region import AFFECTED_CAP, MAX_RING
from methods.imaging.rows import NORMAL_FACES_CAP


@njit(cache=True, _nrt=False)
def live_corners(x, vhead, cnext, falive):
    """How many live faces hold vertex ``x``."""
    n = 0
    for c in corners(x, vhead, cnext):
        if falive[c // 3]:
            n += 1
    return n


@njit(cache=True)
def merged_wedges(a, b, mesh, scratch):
    """The number of distinct wedges the vertex merged from ``a`` and ``b`` would have
    (their corners' wedges after the edge's wedge pairs merge), without a capacity: for
    the rare large fans only (it allocates)."""
    F, FW, vhead, cnext, falive = mesh.F, mesh.FW, mesh.vhead, mesh.cnext, mesh.falive
    gfrom, gto = scratch.wq.gfrom, scratch.wq.gto
    npairs = _wedge_pairs(a, b, (F, FW, vhead, cnext, falive), scratch.efaces, gfrom, gto)
    n = live_corners(a, vhead, cnext, falive) + live_corners(b, vhead, cnext, falive)
    wedges = np.empty(n, np.int64)
    k = 0
    for side in range(2):
        for c in corners(a if side == 0 else b, vhead, cnext):
            f = c // 3
            if falive[f]:
                wedges[k] = _mapped(FW[f, c % 3], gfrom, gto, npairs)
                k += 1
    return np.unique(wedges[:k]).shape[0]


@njit(cache=True, _nrt=False)
def _ring_over_capacity(a, b, mesh, scratch):
    """With a rendered term: True when the vertices of the faces around ``a`` and ``b``
    (those whose normals a collapse changes) are more than ``MAX_RING``, one of them has
    more than ``NORMAL_FACES_CAP`` faces, or their faces together exceed
    ``AFFECTED_CAP`` (an upper bound of the faces one collapse re-renders)."""
    F, vhead, cnext, falive, mark, tick = (mesh.F, mesh.vhead, mesh.cnext, mesh.falive,
                                           scratch.mark, scratch.tick)
    tick[0] += 1
    t = tick[0]
    ring = 0
    faces = 0
    for side in range(2):
        for c in corners(a if side == 0 else b, vhead, cnext):
            f = c // 3
            if falive[f]:
                for j in range(3):
                    x = F[f, j]
                    if mark[x] != t:
                        mark[x] = t
                        ring += 1
                        n = live_corners(x, vhead, cnext, falive)
                        faces += n
                        if ring > MAX_RING or n > NORMAL_FACES_CAP or faces > AFFECTED_CAP:
                            return True
    return False


@njit(cache=True, _nrt=False)
def _verdict(a, b, mesh, rules):
    """:func:`over_capacity` without the rare count of merged wedges: 0 fits, 1 over,
    2 the merged wedges must be counted. Compiled without reference counting (it
    allocates nothing), as it runs for every candidate."""
    corners = (live_corners(a, mesh.vhead, mesh.cnext, mesh.falive)
               + live_corners(b, mesh.vhead, mesh.cnext, mesh.falive))
    if corners <= WEDGE_TARGETS_CAP:  # every workspace below holds at least this many
        return 0
    if corners > LOG_CHANGED_HEADROOM or (renders(rules.weights) and corners > NORMAL_FACES_CAP):
        return 1
    if rules.use_r5 and corners > PROFILE_CAP:
        return 1
    return 2


@njit(cache=True, inline="always")
def over_capacity(a, b, mesh, rules, scratch):
    """True when collapsing edge (a, b) would exceed a workspace of the engine (see the
    module's docstring); ``mesh``, ``rules`` and ``scratch`` are the structures of
    :mod:`methods.engine.state`. Writes only scratch."""
    if renders(rules.weights) and _ring_over_capacity(a, b, mesh, scratch):
        return True
    verdict = _verdict(a, b, mesh, rules)
    if verdict == 2:
        return merged_wedges(a, b, mesh, scratch) > WEDGE_TARGETS_CAP
    return verdict == 1
