"""Seam cracks (:mod:`metrics.topology`): the result's boundary where the original had
none, told apart from a simplified hole.

The cases are a flat plate, hand-built so that every count can be made on paper::

    y
    8 +---+---+---+---+---+---+---+---/      9 x 9 vertices (x, y) at unit spacing,
      |   |   |   |   |   |   |   | / |      each cell split along its rising
      ...                       ...          diagonal; cells (3,3), (4,3), (3,4)
    5 +---+---+---+---+---+/--+---+---+      removed: an L-shaped hole with its
      |   |   |   |###| / |   |   |   |      reflex corner at (4, 4). A UV seam
    4 +---+---+---+---/---+---+---+---+      runs along the diagonal from there
      |   |   |   |###|###|   |   |   |      to the corner (8, 8): the faces above
    3 +---+---+---+---+---+---+---+---+      it use their own copies of its
      ...                                    vertices.
      0   1   2   3   4   5   6   7   8  x

The original's boundary is the outer border (32 edges) and the hole (8 edges). A
"result" is made from it the way simplifiers do: collapsing render vertices (a welded
collapse moves every copy of a vertex: seams stay closed; a collapse on one side's copies
only, or copies moved apart, opens the seam).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.core.mesh import Mesh
from conftest import TET_FACES, TET_POSITIONS
from metrics.topology import counts, crack_edges, seam_cracks

N = 9
HOLE = {(3, 3), (4, 3), (3, 4)}
SEAM_START = 4
#: How far the seam's two copies are moved apart (perpendicular to it), well below
#: SIDE_GAP of the seam's edges (sqrt 2 long): a sliver gap as qslim leaves.
DRIFT = 0.05


def vid(x: int, y: int) -> int:
    """Render vertex of grid point (x, y) used by faces below the seam (and elsewhere)."""
    return y * N + x


def copy(k: int) -> int:
    """Render vertex of the seam vertex (k, k) used by the faces above the seam."""
    return N * N + (k - SEAM_START)


def plate(hole=HOLE, seam: bool = True) -> Mesh:
    """The plate of the module docstring (without the seam if ``seam`` is false)."""
    positions = [(x, y, 0.0) for y in range(N) for x in range(N)]
    uv = [(x / N, y / N) for y in range(N) for x in range(N)]
    if seam:
        positions += [(k, k, 0.0) for k in range(SEAM_START, N)]
        uv += [(k / N + 0.5, k / N) for k in range(SEAM_START, N)]  # another chart

    def corner(x, y, above):
        if seam and above and x == y and x >= SEAM_START:
            return copy(x)
        return vid(x, y)

    faces = []
    for y in range(N - 1):
        for x in range(N - 1):
            if (x, y) in hole:
                continue
            for tri in (((x, y), (x + 1, y), (x + 1, y + 1)),
                        ((x, y), (x + 1, y + 1), (x, y + 1))):
                above = sum(p[1] - p[0] for p in tri) > 0  # centroid above y = x
                faces.append([corner(*p, above) for p in tri])
    return Mesh(np.array(positions, float), np.array(faces), uv=np.array(uv))


def collapse(mesh: Mesh, moves: dict[int, int]) -> Mesh:
    """Half-edge collapses: render vertex ``a`` replaced by ``b`` for each ``a: b`` of
    ``moves``; faces left with a repeated vertex are dropped."""
    faces = mesh.faces.copy()
    for a, b in moves.items():
        faces[faces == a] = b
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & \
        (faces[:, 2] != faces[:, 0])
    return mesh.replace(faces=faces[keep])


def drift(mesh: Mesh, vertices: list[int], step: float = DRIFT) -> Mesh:
    """Render ``vertices`` moved by ``step`` across the seam, above it (towards -x, +y)."""
    positions = mesh.positions.copy()
    positions[vertices] += step * np.array([-1.0, 1.0, 0.0]) / math.sqrt(2)
    return mesh.replace(positions=positions)


def chord_result(original: Mesh) -> Mesh:
    """The hole simplified: its reflex corner (4, 4), where the seam starts, collapsed
    with both its copies onto (5, 4). The hole's loop gets the chord (5,4)-(4,5), whose
    midpoint (4.5, 4.5) lies on the seam and 0.5 from the hole (the rule this module
    replaced counted it as a crack); and (4, 3), the middle of the hole's bottom side,
    moved 0.4 off the hole into the surface, as a collapse's placement moves it."""
    result = collapse(original, {vid(4, 4): vid(5, 4), copy(4): vid(5, 4)})
    positions = result.positions.copy()
    positions[vid(4, 3)] = (4.0, 2.6, 0.0)
    return result.replace(positions=positions)


def opened_result(original: Mesh) -> Mesh:
    """The seam opened as qslim opens it on render vertices: below it, (6, 6) collapsed
    along the seam onto (7, 7) (that side only); above it, the copies of (5, 5), (6, 6)
    and (7, 7) moved DRIFT across it. Its ends, (4, 4) on the hole and (8, 8) on the
    border, stay shut."""
    result = collapse(original, {vid(6, 6): vid(7, 7)})
    return drift(result, [copy(5), copy(6), copy(7)])


def both_result(original: Mesh) -> Mesh:
    """The chord of :func:`chord_result` and the seam opened from (5, 5) on: the copies
    of (6, 6) and (7, 7) above it moved DRIFT across it."""
    result = collapse(original, {vid(4, 4): vid(5, 4), copy(4): vid(5, 4)})
    return drift(result, [copy(6), copy(7)])


def welded_edge(mesh: Mesh, p, q) -> tuple:
    """The welded edge of ``mesh`` between positions ``p`` and ``q`` (x, y)."""
    w = mesh.welded
    index = {tuple(pos[:2]): i for i, pos in enumerate(w.positions)}
    return tuple(sorted((index[tuple(map(float, p))], index[tuple(map(float, q))])))


def edge_set(edges: np.ndarray) -> set:
    return {tuple(e) for e in edges.tolist()}


# -- the original -------------------------------------------------------------------------

def test_the_plate_is_as_drawn():
    mesh = plate()
    summary = mesh.summary()
    assert summary["faces"] == 2 * (8 * 8 - 3)
    assert summary["boundary_edges"] == 4 * 8 + 8
    assert summary["seam_edges"] == N - 1 - SEAM_START  # (4,4)-(5,5) ... (7,7)-(8,8)
    assert summary["non_manifold_edges"] == 0


def test_the_original_itself_has_no_cracks():
    mesh = plate()
    assert seam_cracks(mesh, mesh) == 0


# -- a simplified hole --------------------------------------------------------------------

def test_a_hole_simplified_to_chords_has_no_cracks():
    original = plate()
    result = chord_result(original)
    w = result.welded
    boundary = edge_set(w.edges[w.boundary])
    # the hole's loop lost (5,4)-(4,4) and (4,4)-(4,5) and gained the chord
    assert len(boundary) == 32 + 7
    assert welded_edge(result, (5, 4), (4, 5)) in boundary
    assert seam_cracks(original, result) == 0


# -- an opened seam -----------------------------------------------------------------------

def test_a_seam_opened_on_render_vertices_counts_both_sides():
    original = plate()
    result = opened_result(original)
    w = result.welded
    assert w.boundary.sum() == 32 + 8 + 7
    below = [((4, 4), (5, 5)), ((5, 5), (7, 7)), ((7, 7), (8, 8))]
    got = edge_set(crack_edges(original, result))
    assert {welded_edge(result, p, q) for p, q in below} <= got
    # above: (4,4)-(5,5)'-(6,6)'-(7,7)'-(8,8), the middle vertices moved
    assert len(got) == 3 + 4
    # the ends of each side lie within an edge of the hole or the border: they count
    # because the other side runs alongside them, on the seam
    assert seam_cracks(original, result) == 7


def test_the_sides_count_only_while_they_run_alongside_each_other():
    """Opened wider than SIDE_GAP, the sides' ends within an edge of the hole or the
    border are taken for the hole's or the border's (the limit the module docstring
    states). The copies above moved 0.5 across: the sides' midpoints are then at least
    0.236 from each other's edges, beyond SIDE_GAP of them (0.141 to 0.283). Below, all
    three edges have both ends within an edge of the hole or the border (the longest
    edge at (5, 5) and (7, 7) is the collapsed one, 2 sqrt 2 long); above, only the two
    edges at the moved (6, 6) count: it is 1.65 from the border, beyond its 1.41 edges."""
    original = plate()
    result = drift(collapse(original, {vid(6, 6): vid(7, 7)}),
                   [copy(5), copy(6), copy(7)], step=0.5)
    assert result.welded.boundary.sum() == 32 + 8 + 7
    assert seam_cracks(original, result) == 2


def test_a_hole_and_an_opened_seam_in_one_mesh():
    original = plate()
    result = both_result(original)
    w = result.welded
    assert w.boundary.sum() == 32 + 7 + 6
    got = edge_set(crack_edges(original, result))
    chord = welded_edge(result, (5, 4), (4, 5))
    assert chord not in got
    below = [((5, 5), (6, 6)), ((6, 6), (7, 7)), ((7, 7), (8, 8))]
    assert {welded_edge(result, p, q) for p, q in below} <= got
    assert len(got) == 6


def test_a_tear_away_from_seams_and_holes_is_a_crack():
    """A plate without hole or seam, its cells (4, 4) and (0, 4) removed. The first is
    a tear, 3 from the border: its 4 edges are cracks. The second is a notch in the
    border: its 3 new edges end on the border or 1 from it, within their sqrt 2 edges,
    so they are taken for the border's, as a simplified border would be."""
    original = plate(hole=set(), seam=False)

    def cell(x, y):
        return {vid(x, y), vid(x + 1, y), vid(x + 1, y + 1), vid(x, y + 1)}

    faces = [f for f in original.faces.tolist()
             if not (set(f) <= cell(4, 4) or set(f) <= cell(0, 4))]
    result = original.replace(faces=np.array(faces))
    assert result.welded.boundary.sum() == 32 - 1 + 3 + 4
    assert seam_cracks(original, result) == 4


# -- closed meshes ------------------------------------------------------------------------

def cube() -> Mesh:
    """A unit cube with one chart per side (24 render vertices): closed, every edge a
    seam, like the ``crate`` model."""
    corners = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    sides = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2),
             (1, 3, 7, 5)]  # counter-clockwise seen from outside
    positions, faces = [], []
    for side in sides:
        base = len(positions)
        positions += [corners[c] for c in side]
        faces += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    return Mesh(np.array(positions), np.array(faces))


def test_without_a_boundary_in_the_original_every_boundary_edge_is_a_crack():
    original = cube()
    assert original.summary()["boundary_edges"] == 0
    assert original.summary()["seam_edges"] == 12
    positions = original.positions.copy()
    top = slice(4, 8)  # the side z = 1
    positions[top] = 0.5 + 0.9 * (positions[top] - 0.5) * [1, 1, 0] + [0, 0, 0.5]
    result = original.replace(positions=positions)
    # the top's 4 edges and the 4 top edges of the walls
    assert result.welded.boundary.sum() == 8
    assert seam_cracks(original, result) == 8


def test_a_closed_result_has_no_cracks():
    original = plate()
    closed = Mesh(TET_POSITIONS, TET_FACES)
    assert seam_cracks(original, closed) == 0
    assert seam_cracks(cube(), cube()) == 0


def test_counts_carry_the_crack_count():
    original = plate()
    assert counts(original, opened_result(original))["seam_cracks"] == 7


# -- properties -----------------------------------------------------------------------------

@st.composite
def plates(draw):
    """Small plates with random holes and random charts (seams wherever two faces of
    different charts meet)."""
    n = draw(st.integers(3, 7))
    cells = [(x, y) for y in range(n - 1) for x in range(n - 1)]
    hole = draw(st.sets(st.sampled_from(cells), max_size=len(cells) - 1))
    charts = draw(st.lists(st.integers(0, 2), min_size=2 * len(cells),
                           max_size=2 * len(cells)))
    positions, faces, index = [], [], {}
    for c, (x, y) in enumerate(cells):
        if (x, y) in hole:
            continue
        for t, tri in enumerate((((x, y), (x + 1, y), (x + 1, y + 1)),
                                 ((x, y), (x + 1, y + 1), (x, y + 1)))):
            chart = charts[2 * c + t]
            face = []
            for p in tri:
                if (p, chart) not in index:
                    index[p, chart] = len(positions)
                    positions.append((*p, 0.0))
                face.append(index[p, chart])
            faces.append(face)
    return Mesh(np.array(positions, float), np.array(faces))


def similarity(scale: float, angle: float, shift) -> np.ndarray:
    """A 4x4 similarity transform: rotation about (1, 2, 3), scale, then shift."""
    axis = np.array([1.0, 2.0, 3.0]) / math.sqrt(14)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rotation = np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k
    m = np.eye(4)
    m[:3, :3] = scale * rotation
    m[:3, 3] = shift
    return m


def transformed(mesh: Mesh, m: np.ndarray) -> Mesh:
    return mesh.replace(positions=mesh.positions @ m[:3, :3].T + m[:3, 3])


transforms = st.builds(similarity, st.floats(1e-3, 1e3), st.floats(0, 2 * math.pi),
                       st.tuples(*[st.floats(-1e3, 1e3)] * 3))


@settings(max_examples=60, deadline=None)
@given(plates(), transforms)
def test_a_result_equal_to_its_original_has_no_cracks(mesh, m):
    mesh = transformed(mesh, m)
    assert seam_cracks(mesh, mesh) == 0


@settings(max_examples=40, deadline=None)
@given(transforms)
def test_counts_do_not_depend_on_position_orientation_or_scale(m):
    original = plate()
    for make, expected in ((chord_result, 0), (opened_result, 7), (both_result, 6)):
        result = make(original)
        assert seam_cracks(transformed(original, m), transformed(result, m)) == expected


@pytest.mark.parametrize("make", [chord_result, opened_result, both_result])
def test_the_hand_counts_hold_with_the_faces_in_another_order(make):
    original = plate()
    result = make(original)
    order = np.random.default_rng(0).permutation(result.n_faces)
    shuffled = result.replace(faces=result.faces[order][:, [1, 2, 0]])
    assert seam_cracks(original, shuffled) == seam_cracks(original, result)
