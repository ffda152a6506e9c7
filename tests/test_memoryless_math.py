"""Tests of methods.engine.terms.lindstrom_turk against slow NumPy references and exact invariants.

The references recompute each quantity another way: volumes with ``np.linalg.det``, the
R⁵ minors as determinants of the lifted difference matrix evaluated at three (s, t)
points (instead of expanded by multilinearity), the constraint procedure with SVD null
spaces, ``eigh`` and angles in degrees, and, as an oracle free of alpha, the
lexicographic minimiser of the criteria.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest

from methods.engine.terms.lindstrom_turk import (
    ALPHA_DEG,
    ZERO_TOL,
    Patch,
    _add_if_alpha_compatible,
    _oriented_volume_rows,
    _System,
    lt_cost,
    lt_placement,
    make_profile,
    r5_texture_coordinates,
    texture_kappa,
)

RTOL = 1e-9  # kernel vs reference: both are double-precision solves of 3x3 systems


# -- hand-built meshes --------------------------------------------------------------------

def icosahedron(rng, jitter=0.2):
    """A closed icosahedron with radially jittered vertices, faces wound outward."""
    g = (1 + 5 ** 0.5) / 2
    V = np.array([[-1, g, 0], [1, g, 0], [-1, -g, 0], [1, -g, 0],
                  [0, -1, g], [0, 1, g], [0, -1, -g], [0, 1, -g],
                  [g, 0, -1], [g, 0, 1], [-g, 0, -1], [-g, 0, 1]], dtype=float)
    F = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
                  [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
                  [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
                  [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    V *= 1 + jitter * rng.uniform(-1, 1, size=(12, 1))
    for f in F:  # the icosahedron is convex: outward means normal·centroid > 0
        a, b, c = V[f]
        if np.cross(b - a, c - a) @ (a + b + c) < 0:
            f[[1, 2]] = f[[2, 1]]
    return V, F


def tent():
    """A closed tent: a rectangular floor and a ridge (4)-(5) above it::

        3-----------2        seen from above; the ridge edge 4-5 runs along y = 0
        |  \\     /  |        at height 1, slightly skewed so nothing is symmetric.
        |   4---5   |
        |  /     \\  |
        0-----------1
    """
    V = np.array([[-1.5, -1, 0], [1.6, -1.1, 0], [1.4, 1, 0], [-1.5, 1.2, 0],
                  [-0.5, 0.1, 1.0], [0.6, -0.05, 1.2]])
    F = np.array([[0, 1, 5], [0, 5, 4], [1, 2, 5], [2, 3, 4], [2, 4, 5], [3, 0, 4],
                  [0, 3, 2], [0, 2, 1]])
    return V, F


def grid(nx, ny, rng, jitter=0.2):
    """A (nx x ny)-vertex triangulated grid in z = 0, faces counter-clockwise (+z)."""
    x, y = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float))
    V = np.c_[x.ravel(), y.ravel(), np.zeros(nx * ny)]
    V[:, :2] += jitter * rng.uniform(-1, 1, size=(nx * ny, 2))
    F = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a, b, c, d = j * nx + i, j * nx + i + 1, (j + 1) * nx + i + 1, (j + 1) * nx + i
            F += [[a, b, c], [a, c, d]]
    return V, np.array(F)


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def undirected_count(F):
    count = {}
    for f in F:
        for k in range(3):
            e = frozenset((f[k], f[(k + 1) % 3]))
            count[e] = count.get(e, 0) + 1
    return count


def edges(F):
    return sorted({tuple(sorted(e)) for e in undirected_count(F)})


def edge_profile(V, F, i, j, pad=2):
    """The kernel arguments for collapsing edge (i, j); ``pad`` NaN rows are appended to
    every array to check that only the counted rows are read."""
    inc = [f for f in F if i in f or j in f]
    tri = V[np.array(inc)]
    count = undirected_count(F)
    bnd = [(f[k], f[(k + 1) % 3]) for f in F for k in range(3)
           if count[frozenset((f[k], f[(k + 1) % 3]))] == 1
           and ({f[k], f[(k + 1) % 3]} & {i, j})]
    link = sorted({w for f in inc for w in f} - {i, j})
    nan = np.full((pad, 3), np.nan)
    bnd = np.array(bnd, dtype=int).reshape(-1, 2)
    return dict(tri_a=np.r_[tri[:, 0], nan], tri_b=np.r_[tri[:, 1], nan],
                tri_c=np.r_[tri[:, 2], nan],
                bnd_a=np.r_[V[bnd[:, 0]], nan], bnd_b=np.r_[V[bnd[:, 1]], nan],
                n_tris=len(inc), n_bnd=len(bnd),
                link=np.r_[V[link], nan], n_link=len(link),
                edge_sq_len=float(np.sum((V[i] - V[j]) ** 2)))


def kernel_profile(prof):
    """The kernels' :data:`~methods.engine.state.Profile` of :func:`edge_profile`'s dict."""
    return make_profile(*(prof[k] for k in ("tri_a", "tri_b", "tri_c", "bnd_a", "bnd_b",
                                            "link", "n_tris", "n_bnd", "n_link")))


def place(prof, **kw):
    return lt_placement(kernel_profile(prof), prof["edge_sq_len"], **kw)


def cost(p, prof, **kw):
    return lt_cost(p, kernel_profile(prof), prof["edge_sq_len"], **kw)


def collapse(V, F, i, j, p):
    """Collapse edge (i, j) to p: j merges into i; faces left with a repeated corner go."""
    V = V.copy()
    V[i] = p
    F = np.where(F == j, i, F)
    keep = (F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])
    return V, F[keep]


def enclosed_volume(V, F):
    """Signed volume of a closed surface: Σ det[a, b, c] / 6 (divergence theorem)."""
    return np.linalg.det(V[F]).sum() / 6


def boundary_vector_area(V, F):
    """½ Σ s × t over the directed boundary edges (those in a single face)."""
    count = undirected_count(F)
    total = np.zeros(3)
    for f in F:
        for k in range(3):
            s, t = f[k], f[(k + 1) % 3]
            if count[frozenset((s, t))] == 1:
                total += 0.5 * np.cross(V[s], V[t])
    return total


# -- slow references ----------------------------------------------------------------------
# Two kinds: ``ref_*`` redo the kernels' constraint procedure with NumPy primitives
# (eigh, SVD null spaces, angles in degrees, np.linalg.solve), and ``lexicographic_*``
# are oracles that know nothing of alpha: they minimise each criterion in turn over the
# minimisers of the previous ones. The two must agree whenever no candidate was
# rejected by the angle test.

def _skew(e):
    """[e]×: the matrix with [e]× p = e × p."""
    return np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])


class _Constraints:
    """Equations a · x = r accepted while alpha-compatible (Lindstrom & Turk 1998)."""

    def __init__(self, dim, alpha=ALPHA_DEG):
        self.dim, self.alpha = dim, alpha
        self.rows, self.rhs, self.rejected = [], [], 0

    @property
    def full(self):
        return len(self.rows) == self.dim

    def _angle(self, a):
        """Degrees between a and the span of the accepted rows (lines, or a plane)."""
        if len(self.rows) == 1:
            r = self.rows[0]
            cos = abs(r @ a) / np.linalg.norm(r) / np.linalg.norm(a)
            return np.degrees(np.arccos(min(1.0, cos)))
        m = np.cross(*self.rows)
        sin = abs(m @ a) / np.linalg.norm(m) / np.linalg.norm(a)
        return np.degrees(np.arcsin(min(1.0, sin)))

    def offer(self, a, r, scale):
        if self.full or not (np.all(np.isfinite(a)) and np.isfinite(r)):
            return
        if np.linalg.norm(a) <= ZERO_TOL * scale:
            return
        if self.rows and self._angle(a) <= self.alpha:
            self.rejected += 1
            return
        self.rows.append(np.asarray(a, float))
        self.rhs.append(float(r))

    def offer_quadratic(self, H, c, scale):
        """Stationarity of ½ xᵀHx + cᵀx along the eigenvectors of the reduced Hessian."""
        if self.full:
            return
        if self.rows:
            _, _, Vt = np.linalg.svd(np.array(self.rows))
            Z = Vt[len(self.rows):].T
        else:
            Z = np.eye(self.dim)
        _, U = np.linalg.eigh(Z.T @ H @ Z)
        for q in (Z @ U)[:, ::-1].T:
            self.offer(H @ q, -q @ c, scale)

    def solve(self):
        return np.linalg.solve(np.array(self.rows), np.array(self.rhs)) if self.full else None


def _placement_terms(prof):
    nt, nb = prof["n_tris"], prof["n_bnd"]
    a, b, c = prof["tri_a"][:nt], prof["tri_b"][:nt], prof["tri_c"][:nt]
    s, t = prof["bnd_a"][:nb], prof["bnd_b"][:nb]
    n = np.cross(b - a, c - a)
    d = np.linalg.det(np.stack([a, b, c], axis=1))
    return n, d, t - s, np.cross(s, t)


def ref_placement(prof, volume_weight=0.5, boundary_weight=0.5):
    """Returns (p or None, number of angle rejections)."""
    n, d, e, m = _placement_terms(prof)
    link = prof["link"][:prof["n_link"]]
    system = _Constraints(3)
    system.offer(n.sum(0), d.sum(), np.linalg.norm(n, axis=1).sum())
    if len(e):
        E = e.sum(0)
        system.offer_quadratic(_skew(E).T @ _skew(E), _skew(E).T @ m.sum(0),
                               np.linalg.norm(e, axis=1).sum() ** 2)
    wb = 9 * boundary_weight * prof["edge_sq_len"]
    H = volume_weight * n.T @ n + wb * sum((_skew(ei).T @ _skew(ei) for ei in e),
                                           np.zeros((3, 3)))
    c = -volume_weight * n.T @ d + wb * sum((_skew(ei).T @ mi for ei, mi in zip(e, m)),
                                            np.zeros(3))
    system.offer_quadratic(H, c, np.linalg.norm(H))
    system.offer_quadratic(len(link) * np.eye(3), -link.sum(0), len(link))
    return system.solve(), system.rejected


def _cascade(stages, dim, rel=1e-8):
    """Minimise |M x - y| for each stage (M, y, scale) in turn, over the minimisers of
    the previous stages (x + Z w, Z an SVD null-space basis); singular values below
    rel × scale (default |M|) count as zero. None if x is not fully determined."""
    x, Z = np.zeros(dim), np.eye(dim)
    for M, y, *scale in stages:
        if Z.shape[1] == 0:
            break
        U, sv, Vt = np.linalg.svd(M @ Z)
        k = int(np.sum(sv > rel * (scale[0] if scale else np.linalg.norm(M))))
        if k:
            x = x + Z @ (Vt[:k].T @ ((U[:, :k].T @ (y - M @ x)) / sv[:k]))
            Z = Z @ Vt[k:].T
    return x if Z.shape[1] == 0 else None


def lexicographic_placement(prof, volume_weight=0.5, boundary_weight=0.5):
    n, d, e, m = _placement_terms(prof)
    link = prof["link"][:prof["n_link"]]
    stages = [(n.sum(0)[None], d.sum()[None], np.linalg.norm(n, axis=1).sum())]
    if len(e):
        stages.append((_skew(e.sum(0)), -m.sum(0), np.linalg.norm(e, axis=1).sum()))
    wb = np.sqrt(9 * boundary_weight * prof["edge_sq_len"])
    stages.append((np.vstack([np.sqrt(volume_weight) * n] + [wb * _skew(ei) for ei in e]),
                   np.concatenate([np.sqrt(volume_weight) * d] + [-wb * mi for mi in m])))
    stages.append((np.tile(np.eye(3), (len(link), 1)), link.ravel()))
    return _cascade(stages, 3)


def ref_cost(p, prof, volume_weight=0.5, boundary_weight=0.5, shape_weight=0.0):
    nt, nb, nl = prof["n_tris"], prof["n_bnd"], prof["n_link"]
    vol = sum((np.linalg.det(np.stack([prof["tri_a"][i] - p, prof["tri_b"][i] - p,
                                       prof["tri_c"][i] - p])) / 6) ** 2 for i in range(nt))
    bnd = sum(np.sum((0.5 * np.cross(prof["bnd_a"][j] - p, prof["bnd_b"][j] - p)) ** 2)
              for j in range(nb))
    shape = np.sum((prof["link"][:nl] - p) ** 2)
    L2 = prof["edge_sq_len"]
    return volume_weight * vol + boundary_weight * L2 * bnd + shape_weight * L2 ** 2 * shape


def ref_minors(p, xyz, uv, kappa, s, t):
    """The 10 minors g_r (Eq. 4) of the lifted tetrahedron, for one triangle."""
    X = np.r_[p, kappa * s, kappa * t]
    D = np.c_[xyz, kappa * uv].T - X[:, None]  # 5 x 3
    return np.array([np.linalg.det(D[list(r)]) for r in combinations(range(5), 3)])


def _r5_G(p, tri, uv, kappa):
    """Ḡ_T (Eq. 5) of every triangle, from three evaluations of its affine minors."""
    G = []
    for xyz, w in zip(tri, uv):
        g0 = ref_minors(p, xyz, w, kappa, 0, 0)
        G.append(np.c_[ref_minors(p, xyz, w, kappa, 1, 0) - g0,
                       ref_minors(p, xyz, w, kappa, 0, 1) - g0, g0])
    return np.array(G)


def ref_r5(p, tri, uv, kappa):
    """Returns ((s, t) or None, number of angle rejections)."""
    G = _r5_G(p, tri, uv, kappa)
    Gs = G.sum(0)
    system = _Constraints(2)
    system.offer_quadratic(Gs[:, :2].T @ Gs[:, :2], Gs[:, :2].T @ Gs[:, 2],
                           sum(np.linalg.norm(g[:, :2]) for g in G) ** 2)
    Ho = sum(g[:, :2].T @ g[:, :2] for g in G)
    system.offer_quadratic(Ho, sum(g[:, :2].T @ g[:, 2] for g in G), np.linalg.norm(Ho))
    return system.solve(), system.rejected


def lexicographic_r5(p, tri, uv, kappa):
    G = _r5_G(p, tri, uv, kappa)
    Gs = G.sum(0)
    return _cascade([(Gs[:, :2], -Gs[:, 2], sum(np.linalg.norm(g[:, :2]) for g in G)),
                     (np.vstack(G[:, :, :2]), -np.concatenate(G[:, :, 2]))], 2)


def random_soup(rng, n_tris=12, n_bnd=0, n_link=10):
    prof = dict(tri_a=rng.normal(size=(n_tris, 3)), tri_b=rng.normal(size=(n_tris, 3)),
                tri_c=rng.normal(size=(n_tris, 3)),
                bnd_a=rng.normal(size=(max(n_bnd, 1), 3)),
                bnd_b=rng.normal(size=(max(n_bnd, 1), 3)),
                n_tris=n_tris, n_bnd=n_bnd, link=rng.normal(size=(n_link, 3)),
                n_link=n_link, edge_sq_len=float(rng.uniform(0.1, 2)))
    return prof


# -- placement ----------------------------------------------------------------------------

def test_planar_fan_places_in_the_plane_with_zero_volume_cost():
    rng = np.random.default_rng(1)
    V, F = grid(5, 5, rng)
    for i, j in [(6, 7), (6, 12), (12, 13), (12, 18)]:  # interior edges of the fan
        prof = edge_profile(V, F, i, j)
        p, ok = place(prof)
        assert ok
        assert p[2] == pytest.approx(0, abs=1e-14)
        assert cost(p, prof, boundary_weight=0.0) == pytest.approx(0, abs=1e-28)
        # the shape step centres p on the link (the plane leaves 2 directions free)
        link = prof["link"][:prof["n_link"]]
        np.testing.assert_allclose(p[:2], link[:, :2].mean(0), atol=1e-12)


def test_tilted_planar_fan_stays_in_its_plane():
    rng = np.random.default_rng(2)
    V, F = grid(5, 5, rng)
    R, t = random_rotation(rng), rng.normal(size=3) * 10
    V = V @ R.T + t
    normal = R[:, 2]
    for i, j in [(6, 7), (12, 18), (7, 13)]:
        p, ok = place(edge_profile(V, F, i, j))
        assert ok
        assert normal @ (p - V[i]) == pytest.approx(0, abs=1e-12)


def test_tent_ridge_collapse_preserves_enclosed_volume():
    V, F = tent()
    before = enclosed_volume(V, F)
    assert before > 0  # wound outward
    p, ok = place(edge_profile(V, F, 4, 5))
    assert ok
    V2, F2 = collapse(V, F, 4, 5, p)
    assert len(F2) == len(F) - 2
    assert enclosed_volume(V2, F2) == pytest.approx(before, rel=1e-12)


def test_every_collapse_of_a_closed_mesh_preserves_its_volume():
    rng = np.random.default_rng(3)
    V, F = icosahedron(rng)
    before = enclosed_volume(V, F)
    for i, j in edges(F):
        p, ok = place(edge_profile(V, F, i, j))
        assert ok
        assert enclosed_volume(*collapse(V, F, i, j, p)) == pytest.approx(before, rel=1e-12)


def test_open_planar_strip_keeps_its_boundary_area_vector():
    rng = np.random.default_rng(4)
    V, F = grid(6, 3, rng, jitter=0.3)  # rows of 6: 0-5 bottom, 6-11 middle, 12-17 top
    V = V @ random_rotation(rng).T + rng.normal(size=3)
    before = boundary_vector_area(V, F)
    for i, j in [(1, 2), (2, 3), (14, 15), (8, 2), (9, 15)]:  # boundary, then mixed edges
        prof = edge_profile(V, F, i, j)
        assert prof["n_bnd"] > 0
        p, ok = place(prof)
        assert ok
        after = boundary_vector_area(*collapse(V, F, i, j, p))
        np.testing.assert_allclose(after, before, rtol=0, atol=1e-12 * np.linalg.norm(before))


def _check_placement(prof, unrejected):
    p, ok = place(prof)
    ref, rejected = ref_placement(prof)
    assert ok and ref is not None
    tol = RTOL * max(1.0, np.abs(ref).max())
    np.testing.assert_allclose(p, ref, rtol=0, atol=tol)
    if not rejected:  # alpha never fired: the plain lexicographic minimiser
        np.testing.assert_allclose(p, lexicographic_placement(prof), rtol=0, atol=tol)
        unrejected.append(prof)


@pytest.mark.parametrize("n_bnd", [0, 3])
def test_placement_matches_the_references_on_random_soups(n_bnd):
    rng = np.random.default_rng(5 + n_bnd)
    unrejected = []
    for _ in range(100):
        _check_placement(random_soup(rng, n_tris=int(rng.integers(1, 13)), n_bnd=n_bnd),
                         unrejected)
    assert len(unrejected) >= 50  # the oracle comparison is not vacuous


def test_placement_matches_the_references_on_mesh_edges():
    rng = np.random.default_rng(7)
    meshes = [icosahedron(rng), grid(4, 4, rng), tent()]
    V, F = grid(4, 4, rng)
    V[:, 2] = 0.3 * rng.normal(size=len(V))  # a bumpy open sheet
    meshes.append((V, F))
    unrejected = []
    for V, F in meshes:
        for i, j in edges(F):
            _check_placement(edge_profile(V, F, i, j), unrejected)
    assert len(unrejected) >= 50


def test_placement_is_translation_rotation_and_scale_equivariant():
    rng = np.random.default_rng(8)
    V, F = icosahedron(rng)
    R, t, lam = random_rotation(rng), rng.normal(size=3) * 100, 7.5
    W = lam * V @ R.T + t
    for i, j in edges(F)[:10]:
        p, _ = place(edge_profile(V, F, i, j))
        q, _ = place(edge_profile(W, F, i, j))
        np.testing.assert_allclose(q, lam * R @ p + t, rtol=0, atol=1e-9 * lam)


def test_placement_is_frame_independent_even_when_alpha_rejects():
    # The candidates come from the reduced Hessian's eigenvectors, so which of them the
    # alpha test rejects does not depend on the coordinate axes.
    rng = np.random.default_rng(17)
    checked = 0
    while checked < 20:
        prof = random_soup(rng, n_tris=int(rng.integers(2, 13)), n_bnd=int(rng.integers(0, 4)))
        if not ref_placement(prof)[1]:
            continue
        R, t, lam = random_rotation(rng), rng.normal(size=3) * 50, rng.uniform(0.1, 10)
        moved = {k: (v @ (lam * R).T + t if k in ("tri_a", "tri_b", "tri_c", "bnd_a",
                                                  "bnd_b", "link") else v)
                 for k, v in prof.items()}
        moved["edge_sq_len"] = prof["edge_sq_len"] * lam ** 2
        p, ok = place(prof)
        q, ok2 = place(moved)
        assert ok and ok2
        np.testing.assert_allclose(q, lam * R @ p + t, rtol=0, atol=1e-8 * (lam + 50))
        checked += 1


def test_closed_fan_cancellation_is_not_taken_for_a_constraint():
    # Every face of a tetrahedron touches the edge: Σ n_T is rounding noise, and the
    # volume-preservation plane it would define is meaningless.
    V = np.array([[0.1, 0.2, 0.05], [1.3, 0.1, 0.2], [0.2, 1.1, -0.1], [0.3, 0.2, 0.9]])
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    prof = edge_profile(V, F, 0, 1)
    p, ok = place(prof)
    assert ok
    # without preservation, volume optimisation alone fixes p
    a, b, c = prof["tri_a"][:4], prof["tri_b"][:4], prof["tri_c"][:4]
    n = np.cross(b - a, c - a)
    expected = np.linalg.solve(n.T @ n, n.T @ np.einsum("ij,ij->i", n, a))
    np.testing.assert_allclose(p, expected, rtol=1e-10)


def test_degenerate_profiles_return_not_ok_without_nan():
    empty = np.zeros((0, 3))
    point = np.full((5, 3), 0.7)  # five triangles collapsed to one point
    cases = [
        (empty, empty, empty, empty, empty, 0, 0, empty, 0),
        (point, point, point, empty, empty, 5, 0, empty, 0),
        (point, point, point, point, point, 5, 5, empty, 0),
    ]
    nan = np.full((3, 3), np.nan)
    cases.append((nan, nan, nan, empty, empty, 3, 0, nan, 3))
    for tri_a, tri_b, tri_c, bnd_a, bnd_b, n_tris, n_bnd, link, n_link in cases:
        pr = make_profile(tri_a, tri_b, tri_c, bnd_a, bnd_b, link, n_tris, n_bnd, n_link)
        p, ok = lt_placement(pr, 1.0)
        assert not ok
        assert np.array_equal(p, np.zeros(3))


def test_placement_rejects_counts_beyond_the_arrays():
    a = np.zeros((2, 3))
    with pytest.raises(ValueError, match="n_tris"):
        lt_placement(make_profile(a, a, a, a, a, a, 3, 0, 0), 1.0)
    with pytest.raises(ValueError, match="n_bnd"):
        lt_placement(make_profile(a, a, a, a, a, a, 1, 5, 0), 1.0)
    with pytest.raises(ValueError, match="n_link"):
        lt_placement(make_profile(a, a, a, a, a, a, 1, 0, -1), 1.0)
    with pytest.raises(ValueError, match="n_tris"):
        lt_cost(np.zeros(3), make_profile(a, a, a, a, a, a, 3, 0, 0), 1.0)


def test_alpha_compatibility_follows_the_angle():
    cos2 = lambda d: np.cos(np.radians(d)) ** 2  # noqa: E731
    sin2 = lambda d: np.sin(np.radians(d)) ** 2  # noqa: E731
    half = np.radians(0.5)
    def system():
        return _System(A=np.zeros((3, 3)), b=np.zeros(3), H=np.zeros((3, 3)), c=np.zeros(3))

    for alpha, accepted in [(ALPHA_DEG, False), (0.25, True)]:
        s, cone = system(), (cos2(alpha), sin2(alpha))
        n = _add_if_alpha_compatible(s, 0, 2.0, 0.0, 0.0, 4.0, 1.0, cone)
        # stored normalised
        assert n == 1 and np.allclose(s.A[0], [1, 0, 0]) and s.b[0] == 2.0
        # a second line 0.5° from the first
        n = _add_if_alpha_compatible(s, n, np.cos(half), np.sin(half), 0.0, 0.0, 1.0, cone)
        assert n == 1 + accepted
        s.A[1], n = [0, 1, 0], 2
        # a third row 0.5° out of the plane of the first two
        n = _add_if_alpha_compatible(s, n, 0.0, np.cos(half), np.sin(half), 0.0, 1.0, cone)
        assert n == 2 + accepted
    # a numerical zero is refused whatever its direction
    assert _add_if_alpha_compatible(system(), 0, 1e-17, 0.0, 0.0, 0.0, 1.0, (1.0, 0.0)) == 0


# -- cost ---------------------------------------------------------------------------------

@pytest.mark.parametrize("weights", [(0.5, 0.5, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0),
                                     (0.2, 0.3, 0.7)])
def test_cost_matches_the_reference_on_random_soups(weights):
    rng = np.random.default_rng(9)
    kw = dict(zip(("volume_weight", "boundary_weight", "shape_weight"), weights))
    for _ in range(30):
        prof = random_soup(rng, n_bnd=int(rng.integers(0, 4)))
        p = rng.normal(size=3)
        assert cost(p, prof, **kw) == pytest.approx(ref_cost(p, prof, **kw), rel=1e-12)


def test_cost_scales_as_length_to_the_sixth():
    rng = np.random.default_rng(10)
    prof = random_soup(rng, n_bnd=3)
    p = rng.normal(size=3)
    lam = 3.0
    big = {k: (v * lam if isinstance(v, np.ndarray) else v) for k, v in prof.items()}
    big["edge_sq_len"] = prof["edge_sq_len"] * lam ** 2
    kw = dict(volume_weight=0.4, boundary_weight=0.6, shape_weight=0.3)
    assert cost(lam * p, big, **kw) == pytest.approx(lam ** 6 * cost(p, prof, **kw), rel=1e-12)


def test_placement_minimises_the_cost_on_the_volume_plane():
    # interior edge: volume preservation, then the optimisation step minimises the cost
    rng = np.random.default_rng(11)
    V, F = icosahedron(rng)
    prof = edge_profile(V, F, 0, 5)
    p, ok = place(prof)
    a, b, c = (prof[k][:prof["n_tris"]] for k in ("tri_a", "tri_b", "tri_c"))
    normal = np.cross(b - a, c - a).sum(0)
    u = np.cross(normal, [1.0, 0, 0])
    u /= np.linalg.norm(u)
    w = np.cross(normal, u) / np.linalg.norm(normal)
    c0 = cost(p, prof)
    for d in (u, w, (u + w) / 2 ** 0.5):
        for h in (1e-3, -1e-3):
            assert cost(p + h * d, prof) >= c0


# -- texture coordinates ------------------------------------------------------------------

def r5(p, tri, uv, kappa, **kw):
    return r5_texture_coordinates(p, patch_of(tri, uv), len(tri), kappa, **kw)


def patch_of(tri, uv):
    """The kernels' :data:`~methods.engine.state.Patch` of triangles (K, 3, 3) and their
    UVs (K, 3, 2)."""
    return Patch(tri[:, 0], tri[:, 1], tri[:, 2], uv[:, 0], uv[:, 1], uv[:, 2])


def test_r5_reproduces_an_affine_texture_on_a_planar_patch():
    rng = np.random.default_rng(12)
    V, F = grid(5, 5, rng)
    R, t = random_rotation(rng), rng.normal(size=3)
    X = V @ R.T + t
    inc = [f for f in F if 6 in f or 12 in f]  # the fan around edge (6, 12)
    for kappa in (0.05, 1.0, 37.0):
        M, m = rng.normal(size=(2, 3)), rng.normal(size=2)
        uv = X @ M.T + m
        for _ in range(5):
            q = rng.uniform(-2, 6, size=2)  # anywhere in the plane, not only near the edge
            p = R @ np.r_[q, 0] + t
            st, ok = r5(p, X[inc], uv[inc], kappa)
            assert ok
            np.testing.assert_allclose(st, M @ p + m, rtol=0, atol=1e-10)


@pytest.mark.parametrize("kappa", [0.3, 1.0, 4.0])
def test_r5_matches_the_references_on_random_soups(kappa):
    rng = np.random.default_rng(13)
    unrejected = 0
    for _ in range(40):
        k = int(rng.integers(2, 9))
        tri, uv, p = rng.normal(size=(k, 3, 3)), rng.normal(size=(k, 3, 2)), rng.normal(size=3)
        st, ok = r5(p, tri, uv, kappa)
        ref, rejected = ref_r5(p, tri, uv, kappa)
        assert ok and ref is not None
        tol = 1e-8 * max(1.0, np.abs(ref).max())
        np.testing.assert_allclose(st, ref, rtol=0, atol=tol)
        if not rejected:
            np.testing.assert_allclose(st, lexicographic_r5(p, tri, uv, kappa),
                                       rtol=0, atol=tol)
            unrejected += 1
    assert unrejected >= 20


def test_r5_minors_give_the_tetrahedron_volume():
    # Eq. 5: V² = (1/36) |Ḡ (s, t, 1)|², and V = √det(Gram) / 6 for a 3-simplex in R⁵
    rng = np.random.default_rng(14)
    tri, uv = rng.normal(size=(1, 3, 3)), rng.normal(size=(1, 3, 2))
    p, kappa, s, t = rng.normal(size=3), 1.7, 0.3, -0.8
    G, D = np.empty((10, 3)), np.empty((5, 3))
    uv0 = uv[0, 0].copy()
    _oriented_volume_rows(p, patch_of(tri, uv), 0, uv0, kappa, D, G)
    g = G @ np.r_[s - uv0[0], t - uv0[1], 1.0]
    np.testing.assert_allclose(np.abs(g), np.abs(ref_minors(p, tri[0], uv[0], kappa, s, t)),
                               rtol=1e-12, atol=1e-12)
    E = np.c_[tri[0], kappa * uv[0]] - np.r_[p, kappa * s, kappa * t]  # 3 x 5
    assert np.sum(g ** 2) / 36 == pytest.approx(np.linalg.det(E @ E.T) / 36, rel=1e-12)


def test_r5_constant_texture_is_kept():
    rng = np.random.default_rng(15)
    tri = rng.normal(size=(6, 3, 3))
    uv = np.broadcast_to([0.25, 0.75], (6, 3, 2)).copy()
    st, ok = r5(rng.normal(size=3), tri, uv, 2.0)
    assert ok
    np.testing.assert_allclose(st, [0.25, 0.75], atol=1e-14)


def test_r5_degenerate_input_returns_not_ok_without_nan():
    point = np.full((4, 3, 3), 0.5)
    uv = np.full((4, 3, 2), 0.1)
    st, ok = r5(np.full(3, 0.5), point, uv, 1.0)  # every lifted tetrahedron is a point
    assert not ok and np.array_equal(st, np.zeros(2))
    st, ok = r5(np.zeros(3), np.zeros((0, 3, 3)), np.zeros((0, 3, 2)), 1.0)
    assert not ok and np.array_equal(st, np.zeros(2))
    bad = np.full((3, 3, 2), np.nan)
    st, ok = r5(np.zeros(3), np.ones((3, 3, 3)), bad, 1.0)
    assert not ok and np.array_equal(st, np.zeros(2))


def test_r5_rejects_bad_arguments():
    tri, uv = np.zeros((2, 3, 3)), np.zeros((2, 3, 2))
    with pytest.raises(ValueError, match="kappa"):
        r5(np.zeros(3), tri, uv, 0.0)
    with pytest.raises(ValueError, match="n_tris"):
        r5_texture_coordinates(np.zeros(3), patch_of(tri, uv), 3, 1.0)


# -- texture scale ------------------------------------------------------------------------

def test_kappa_is_the_ratio_of_average_edge_lengths():
    rng = np.random.default_rng(16)
    V, F = grid(4, 4, rng)
    face_uv = np.empty((len(F), 3, 2))
    patch = np.arange(len(F)) % 3  # patch 0 at scale 1/3, patch 1 at 1/8, patch 2 constant
    for f, face in enumerate(F):
        scale = (1 / 3, 1 / 8, 0.0)[patch[f]]
        face_uv[f] = V[face, :2] * scale + 0.1
    kappa = texture_kappa(V, F, face_uv, patch, 4)
    np.testing.assert_allclose(kappa, [3.0, 8.0, 1.0, 1.0], rtol=1e-12)
    with pytest.raises(ValueError, match="face_patch"):
        texture_kappa(V, F, face_uv, patch, 2)
