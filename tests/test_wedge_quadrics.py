"""Wedges across collapses: Garland & Heckbert 1998 wedge quadrics against a brute-force
sum over the original faces, at hand-picked collapses between ends with unequal wedge
counts and over random valid collapse sequences, and UVs interpolated along the edge.
(``tests/test_engine.py`` replays the engine's own run on a textured box against the
same kind of sums and checks that the box keeps its corners.)

The oracle is built here in NumPy, independently of the engine: each face's 5-D quadric
(area × squared distance to the plane its corners span in (x, y, z, w·u, w·v)) from a
QR basis, and for every original wedge the wedge that holds it now, followed across
each collapse from the faces of the collapsed edge. A wedge's quadric must be the sum,
over the original corners whose wedges it holds, of their face's quadric; a wedge with
no partner across the edge keeps what it holds (and so its quadric).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.catalog.gamemodels import make_crate
from methods.engine.collapse import _collapse
from methods.engine.cost import _evaluate
from methods.engine.loop import _check_candidate
from methods.engine.policy import VALID, Policy
from methods.engine.simplify import _prepare, _quadrics, _rules, _terms
from methods.engine.state import N_KINDS, Images, new_scratch
from methods.engine.terms.quadric import _edge_quadric
from methods.imaging.state import dummy_state

TEXTURE_WEIGHT = 1.0
POLICY = Policy(texture_weight=TEXTURE_WEIGHT)


# -- the oracle ----------------------------------------------------------------------------

def face_quadric5(P, uv, weight):
    """(6, 6) homogeneous quadric over plain (x, y, z, u, v, 1) of one face with corner
    positions ``P`` (3, 3) and UVs ``uv`` (3, 2): its area times the squared distance of
    (x, y, z, w·u, w·v) to the plane through the lifted corners."""
    X = np.column_stack([P, weight * uv])
    basis = np.linalg.qr((X[1:] - X[0]).T)[0]  # (5, 2) orthonormal
    A = np.eye(5) - basis @ basis.T
    H = np.zeros((6, 6))
    H[:5, :5] = A
    H[:5, 5] = H[5, :5] = -A @ X[0]
    H[5, 5] = X[0] @ A @ X[0]
    S = np.diag([1.0, 1.0, 1.0, weight, weight, 1.0])
    area = 0.5 * np.linalg.norm(np.cross(P[1] - P[0], P[2] - P[0]))
    return area * (S @ H @ S)


def unpack5(row):
    """The engine's 31 floats (A 5x5, b 5, c) as a (6, 6) homogeneous matrix."""
    H = np.zeros((6, 6))
    H[:5, :5] = row[:25].reshape(5, 5)
    H[:5, 5] = H[5, :5] = row[25:30]
    H[5, 5] = row[30]
    return H


def unpack3(q):
    """The engine's 10-float vertex quadric as a (4, 4) homogeneous matrix."""
    return np.array([[q[0], q[1], q[2], q[3]], [q[1], q[4], q[5], q[6]],
                     [q[2], q[5], q[7], q[8]], [q[3], q[6], q[8], q[9]]])


def reduced(H):
    """The (4, 4) quadric over (x, y, z, 1) of H minimised over (u, v)."""
    keep, uv = [0, 1, 2, 5], [3, 4]
    return (H[np.ix_(keep, keep)]
            - H[np.ix_(keep, uv)] @ np.linalg.solve(H[np.ix_(uv, uv)], H[np.ix_(uv, keep)]))


def uv_minimiser(H, p):
    """The (u, v) minimising H at position p."""
    return -np.linalg.solve(H[3:5, 3:5], H[3:5, :3] @ p + H[3:5, 5])


class Oracle:
    """For every original wedge, the wedge that holds it now; and the brute-force sums."""

    def __init__(self, P, F, FW, uv, weight):
        self.corner_quadric = np.stack([face_quadric5(P[F[f]], uv[FW[f]], weight)
                                        for f in range(len(F))])
        self.FW0 = FW.copy()
        self.owner = np.arange(int(FW.max()) + 1)

    def quadrics(self):
        """(n_wedges, 6, 6): for each wedge, the sum over the original corners it holds
        of their face's quadric."""
        total = np.zeros((len(self.owner), 6, 6))
        np.add.at(total, self.owner[self.FW0].reshape(-1),
                  np.repeat(self.corner_quadric, 3, axis=0))
        return total

    def groups(self, u, v, F, FW, falive):
        """For collapsing u into v on the current arrays: {merged wedge: the wedges of u
        and v that end up in it}. Each face of the edge pairs its own wedges of u and v;
        a wedge of u with no pair stays a wedge of its own."""
        alive = np.flatnonzero(falive)
        pairs = set()
        for f in alive:
            if u in F[f] and v in F[f]:
                pairs.add((int(FW[f][F[f] == u][0]), int(FW[f][F[f] == v][0])))
        to = dict(pairs)
        assert len(to) == len(pairs), "a wedge of u pairs with two wedges of v"
        groups = {}
        for f in alive:
            for x in (u, v):
                if x in F[f]:
                    w = int(FW[f][F[f] == x][0])
                    groups.setdefault(to.get(w, w), set()).add(w)
        return groups

    def merge(self, groups):
        for target, wedges in groups.items():
            self.owner[np.isin(self.owner, list(wedges))] = target


def engine(mesh):
    """The engine's state for ``mesh`` under POLICY, before any collapse."""
    prep = _prepare(mesh, POLICY, None)
    arrays = _quadrics(mesh, POLICY, prep)
    rules = _rules(mesh, POLICY, None, prep, 1, False, None)
    terms = _terms(POLICY, prep, None, rules)
    return arrays, rules, terms, new_scratch(len(arrays.P)), Images(*dummy_state())


def check_collapse(u, v, p, oracle, arrays, rules, terms, scratch):
    """Collapse u into v at p, checking the edge's summed quadric (before) and every
    live wedge's quadric and the merged wedges' UVs (after) against the oracle."""
    groups = oracle.groups(u, v, arrays.F, arrays.FW, arrays.falive)
    _edge_quadric(u, v, arrays, scratch)
    before = oracle.quadrics()
    merged = {t: sum(before[w] for w in ws) for t, ws in groups.items()}
    expected = sum(reduced(H) for H in merged.values())
    scale = np.abs(expected).max()
    np.testing.assert_allclose(unpack3(scratch.qsum), expected, rtol=1e-9, atol=1e-12 * scale)
    _collapse(u, v, p.copy(), arrays, rules, terms, scratch,
              (np.empty(3 * len(arrays.F), np.int64), 0, np.zeros(N_KINDS, np.int64)))
    oracle.merge(groups)
    live = np.unique(arrays.FW[arrays.falive])
    expected = oracle.quadrics()[live]
    got = np.stack([unpack5(arrays.WQ[w]) for w in live])
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())
    for t, H in merged.items():  # each merged wedge's UV minimises its quadric at p
        np.testing.assert_allclose(arrays.uv[t], uv_minimiser(H, p), rtol=0, atol=1e-9)


def crate_with_jittered_uvs(n, seed):
    """make_crate(n) with every render vertex's UV jittered (seeded), so that no two
    faces share a 5-D plane and a face's quadric in the wrong wedge shows."""
    mesh = make_crate(n, texture_size=8)
    rng = np.random.default_rng(seed)
    return mesh.replace(uv=mesh.uv + rng.uniform(-0.03, 0.03, mesh.uv.shape))


def vertex_at(mesh, point):
    """The welded vertex at ``point`` (input units)."""
    (i,) = np.flatnonzero(np.all(mesh.welded.positions == point, axis=1))
    return int(i)


# -- the oracle against the engine ---------------------------------------------------------

def test_wedge_quadrics_across_collapses_with_unequal_wedge_counts():
    """On a 2×2-quads-a-side crate: a face centre (one wedge) into an edge midpoint
    (two: the edge is inside one box face, so both of its faces pair the same two
    wedges), then that vertex (two wedges) into a corner (three) along the box edge,
    and a corner (three) into an edge midpoint (two), whose third wedge has no
    partner and moves over with its own quadric. Each collapse's summed quadric and
    every wedge's quadric afterwards equal the brute-force sums."""
    mesh = crate_with_jittered_uvs(2, seed=5)
    arrays, rules, terms, scratch, _ = engine(mesh)
    oracle = Oracle(arrays.P, arrays.F, arrays.FW, arrays.uv, TEXTURE_WEIGHT)
    steps = [((1, 0, 0), (1, 1, 0), (1, 1, 0)),    # 1 wedge -> 2, kept in place
             ((1, 1, 0), (1, 1, 1), (1, 1, 1)),    # 2 -> 3 along the box edge
             ((-1, -1, -1), (-1, -1, 0), (-1, -1, -1))]  # 3 -> 2, kept at the corner
    for removed, kept, at in steps:
        u, v = vertex_at(mesh, removed), vertex_at(mesh, kept)
        p = arrays.P[vertex_at(mesh, at)].copy()
        counts = [len(np.unique(arrays.FW[arrays.falive][arrays.F[arrays.falive] == x]))
                  for x in (u, v)]
        assert counts[0] != counts[1]
        check_collapse(u, v, p, oracle, arrays, rules, terms, scratch)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), steps=st.integers(1, 30))
def test_wedge_quadrics_over_random_collapse_sequences(seed, steps):
    """Random valid collapses (the engine's own placement and validity rules) on a
    3×3-quads-a-side crate with jittered UVs, each checked against the oracle."""
    mesh = crate_with_jittered_uvs(3, seed)
    arrays, rules, terms, scratch, images = engine(mesh)
    oracle = Oracle(arrays.P, arrays.F, arrays.FW, arrays.uv, TEXTURE_WEIGHT)
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        F = arrays.F[arrays.falive]
        edges = np.unique(np.sort(F[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1),
                          axis=0)
        for a, b in edges[rng.permutation(len(edges))]:
            cost, keep = _evaluate(a, b, arrays, rules, terms, scratch, images)
            u = a if keep == b else b
            if cost == np.inf or _check_candidate(u, keep, cost, arrays, rules,
                                                  scratch) != VALID:
                continue
            check_collapse(u, keep, scratch.p.copy(), oracle, arrays, rules, terms, scratch)
            break
        else:
            break


@pytest.mark.parametrize("target", [60, 20])
def test_interpolated_uvs_keep_an_affine_texture_map_exact(target):
    """Without texture quadrics a merged wedge's UV is interpolated along the edge. On a
    flat grid whose UVs are affine in position, midpoint collapses then keep every UV
    exact, in the engine's result and in the Multi-Triangulation replayed from its log,
    provided each wedge pair is blended once: an edge inside a UV chart pairs the same
    wedges on both of its faces, and blended twice the midpoint took 3/4 of one end's UV
    and 1/4 of the other's."""
    from test_engine import affine_textured_grid

    from methods.engine.simplify import simplify_mesh
    from methods.mt.dag import from_log

    mesh, affine = affine_textured_grid()
    result = simplify_mesh(mesh, target, Policy(placement="midpoint"))
    out = result.mesh
    assert target - 1 <= out.n_faces <= target  # a boundary collapse removes one face
    np.testing.assert_allclose(out.uv, affine(out.positions), rtol=0, atol=1e-12)
    mt = from_log(mesh, result.log)
    np.testing.assert_allclose(mt.uv, affine(mt.positions), rtol=0, atol=1e-12)
