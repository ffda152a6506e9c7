"""The report's 3D view: per model, the original and any LOD side by side, orbited with
one shared camera, from the GLB files the run wrote (:func:`bench.harness.jobs.mesh_paths`).

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

from bench.report.images import run_file
from bench.report.table import esc
from bench.harness.results import evaluated

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
        from bench.harness.jobs import mesh_paths
        from bench.harness.results import shading_label

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
VIEWER_SCRIPT = """<script>/* bench report: 3D view of the LODs */
(function () {
  var active = null, meshes = {}, library = null;
  function loadScript(src) {
    return new Promise(function (resolve, reject) {
      var s = document.createElement("script");
      s.src = src;
      s.onload = function () { resolve(); };
      s.onerror = function () { reject(new Error("cannot load " + src + " (is the run folder whole?)")); };
      document.head.appendChild(s);
    });
  }
  function three(src) {
    if (!library) library = loadScript(src).then(function () {
      if (!window.THREE || !THREE.GLTFLoader || !THREE.OrbitControls)
        throw new Error(src + " did not define three.js");
      THREE.ColorManagement.enabled = false;  // colours as the protocol's images: no conversions
    });
    return library;
  }
  function glb(src, id) {  /* the parsed glTF of a wrapped GLB, once per page */
    if (!meshes[id]) meshes[id] = loadScript(src).then(function () {
      var text = (window.benchGlb || {})[id];
      if (typeof text !== "string") throw new Error(src + " holds no mesh");
      delete window.benchGlb[id];
      var bin = atob(text), bytes = new Uint8Array(bin.length);
      for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
      return new Promise(function (resolve, reject) {
        new THREE.GLTFLoader().parse(bytes.buffer, "", resolve, function (e) {
          reject(new Error("cannot read " + src + ": " + (e && e.message || e)));
        });
      });
    }).then(prepare);
    return meshes[id];
  }
  function prepare(gltf) {  /* the protocol's material on every primitive, a wireframe beside */
    var parts = [], faces = 0, textured = false;
    gltf.scene.traverse(function (o) { if (o.isMesh) parts.push(o); });
    parts.forEach(function (o) {
      var g = o.geometry, map = o.material.map || null;
      if (!g.getAttribute("normal")) g.computeVertexNormals();
      if (map) { map.colorSpace = THREE.NoColorSpace; textured = true; }
      o.userData.map = map;
      o.material = new THREE.MeshLambertMaterial({
        color: map ? 0xffffff : o.material.color, map: map, side: THREE.DoubleSide,
        vertexColors: !!g.getAttribute("color"),
        polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1});
      var wire = new THREE.Mesh(g, new THREE.MeshBasicMaterial({color: 0x1a1a1a, wireframe: true}));
      wire.visible = false;
      o.add(wire);
      o.userData.wire = wire;
      faces += (g.index ? g.index.count : g.getAttribute("position").count) / 3;
    });
    return {object: gltf.scene, parts: parts, faces: faces, textured: textured};
  }
  function Viewer(root) {
    var q = function (s) { return root.querySelector(s); };
    this.root = root; this.lod = q(".v3d-lod"); this.shading = q(".v3d-shading");
    this.texture = q(".v3d-texture"); this.wire = q(".v3d-wire"); this.stage = q(".v3d-stage");
    this.status = q(".v3d-status"); this.caption = q(".v3d-caption"); this.token = 0;
    var self = this;
    this.syncShading();
    q(".v3d-open").addEventListener("click", function () { self.open(); });
    this.lod.addEventListener("change", function () {  /* open: keep the reader's shading */
      if (self.renderer) self.show(); else self.syncShading();
    });
    [this.shading, this.texture, this.wire].forEach(function (c) {
      c.addEventListener("change", function () { if (self.renderer) { self.restyle(); self.draw(); } });
    });
    this.resize = function () { self.layout(); self.draw(); };
  }
  Viewer.prototype.syncShading = function () {  /* the shading the chosen job was evaluated with */
    var option = this.lod.options[this.lod.selectedIndex];
    if (option && option.getAttribute("data-shading")) this.shading.value = option.getAttribute("data-shading");
  };
  Viewer.prototype.fail = function (error) {
    this.root.setAttribute("data-status", "error");
    this.status.textContent = "3D view: " + (error && error.message || error);
  };
  Viewer.prototype.open = function () {
    var self = this;
    if (active && active !== this) active.close();
    active = this;
    this.root.setAttribute("data-status", "loading");
    this.status.textContent = "Loading three.js ...";
    return three(this.root.getAttribute("data-three")).then(function () {
      self.start();
      return self.show();
    }).catch(function (e) { self.fail(e); });
  };
  Viewer.prototype.start = function () {
    if (this.renderer) return;
    var renderer;
    try {
      renderer = new THREE.WebGLRenderer({antialias: true});
    } catch (e) {
      throw new Error("WebGL is not available in this browser, so nothing can be drawn (" + (e.message || e) + ")");
    }
    renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    renderer.setScissorTest(true);
    this.stage.appendChild(renderer.domElement);
    this.renderer = renderer;
    this.camera = new THREE.PerspectiveCamera(60, 1, 0.01, 100);
    this.controls = new THREE.OrbitControls(this.camera, renderer.domElement);
    var self = this;
    this.controls.addEventListener("change", function () { self.draw(); });
    this.scenes = [0, 1].map(function () {
      var scene = new THREE.Scene();
      scene.background = new THREE.Color(0.5, 0.5, 0.5);
      scene.add(new THREE.AmbientLight(0xffffff, 0.1 * Math.PI));
      scene.userData.light = new THREE.PointLight(0xffffff, 0.9 * Math.PI, 0, 0);  // at the eye
      scene.add(scene.userData.light);
      return scene;
    });
    this.shown = [null, null];
    window.addEventListener("resize", this.resize);
    this.layout();
  };
  Viewer.prototype.show = function () {
    var self = this, option = this.lod.options[this.lod.selectedIndex], token = ++this.token;
    var get = function (name) { return option.getAttribute("data-" + name); };
    this.root.setAttribute("data-status", "loading");
    this.status.textContent = "Loading " + option.textContent + " ...";
    return Promise.all([glb(get("original"), get("original-id")), glb(get("lod"), get("lod-id"))]).then(function (both) {
      if (token !== self.token || !self.renderer) return;  // another choice came since, or closed
      var refit = self.shown[0] !== both[0];
      both.forEach(function (m, i) {
        if (self.shown[i]) self.scenes[i].remove(self.shown[i].object);
        self.scenes[i].add(m.object);
        self.shown[i] = m;
      });
      if (refit) self.fit(both[0]);
      self.texture.disabled = !(both[0].textured || both[1].textured);
      self.restyle();
      self.draw();
      self.root.setAttribute("data-faces", String(both[1].faces));
      self.root.setAttribute("data-original-faces", String(both[0].faces));
      self.root.setAttribute("data-status", "ready");
      self.status.textContent = "Left: the original, " + both[0].faces + " triangles. Right: " +
        option.textContent + ", " + both[1].faces + " triangles drawn. Drag to orbit, right-drag to pan, " +
        "wheel to zoom: both views share one camera. A light at the eye, 50 % gray background, as the protocol renders.";
      self.links(get("original-glb"), get("lod-glb"));
    }).catch(function (e) { if (token === self.token) self.fail(e); });
  };
  Viewer.prototype.links = function (original, lod) {
    var c = this.caption;
    c.textContent = "The meshes as GLB files (any glTF viewer opens them): ";
    [["original", original], ["this LOD", lod]].forEach(function (pair, i) {
      var a = document.createElement("a");
      a.href = pair[1];
      a.textContent = pair[0];
      if (i) c.appendChild(document.createTextNode(", "));
      c.appendChild(a);
    });
  };
  Viewer.prototype.fit = function (shown) {  /* the original's bounding sphere fills 90 % of the height */
    var c = new THREE.Box3().setFromObject(shown.object).getCenter(new THREE.Vector3());
    var r = 0, p = new THREE.Vector3();
    shown.parts.forEach(function (o) {
      var a = o.geometry.getAttribute("position");
      o.updateWorldMatrix(true, false);
      for (var i = 0; i < a.count; i++) r = Math.max(r, p.fromBufferAttribute(a, i).applyMatrix4(o.matrixWorld).distanceTo(c));
    });
    r = r || 1;
    this.camera.near = r * 0.02; this.camera.far = r * 20;
    this.camera.position.copy(c).add(new THREE.Vector3(0.6, 0.45, 1).normalize().multiplyScalar(2.2 * r));
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(c);
    this.controls.update();
  };
  Viewer.prototype.restyle = function () {
    var flat = this.shading.value === "flat", texture = this.texture.checked, wire = this.wire.checked;
    this.root.setAttribute("data-shading", this.shading.value);
    this.root.setAttribute("data-wireframe", String(wire));
    this.shown.forEach(function (m) {
      if (m) m.parts.forEach(function (o) {
        o.material.flatShading = flat;
        o.material.map = texture ? o.userData.map : null;
        o.material.needsUpdate = true;
        o.userData.wire.visible = wire;
      });
    });
  };
  Viewer.prototype.layout = function () {
    var width = Math.max(200, this.stage.clientWidth), height = Math.min(560, Math.round(width / 2));
    this.size = [width, height];
    this.renderer.setSize(width, height);
    this.camera.aspect = (width / 2 - 1) / height;
    this.camera.updateProjectionMatrix();
  };
  Viewer.prototype.draw = function () {
    if (!this.renderer) return;
    var w = this.size[0], h = this.size[1], half = Math.floor(w / 2), self = this;
    this.scenes.forEach(function (scene, i) {
      var x = i ? half + 1 : 0, width = i ? w - half - 1 : half - 1;
      scene.userData.light.position.copy(self.camera.position);
      self.renderer.setViewport(x, 0, width, h);
      self.renderer.setScissor(x, 0, width, h);
      self.renderer.render(scene, self.camera);
    });
  };
  Viewer.prototype.close = function () {
    if (!this.renderer) return;
    window.removeEventListener("resize", this.resize);
    this.controls.dispose();
    this.renderer.dispose();
    this.renderer.forceContextLoss();
    this.stage.removeChild(this.renderer.domElement);
    this.renderer = null;
    this.token++;
    this.root.setAttribute("data-status", "closed");
    this.status.textContent = "Closed: another model's 3D view is open (one at a time).";
  };
  var viewers = Array.prototype.map.call(document.querySelectorAll("div.viewer3d"),
                                         function (root) { return new Viewer(root); });
  function decode(text) {  /* a malformed % escape leaves the text as it is */
    try { return decodeURIComponent(text); } catch (e) { return text; }
  }
  function address() {  /* the fragment's key=value pairs, split on "&" (a bare key: ""); the first of a key counts */
    var found = Object.create(null);
    location.hash.replace(/^#/, "").split("&").forEach(function (part) {
      var at = part.indexOf("="), key = decode(at < 0 ? part : part.slice(0, at));
      if (key && !(key in found)) found[key] = at < 0 ? "" : decode(part.slice(at + 1));
    });
    return found;
  }
  var wanted = address();
  if ("view3d" in wanted && viewers.length) {
    var chosen = viewers.filter(function (v) {
      return v.root.getAttribute("data-model") === wanted.view3d;
    })[0] || viewers[0];
    var n = /^\\d+$/.test(wanted.lod || "") ? Number(wanted.lod) : -1;
    var pick = n >= 0 ? chosen.lod.options[n] : null;
    if (pick && !pick.disabled) chosen.lod.selectedIndex = n;
    chosen.syncShading();
    if (wanted.shading === "flat" || wanted.shading === "smooth") chosen.shading.value = wanted.shading;
    if ("wireframe" in wanted) chosen.wire.checked = true;
    chosen.root.scrollIntoView();
    chosen.open();
  }
})();
</script>"""
