"""Random small OBJ texts through the loader: each is refused with a clean InputError or
loads as a mesh that validates (indices in range, finite positions, no degenerate face).

The texts mix duplicate, flipped and degenerate faces, polygons (convex or not), faces
of 1 or 2 corners, disconnected parts, relative and out-of-range indices (of vertices
and texture coordinates), at scales from 1e-150 to 1e300. A fixed-seed profile keeps
the run short and the same on every machine.
"""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.core.errors import InputError
from bench.core.mesh import face_normals
from bench.io.meshio import load_mesh

settings.register_profile("loader", derandomize=True, max_examples=120, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])

SCALES = (1e-150, 1e-3, 1.0, 1e3, 1e100, 1e300)


@st.composite
def obj_texts(draw) -> str:
    scale = draw(st.sampled_from(SCALES))
    parts = draw(st.integers(1, 2))
    lines, n_v = [], 0
    for part in range(parts):
        count = draw(st.integers(3, 6))
        for _ in range(count):
            x, y, z = (draw(st.integers(-3, 3)) for _ in range(3))
            lines.append(f"v {(x + 10 * part) * scale!r} {y * scale!r} {z * scale!r}")
        n_v += count
        for _ in range(draw(st.integers(1, 6))):
            size = draw(st.sampled_from((1, 2, 3, 3, 3, 4, 5)))
            corners = [draw(st.integers(n_v - count + 1, n_v)) for _ in range(size)]
            if draw(st.integers(0, 9)) == 0:  # out of range, zero or relative
                corners[0] = draw(st.sampled_from((0, n_v + 1, -(n_v + 1), -1)))
            lines.append("f " + " ".join(map(str, corners)))
            if draw(st.booleans()):  # duplicated, or flipped
                lines.append("f " + " ".join(map(str, corners[::draw(st.sampled_from((1, -1)))])))
    if draw(st.booleans()):  # texture coordinates, sometimes indexed out of range
        lines.append("vt 0 0\nvt 1 0")
        top = draw(st.sampled_from((2, 3)))
        lines.append(f"f 1/1 2/2 3/{top}")
    return "\n".join(lines) + "\n"


@settings(settings.get_profile("loader"))
@given(obj_texts())
def test_loader_refuses_cleanly_or_returns_a_valid_mesh(text):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.obj"
        path.write_text(text)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                mesh = load_mesh(path)
            except InputError as exc:
                message = str(exc)
                assert message.startswith(str(path)) and "\n" not in message, message
                return
    assert mesh.n_faces > 0
    assert np.isfinite(mesh.positions).all()
    assert ((mesh.faces >= 0) & (mesh.faces < mesh.n_vertices)).all()
    welded = mesh.welded.faces
    assert (welded[:, 0] != welded[:, 1]).all() and (welded[:, 1] != welded[:, 2]).all() \
        and (welded[:, 2] != welded[:, 0]).all()
    assert face_normals(mesh.positions, mesh.faces).any(axis=1).all()
