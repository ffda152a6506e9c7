"""Placement, cost and texture coordinates of memoryless simplification (numba kernels).

Memoryless simplification (Lindstrom & Turk 1998, 1999) never looks back at the
original mesh: where the vertex of a collapsed edge goes, and what the collapse costs,
are computed from the triangles around the edge *now*. The three public kernels are
called by the edge-collapse engine once per candidate edge, inside its own numba loop::

    p, ok = lt_placement(profile, edge_sq_len)
    cost = lt_cost(p, profile, edge_sq_len)
    uv, ok = r5_texture_coordinates(p, patch, n_tris, kappa)  # once per texture patch

and :func:`texture_kappa` computes the per-patch texture scale κ once, before the
loop. A :data:`Profile` is fixed-size arrays with counts of their valid rows, so the
engine reuses one as its scratch buffer. (From Python, pass every argument: numba's
dispatcher is some 50 times slower when defaults are omitted.)

The edge profile (:data:`Profile`)
----------------------------------
``tri_a, tri_b, tri_c`` are the corners of every triangle incident to either endpoint
of the edge *before* the collapse, including the one or two triangles the collapse
deletes, wound counter-clockwise seen from outside (normal by the right-hand rule).
``bnd_a, bnd_b`` are the boundary edges incident to either endpoint (the collapsed edge
itself included when it is a boundary edge), each oriented as in its triangle.
``link`` holds the distinct corners of those triangles other than the two endpoints.
``counts`` holds the valid rows of each: triangles, boundary edges, link vertices.
``edge_sq_len`` is the squared length L² of the collapsed edge.

Placement: constraints in order, while alpha-compatible
-------------------------------------------------------
The new vertex p solves three linear equations a_k · p = b_k. Candidate equations come
from four steps (five criteria, volume and boundary optimisation being one weighted
step), tried in this order; a candidate is kept only if it is *alpha-compatible* with
those already kept (see below), and the search stops at three:

================================  =======================================================
volume preservation               Σ_T V_T(p) = 0, V_T the signed volume of the tetrahedron
                                  (p, T): the volume enclosed by the surface is unchanged.
                                  One plane: (Σ n_T) · p = Σ det[a, b, c].
boundary preservation             (only with boundary edges) Σ_e A_e(p) = 0, A_e the
                                  area vector ½ (s - p) × (t - p) of the triangle swept by
                                  boundary edge e = (s, t): the vector area of the boundary
                                  loop is unchanged. Rank 2, solved in least squares.
volume + boundary optimisation    minimise w_V Σ V_T² + w_B L² Σ |A_e|², the cost below
                                  without its shape term (one quadratic; on interior edges
                                  only the volume part).
triangle shape optimisation       minimise Σ_link |p - v|²: prefer well-shaped triangles
                                  where the surface is flat.
================================  =======================================================

A linear criterion contributes its equation directly. A quadratic criterion
½ pᵀHp + cᵀp contributes the stationarity conditions of its minimum *on the set already
fixed*: with Q an orthonormal basis of the directions the kept equations leave free,
the candidates are the rows of Qᵀ H p = -Qᵀ c, one per column q of Q, each tested for
alpha-compatibility as it comes. Lindstrom & Turk leave the basis open; CGAL takes
Q = I when nothing is fixed and otherwise vectors built from the coordinate axes. Here
the columns of Q are the eigenvectors of the reduced Hessian QᵀHQ, largest eigenvalue
first: when every candidate is accepted the basis does not matter, and when the alpha
test rejects one (a direction the criterion barely determines) this choice makes the
outcome independent of the coordinate frame, so a rotated mesh is simplified the same
way.

Volume and boundary optimisation are a single weighted step, as in CGAL's
``LindstromTurk_placement``: volume is in length⁶ and squared area in length⁴, so the
boundary part is scaled by L² to be commensurate, and the step then minimises exactly
the cost :func:`lt_cost` reports (minus its shape term, whose default weight is 0).

CGAL tries boundary preservation *before* volume preservation; here volume preservation
comes first, as listed above. On a planar boundary both are satisfied exactly either
way; they differ only when the boundary chain is not planar, where the boundary
equations have no exact solution.

Alpha-compatibility (Lindstrom & Turk 1998; CGAL ``add_constraint_if_alpha_compatible``)
-----------------------------------------------------------------------------------------
A candidate a · p = b, with a ≠ 0, is accepted when

- no equation is kept yet: always;
- one equation a₀ is kept: the angle between the lines of a and a₀ exceeds α,
  i.e. (a₀ · a)² < cos²α |a₀|² |a|²;
- two equations a₀, a₁ are kept: the angle between a and their plane exceeds α,
  i.e. with m = a₀ × a₁, (m · a)² > sin²α |m|² |a|².

α = 1° by default (:data:`ALPHA_DEG`), CGAL's fixed value. The test keeps
the 3x3 system well conditioned: its determinant is at least sin²α in absolute value
once the rows are normalised. Before the angle test, a candidate whose coefficient
vector is a numerical zero, |a| ≤ :data:`ZERO_TOL` × (the magnitude of the terms summed
into it), is discarded: sums like Σ n_T over a closed fan cancel to rounding noise, and
rounding noise has no direction.

When fewer than three equations are accepted (all triangles degenerate, empty link, NaN
input), ``ok`` is False and ``p`` is zeros; the engine falls back to another placement.

Cost
----
``lt_cost`` = w_V · Σ_T V_T(p)²  +  w_B · L² · Σ_e |A_e(p)|²  +  w_S · L⁴ · Σ_link |p - v|²

with V_T = det[a - p, b - p, c - p] / 6 (the tetrahedron's volume, so the /6 *is* applied)
and A_e = ½ (s - p) × (t - p): the normalisation of CGAL's ``LindstromTurk_cost`` (volume
cost /36, boundary cost /4, boundary term × L², shape term × L⁴). Defaults w_V = w_B = 0.5,
w_S = 0: CGAL's defaults (``LindstromTurk_params``), kept so that results can be
compared with CGAL's simplifier. Every term then scales as length⁶: scaling the mesh
by λ scales the cost by λ⁶ (volume cost alone ~ length⁶, boundary cost alone ~ length⁴,
shape cost alone ~ length²; the L² and L⁴ factors of the collapsed edge make them
commensurate). Costs of different models
are therefore only comparable after normalising the models' size.

Texture coordinates in R⁵ (Lindstrom & Turk 2000, §4.1.1, Eqs. 4–7)
---------------------------------------------------------------------
See :func:`r5_texture_coordinates`. Reconstruction notes: in our copy of the paper the
1/18 of Eqs. 6–7 and the outer ½ combine to the 1/36 of Eq. 5, which is what is used
(a constant factor does not move the minimiser). The sign convention of the g's does
not matter: every term is squared, and in Eq. 6 each g is summed with itself across
triangles. On a planar patch with an affine texture map and p in its plane, all lifted
points lie in one 2-plane of R⁵, every tetrahedron is flat at the true (s, t), and the
preservation step alone recovers the affine map exactly (tested).

References
----------
.. [1] P. Lindstrom and G. Turk, "Fast and memory efficient polygonal simplification",
   Proc. IEEE Visualization 1998, pp. 279–286.
.. [2] P. Lindstrom and G. Turk, "Evaluation of memoryless simplification", IEEE TVCG
   5(2), 1999, pp. 98–115.
.. [3] P. Lindstrom and G. Turk, "Image-driven simplification", ACM Transactions on
   Graphics 19(3), 2000, §4.1 and §4.1.1.
.. [4] F. Cacciola, CGAL Triangulated Surface Mesh Simplification, "Lindstrom-Turk Cost
   and Placement Strategy"; classes ``LindstromTurk_cost`` and ``LindstromTurk_placement``.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from methods.engine.state import Patch, Profile

__all__ = ["lt_placement", "lt_cost", "r5_texture_coordinates", "texture_kappa",
           "Patch", "Profile", "make_profile", "ALPHA_DEG", "VOLUME_WEIGHT", "BOUNDARY_WEIGHT",
           "SHAPE_WEIGHT", "ZERO_TOL"]

#: Alpha-compatibility angle in degrees (CGAL's fixed value).
ALPHA_DEG = 1.0
#: Default weights of the cost terms (CGAL's ``LindstromTurk_params`` defaults).
VOLUME_WEIGHT = 0.5
BOUNDARY_WEIGHT = 0.5
SHAPE_WEIGHT = 0.0
#: A constraint vector shorter than ZERO_TOL times the magnitude of the terms summed into
#: it is rounding noise (1e-10 leaves ~6 digits of headroom above double rounding).
ZERO_TOL = 1e-10

#: The constraint system ``A`` p = ``b`` (A (3, 3), b (3,)) that the placement fills row
#: by row, and the Hessian ``H`` (3, 3) and linear part ``c`` (3,) of the quadratic
#: criterion being added.
_System = namedtuple("_System", "A b H c")


def make_profile(tri_a, tri_b, tri_c, bnd_a, bnd_b, link, n_tris, n_bnd, n_link) -> Profile:
    """A :data:`Profile` of the given arrays (as float64) and counts."""
    f = [np.ascontiguousarray(x, dtype=np.float64) for x in (tri_a, tri_b, tri_c, bnd_a,
                                                                bnd_b, link)]
    return Profile(*f, np.array([n_tris, n_bnd, n_link], np.int64))


# The 10 choices of 3 of the 5 R^5 coordinates (x, y, z, κs, κt): the 3x3 minors that
# make up the oriented volume of Eq. 4, in lexicographic order.
_TRIPLES = np.array([[a, b, c] for a in range(5) for b in range(a + 1, 5)
                     for c in range(b + 1, 5)], dtype=np.int64)


# -- small linear algebra -----------------------------------------------------------------

@njit(cache=True, _nrt=False)
def _det3(a, b, c):
    """Determinant of the 3x3 matrix with rows ``a``, ``b``, ``c`` (3-tuples)."""
    (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = a, b, c
    return a0 * (b1 * c2 - b2 * c1) - a1 * (b0 * c2 - b2 * c0) + a2 * (b0 * c1 - b1 * c0)


@njit(cache=True, _nrt=False)
def _frobenius3(H):
    s = 0.0
    for i in range(3):
        for j in range(3):
            s += H[i, j] * H[i, j]
    return math.sqrt(s)


@njit(cache=True, _nrt=False)
def _check_profile(pr):
    """Raise ValueError when a count of ``pr`` is negative or exceeds its arrays' rows."""
    n_tris, n_bnd, n_link = pr.counts[0], pr.counts[1], pr.counts[2]
    if n_tris < 0 or n_tris > pr.tri_a.shape[0] or n_tris > pr.tri_b.shape[0] \
            or n_tris > pr.tri_c.shape[0]:
        raise ValueError("n_tris must be in [0, rows of tri_a/tri_b/tri_c]")
    if n_bnd < 0 or n_bnd > pr.bnd_a.shape[0] or n_bnd > pr.bnd_b.shape[0]:
        raise ValueError("n_bnd must be in [0, rows of bnd_a/bnd_b]")
    if n_link < 0 or n_link > pr.link.shape[0]:
        raise ValueError("n_link must be in [0, rows of link]")


# -- the constraint system A p = b (3D) ---------------------------------------------------

@njit(cache=True, _nrt=False)
def _add_if_alpha_compatible(s, n, a0, a1, a2, rhs, ref, cone):
    """Append the equation a · p = rhs to the first ``n`` rows of ``s.A p = s.b``
    (:data:`_System`) if it is alpha-compatible with them; return the new count.

    ``ref`` is the magnitude of the terms summed into ``a`` (the numerical-zero test);
    ``cone`` is (cos²α, sin²α). Kept rows are stored normalised.
    """
    A, b = s.A, s.b
    cos2, sin2 = cone
    if n >= 3:
        return n
    aa = a0 * a0 + a1 * a1 + a2 * a2
    zero = ZERO_TOL * ref
    if not (aa > zero * zero) or not math.isfinite(aa) or not math.isfinite(rhs):
        return n
    if n == 1:
        d = A[0, 0] * a0 + A[0, 1] * a1 + A[0, 2] * a2  # row 0 is unit length
        if d * d >= cos2 * aa:
            return n  # within α of the first line
    elif n == 2:
        m0 = A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]
        m1 = A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]
        m2 = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
        d = m0 * a0 + m1 * a1 + m2 * a2
        if d * d <= sin2 * (m0 * m0 + m1 * m1 + m2 * m2) * aa:
            return n  # within α of the plane of the first two
    inv = 1.0 / math.sqrt(aa)
    A[n, 0] = a0 * inv
    A[n, 1] = a1 * inv
    A[n, 2] = a2 * inv
    b[n] = rhs * inv
    return n + 1


@njit(cache=True)
def _add_from_gradient(s, n, ref, cone):
    """Candidates for minimising ½ pᵀHp + cᵀp (``s.H``, ``s.c``) on the set the first
    ``n`` equations of ``s`` fix: the rows (H q) · p = -q · c for q in an orthonormal
    basis of the free directions.

    q runs over the eigenvectors of the reduced Hessian QᵀHQ, largest eigenvalue (best
    determined direction) first. Any basis gives the same minimiser when all
    candidates are accepted; the eigenbasis makes the alpha test, which sees the raw
    rows H q, independent of the coordinate frame.
    """
    A, H, c = s.A, s.H, s.c
    for i in range(3):
        if not (math.isfinite(c[i]) and math.isfinite(H[i, 0]) and math.isfinite(H[i, 1])
                and math.isfinite(H[i, 2])):
            return n
    if n == 0:
        _, U = np.linalg.eigh(H)  # ascending eigenvalues
        for k in range(2, -1, -1):
            n = _add_projected_row(s, n, U[0, k], U[1, k], U[2, k], ref, cone)
    elif n == 1:
        # u = a0 × (the axis least aligned with a0), w = a0 × u: unit, ⟂ a0 and each other
        k = 0
        if abs(A[0, 1]) < abs(A[0, k]):
            k = 1
        if abs(A[0, 2]) < abs(A[0, k]):
            k = 2
        x0, x1, x2 = A[0, 0], A[0, 1], A[0, 2]
        if k == 0:
            u0, u1, u2 = 0.0, x2, -x1
        elif k == 1:
            u0, u1, u2 = -x2, 0.0, x0
        else:
            u0, u1, u2 = x1, -x0, 0.0
        inv = 1.0 / math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        u0 *= inv
        u1 *= inv
        u2 *= inv
        w0 = x1 * u2 - x2 * u1
        w1 = x2 * u0 - x0 * u2
        w2 = x0 * u1 - x1 * u0
        # principal axes of the 2x2 reduced Hessian [[r00, r01], [r01, r11]]
        r00 = _quad_form(H, u0, u1, u2, u0, u1, u2)
        r01 = _quad_form(H, u0, u1, u2, w0, w1, w2)
        r11 = _quad_form(H, w0, w1, w2, w0, w1, w2)
        theta = 0.5 * math.atan2(2.0 * r01, r00 - r11)
        cs, sn = math.cos(theta), math.sin(theta)
        n = _add_projected_row(s, n, cs * u0 + sn * w0, cs * u1 + sn * w1,
                               cs * u2 + sn * w2, ref, cone)
        n = _add_projected_row(s, n, cs * w0 - sn * u0, cs * w1 - sn * u1,
                               cs * w2 - sn * u2, ref, cone)
    elif n == 2:
        q0 = A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]
        q1 = A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]
        q2 = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
        inv = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
        n = _add_projected_row(s, n, q0 * inv, q1 * inv, q2 * inv, ref, cone)
    return n


@njit(cache=True, _nrt=False)
def _quad_form(H, x0, x1, x2, y0, y1, y2):
    """xᵀ H y."""
    return (x0 * (H[0, 0] * y0 + H[0, 1] * y1 + H[0, 2] * y2)
            + x1 * (H[1, 0] * y0 + H[1, 1] * y1 + H[1, 2] * y2)
            + x2 * (H[2, 0] * y0 + H[2, 1] * y1 + H[2, 2] * y2))


@njit(cache=True, _nrt=False)
def _add_projected_row(s, n, q0, q1, q2, ref, cone):
    """Candidate (H q) · p = -q · c for a unit free direction q (H symmetric)."""
    H, c = s.H, s.c
    a0 = H[0, 0] * q0 + H[0, 1] * q1 + H[0, 2] * q2
    a1 = H[1, 0] * q0 + H[1, 1] * q1 + H[1, 2] * q2
    a2 = H[2, 0] * q0 + H[2, 1] * q1 + H[2, 2] * q2
    rhs = -(c[0] * q0 + c[1] * q1 + c[2] * q2)
    return _add_if_alpha_compatible(s, n, a0, a1, a2, rhs, ref, cone)


@njit(cache=True, _nrt=False)
def _solve3(A, b, out):
    """Solve A x = b by Cramer's rule into ``out``; return False if singular/non-finite."""
    c00 = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    c01 = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    c02 = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    det = A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02
    if not (abs(det) > 0.0) or not math.isfinite(det):
        return False
    # x = (b0 (a1 × a2) + b1 (a2 × a0) + b2 (a0 × a1)) / det
    for k in range(3):
        k1 = (k + 1) % 3
        k2 = (k + 2) % 3
        out[k] = (b[0] * (A[1, k1] * A[2, k2] - A[1, k2] * A[2, k1])
                  + b[1] * (A[2, k1] * A[0, k2] - A[2, k2] * A[0, k1])
                  + b[2] * (A[0, k1] * A[1, k2] - A[0, k2] * A[1, k1])) / det
    return math.isfinite(out[0]) and math.isfinite(out[1]) and math.isfinite(out[2])


# -- the criteria -------------------------------------------------------------------------
# Coordinates are taken relative to an origin o near the edge (the first corner of the
# first triangle): the determinants below are then free of the cancellation a far-away
# world origin would cause, and the result does not depend on where the mesh sits.

@njit(cache=True, _nrt=False)
def _triangle_normal_det(tri_a, tri_b, tri_c, i, o):
    """n_T = (b - a) × (c - a) (twice the area vector) and det[a, b, c] = n_T · a for
    triangle i, corners relative to ``o``: V_T(p) = (det - n_T · p) / 6."""
    a0 = tri_a[i, 0] - o[0]
    a1 = tri_a[i, 1] - o[1]
    a2 = tri_a[i, 2] - o[2]
    u0 = tri_b[i, 0] - tri_a[i, 0]
    u1 = tri_b[i, 1] - tri_a[i, 1]
    u2 = tri_b[i, 2] - tri_a[i, 2]
    v0 = tri_c[i, 0] - tri_a[i, 0]
    v1 = tri_c[i, 1] - tri_a[i, 1]
    v2 = tri_c[i, 2] - tri_a[i, 2]
    n0 = u1 * v2 - u2 * v1
    n1 = u2 * v0 - u0 * v2
    n2 = u0 * v1 - u1 * v0
    return n0, n1, n2, n0 * a0 + n1 * a1 + n2 * a2


@njit(cache=True, _nrt=False)
def _boundary_edge_terms(bnd_a, bnd_b, j, o):
    """e = t - s and m = s × t for boundary edge j (relative to ``o``): the swept area
    vector is A_e(p) = ½ (e × p + m)."""
    s0 = bnd_a[j, 0] - o[0]
    s1 = bnd_a[j, 1] - o[1]
    s2 = bnd_a[j, 2] - o[2]
    t0 = bnd_b[j, 0] - o[0]
    t1 = bnd_b[j, 1] - o[1]
    t2 = bnd_b[j, 2] - o[2]
    return (t0 - s0, t1 - s1, t2 - s2,
            s1 * t2 - s2 * t1, s2 * t0 - s0 * t2, s0 * t1 - s1 * t0)


@njit(cache=True, _nrt=False)
def _add_cross_gram(H, e0, e1, e2, w):
    """H += w ([e]×ᵀ [e]×) = w (|e|² I - e eᵀ)."""
    ee = e0 * e0 + e1 * e1 + e2 * e2
    H[0, 0] += w * (ee - e0 * e0)
    H[1, 1] += w * (ee - e1 * e1)
    H[2, 2] += w * (ee - e2 * e2)
    H[0, 1] -= w * e0 * e1
    H[1, 0] -= w * e0 * e1
    H[0, 2] -= w * e0 * e2
    H[2, 0] -= w * e0 * e2
    H[1, 2] -= w * e1 * e2
    H[2, 1] -= w * e1 * e2


@njit(cache=True, _nrt=False)
def _add_volume_preservation(s, n, pr, o, cone):
    """Σ_T V_T(p) = 0  ⇔  (Σ n_T) · p = Σ det[a, b, c]."""
    s0 = s1 = s2 = sd = ref = 0.0
    for i in range(pr.counts[0]):
        n0, n1, n2, d = _triangle_normal_det(pr.tri_a, pr.tri_b, pr.tri_c, i, o)
        s0 += n0
        s1 += n1
        s2 += n2
        sd += d
        ref += math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    return _add_if_alpha_compatible(s, n, s0, s1, s2, sd, ref, cone)


@njit(cache=True)
def _add_boundary_preservation(s, n, pr, o, cone):
    """Σ_e A_e(p) = 0  ⇔  E × p = -M with E = Σ e, M = Σ m; rank 2, so minimise
    ½ |E × p + M|²: H = |E|² I - E Eᵀ, c = [E]×ᵀ M = -E × M."""
    H, c = s.H, s.c
    E0 = E1 = E2 = M0 = M1 = M2 = ref = 0.0
    for j in range(pr.counts[1]):
        e0, e1, e2, m0, m1, m2 = _boundary_edge_terms(pr.bnd_a, pr.bnd_b, j, o)
        E0 += e0
        E1 += e1
        E2 += e2
        M0 += m0
        M1 += m1
        M2 += m2
        ref += math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    H[:, :] = 0.0
    _add_cross_gram(H, E0, E1, E2, 1.0)
    c[0] = -(E1 * M2 - E2 * M1)
    c[1] = -(E2 * M0 - E0 * M2)
    c[2] = -(E0 * M1 - E1 * M0)
    return _add_from_gradient(s, n, ref * ref, cone)


@njit(cache=True)
def _add_volume_boundary_optimisation(s, n, pr, o, edge_sq_len, volume_weight,
                                      boundary_weight, cone):
    """Minimise w_V Σ V_T² + w_B L² Σ |A_e|², multiplied by 36 so that the volume part
    is Σ (n_T · p - det_T)² and the boundary part 9 w_B L² Σ |e × p + m|²."""
    H, c = s.H, s.c
    H[:, :] = 0.0
    c[:] = 0.0
    for i in range(pr.counts[0]):
        n0, n1, n2, d = _triangle_normal_det(pr.tri_a, pr.tri_b, pr.tri_c, i, o)
        H[0, 0] += volume_weight * n0 * n0
        H[0, 1] += volume_weight * n0 * n1
        H[0, 2] += volume_weight * n0 * n2
        H[1, 1] += volume_weight * n1 * n1
        H[1, 2] += volume_weight * n1 * n2
        H[2, 2] += volume_weight * n2 * n2
        c[0] -= volume_weight * d * n0
        c[1] -= volume_weight * d * n1
        c[2] -= volume_weight * d * n2
    H[1, 0] = H[0, 1]
    H[2, 0] = H[0, 2]
    H[2, 1] = H[1, 2]
    wb = 9.0 * boundary_weight * edge_sq_len
    for j in range(pr.counts[1]):
        e0, e1, e2, m0, m1, m2 = _boundary_edge_terms(pr.bnd_a, pr.bnd_b, j, o)
        _add_cross_gram(H, e0, e1, e2, wb)
        c[0] -= wb * (e1 * m2 - e2 * m1)
        c[1] -= wb * (e2 * m0 - e0 * m2)
        c[2] -= wb * (e0 * m1 - e1 * m0)
    return _add_from_gradient(s, n, _frobenius3(H), cone)


@njit(cache=True)
def _add_shape_optimisation(s, n, pr, o, cone):
    """Minimise ½ Σ_link |p - v|²: H = |link| I, c = -Σ v."""
    H, c, link, n_link = s.H, s.c, pr.link, pr.counts[2]
    H[:, :] = 0.0
    c[:] = 0.0
    for k in range(n_link):
        for j in range(3):
            c[j] -= link[k, j] - o[j]
    for j in range(3):
        H[j, j] = n_link
    return _add_from_gradient(s, n, float(n_link), cone)


# -- public kernels -----------------------------------------------------------------------

@njit(cache=True)
def lt_placement(pr, edge_sq_len, alpha_deg=ALPHA_DEG, volume_weight=VOLUME_WEIGHT,
                 boundary_weight=BOUNDARY_WEIGHT):
    """Lindstrom–Turk vertex placement for one edge collapse.

    Parameters
    ----------
    pr : Profile
        The edge's profile (:data:`Profile`): the triangles incident to either endpoint
        before the collapse (the 1–2 deleted triangles included), counter-clockwise
        seen from outside; the boundary edges incident to either endpoint, oriented as
        in their triangle; the link (the shape criterion); only the counted rows.
    edge_sq_len : float
        Squared length L² of the collapsed edge (scales the boundary term).
    alpha_deg : float, default 1.0
        Alpha-compatibility angle in degrees.
    volume_weight, boundary_weight : float, default 0.5
        w_V and w_B of the combined optimisation step (module docstring).

    Returns
    -------
    p : ndarray of shape (3,), float64
        The new vertex; zeros when ``ok`` is False.
    ok : bool
        False when fewer than three alpha-compatible constraints exist (degenerate
        neighbourhood or non-finite input); the caller must fall back.

    Raises
    ------
    ValueError
        If a count is negative or exceeds the rows of its arrays.
    """
    _check_profile(pr)
    alpha = math.radians(alpha_deg)
    cone = (math.cos(alpha) ** 2, math.sin(alpha) ** 2)
    o = np.zeros(3)
    if pr.counts[0] > 0:
        o[:] = pr.tri_a[0]
    elif pr.counts[2] > 0:
        o[:] = pr.link[0]
    s = _System(A=np.zeros((3, 3)), b=np.zeros(3), H=np.empty((3, 3)), c=np.empty(3))
    p = np.zeros(3)

    n = _add_volume_preservation(s, np.int64(0), pr, o, cone)
    if n < 3 and pr.counts[1] > 0:
        n = _add_boundary_preservation(s, n, pr, o, cone)
    if n < 3:
        n = _add_volume_boundary_optimisation(s, n, pr, o, edge_sq_len, volume_weight,
                                              boundary_weight, cone)
    if n < 3:
        n = _add_shape_optimisation(s, n, pr, o, cone)
    if n < 3 or not _solve3(s.A, s.b, p):
        p[:] = 0.0
        return p, False
    p += o
    if not (math.isfinite(p[0]) and math.isfinite(p[1]) and math.isfinite(p[2])):
        p[:] = 0.0
        return p, False
    return p, True


@njit(cache=True, _nrt=False)
def lt_cost(p, pr, edge_sq_len, volume_weight=VOLUME_WEIGHT,
            boundary_weight=BOUNDARY_WEIGHT, shape_weight=SHAPE_WEIGHT):
    """Lindstrom–Turk cost of collapsing the edge to ``p``.

    cost = w_V Σ_T V_T² + w_B L² Σ_e |A_e|² + w_S L⁴ Σ_link |p - v|², with
    V_T = det[a - p, b - p, c - p] / 6 and A_e = ½ (s - p) × (t - p) (CGAL's
    normalisation; see the module docstring for scale and weights).

    Parameters
    ----------
    p : ndarray of shape (3,), float64
        Candidate position of the new vertex.
    pr, edge_sq_len
        The edge's profile and squared length, as in :func:`lt_placement`.
    volume_weight, boundary_weight, shape_weight : float, default 0.5, 0.5, 0.0

    Returns
    -------
    float
        The cost (length⁶ units); NaN only if the input is non-finite.
    """
    _check_profile(pr)
    tri_a, tri_b, tri_c, bnd_a, bnd_b, link = pr.tri_a, pr.tri_b, pr.tri_c, pr.bnd_a, \
        pr.bnd_b, pr.link
    n_tris, n_bnd, n_link = pr.counts[0], pr.counts[1], pr.counts[2]
    o0, o1, o2 = p[0], p[1], p[2]  # relative to p, V_T = det[a, b, c] / 6
    volume = 0.0
    for i in range(n_tris):
        v = _det3((tri_a[i, 0] - o0, tri_a[i, 1] - o1, tri_a[i, 2] - o2),
                  (tri_b[i, 0] - o0, tri_b[i, 1] - o1, tri_b[i, 2] - o2),
                  (tri_c[i, 0] - o0, tri_c[i, 1] - o1, tri_c[i, 2] - o2))
        volume += v * v
    boundary = 0.0
    for j in range(n_bnd):
        s0, s1, s2 = bnd_a[j, 0] - o0, bnd_a[j, 1] - o1, bnd_a[j, 2] - o2
        t0, t1, t2 = bnd_b[j, 0] - o0, bnd_b[j, 1] - o1, bnd_b[j, 2] - o2
        w0 = s1 * t2 - s2 * t1
        w1 = s2 * t0 - s0 * t2
        w2 = s0 * t1 - s1 * t0
        boundary += w0 * w0 + w1 * w1 + w2 * w2
    shape = 0.0
    for k in range(n_link):
        d0, d1, d2 = link[k, 0] - o0, link[k, 1] - o1, link[k, 2] - o2
        shape += d0 * d0 + d1 * d1 + d2 * d2
    return (volume_weight * volume / 36.0
            + boundary_weight * edge_sq_len * boundary / 4.0
            + shape_weight * edge_sq_len * edge_sq_len * shape)


# -- texture coordinates in R^5 -----------------------------------------------------------

@njit(cache=True, _nrt=False)
def _add_if_alpha_compatible2(s, n, a0, a1, rhs, ref, cos2):
    """2D version of :func:`_add_if_alpha_compatible`: the unknowns are the two texture
    coordinates (``s`` is the :data:`_System`)."""
    A, b = s.A, s.b
    if n >= 2:
        return n
    aa = a0 * a0 + a1 * a1
    zero = ZERO_TOL * ref
    if not (aa > zero * zero) or not math.isfinite(aa) or not math.isfinite(rhs):
        return n
    if n == 1:
        d = A[0, 0] * a0 + A[0, 1] * a1
        if d * d >= cos2 * aa:
            return n
    inv = 1.0 / math.sqrt(aa)
    A[n, 0] = a0 * inv
    A[n, 1] = a1 * inv
    b[n] = rhs * inv
    return n + 1


@njit(cache=True)
def _add_from_gradient2(s, n, ref, cos2):
    """2D version of :func:`_add_from_gradient` (principal axes of H when n = 0)."""
    if n == 0:
        H = s.H
        theta = 0.5 * math.atan2(2.0 * H[0, 1], H[0, 0] - H[1, 1])
        cs, sn = math.cos(theta), math.sin(theta)
        n = _add_projected_row2(s, n, cs, sn, ref, cos2)
        n = _add_projected_row2(s, n, -sn, cs, ref, cos2)
    elif n == 1:
        n = _add_projected_row2(s, n, -s.A[0, 1], s.A[0, 0], ref, cos2)
    return n


@njit(cache=True, _nrt=False)
def _add_projected_row2(s, n, q0, q1, ref, cos2):
    """Candidate (H q) · uv = -q · c for a unit direction q (``s``: the :data:`_System`)."""
    H, c = s.H, s.c
    return _add_if_alpha_compatible2(s, n, H[0, 0] * q0 + H[0, 1] * q1,
                                     H[1, 0] * q0 + H[1, 1] * q1,
                                     -(c[0] * q0 + c[1] * q1), ref, cos2)


@njit(cache=True)
def _oriented_volume_rows(p, patch, i, uv0, kappa, D, G):
    """Ḡ_T of Eq. 5 for triangle i of ``patch`` into ``G`` (10, 3): row r holds the coefficients
    (of s', t', 1) of the r-th 3x3 minor g_r of the tetrahedron (X, X_1, X_2, X_3) in R⁵,
    X = (p, κ s, κ t), s' = s - uv0[0], t' = t - uv0[1].

    The 4x4 determinants of Eq. 4 (three coordinate rows and a row of ones) equal, up
    to sign, the 3x3 minors of the difference matrix D = [X_j - X] (5x3, one column per
    corner). Each minor is affine in (s', t'): the s row of D is κ (s_j - uv0_s) - κ s',
    so by multilinearity its s' coefficient is -κ times the minor with that row replaced
    by ones (likewise for t', and the s' t' term has two rows of ones and vanishes).
    """
    tri_a, tri_b, tri_c, uv_a, uv_b, uv_c = patch
    for j in range(3):
        D[j, 0] = tri_a[i, j] - p[j]
        D[j, 1] = tri_b[i, j] - p[j]
        D[j, 2] = tri_c[i, j] - p[j]
    for j in range(2):
        D[3 + j, 0] = kappa * (uv_a[i, j] - uv0[j])
        D[3 + j, 1] = kappa * (uv_b[i, j] - uv0[j])
        D[3 + j, 2] = kappa * (uv_c[i, j] - uv0[j])
    for r in range(10):
        ra, rb, rc = _TRIPLES[r, 0], _TRIPLES[r, 1], _TRIPLES[r, 2]
        G[r, 2] = _det3((D[ra, 0], D[ra, 1], D[ra, 2]), (D[rb, 0], D[rb, 1], D[rb, 2]),
                        (D[rc, 0], D[rc, 1], D[rc, 2]))
        G[r, 0] = 0.0
        G[r, 1] = 0.0
        # only rb and rc can be texture rows (3 or 4), since ra < rb < rc <= 4
        if rc == 3:
            G[r, 0] = -kappa * _det3((D[ra, 0], D[ra, 1], D[ra, 2]), (D[rb, 0], D[rb, 1], D[rb, 2]),
                                     (1.0, 1.0, 1.0))
        elif rc == 4 and rb == 3:
            G[r, 0] = -kappa * _det3((D[ra, 0], D[ra, 1], D[ra, 2]), (1.0, 1.0, 1.0),
                                     (D[rc, 0], D[rc, 1], D[rc, 2]))
            G[r, 1] = -kappa * _det3((D[ra, 0], D[ra, 1], D[ra, 2]), (D[rb, 0], D[rb, 1], D[rb, 2]),
                                     (1.0, 1.0, 1.0))
        elif rc == 4:
            G[r, 1] = -kappa * _det3((D[ra, 0], D[ra, 1], D[ra, 2]), (D[rb, 0], D[rb, 1], D[rb, 2]),
                                     (1.0, 1.0, 1.0))


@njit(cache=True)
def r5_texture_coordinates(p, patch, n_tris, kappa, alpha_deg=ALPHA_DEG):
    """Texture coordinates (s, t) of the new vertex by oriented volumes in R⁵.

    Lindstrom & Turk 2000, §4.1.1: every triangle T of one texture patch is lifted to
    R⁵ as (x, y, z, κ s, κ t), and so is the new vertex X = (p, κ s, κ t) with p given.
    The tetrahedron (X, T) has an oriented volume V_T (Eq. 4), a skew 5x5 matrix whose
    10 upper entries g_1..g_10 are the 3x3 minors of [X_1 - X, X_2 - X, X_3 - X] (3 of
    the 5 coordinates each), affine in (s, t): g = Ḡ_T (s, t, 1)ᵀ (Eq. 5). Then

    - preservation (Eq. 6): minimise f_Tp = (1/36) |Σ_T Ḡ_T (s, t, 1)ᵀ|², the squared
      norm of the summed oriented volume;
    - optimisation (Eq. 7): minimise f_To = (1/36) Σ_T |Ḡ_T (s, t, 1)ᵀ|² = Σ_T V_T², the
      sum of squared (unsigned) tetrahedron volumes, V_T² = ½ ‖V_T‖²_F (Eq. 5);

    with the constraint procedure of :func:`lt_placement` in two unknowns: the
    stationarity rows of f_Tp are kept while alpha-compatible, and if fewer than two
    survive, f_To supplies the rest on the remaining free direction (the module
    docstring has notes on the reconstruction).

    Parameters
    ----------
    p : ndarray of shape (3,), float64
        The new vertex (from :func:`lt_placement`).
    patch : Patch
        The triangles around the edge that belong to this texture patch: corners
        (K, 3), same layout and winding as in :func:`lt_placement`, and their texture
        coordinates (K, 2), corner by corner (:data:`Patch`).
    n_tris : int
        Valid rows.
    kappa : float
        The patch's texture scale κ (:func:`texture_kappa`), object length per texture
        length; must be positive.
    alpha_deg : float, default 1.0

    Returns
    -------
    uv : ndarray of shape (2,), float64
        (s, t); zeros when ``ok`` is False.
    ok : bool
        False when fewer than two alpha-compatible constraints exist (e.g. every
        triangle degenerate in R⁵, or non-finite input).

    Raises
    ------
    ValueError
        If ``n_tris`` is negative or exceeds the rows of the arrays, or ``kappa`` <= 0.
    """
    if n_tris < 0 or n_tris > patch.tri_a.shape[0] or n_tris > patch.tri_b.shape[0] \
            or n_tris > patch.tri_c.shape[0] or n_tris > patch.uv_a.shape[0] \
            or n_tris > patch.uv_b.shape[0] or n_tris > patch.uv_c.shape[0]:
        raise ValueError("n_tris must be in [0, rows of tri_*/uv_*]")
    if not kappa > 0.0:
        raise ValueError("kappa must be positive")
    cos2 = math.cos(math.radians(alpha_deg)) ** 2
    uv = np.zeros(2)
    if n_tris == 0:
        return uv, False
    uv0 = np.empty(2)
    uv0[:] = patch.uv_a[0]  # solve for uv - uv0: texture coordinates stay small
    Gsum = np.zeros((10, 3))  # Σ_T Ḡ_T (Eq. 6)
    Ho = np.zeros((2, 2))     # Σ_T Ḡ_Tᵀ Ḡ_T, split into the (s,t) block and c (Eq. 7)
    co = np.zeros(2)
    ref = _r5_volume_sums(p, patch, n_tris, uv0, kappa, Gsum, Ho, co)
    Hp = np.zeros((2, 2))
    cp = np.zeros(2)
    _r5_preservation(Gsum, Hp, cp)
    A = np.zeros((2, 2))
    b = np.zeros(2)
    n = _add_from_gradient2(_System(A=A, b=b, H=Hp, c=cp), np.int64(0), ref * ref, cos2)
    if n < 2:
        ho = math.sqrt(Ho[0, 0] ** 2 + 2.0 * Ho[0, 1] ** 2 + Ho[1, 1] ** 2)
        n = _add_from_gradient2(_System(A=A, b=b, H=Ho, c=co), n, ho, cos2)
    if n < 2:
        return uv, False
    det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    uv[0] = (b[0] * A[1, 1] - b[1] * A[0, 1]) / det + uv0[0]
    uv[1] = (A[0, 0] * b[1] - A[1, 0] * b[0]) / det + uv0[1]
    if not (math.isfinite(uv[0]) and math.isfinite(uv[1])):
        uv[:] = 0.0
        return uv, False
    return uv, True


@njit(cache=True)
def _r5_volume_sums(p, patch, n_tris, uv0, kappa, Gsum, Ho, co):
    """Over the patch's triangles, accumulate Σ_T Ḡ_T into ``Gsum`` (10, 3) (Eq. 6) and
    Σ_T Ḡ_Tᵀ Ḡ_T into its (s, t) block ``Ho`` (2, 2) and linear part ``co`` (2,)
    (Eq. 7). Returns Σ_T ‖Ḡ_T[:, :2]‖_F, the scale of Σ_T Ḡ_T before cancelling."""
    D = np.empty((5, 3))
    G = np.empty((10, 3))
    ref = 0.0
    for i in range(n_tris):
        _oriented_volume_rows(p, patch, i, uv0, kappa, D, G)
        gg = 0.0
        for r in range(10):
            for k in range(3):
                Gsum[r, k] += G[r, k]
            Ho[0, 0] += G[r, 0] * G[r, 0]
            Ho[0, 1] += G[r, 0] * G[r, 1]
            Ho[1, 1] += G[r, 1] * G[r, 1]
            co[0] += G[r, 0] * G[r, 2]
            co[1] += G[r, 1] * G[r, 2]
            gg += G[r, 0] * G[r, 0] + G[r, 1] * G[r, 1]
        ref += math.sqrt(gg)
    Ho[1, 0] = Ho[0, 1]
    return ref


@njit(cache=True)
def _r5_preservation(Gsum, Hp, cp):
    """The quadratic form of |Σ_T Ḡ_T (s, t, 1)ᵀ|² (Eq. 6): (s, t) block ``Hp`` (2, 2)
    and linear part ``cp`` (2,), both zero on entry."""
    for r in range(10):
        Hp[0, 0] += Gsum[r, 0] * Gsum[r, 0]
        Hp[0, 1] += Gsum[r, 0] * Gsum[r, 1]
        Hp[1, 1] += Gsum[r, 1] * Gsum[r, 1]
        cp[0] += Gsum[r, 0] * Gsum[r, 2]
        cp[1] += Gsum[r, 1] * Gsum[r, 2]
    Hp[1, 0] = Hp[0, 1]


@njit(cache=True)
def texture_kappa(vertices, faces, face_uv, face_patch, n_patches):
    """Texture scale κ of each texture patch: average object-space edge length over
    average texture-space edge length (Lindstrom & Turk 2000, §4.1.1).

    Each triangle contributes its three edges, in 3D and in its own texture
    coordinates, so an edge inside a patch counts once from each side and a seam edge
    once for each patch; both averages run over the same edges, so κ is the ratio of
    the two sums. Compute κ once on the input mesh and keep it fixed while simplifying.

    Parameters
    ----------
    vertices : ndarray of shape (n, 3), float64
    faces : ndarray of shape (m, 3), int
    face_uv : ndarray of shape (m, 3, 2), float64
        Texture coordinates of each face corner.
    face_patch : ndarray of shape (m,), int
        Texture patch of each face, in [0, n_patches).
    n_patches : int

    Returns
    -------
    kappa : ndarray of shape (n_patches,), float64
        1.0 for a patch without faces or whose texture edges all have zero length (the
        texture is then constant there and κ does not matter).

    Raises
    ------
    ValueError
        If a face's patch is outside [0, n_patches).
    """
    geo = np.zeros(n_patches)
    tex = np.zeros(n_patches)
    for f in range(faces.shape[0]):
        k = face_patch[f]
        if k < 0 or k >= n_patches:
            raise ValueError("face_patch values must be in [0, n_patches)")
        for j in range(3):
            j1 = (j + 1) % 3
            a, b = faces[f, j], faces[f, j1]
            dx = vertices[a, 0] - vertices[b, 0]
            dy = vertices[a, 1] - vertices[b, 1]
            dz = vertices[a, 2] - vertices[b, 2]
            geo[k] += math.sqrt(dx * dx + dy * dy + dz * dz)
            du = face_uv[f, j, 0] - face_uv[f, j1, 0]
            dv = face_uv[f, j, 1] - face_uv[f, j1, 1]
            tex[k] += math.sqrt(du * du + dv * dv)
    kappa = np.ones(n_patches)
    for k in range(n_patches):
        if tex[k] > 0.0 and geo[k] > 0.0:
            kappa[k] = geo[k] / tex[k]
    return kappa
