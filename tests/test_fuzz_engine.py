"""Random small meshes through every method on the engine: never a crash, and a result
that validates.

The meshes are built as a loader would (:func:`bench.io.validate.build_mesh`) from a
closed or open base (an icosphere, a grid patch, two disjoint parts) at scales from
1e-150 to 1e300, jittered, with UV seams cut into them (render vertices duplicated
with other texture coordinates), and with hostile faces added: duplicated, flipped,
degenerate (a repeated corner, three collinear corners) and non-manifold fans (a third
face on an edge). Each goes through ``quadric``, ``memoryless``, ``canny-texture``,
``image-driven`` and ``entropy-twin`` at a budget between 1 face and half the faces.

What must hold: the loader either refuses the mesh with a clean :class:`InputError` or
returns one; a method then returns a result (no exception of any kind) whose faces
index its vertices, whose positions and texture coordinates are finite, that has no
face with two corners on one welded vertex, no more faces than the input, a stop reason
whenever it is off the target, and, where the input is a closed manifold, no boundary
(the engine never splits the welded topology, so it opens no seam and no hole). The one
refusal allowed is canny-texture's of a mesh without a texture, in one line.

The default profile is fixed-seed and short (the CI's); ``-m slow`` adds a longer one.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.core.errors import InputError
from bench.core.method import run_method, target_tolerance
from bench.core.registry import registry
from bench.io.validate import build_mesh

for name, examples in (("engine", 40), ("engine-long", 300)):
    settings.register_profile(name, derandomize=True, max_examples=examples, deadline=None,
                              suppress_health_check=[HealthCheck.too_slow,
                                                     HealthCheck.data_too_large,
                                                     HealthCheck.function_scoped_fixture])

SCALES = (1e-150, 1e-3, 1.0, 1e3, 1e100, 1e300)

#: Every method on the engine, with small images for the view-based ones.
METHODS = {
    "quadric": {},
    "memoryless": {},
    "canny-texture": {},
    "image-driven": {"resolution": 32, "views": 6},
    "entropy-twin": {"resolution": 32},
}


def _icosphere():
    import trimesh

    ico = trimesh.creation.icosphere(1)
    return np.asarray(ico.vertices), np.asarray(ico.faces)


def _grid(n: int = 4):
    ij = np.stack(np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij"), -1)
    positions = np.concatenate([ij.reshape(-1, 2) / n, np.zeros(((n + 1) ** 2, 1))], axis=1)
    faces = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = i * (n + 1) + j, (i + 1) * (n + 1) + j, (i + 1) * (n + 1) + j + 1, \
                i * (n + 1) + j + 1
            faces += [(a, b, c), (a, c, d)]
    return positions, np.array(faces)


def _two_parts():
    p, f = _icosphere()
    q, g = _grid()
    return np.concatenate([p, q + 3.0]), np.concatenate([f, g + len(p)])


BASES = {"icosphere": _icosphere, "grid": _grid, "two parts": _two_parts}
CLOSED = {"icosphere"}


@st.composite
def meshes(draw):
    """(mesh, closed): a hostile small mesh as the loader returns it, and whether its
    welded topology is a closed manifold."""
    base = draw(st.sampled_from(sorted(BASES)))
    positions, faces = BASES[base]()
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 16)))
    scale = draw(st.sampled_from(SCALES))
    positions = (positions + 0.05 * rng.standard_normal(positions.shape)) * scale
    faces = faces.astype(np.int64)
    closed = base in CLOSED
    uv = None
    if draw(st.booleans()):  # texture coordinates, with a seam cut along some edges
        uv = (positions[:, :2] / scale) % 1.0
        n_cut = draw(st.integers(0, 4))
        for f in rng.choice(len(faces), size=n_cut, replace=False):
            for j in range(2):  # two corners of face f get their own render vertex
                v = faces[f, j]
                positions = np.concatenate([positions, positions[v:v + 1]])
                uv = np.concatenate([uv, (uv[v:v + 1] + 0.37) % 1.0])
                faces[f, j] = len(positions) - 1
    hostile = draw(st.lists(st.sampled_from(("duplicate", "flipped", "repeated corner",
                                             "collinear", "fan")), max_size=4))
    extra = []
    for kind in hostile:
        f = faces[rng.integers(len(faces))]
        if kind == "duplicate":
            extra.append(f.copy())
        elif kind == "flipped":
            extra.append(f[::-1].copy())
        elif kind == "repeated corner":
            extra.append(np.array([f[0], f[0], f[1]]))
        elif kind == "collinear":  # a new vertex at an edge's midpoint
            mid = 0.5 * (positions[f[0]] + positions[f[1]])
            positions = np.concatenate([positions, mid[None]])
            if uv is not None:
                uv = np.concatenate([uv, 0.5 * (uv[f[0]] + uv[f[1]])[None]])
            extra.append(np.array([f[0], f[1], len(positions) - 1]))
        else:  # a third face on edge (f[0], f[1]), to a new vertex off the surface
            apex = positions[f[0]] + (positions[f[1]] - positions[f[2]])
            positions = np.concatenate([positions, apex[None]])
            if uv is not None:
                uv = np.concatenate([uv, uv[f[2]][None]])
            extra.append(np.array([f[1], f[0], len(positions) - 1]))
    if hostile:
        closed = False
        faces = np.concatenate([faces, np.array(extra)])
    texture = None
    if uv is not None:
        texture = rng.integers(0, 256, (16, 16, 3), dtype=np.uint8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            mesh = build_mesh(positions, faces, source="fuzzed", uv=uv, texture=texture,
                              name=f"fuzzed-{base}")
        except InputError as exc:  # a clean refusal is a valid outcome of the loader
            assert "\n" not in str(exc)
            mesh = None
    return mesh, closed


def _welded_edge_counts(mesh) -> np.ndarray:
    w = mesh.welded
    edges = np.sort(np.concatenate([w.faces[:, [0, 1]], w.faces[:, [1, 2]],
                                    w.faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return counts


def _check(name, mesh, closed, target):
    method = registry("method").load(name)(**METHODS[name])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if name == "canny-texture" and not mesh.has_texture:  # refused, in one line
            with pytest.raises(InputError, match=r"^[^\n]*needs a texture and UVs[^\n]*$"):
                run_method(method, mesh, target)
            return
        result = run_method(method, mesh, target)  # any other exception fails the test
    out = result.mesh
    assert out.n_faces >= 1
    assert out.faces.min() >= 0 and out.faces.max() < out.n_vertices
    assert np.isfinite(out.positions).all()
    if out.uv is not None:
        assert np.isfinite(out.uv).all()
    wf = out.welded.faces
    assert ((wf[:, 0] != wf[:, 1]) & (wf[:, 1] != wf[:, 2]) & (wf[:, 2] != wf[:, 0])).all()
    assert out.n_faces <= mesh.n_faces
    if abs(out.n_faces - target) > target_tolerance(target):
        assert result.stop_reason
    if closed:
        assert (_welded_edge_counts(out) == 2).all(), "a closed input came back open"


def _fuzz(name, data):
    mesh, closed = data.draw(meshes())
    if mesh is None:
        return
    closed = closed and (_welded_edge_counts(mesh) == 2).all()
    target = data.draw(st.sampled_from((1, max(1, mesh.n_faces // 10),
                                        max(1, mesh.n_faces // 2))))
    _check(name, mesh, closed, target)


@pytest.mark.parametrize("name", sorted(METHODS))
@settings(settings.get_profile("engine"))
@given(data=st.data())
def test_engine_methods_survive_hostile_meshes(name, data):
    _fuzz(name, data)


@pytest.fixture
def asked_for_slow(request):
    """The long profile runs only when asked for (``-m slow``), not in the default run."""
    if "slow" not in (request.config.getoption("markexpr") or ""):
        pytest.skip("the long fuzzing profile runs with -m slow")


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(METHODS))
@settings(settings.get_profile("engine-long"))
@given(data=st.data())
def test_engine_methods_survive_hostile_meshes_long(asked_for_slow, name, data):
    _fuzz(name, data)


@pytest.mark.parametrize("name", sorted(METHODS))
@pytest.mark.parametrize("exponent", [1000, -500])
def test_a_mesh_near_1e300_or_1e_150_simplifies_as_at_unit_scale(name, exponent):
    """Coordinates of 2^1000 (about 1e301) overflowed squared lengths and 2^-500 (about
    3e-151) underflowed them (entropy-twin failed on its cameras' clipping planes). The
    engine now simplifies such a mesh as a copy scaled by a power of two, so its result
    is the unit-scale result, scaled: the same faces, positions times 2^exponent."""
    from conftest import blob

    mesh = blob(2)
    uv = (mesh.positions[:, :2] + 1.5) / 3.0
    mesh = mesh.replace(uv=uv, texture=np.random.default_rng(3).integers(
        0, 256, (16, 16, 3), dtype=np.uint8))
    method = registry("method").load(name)(**METHODS[name])
    unit = run_method(method, mesh, 60).mesh
    far = run_method(method, mesh.replace(positions=np.ldexp(mesh.positions, exponent)),
                     60).mesh
    np.testing.assert_array_equal(far.faces, unit.faces)
    np.testing.assert_array_equal(far.positions, np.ldexp(unit.positions, exponent))
