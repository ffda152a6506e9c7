"""The model catalog and the procedural torus."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from bench.catalog import BUNNY, BUNNY_TEXTURED, TORUS, resolve_model
from bench.catalog.torus import make_torus, torus_texture
from bench.core.errors import UnknownNameError
from conftest import write


def signed_volume(positions: np.ndarray, faces: np.ndarray) -> float:
    """Volume enclosed by a closed triangle mesh, by the divergence theorem: the sum of
    the signed volumes of the tetrahedra (origin, a, b, c). Positive when the faces are
    wound counter-clockwise seen from outside."""
    a, b, c = (positions[faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->", a, np.cross(b, c))) / 6.0


def edge_face_counts_by_position(positions: np.ndarray, faces: np.ndarray) -> Counter:
    """Faces per undirected edge, with vertices identified by their exact coordinates
    (an independent weld, not bench.core.mesh's)."""
    key = [tuple(p) for p in positions.tolist()]
    counts = Counter()
    for f in faces.tolist():
        for i in range(3):
            a, b = key[f[i]], key[f[(i + 1) % 3]]
            counts[(min(a, b), max(a, b))] += 1
    return counts


# -- catalog ----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def bunny():
    return BUNNY.load()


@pytest.fixture(scope="module")
def torus():
    return TORUS.load()


def test_bunny(bunny):
    assert bunny.name == "bunny"
    assert bunny.n_faces == 56172
    assert bunny.n_vertices == 28088
    assert bunny.uv is None and bunny.texture is None
    assert not bunny.has_texture
    assert bunny.metadata["model"] == "bunny"


def test_bunny_textured(bunny_textured):
    m = bunny_textured
    assert m.name == "bunny-textured"
    assert m.n_faces == 9999
    assert m.n_vertices == 6451
    assert m.welded.n_vertices == 5051
    assert m.has_texture
    assert m.texture.ndim == 3 and m.texture.shape[2] in (3, 4)
    assert m.welded.seam.sum() > 0
    assert np.isfinite(m.uv).all()


def test_torus(torus):
    assert torus.name == "torus"
    assert torus.n_faces == 65536
    assert torus.n_vertices == 33153  # 257 x 129 grid, wrap rows duplicated
    assert torus.welded.n_vertices == 32768  # 256 x 128
    assert torus.welded.boundary.sum() == 0
    assert torus.welded.non_manifold.sum() == 0
    assert torus.welded.seam.sum() == 256 + 128  # the two wrap seams
    assert torus.texture.shape == (1024, 1024, 3)
    assert torus.texture.dtype == np.uint8
    assert torus.has_texture


def test_torus_volume_matches_pappus(torus):
    # An ellipse of semi-axes 0.42, 0.18 swept around a circle of radius 1 with its
    # centroid on the circle: V = area * path length = (pi a b)(2 pi).
    exact = np.pi * 0.42 * 0.18 * 2 * np.pi
    volume = signed_volume(torus.welded.positions, torus.welded.faces)
    assert volume == pytest.approx(exact, rel=0.01)


def test_catalog_specs_are_described():
    for spec in (BUNNY, BUNNY_TEXTURED, TORUS):
        assert spec.name and spec.description and spec.source


# -- make_torus -----------------------------------------------------------------------------

def test_make_torus_sizes():
    m = make_torus(16, 8)
    assert m.n_faces == 2 * 16 * 8
    assert m.n_vertices == 17 * 9
    assert m.welded.n_vertices == 16 * 8
    assert m.texture.shape == (1024, 1024, 3)
    assert m.metadata["seed"] == 2000


def test_make_torus_is_deterministic():
    a, b = make_torus(16, 8), make_torus(16, 8)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.faces, b.faces)
    np.testing.assert_array_equal(a.uv, b.uv)
    np.testing.assert_array_equal(a.texture, b.texture)


def test_make_torus_seed_changes_only_the_texture():
    a, b = make_torus(16, 8), make_torus(16, 8, seed=7)
    assert not np.array_equal(a.texture, b.texture)
    np.testing.assert_array_equal(a.positions, b.positions)
    assert b.metadata["seed"] == 7


def test_torus_texture_size_and_background():
    tex = torus_texture(64, seed=1)
    assert tex.shape == (64, 64, 3) and tex.dtype == np.uint8
    # mostly white background
    assert (tex == 255).all(axis=2).mean() > 0.3


def test_make_torus_is_outward_oriented():
    m = make_torus(16, 8)
    assert signed_volume(m.positions, m.faces) > 0
    flipped = m.faces[:, ::-1]
    assert signed_volume(m.positions, flipped) < 0


def test_make_torus_welded_is_a_closed_manifold():
    m = make_torus(16, 8)
    counts = edge_face_counts_by_position(m.positions, m.faces)
    assert set(counts.values()) == {2}
    assert len(counts) == 3 * 16 * 8
    w = m.welded
    assert len(w.edges) == len(counts)
    assert (w.edge_face_count == 2).all()
    assert w.n_vertices - len(w.edges) + m.n_faces == 0  # Euler characteristic of a torus


def test_make_torus_faces_consistently_oriented():
    # On a closed oriented manifold every directed (welded) edge occurs exactly once.
    w = make_torus(16, 8).welded
    directed = w.faces[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2)
    assert len(np.unique(directed, axis=0)) == len(directed)


def test_make_torus_seams_are_where_uv_wraps():
    m = make_torus(16, 8)
    assert m.welded.seam.sum() == 16 + 8
    assert m.uv.min() == 0.0 and m.uv.max() == 1.0


def test_make_torus_rejects_too_few_segments():
    with pytest.raises(ValueError, match="at least 3 segments"):
        make_torus(2, 8)
    with pytest.raises(ValueError, match="at least 3 segments"):
        make_torus(8, 2)


# -- resolve_model ----------------------------------------------------------------------------

def test_resolve_model_by_name_is_cached(bunny_textured):
    a = resolve_model("bunny-textured")
    assert a is resolve_model("bunny-textured")
    assert a.n_faces == bunny_textured.n_faces


def test_resolve_model_with_a_path_loads_the_file(tmp_path):
    path = write(tmp_path / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    mesh = resolve_model(str(path))
    assert mesh.name == "tri"
    assert mesh.n_faces == 1


def test_resolve_model_with_relative_file_name(tmp_path, monkeypatch):
    write(tmp_path / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    monkeypatch.chdir(tmp_path)
    assert resolve_model("tri.obj").n_faces == 1


def test_resolve_model_unknown_name():
    with pytest.raises(UnknownNameError, match=r"unknown model 'bunnny'; did you mean 'bunny'"):
        resolve_model("bunnny")


def test_resolve_model_unknown_name_without_suggestion():
    with pytest.raises(UnknownNameError, match=r"unknown model 'zzzz' \(not a file either"):
        resolve_model("zzzz")
