"""The corner lists that every kernel of the engine, the image term and the
Multi-Triangulation walks.

A mesh of m faces has 3m corners, corner ``c`` being vertex ``F[c // 3, c % 3]``. Each
vertex's corners form a singly linked list: ``vhead[x]`` is its first corner (-1: none)
and ``cnext[c]`` the corner after ``c`` (-1: the last). A collapse appends the removed
vertex's list to the kept one's; a face that dies stays in the lists (its ``falive`` is
False) until the engine compacts them.

Walk a vertex's corners with :func:`corners`::

    for c in corners(x, vhead, cnext):
        f = c // 3
        if falive[f]:
            ...

numba compiles the generator into its caller's loop (as fast as the hand-written
``while c != -1: ...; c = cnext[c]``; it reads ``cnext[c]`` after the loop's body, as
that loop did, so a body may rewrite the face of ``c`` but not ``cnext[c]``).

:func:`corners` is not cached on its own (``cache=False``): numba cannot load a cached
generator into a function it compiles later (numba issues #8679 and #8778: a
``KeyError`` on the generator's type in the second process). Its callers are cached, and
their cache holds its code.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from bench.core.numba_cache import lock_cache_writes

lock_cache_writes()  # several processes compile at once (bench.core.numba_cache)

__all__ = ["corner_lists", "corners"]


@njit(cache=False, _nrt=False)
def corners(x, vhead, cnext):
    """Each corner of vertex ``x``, in list order, dead faces' corners included."""
    c = vhead[x]
    while c != -1:
        yield c
        c = cnext[c]


@njit(cache=True)
def corner_lists(F, nv):
    """vhead (nv,) and cnext (3m,) int64 linking each vertex's corners, in corner order
    (built from the last corner back, each put in front of its vertex's list)."""
    m = F.shape[0]
    vhead = np.full(nv, -1, np.int64)
    cnext = np.full(3 * m, -1, np.int64)
    for corner in range(3 * m - 1, -1, -1):
        x = F[corner // 3, corner % 3]
        cnext[corner] = vhead[x]
        vhead[x] = corner
    return vhead, cnext
