"""The 3D view's files: the GLB of each job's evaluated mesh and of its original (what a
job hands back), and what the report makes of a run folder's GLBs — a classic-script
wrapper per GLB, the vendored three.js copied in, a viewer per model whose page names
only files inside the run folder, everything from a record escaped, and a GLB that is
not what it should be refused with a reason. Meshes are hand-built and tiny; nothing
is simplified or rendered (tests/test_report_browser.py opens a real run's view).
"""

from __future__ import annotations

import base64
import hashlib
import json
import posixpath
import re
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import pytest
import trimesh

from bench.run.jobs import Job, JobResult, _mesh_files, mesh_paths, store_result
from bench.records.results import load_records, write_record
from bench.io.meshio import glb_bytes, load_mesh
from bench.core.mesh import Mesh
from bench.report.page import write_report
from bench.report.viewer import VIEWER_SCRIPT, glb_problem, wrapper_path
from conftest import SEAM_FACES, SEAM_POSITIONS, SEAM_UV, icosphere
from conftest import made_up_record as record

VENDOR = Path(__file__).parent.parent / "bench" / "report" / "vendor" / "three"


def textured_seam() -> Mesh:
    """The two-triangle seam mesh with a 4 × 2 texture of distinct colours."""
    texture = np.arange(4 * 2 * 3, dtype=np.uint8).reshape(2, 4, 3) * 10
    return Mesh(SEAM_POSITIONS, SEAM_FACES, uv=SEAM_UV, texture=texture, name="seam")


def test_a_glb_keeps_faces_uvs_texture_and_normals():
    mesh = textured_seam()
    data = glb_bytes(mesh.replace(normals=mesh.vertex_normals), "lod")
    assert data[:4] == b"glTF" and glb_problem(data) is None
    loaded = trimesh.load(trimesh.util.wrap_as_stream(data), file_type="glb", force="mesh",
                          process=False)
    assert len(loaded.faces) == 2 and len(loaded.vertices) == 6  # the seam's copies kept
    assert np.allclose(loaded.visual.uv, SEAM_UV)
    image = np.asarray(loaded.visual.material.baseColorTexture.convert("RGB"))
    assert np.array_equal(image, mesh.texture)
    assert np.allclose(loaded.vertex_normals, [[0, 0, 1]] * 6)


def test_a_job_hands_back_its_glb_and_the_originals(tmp_path):
    original = icosphere(2, name="ico")
    lod = icosphere(1, name="ico")
    job = Job("ico.obj", "qslim", 80)
    result = JobResult(job, record())
    _mesh_files(job, original, lod, result)
    mine, theirs = mesh_paths(job.key, original.content_hash)
    assert mine == f"meshes/{job.key}.glb"
    assert theirs == f"meshes/original__{original.content_hash[:12]}.glb"
    assert list(result.files) == [mine] and list(result.shared_files) == [theirs]
    assert "mesh_file_error" not in result.record
    # files first, then the record; the original written only once per model
    store_result(tmp_path, result)
    for path, faces in ((mine, 80), (theirs, 320)):
        back = load_mesh(tmp_path / path)
        assert back.n_faces == faces
    (tmp_path / theirs).write_bytes(b"kept")
    store_result(tmp_path, result)
    assert (tmp_path / theirs).read_bytes() == b"kept"


def test_a_mesh_glb_cannot_hold_leaves_the_job_ok_with_the_reason():
    huge = icosphere(1, name="huge")
    huge = huge.replace(positions=huge.positions * 1e300)
    job = Job("huge", "qslim", 40)
    result = JobResult(job, record())
    _mesh_files(job, huge, huge, result)
    assert result.files == {} and result.shared_files == {}
    error = result.record["mesh_file_error"]
    assert "do not fit the 32-bit floats" in error and "\n" not in error
    assert error.count("meshes/") == 2


def _glb(mesh: Mesh) -> bytes:
    return glb_bytes(mesh.replace(normals=mesh.vertex_normals))


def _run(tmp_path: Path, records: list[dict], meshes: dict[str, bytes]) -> Path:
    run = tmp_path / "run"
    for i, r in enumerate(records):
        write_record(run / "records" / f"r{i}.json", r)
    for name, data in meshes.items():
        path = run / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    return run


def _lod_record(label: str, faces: int, digest: str, **changes) -> dict:
    """An ok record of model ``m`` (320 faces, content hash ``digest``) at ``faces``,
    whose files are named after the key ``<label>-<faces>``."""
    r = record(label=label, **changes)
    r["job"]["target_faces"] = faces
    r["metrics"]["faces"] = faces
    r["model"] = {"name": "m", "hash": digest, "faces": 320}
    r["job"]["key"] = f"{label}-{faces}"
    return r


def _viewer_files(page: str) -> list[str]:
    """Every file a page's 3D view names (data-* attributes of its options)."""
    return re.findall(r"data-(?:lod|original|lod-glb|original-glb|three)='([^']*)'", page)


def test_the_report_wraps_each_glb_and_names_only_files_of_the_run(tmp_path):
    digest = "ab" * 20
    records = [_lod_record("q", 80, digest), _lod_record("q", 20, digest)]
    meshes = {f"meshes/q-{n}.glb": _glb(icosphere(1)) for n in (80, 20)}
    meshes[f"meshes/original__{digest[:12]}.glb"] = _glb(icosphere(2))
    run = _run(tmp_path, records, meshes)
    write_report(run)
    page = (run / "index.html").read_text()
    assert page.count(VIEWER_SCRIPT) == 1 and page.count("<div class='viewer3d'") == 1
    named = _viewer_files(page)
    assert "vendor/three.min.js" in named
    assert {"meshes/q-80.glb", "meshes/q-20.glb", "meshes/js/q-80.glb.js",
            "meshes/js/q-20.glb.js", f"meshes/js/original__{digest[:12]}.glb.js"} <= set(named)
    for name in named:
        path = (run / name).resolve()
        assert path.is_relative_to(run.resolve()) and path.is_file(), name
    # the bundle is the vendored one, with its licence; a wrapper holds the GLB's bytes
    assert (run / "vendor/three.min.js").read_bytes() == (VENDOR / "three.min.js").read_bytes()
    assert (run / "vendor/three.LICENSE.txt").read_text().startswith("The MIT License")
    wrapper = (run / "meshes/js/q-80.glb.js").read_text()
    ident, text = re.fullmatch(r'\(window\.benchGlb=window\.benchGlb\|\|\{\}\)\["([0-9a-f]{16})"\]'
                               r'="([A-Za-z0-9+/=]*)";\n', wrapper).groups()
    assert base64.b64decode(text) == meshes["meshes/q-80.glb"]
    assert f"data-lod-id='{ident}'" in page
    # the largest budget first and selected, each with the record's face count
    options = re.findall(r"<option( selected)? data-lod='([^']*)'.*?data-faces='(\d+)'", page)
    assert options == [(" selected", "meshes/js/q-80.glb.js", "80"),
                       ("", "meshes/js/q-20.glb.js", "20")]
    version = dict(line.split(" ", 1) for line in (VENDOR / "VERSION").read_text().splitlines())
    assert hashlib.sha256((VENDOR / "three.min.js").read_bytes()).hexdigest() == version["sha256"]


def test_names_in_the_view_are_escaped(tmp_path):
    hostile = "<script>alert(1)</script>"
    digest = "cd" * 20
    r = _lod_record("q", 80, digest)
    r["job"]["label"] = f"q[x={hostile}]"
    r["job"]["model"] = f"<img src=x onerror=alert(2)>{hostile}"
    broken = _lod_record("q", 20, digest, mesh_file_error=f"</option>{hostile}")
    broken["job"]["model"] = r["job"]["model"]
    run = _run(tmp_path, [r, broken], {"meshes/q-80.glb": _glb(icosphere(1)),
                                       f"meshes/original__{digest[:12]}.glb": _glb(icosphere(1))})
    write_report(run)
    page = (run / "index.html").read_text()
    view = page[page.index("<h3>3D view"):page.index("v3d-caption")]
    assert "<script" not in view and "<img" not in view
    assert "q[x=&lt;script&gt;alert(1)&lt;/script&gt;]" in view
    # the job whose mesh could not be written is listed, disabled, with its reason
    assert "<option disabled>" in view and "&lt;/option&gt;&lt;script&gt;" in view


HOSTILE_GLBS = {
    "not a GLB": (b"PK\x03\x04 a zip", "not a GLB file"),
    "truncated": (None, "not a whole glTF 2 binary file"),
    "a uri": (None, "name a file or address outside it"),
}


def _with_uri(data: bytes) -> bytes:
    """``data`` (a GLB) with its image pointing at an address."""
    n = struct.unpack_from("<I", data, 12)[0]
    tree = json.loads(data[20:20 + n])
    tree["images"] = [{"uri": "http://example.com/x.png"}]
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    rest = data[20 + n:]
    out = struct.pack("<II", len(text), 0x4E4F534A) + text + rest
    return b"glTF" + struct.pack("<II", 2, 12 + len(out)) + out


@pytest.mark.parametrize("case", list(HOSTILE_GLBS))
def test_a_glb_that_is_not_what_it_should_be_is_refused(tmp_path, case):
    good = _glb(icosphere(1))
    data, why = HOSTILE_GLBS[case]
    data = {"truncated": good[:-8], "a uri": _with_uri(good)}.get(case, data)
    digest = "ef" * 20
    r = _lod_record("q", 80, digest)
    run = _run(tmp_path, [r], {"meshes/q-80.glb": data,
                               f"meshes/original__{digest[:12]}.glb": good})
    with pytest.warns(Warning, match=why):
        write_report(run)
    page = (run / "index.html").read_text()
    assert why in page and "&#x27;meshes/q-80.glb&#x27;" in page
    assert not (run / "meshes/js/q-80.glb.js").exists()
    assert "No 3D meshes for this model" in page and VIEWER_SCRIPT not in page


def test_a_glb_linked_from_outside_the_run_folder_is_not_read(tmp_path):
    secret = tmp_path / "secret.glb"
    secret.write_bytes(_glb(icosphere(3)))  # unlike any mesh of the run
    digest = "01" * 20
    r = _lod_record("q", 80, digest)
    run = _run(tmp_path, [r], {f"meshes/original__{digest[:12]}.glb": _glb(icosphere(1))})
    (run / "meshes" / "q-80.glb").symlink_to(secret)
    with pytest.warns(Warning, match="outside the run folder"):
        write_report(run)
    assert not (run / "meshes/js/q-80.glb.js").exists()
    assert base64.b64encode(secret.read_bytes()).decode() not in "".join(
        p.read_text() for p in run.rglob("*.js") if p.name != "three.min.js")
    assert "No 3D meshes for this model" in (run / "index.html").read_text()


def test_a_single_file_report_leaves_the_view_out_and_says_so(tmp_path):
    digest = "23" * 20
    r = _lod_record("q", 80, digest)
    run = _run(tmp_path, [r], {"meshes/q-80.glb": _glb(icosphere(1)),
                               f"meshes/original__{digest[:12]}.glb": _glb(icosphere(1))})
    write_report(run, single_file=True)
    page = (run / "index.html").read_text()
    assert "Left out of this single-file report: the 3D view" in page
    assert VIEWER_SCRIPT not in page and "viewer3d" not in page
    assert not (run / "vendor").exists() and not (run / "meshes" / "js").exists()


def test_a_run_without_meshes_says_so(tmp_path):
    """A run folder made before the run wrote meshes: a note, no script, no files."""
    run = _run(tmp_path, [record()], {})
    write_report(run)
    page = (run / "index.html").read_text()
    assert "No 3D meshes for this model" in page and VIEWER_SCRIPT not in page
    assert not (run / "vendor").exists()
    assert len(load_records(run)) == 1


def test_wrappers_are_not_written_through_a_link_out_of_the_run_folder(tmp_path):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    digest = "45" * 20
    r = _lod_record("q", 80, digest)
    run = _run(tmp_path, [r], {"meshes/q-80.glb": _glb(icosphere(1)),
                               f"meshes/original__{digest[:12]}.glb": _glb(icosphere(1))})
    (run / "meshes" / "js").symlink_to(outside)
    with pytest.warns(Warning, match="its folder leaves the run folder"):
        write_report(run)
    assert list(outside.iterdir()) == []
    page = (run / "index.html").read_text()
    assert "&#x27;meshes/js/q-80.glb.js&#x27;: its folder leaves the run folder" in page
    assert "No 3D meshes for this model" in page


def test_the_download_links_are_the_checked_paths_not_the_keys(tmp_path):
    """A link inside the run folder (``meshes/a`` -> ``p/q/r``) and a job key with
    ``..``: Python follows the link before ``..`` (the GLB is ``x.glb``, inside), a
    browser drops ``..`` textually (``meshes/a/../../../x.glb`` is ``../x.glb``,
    outside). Every file the view names is the checked path, inside as a browser reads
    it."""
    digest = "67" * 20
    r = _lod_record("q", 80, digest)
    r["job"]["key"] = "a/../../../x"
    run = _run(tmp_path, [r], {"x.glb": _glb(icosphere(1)),
                               f"meshes/original__{digest[:12]}.glb": _glb(icosphere(2))})
    (run / "p" / "q" / "r").mkdir(parents=True)
    (run / "meshes" / "a").symlink_to(run / "p" / "q" / "r")
    write_report(run)
    page = (run / "index.html").read_text()
    assert page.count("<div class='viewer3d'") == 1
    named = _viewer_files(page)
    assert "x.glb" in named
    for name in named:
        text = posixpath.normpath(unquote(name))  # as a browser resolves it
        assert not text.startswith("../") and not text.startswith("/"), name
        assert (run / text).is_file(), name


def test_two_glbs_never_share_a_wrapper(tmp_path):
    """``meshes/_/x.glb`` and ``x.glb`` (beside ``meshes/``) get wrappers of their own,
    each holding its GLB under its id."""
    digest = "89" * 20
    inside, beside = _lod_record("q", 80, digest), _lod_record("q", 20, digest)
    inside["job"]["key"], beside["job"]["key"] = "_/x", "../x"
    meshes = {"meshes/_/x.glb": _glb(icosphere(1)), "x.glb": _glb(icosphere(2)),
              f"meshes/original__{digest[:12]}.glb": _glb(icosphere(2))}
    run = _run(tmp_path, [inside, beside], meshes)
    write_report(run)
    page = (run / "index.html").read_text()
    options = re.findall(r"data-lod='([^']*)' data-lod-id='([0-9a-f]{16})' "
                         r"data-lod-glb='([^']*)'", page)
    assert [glb for _, _, glb in options] == ["meshes/_/x.glb", "x.glb"]
    assert len({url for url, _, _ in options}) == 2
    for url, ident, glb in options:
        wrapper = (run / unquote(url)).read_text()
        text = re.fullmatch(rf'\(window\.benchGlb=window\.benchGlb\|\|\{{\}}\)\["{ident}"\]'
                            r'="([A-Za-z0-9+/=]*)";\n', wrapper).group(1)
        assert base64.b64decode(text) == meshes[glb]


def test_wrapper_names_cannot_collide():
    paths = ["meshes/x.glb", "meshes/_/x.glb", "x.glb", "_/x.glb", "meshes/_/_/x.glb",
             "_/_/x.glb", "meshes/js/x.glb", "js/x.glb", "meshes/__/x.glb", "meshes/_x.glb"]
    names = [wrapper_path(p) for p in paths]
    assert len(set(names)) == len(paths)
    assert all(n.startswith("meshes/js/") and n.endswith(".glb.js") for n in names)
    assert wrapper_path("meshes/q-80.glb") == "meshes/js/q-80.glb.js"


def test_only_the_pages_with_a_view_load_its_script(tmp_path):
    """A split report (over 50 jobs): the page of the model with meshes loads the
    view's script, the other model's page and the index do not."""
    digest = "ab" * 20
    shown = _lod_record("q", 80, digest)
    shown["job"]["model"] = shown["model"]["name"] = "shown"
    others = [record(label=f"q{i}", model="bare") for i in range(50)]
    run = _run(tmp_path, [shown, *others],
               {"meshes/q-80.glb": _glb(icosphere(1)),
                f"meshes/original__{digest[:12]}.glb": _glb(icosphere(2))})
    write_report(run)
    pages = {p.name: p.read_text() for p in run.glob("*.html")}
    assert sorted(pages) == ["index.html", "model-bare.html", "model-shown.html"]
    assert pages["model-shown.html"].count(VIEWER_SCRIPT) == 1
    assert "<div class='viewer3d'" in pages["model-shown.html"]
    assert VIEWER_SCRIPT not in pages["model-bare.html"] and VIEWER_SCRIPT not in pages["index.html"]
