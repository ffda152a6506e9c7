"""The example plug-in: its method and metric on tiny meshes with exact expectations, and
both found by bench through their entry points once the package is installed."""

import numpy as np
import pytest
from bench_example.area import AREA_CHANGE, area_change
from bench_example.clustering import VertexClustering, cluster

from bench.core.mesh import Mesh
from bench.core.method import run_method
from bench.core.registry import registry


def grid(n: int, uv: bool = False) -> Mesh:
    """A flat n × n grid of squares on [0, 1]², two triangles each."""
    t = np.linspace(0.0, 1.0, n + 1)
    x, y = np.meshgrid(t, t)
    positions = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    faces = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            faces += [(a, a + 1, a + n + 2), (a, a + n + 2, a + n + 1)]
    return Mesh(positions, np.array(faces), uv=positions[:, :2] if uv else None, name="grid")


def test_the_grid_of_the_mesh_itself_keeps_every_face():
    mesh = grid(4)  # vertices at 0, 1/4, ..., 1: with cells of 1/5 each has its own
    result = cluster(mesh, 5)
    assert result.n_faces == mesh.n_faces == 32
    assert np.array_equal(result.faces, mesh.faces)


def test_two_cells_a_side_leave_the_square_as_two_triangles():
    # cells of 1/2: coordinates 0, 1/4 fall in the first (mean 1/8), 1/2, 3/4 and 1 (the
    # far side is clipped into the last cell) in the second (mean 3/4)
    result = cluster(grid(4), 2)
    assert result.n_faces == 2
    assert sorted(map(tuple, result.positions[:, :2].tolist())) == [
        (0.125, 0.125), (0.125, 0.75), (0.75, 0.125), (0.75, 0.75)]


def test_one_cell_leaves_nothing():
    assert cluster(grid(4), 1).n_faces == 0


def test_the_method_reaches_at_most_its_target_and_keeps_uvs():
    mesh = grid(16, uv=True)
    result = run_method(VertexClustering(), mesh, 100)
    assert 0 < result.mesh.n_faces <= 100
    assert result.stats["cells"] >= 2
    # each vertex kept its own UV: a UV of the input's vertex at the same grid point
    assert set(map(tuple, result.mesh.uv.tolist())) <= set(map(tuple, mesh.uv.tolist()))


def test_area_change_is_exact_on_a_half_and_a_doubled_square():
    square = grid(1)
    half = square.keep_faces(square.faces[:1])
    doubled = square.replace(positions=square.positions * [2.0, 1.0, 1.0])
    assert area_change(square, square, {}) == 0.0
    assert area_change(square, half, {}) == 0.5
    assert area_change(square, doubled, {}) == 1.0
    assert AREA_CHANGE.direction == "lower is better"


def test_area_change_is_undefined_without_area():
    flat = Mesh([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])
    assert area_change(flat, flat, {}) is None


@pytest.mark.parametrize("kind, name", [("method", "vertex-clustering"),
                                        ("metric", "area_change")])
def test_registered_through_its_entry_point(kind, name):
    entry = registry(kind).entry(name)
    assert entry.available, entry.problem
    assert entry.load() is (VertexClustering if kind == "method" else AREA_CHANGE)


def test_a_grid_of_one_cell_is_refused_by_the_declared_range():
    from bench.core.errors import ParamError

    with pytest.raises(ParamError, match="max_cells"):
        VertexClustering(max_cells=1)
