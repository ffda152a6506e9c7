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


#: Corner forms of a face: the kinds of index each has (v, vt, vn), as OBJ writes them.
FORMS = {"v": "{v}", "v/vt": "{v}/{t}", "v//vn": "{v}//{n}", "v/vt/vn": "{v}/{t}/{n}"}


@st.composite
def triangle_files(draw) -> bytes:
    """OBJ texts near the common case: triangles of one corner form with indices in
    range, in half of them with one thing that makes a file uncommon (another form in
    one corner, an index 0, negative, past the end or of 18 digits, a polygon, a short
    face), with CRLF line ends, tabs and material lines drawn now and then."""
    counts = [draw(st.integers(1, 5)) for _ in range(3)]
    heads = ["v", "vt", "vn"]
    lines = [f"{heads[k]}{draw(st.sampled_from([' ', chr(9)]))}0 0 0"
             for k in range(3) for _ in range(counts[k])]
    lines = draw(st.permutations(lines))
    form = draw(st.sampled_from(sorted(FORMS)))
    faces = []
    for _ in range(draw(st.integers(1, 5))):
        faces.append([{"form": form, "v": draw(st.integers(1, counts[0])),
                       "t": draw(st.integers(1, counts[1])),
                       "n": draw(st.integers(1, counts[2]))} for _ in range(3)])
    flaw = draw(st.sampled_from([None, None, None, None, None, "form", "zero", "negative",
                                 "past", "long", "polygon", "short"]))
    face, corner = draw(st.sampled_from(faces)), draw(st.integers(0, 2))
    key = draw(st.sampled_from("vtn"))
    if flaw == "form":
        face[corner]["form"] = draw(st.sampled_from(sorted(FORMS)))
    elif flaw in ("zero", "negative", "past", "long"):
        face[corner][key] = {"zero": 0, "negative": -1, "past": 6,
                             "long": "000000000000000001"}[flaw]
    elif flaw == "polygon":
        face.append(dict(face[0]))
    elif flaw == "short":
        face.pop()
    for corners in faces:
        sep = draw(st.sampled_from([" ", "  ", chr(9)]))
        text = sep.join(FORMS[c["form"]].format(**c) for c in corners)
        lines.insert(draw(st.integers(0, len(lines))), "f" + sep + text)
    for extra in draw(st.lists(st.sampled_from(["usemtl red", "usemtl blue", "mtllib a.mtl",
                                                "# f 1 2 3", "vp 0 0"]), max_size=3)):
        lines.insert(draw(st.integers(0, len(lines))), extra)
    end = draw(st.sampled_from(["\n", "\r\n"]))
    return (end.join(lines) + draw(st.sampled_from(["", end]))).encode()


@settings(settings.get_profile("loader"))
@given(triangle_files())
def test_the_whole_file_scan_reads_as_the_line_by_line_scan(data):
    """bench.io.meshio._ObjLines.triangles, which reads the common case as a whole, gives
    what reading line by line gives, or leaves the file to it (and its errors)."""
    from bench.io import meshio

    def scanned(whole: bool):
        try:
            if not whole:
                meshio._ObjLines.triangles = classmethod(lambda cls, *a: None)
            return meshio._scan_obj(path)
        except InputError as exc:
            return str(exc)
        finally:
            meshio._ObjLines.triangles = fast

    fast = vars(meshio._ObjLines)["triangles"]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.obj"
        path.write_bytes(data)
        assert scanned(True) == scanned(False)


def test_the_whole_file_scan_takes_the_common_case():
    from bench.io import meshio

    data = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\r\nusemtl red\nf 1//1 2//1\t3//1\r\n"
    lines = meshio._ObjLines.triangles(Path("m.obj"), data, "utf-8")
    assert lines.counts == [3, 0, 1] and list(lines.usemtl) == ["red"]
    assert meshio._ObjLines.triangles(Path("m.obj"), data.replace(b"3//1", b"4//1"),
                                      "utf-8") is None
