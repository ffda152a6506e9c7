"""The report's 3D view: per model, the original and any LOD side by side, orbited with
one shared camera, from the GLB files the run wrote (:func:`bench.run.jobs.mesh_paths`).

It opens from disk (``file://``) with no server and no network. Chromium loads neither
ES modules nor ``fetch``/XHR of ``file://`` URLs from a ``file://`` page, but it runs
classic ``<script src>`` files, so:

- three.js (with its GLTFLoader and OrbitControls) is a classic script, a pinned
  release from the npm registry bundled by ``scripts/vendor_three.sh`` into
  ``bench/report/vendor/three/``; the report copies it to ``vendor/three.min.js``
  (with its licence beside it) and loads it when a reader first opens a view;
- each GLB that passes :func:`run_glb` is wrapped in a classic script,
  ``meshes/js/<name>.glb.js`` (:func:`wrapper_path`), that stores its bytes (base64)
  under an id in ``window.benchGlb``; the view inserts that script when its LOD is
  chosen and hands the bytes to ``GLTFLoader.parse``.

The page holds only the selector and the file names (:func:`viewer_section`); the
script (:data:`VIEWER_SCRIPT`, vanilla JavaScript, inline) draws both meshes in one
WebGL canvas with two viewports and one camera: a Lambert material (ambient 0.1,
diffuse 0.9, white unless textured), two-sided, a point light at the eye and a 50 %
gray background as the protocol renders; flat (face normals) or smooth shading (the
vertex normals the evaluation's Gouraud shading uses, written into the GLB),
textured or not, a wireframe overlay. It starts in the shading the chosen LOD's job was
evaluated with (set again when the LOD changes while the view is closed; once it is open,
the reader's choice stays). A view starts on a click,
or on opening the page with ``#view3d=<model slug>`` (scrolled into view; ``&lod=N``
picks the entry N, counted from 0, ``&shading=smooth`` and ``&wireframe`` set those:
the fragment is read as ``&``-separated keys and values); opening one closes any other,
so a page holds one WebGL context at most. It writes what it shows into
attributes of its ``div.viewer3d`` (``data-status`` loading/ready/error,
``data-faces`` and ``data-original-faces``, the triangles drawn, ``data-shading`` and
``data-wireframe``) and every failure —
WebGL unavailable, a file missing — as text in the page.

A run folder is someone else's data: a GLB is wrapped only when it lies inside the run
folder, is a whole glTF 2 binary file and refers to no file or address outside itself
(no ``uri`` in its buffers or images); its wrapper and its download link are named
after its checked path (resolved: a link in the run folder and a ``..`` in a job key
cannot take a browser, which drops ``..`` textually, elsewhere), the wrapper's id is a
hash, and every string from a record reaches the page HTML-escaped.
"""

from __future__ import annotations

import base64
import hashlib
import json
import math
import struct
from importlib.resources import files
from pathlib import Path
from typing import NamedTuple

from bench.records.results import evaluated
from bench.report import script
from bench.report.images import run_file
from bench.report.table import esc

__all__ = ["MAX_MESH_BYTES", "VIEWER_SCRIPT", "Glb", "Viewers", "run_glb", "single_file_note",
           "wrapper_path"]

#: Largest GLB shown (the 56k-face bunny is 1.4 MB; a 2M-face scan about 50 MB).
MAX_MESH_BYTES = 256 << 20
#: The vendored bundle inside the package, and where the report puts it.
_BUNDLE = "vendor/three/three.min.js"
_BUNDLE_LICENSE = "vendor/three/LICENSE"
THREE_URL = "vendor/three.min.js"
_THREE_LICENSE_URL = "vendor/three.LICENSE.txt"

_GLB_MAGIC = b"glTF"
_JSON_CHUNK = 0x4E4F534A


class Glb(NamedTuple):
    """A GLB file of the run folder that may be shown: its bytes, and its path relative
    to the (resolved) run folder."""

    data: bytes
    path: str


def run_glb(run_dir: Path, relative, refused: list[str] | None = None,
            what: str = "3D mesh") -> Glb | None:
    """The GLB file ``run_dir/relative``, or None: absent (no reason given), or refused
    with a reason in ``refused``, as :func:`~bench.report.images.run_file`
    refuses (outside the run folder, not ``.glb``, over :data:`MAX_MESH_BYTES`) or for
    its content (:func:`glb_problem`)."""
    found = run_file(run_dir, relative, refused, what, ".glb", MAX_MESH_BYTES)
    if found is None:
        return None
    data, path = found
    problem = glb_problem(data)
    if problem:
        if refused is not None:
            refused.append(f"{what} {str(relative)!r}: {problem}; not shown")
        return None
    return Glb(data, path)


def glb_problem(data: bytes) -> str | None:
    """Why ``data`` is not a GLB file the 3D view may load, or None: it must be a whole
    glTF 2 binary file whose JSON chunk parses and whose buffers and images name no
    ``uri`` (the bytes are all inside; a browser would otherwise reach for other files
    or the network)."""
    if len(data) < 20 or data[:4] != _GLB_MAGIC:
        return "not a GLB file"
    version, length = struct.unpack_from("<II", data, 4)
    if version != 2 or length != len(data):
        return "not a whole glTF 2 binary file"
    chunk, kind = struct.unpack_from("<II", data, 12)
    if kind != _JSON_CHUNK or 20 + chunk > len(data):
        return "its first chunk is not glTF JSON"
    try:
        tree = json.loads(data[20:20 + chunk])
    except (ValueError, RecursionError):
        return "its glTF JSON does not parse"
    if not isinstance(tree, dict):
        return "its glTF JSON is not an object"
    for part in ("buffers", "images"):
        items = tree.get(part, [])
        if not isinstance(items, list) or not all(isinstance(i, dict) for i in items):
            return f"its glTF {part} are not a list of objects"
        if any("uri" in item for item in items):
            return f"its glTF {part} name a file or address outside it (uri)"
    return None


def single_file_note(records: list[dict]) -> str:
    """What a ``--single-file`` report says instead of a model's 3D view."""
    if not any(evaluated(r) for r in records):
        return ""
    return ("<h3>3D view</h3><p class='note'>Left out of this single-file report: the 3D "
            "view loads three.js and the meshes as files of the run folder "
            "(<code>meshes/*.glb</code>, which any glTF viewer opens). "
            "<code>bench report DIR</code> without <code>--single-file</code> shows it.</p>")


class _Wrapped(NamedTuple):
    """A GLB of the run folder as the view names it: its wrapper's URL and id, and the
    URL of the GLB itself (the download link)."""

    url: str
    ident: str
    glb: str


def wrapper_path(path: str) -> str:
    """Where the script wrapper of the run folder's GLB ``path`` (relative to the run
    folder, no ``..``) goes: ``meshes/<name>`` wraps as ``meshes/js/<name>.js``, any
    other GLB — and one under ``meshes/_/``, so that no two paths share a wrapper — as
    ``meshes/js/_/<path>.js``."""
    if path.startswith("meshes/") and not path.startswith("meshes/_/"):
        return f"meshes/js/{path.removeprefix('meshes/')}.js"
    return f"meshes/js/_/{path}.js"


class Viewers:
    """The 3D views of one report build: writes each GLB's script wrapper and the
    three.js bundle into the run folder once, through ``out``
    (:class:`~bench.report.images.RunFiles`); what cannot be shown is noted in
    ``refused``. :attr:`shown` holds the slugs of the models whose section holds a
    view, :attr:`used` whether any does: the pages that need :data:`VIEWER_SCRIPT`."""

    def __init__(self, run_dir: Path, out, refused: list[str]):
        self.run_dir = Path(run_dir)
        self.out = out
        self.refused = refused
        self.shown: set[str] = set()
        self._wrapped: dict[str, _Wrapped | None] = {}
        self._three: str | None = None

    def _bundle(self) -> str:
        """The URL of the three.js bundle in the run folder ("" when it cannot be
        written, or is missing from this installation)."""
        if self._three is None:
            try:
                package = files("bench.report")
                bundle = package.joinpath(_BUNDLE).read_bytes()
                licence = package.joinpath(_BUNDLE_LICENSE).read_bytes()
            except OSError:
                self.refused.append(f"the 3D view: {_BUNDLE} is missing from this "
                                    "installation of bench (reinstall it); not shown")
                self._three = ""
                return ""
            self._three = self.out.file(THREE_URL, bundle)
            if self._three:
                self.out.file(_THREE_LICENSE_URL, licence)
        return self._three

    @property
    def used(self) -> bool:
        """Whether some model's section holds a 3D view."""
        return bool(self.shown)

    def _wrap(self, relative: str) -> _Wrapped | None:
        """The script wrapper of the GLB ``relative`` of the run folder, written once per
        report; None when it is absent or refused. Its URL, its id and the GLB's own URL
        are all made from the checked path (resolved, inside the run folder), never from
        ``relative``, whose ``..`` a browser would resolve differently (textually, not
        after following links)."""
        if relative not in self._wrapped:
            glb = run_glb(self.run_dir, relative, self.refused)
            self._wrapped[relative] = None
            if glb is not None:
                ident = hashlib.sha1(glb.path.encode()).hexdigest()[:16]
                text = (f'(window.benchGlb=window.benchGlb||{{}})["{ident}"]="'
                        f'{base64.b64encode(glb.data).decode()}";\n')
                url = self.out.file(wrapper_path(glb.path), text.encode())
                if url:
                    self._wrapped[relative] = _Wrapped(url, ident, _quote(glb.path))
        return self._wrapped[relative]

    def section(self, records: list[dict], keys: dict, slug: str,
                several_shadings: bool) -> str:
        """The 3D view of one model's ``records`` (its ok jobs, each with its original;
        ``keys`` maps ``id(record)`` to the job key its files are named after), or a note
        saying why there is none. ``slug`` is the model's part of file names and ids."""
        from bench.records.results import shading_label
        from bench.run.jobs import mesh_paths

        ok = [r for r in records if evaluated(r) and id(r) in keys]
        if not ok:
            return ""
        ok.sort(key=lambda r: (-r["job"]["target_faces"], r["job"]["label"]))
        options, missing = [], 0
        for r in ok:
            job, digest = r["job"], r["model"].get("hash")
            faces = (r.get("metrics") or {}).get("faces")
            shading = shading_label(job["protocol"])
            text = (f"{job['label']}, {_count(faces)} faces (target {job['target_faces']})"
                    + (f", {shading} job" if several_shadings else ""))
            mine, theirs = mesh_paths(keys[id(r)], digest or "")
            lod = self._wrap(mine)
            original = self._wrap(theirs) if digest else None
            if lod is None or original is None:
                missing += 1
                why = r.get("mesh_file_error") if isinstance(r.get("mesh_file_error"), str) \
                    else "no mesh file in the run folder"
                options.append(f"<option disabled>{esc(text)}: {esc(why)}</option>")
                continue
            attrs = {"lod": lod.url, "lod-id": lod.ident, "lod-glb": lod.glb,
                     "original": original.url, "original-id": original.ident,
                     "original-glb": original.glb,
                     "faces": _count(faces, ""), "original-faces": _count(r["model"].get("faces"), ""),
                     "shading": "flat" if shading.startswith("flat") else "smooth"}
            data = "".join(f" data-{k}='{esc(v)}'" for k, v in attrs.items())
            selected = " selected" if len(options) == missing else ""  # the first usable
            options.append(f"<option{selected}{data}>{esc(text)}</option>")
        if missing == len(ok):
            return ("<h3>3D view</h3><p class='note'>No 3D meshes for this model in the run "
                    "folder (a run made before <code>bench run</code> wrote "
                    "<code>meshes/*.glb</code>, or each one was refused).</p>")
        three = self._bundle()
        if not three:
            return ""
        self.shown.add(slug)
        return (
            f"<h3>3D view</h3><div class='viewer3d' id='view3d-{slug}' data-model='{slug}' "
            f"data-three='{three}' data-status='closed'>"
            "<div class='v3d-controls'><button type='button' class='v3d-open'>show in 3D"
            "</button> <label>LOD <select class='v3d-lod'>" + "".join(options) +
            "</select></label> <label>shading <select class='v3d-shading'>"
            "<option value='flat'>flat</option><option value='smooth'>smooth</option>"
            "</select></label> <label><input type='checkbox' class='v3d-texture' checked> "
            "texture</label> <label><input type='checkbox' class='v3d-wire'> wireframe"
            "</label></div><div class='v3d-stage'><span class='v3d-left'>original</span>"
            "<span class='v3d-right'>LOD</span></div>"
            "<p class='v3d-status note'>The original (left) and the chosen LOD (right), "
            "orbited together: press “show in 3D” (three.js, loaded from this folder; "
            "nothing comes from the network).</p><p class='v3d-caption note'></p></div>")


def _count(value, empty: str = "?") -> str:
    """A face count from a record as text (``empty`` when it is not a finite number)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return empty
    return str(int(value))


def _quote(path: str) -> str:
    from urllib.parse import quote

    return quote(path, safe="/")


#: The viewer, inline in the pages that hold a 3D view (after the page's other scripts).
VIEWER_SCRIPT = script("viewer.js")
