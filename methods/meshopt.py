"""meshoptimizer and gltfpack: the simplifier game engines ship (Kapoulkine's meshoptimizer).

Every row runs meshoptimizer 1.3.0 as published on the npm registry (its
``MeshoptSimplifier`` module, the C++ library built to WebAssembly by its author), on
Node.js, from the job's own process: a small script of ours,
``methods/meshopt_node/simplify.mjs``, started once per process and kept, reads index and
vertex buffers on its stdin, makes one library call per request and writes the kept
indices (and, for ``simplifyWithUpdate``, the updated vertices) on its stdout.
``methods/meshopt_node/package-lock.json`` pins the library and gltfpack 1.3.0 with
their integrity hashes; ``scripts/setup.sh`` installs them (``npm ci``). Why Node and a
kept process: docs/maintainers.md, "meshoptimizer on Node".

Rows (the library's documentation is its README, https://github.com/zeux/meshoptimizer,
sections named below; the npm package's README, ``js/README.md`` there, documents the
same flags and ``vertex_lock`` values for the JavaScript interface; gltfpack's options
are its ``gltfpack -h``):

- ``meshopt``: ``simplify``, no flags. Seams stay closed: the library infers them from
  split render vertices.
- ``meshopt-attributes``: ``simplifyWithAttributes`` with UVs and normals
  ("Attribute-aware simplification").
- ``meshopt-update``: ``simplifyWithUpdate`` with the same attributes; the library solves
  for the kept vertices' positions and attributes and writes them back
  ("Simplification with vertex update").
- ``meshopt-permissive``: ``simplifyWithAttributes`` with ``Permissive`` and
  ``Regularize``, seams protected selectively with ``vertex_lock``
  ("Permissive simplification").
- ``meshopt-sloppy``: ``simplifySloppy``, grid clustering that ignores topology.
- ``gltfpack``: gltfpack 1.3.0 (the library's glTF optimiser, also WebAssembly on Node)
  on the model written as GLB, read back like a file a user gave.

The library returns an index buffer into the original vertices; the result keeps the
surviving vertices (UVs, normals, colours and the texture carried along) and drops
unused ones. The error the library reports (its ``result_error``) is recorded in the
statistics relative to the mesh's extent (``library_error``, the library's default
unit), and times ``getScale`` in model units (``library_error_absolute``); results.csv
has the relative one as its ``library_error`` column.
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import tempfile
import threading
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from bench.core.errors import MeshWarning, MethodError, ParamError
from bench.core.mesh import Mesh, compact
from bench.core.method import Method, SimplifyResult, bounded, target_tolerance

__all__ = [
    "LIBRARY_VERSION",
    "NODE_DIR",
    "Gltfpack",
    "Meshopt",
    "MeshoptAttributes",
    "MeshoptPermissive",
    "MeshoptSloppy",
    "MeshoptUpdate",
    "call_library",
    "node_problem",
    "protected_vertices",
    "simplify_index_buffer",
    "uv_density_weight",
]

#: The pinned releases (methods/meshopt_node/package-lock.json holds their hashes).
LIBRARY_VERSION = "1.3.0"
GLTFPACK_VERSION = "1.3.0"
#: Our Node script and its node_modules.
NODE_DIR = Path(__file__).parent / "meshopt_node"
SCRIPT = NODE_DIR / "simplify.mjs"
#: Where the package-lock installs each package.
_PACKAGES = {"meshoptimizer": LIBRARY_VERSION, "gltfpack": GLTFPACK_VERSION}

#: An error bound that never stops a collapse: the largest float32. With it a stop
#: above the target is the library's topology rules (seams, borders), not its error bound.
UNBOUNDED_ERROR = float(np.finfo(np.float32).max)

#: ``vertex_lock`` values (meshopt_SimplifyVertex_Lock / _Protect in the C header; the
#: npm README: "1 means that the vertex is locked ... In permissive mode, 2 can be used
#: to protect seams while allowing vertices to collapse along them").
VERTEX_LOCK, VERTEX_PROTECT = 1, 2

#: Why simplify_sloppy lands below a target: it searches grid sizes (whole cells per
#: axis) and keeps the finest grid it found whose clustering stays under the target;
#: the face count jumps between neighbouring grid sizes.
SLOPPY_BELOW = ("simplifySloppy keeps the finest grid it found whose clustering stays under "
                "the target, and face counts jump between grid sizes")


def node_binary() -> str | None:
    """The Node.js executable: ``$BENCH_NODE``, else ``node`` or ``nodejs`` on PATH."""
    return os.environ.get("BENCH_NODE") or shutil.which("node") or shutil.which("nodejs")


def node_problem(package: str = "meshoptimizer") -> str | None:
    """Why the rows that need ``package`` cannot run here, with the command that fixes
    it; None when Node and the pinned package are installed."""
    fix = f"npm ci --prefix {NODE_DIR}"
    node = node_binary()
    if os.environ.get("BENCH_NODE") and shutil.which(node) is None:
        return f"BENCH_NODE={node} is not an executable; point it at Node.js or unset it"
    if node is None:
        return ("needs Node.js (node not found on PATH); install with: sudo apt-get install "
                f"nodejs npm && {fix}  (or: bash scripts/setup.sh --no-run)")
    manifest = NODE_DIR / "node_modules" / package / "package.json"
    try:
        found = json.loads(manifest.read_text()).get("version")
    except (OSError, ValueError):
        found = None
    if found != _PACKAGES[package]:
        have = f"version {found} is installed" if found else "it is not installed"
        return (f"needs {package} {_PACKAGES[package]} from npm ({have}); install with: {fix}")
    return None


# -- one library call -------------------------------------------------------------------

@dataclass
class LibraryResult:
    """What one call of the Node script returned."""

    kept: np.ndarray  #: (k, 3) uint32, indices into the vertex buffer sent
    error: float  #: the library's result_error
    scale: float  #: getScale of the positions sent
    seconds: float  #: the library call alone, timed inside Node
    version: str  #: meshoptimizer's version, from its package.json
    node: str  #: Node's version
    positions: np.ndarray | None = None  #: simplifyWithUpdate: the updated positions
    attributes: np.ndarray | None = None  #: simplifyWithUpdate: the updated attributes


def call_library(op: str, indices: np.ndarray, positions: np.ndarray, *,
                 attributes: np.ndarray | None = None, weights=(), lock: np.ndarray | None = None,
                 target_index_count: int = 0, target_error: float = UNBOUNDED_ERROR,
                 flags=()) -> LibraryResult:
    """One meshoptimizer call, made by this process's ``simplify.mjs`` worker.

    Parameters
    ----------
    op : {"simplify", "attributes", "update", "sloppy"}
        ``MeshoptSimplifier.simplify``, ``simplifyWithAttributes``,
        ``simplifyWithUpdate`` or ``simplifySloppy``.
    indices : ndarray of uint32, flat
    positions : ndarray of shape (n, 3) float32
    attributes : ndarray of shape (n, a) float32, optional
    weights : sequence of float, one per attribute column
    lock : ndarray of shape (n,) uint8, optional
        ``vertex_lock`` (0, VERTEX_LOCK, VERTEX_PROTECT).
    flags : sequence of str
        The library's flag names ('LockBorder', 'Permissive', ...).

    Raises
    ------
    MethodError
        Node or the library refused the request; one line saying why.
    """
    problem = node_problem()
    if problem is not None:
        raise MethodError(f"meshoptimizer is unavailable: {problem}")
    indices = np.ascontiguousarray(indices, dtype="<u4").reshape(-1)
    positions = np.ascontiguousarray(positions, dtype="<f4").reshape(-1, 3)
    n = len(positions)
    header = {"op": op, "index_count": len(indices), "vertex_count": int(n),
              "target_index_count": int(target_index_count), "target_error": float(target_error),
              "flags": list(flags), "weights": [float(w) for w in weights], "lock": lock is not None}
    buffers = [indices.tobytes(), positions.tobytes()]
    if attributes is not None:
        attributes = np.ascontiguousarray(attributes, dtype="<f4").reshape(n, -1)
        header["attribute_count"] = int(attributes.shape[1])
        buffers.append(attributes.tobytes())
    if lock is not None:
        buffers.append(np.ascontiguousarray(lock, dtype=np.uint8).tobytes())
    payload = b"".join(buffers)
    header["bytes"] = len(payload)
    head = json.dumps(header).encode()
    meta, reply = _WORKER.call(struct.pack("<I", len(head)) + head + payload)
    count = int(meta["index_count"])
    kept = np.frombuffer(reply, "<u4", count, 0).reshape(-1, 3)
    offset = 4 * count
    result = LibraryResult(kept, float(meta["error"]), float(meta["scale"]),
                           float(meta["seconds"]), meta["version"], meta["node"])
    if op == "update":
        result.positions = np.frombuffer(reply, "<f4", 3 * n, offset).reshape(n, 3)
        offset += 12 * n
        result.attributes = np.frombuffer(reply, "<f4", attributes.size, offset).reshape(n, -1)
    return result


class _NodeWorker:
    """One Node process running ``simplify.mjs`` for this Python process, started on
    the first call and kept: every call is then a request and a reply on its pipes,
    without Node's start (docs/maintainers.md, "meshoptimizer on Node"). A worker that
    died (or belongs to the parent of a fork) is replaced on the next call."""

    def __init__(self):
        self._proc = None
        self._errors = None
        self._pid = None
        self._lock = threading.Lock()

    def call(self, request: bytes) -> tuple[dict, bytes]:
        """Send one request; the reply's header and body. MethodError with the script's
        one-line reason when it refused the request, or when Node failed."""
        with self._lock:
            proc = self._process()
            try:
                proc.stdin.write(request)
                proc.stdin.flush()
                meta, body = _read_reply(proc.stdout)
            except (OSError, EOFError, ValueError) as exc:
                self._stop()
                raise MethodError(f"simplify.mjs stopped ({type(exc).__name__}: {exc}); "
                                  f"{_stderr_tail(proc, self._errors)}") from None
        if meta.get("refused"):
            raise MethodError(f"simplify.mjs refused the request: {meta['refused']}")
        return meta, body

    def _process(self):
        if self._proc is None or self._proc.poll() is not None or self._pid != os.getpid():
            try:
                # Node's messages go to a file, read only when it dies (a pipe nobody
                # reads could fill); the file lives as long as the process
                errors = tempfile.TemporaryFile()  # noqa: SIM115
                self._proc = subprocess.Popen(
                    [node_binary(), str(SCRIPT)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                    stderr=errors, cwd=NODE_DIR)
                self._errors = errors
            except OSError as exc:
                raise MethodError(f"cannot start Node.js ({exc.strerror or exc}); "
                                  f"{node_problem() or 'check BENCH_NODE'}") from None
            self._pid = os.getpid()
        return self._proc

    def _stop(self) -> None:
        if self._proc is not None and self._proc.poll() is None:
            self._proc.kill()
            self._proc.wait()
        self._proc = None


_WORKER = _NodeWorker()


def _read_reply(stream) -> tuple[dict, bytes]:
    """One reply frame: u32 header length, JSON header (with ``bytes``), body."""
    head = _read_exactly(stream, 4)
    (size,) = struct.unpack("<I", head)
    meta = json.loads(_read_exactly(stream, size))
    return meta, _read_exactly(stream, int(meta.get("bytes", 0)))


def _read_exactly(stream, n: int) -> bytes:
    data = stream.read(n)
    if len(data) != n:
        raise EOFError(f"Node's reply ended after {len(data)} of {n} bytes")
    return data


def _stderr_tail(proc, errors) -> str:
    """The last line Node wrote to stderr (why it died), or a fallback."""
    try:
        errors.seek(0)
        lines = errors.read().decode("utf-8", "replace").strip().splitlines()
    except (OSError, ValueError):
        lines = []
    return lines[-1] if lines else f"exit status {proc.poll()}"


def _node(args: list[str], stdin: bytes, timeout: float | None) -> bytes:
    """Run Node once with ``args``; its stdout, or MethodError with its last stderr line."""
    try:
        proc = subprocess.run([node_binary(), *args], input=stdin, capture_output=True,
                              cwd=NODE_DIR, timeout=timeout, check=False)
    except OSError as exc:
        raise MethodError(f"cannot start Node.js ({exc.strerror or exc}); "
                          f"{node_problem() or 'check BENCH_NODE'}") from None
    if proc.returncode != 0:
        lines = proc.stderr.decode("utf-8", "replace").strip().splitlines()
        raise MethodError(f"{Path(args[0]).name} failed (exit status {proc.returncode}): "
                          f"{lines[-1] if lines else 'no message'}")
    return proc.stdout


# -- parameters ---------------------------------------------------------------------------

@dataclass
class MeshoptParams:
    """Parameters of ``MeshoptSimplifier.simplify`` (flags as booleans).

    By default the face target alone stops the simplifier, as the suite compares
    methods at equal budgets: the library gets an error bound no collapse reaches
    (``UNBOUNDED_ERROR``, the README's "To disable the error limit, target_error can be
    set to FLT_MAX"). With ``bound_error`` it gets ``target_error`` instead, relative to
    the mesh's extent (in model units with ``error_absolute``), as engines call it and
    accept a LOD that stops short.
    """

    bound_error: bool = False
    target_error: float = bounded(0.01, ge=0)  #: used only with bound_error
    lock_border: bool = False  #: 'LockBorder': never move border vertices
    prune: bool = False  #: 'Prune': remove isolated components (needs bound_error)
    error_absolute: bool = False  #: 'ErrorAbsolute': errors in model units


@dataclass
class MeshoptAttributesParams(MeshoptParams):
    """``MeshoptParams`` plus the attribute weights of ``simplifyWithAttributes``.

    normal_weight: the README ("Attribute-aware simplification") calls a weight "around
    1.0 usually appropriate" for normalised attributes, since "a change of 1/weight in
    attribute value over a distance d is approximately equivalent to a change of d in
    position", and uses 0.5 for normals in its example (as gltfpack does); 0.5 here.
    uv_weight_scale multiplies the UV weight the README recommends computing from the
    UV density, "1/sqrt(sum(abs(uv area)) / triangle count)" (:func:`uv_density_weight`;
    it calls 10-100 usual); 0 leaves UVs out of the metric. The error bound then covers
    positions and attributes together.
    """

    normal_weight: float = bounded(0.5, ge=0)
    uv_weight_scale: float = bounded(1.0, ge=0)


@dataclass
class MeshoptPermissiveParams(MeshoptAttributesParams):
    """``MeshoptAttributesParams`` plus which seam vertices get ``Vertex_Protect``.

    protect: ``orientation`` protects UV-seam vertices where the charts meeting there
    have opposite UV winding (a mirrored chart; gltfpack's ``-sp`` protects these too),
    ``seams`` every UV-seam vertex (the README's example), ``none`` none. Material
    boundaries are protected in every case (README: "in which case material boundaries
    should be protected via vertex_lock"). regularize: the 'Regularize' flag.
    """

    protect: str = "orientation"
    regularize: bool = True


@dataclass
class MeshoptSloppyParams:
    """Parameters of ``simplifySloppy`` (it takes no flags); the error bound as in
    :class:`MeshoptParams`, always relative to the mesh's extent."""

    bound_error: bool = False
    target_error: float = bounded(0.01, ge=0)  #: used only with bound_error


PROTECT_CHOICES = ("orientation", "seams", "none")


# -- the rows -----------------------------------------------------------------------------

class _Node(Method):
    """The rows run on Node: available only where Node and the pinned package are."""

    package: ClassVar[str] = "meshoptimizer"

    @classmethod
    def unavailable_reason(cls) -> str | None:
        """Why this row cannot run here (Node or the npm package missing), with the
        command that fixes it; None when it can (bench.core.registry asks)."""
        return node_problem(cls.package)


class Meshopt(_Node):
    """meshoptimizer's ``simplify`` on the render-vertex index buffer, no flags.

    Split vertices with equal positions tell the library where the seams are; it keeps
    them closed (what an engine gets with no extra work) and may stop above the target
    when the remaining collapses would break a seam (README, "Simplification": "it is
    not guaranteed to reach the target index count and can stop earlier").
    """

    name = "meshopt"
    version = "2"  # 2: meshoptimizer 1.3.0 (npm, WebAssembly) replaces the 0.22 core
    summary = "meshoptimizer's quadric edge collapse on render vertices, seams kept"
    reference = ("A. Kapoulkine, meshoptimizer 1.3 (software), meshopt_simplify; after Garland "
                 "& Heckbert, Surface simplification using quadric error metrics, SIGGRAPH 1997")
    Params = MeshoptParams

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        p = _checked(self.params)
        return simplify_index_buffer(mesh, target_faces, "simplify", _error_bound(p),
                                     flags=_flags(p), absolute=p.error_absolute)


class MeshoptAttributes(_Node):
    """meshoptimizer's ``simplifyWithAttributes`` with UV and normal quadrics.

    Attributes per render vertex: (u, v) weighted by the README's UV density rule,
    1/sqrt(mean |UV area|), and the vertex normal (the file's, else area-weighted over
    the welded vertex) weighted 0.5, the README's example weight for normals (it calls
    ~1.0 appropriate for normalised attributes); see :class:`MeshoptAttributesParams`.
    Seams are inferred and kept as in ``meshopt``.
    """

    name = "meshopt-attributes"
    version = "2"  # 2: meshoptimizer 1.3.0 (its attribute metric was reworked after 0.22)
    summary = "meshoptimizer's edge collapse with UV and normal attribute quadrics"
    reference = ("A. Kapoulkine, meshoptimizer 1.3 (software), meshopt_simplifyWithAttributes; "
                 "after Hoppe, New quadric metric for simplifying meshes with appearance "
                 "attributes, IEEE Visualization 1999")
    Params = MeshoptAttributesParams

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        return _with_attributes("attributes", _checked(self.params), mesh, target_faces)


def _with_attributes(call: str, p, mesh: Mesh, target_faces: int) -> SimplifyResult:
    """``call`` ("attributes" or "update") with the UV and normal attributes and weights
    of :func:`vertex_attributes`, their statistics added to the result's."""
    attributes, weights, stats = vertex_attributes(mesh, p)
    result = simplify_index_buffer(mesh, target_faces, call, _error_bound(p),
                                   flags=_flags(p), absolute=p.error_absolute,
                                   attributes=attributes, weights=weights)
    result.stats.update(stats)
    return result


class MeshoptUpdate(_Node):
    """meshoptimizer's ``simplifyWithUpdate``: collapse, then the kept vertices'
    positions and attributes solved for and written back.

    The same attributes and weights as ``meshopt-attributes`` (the README, "Simplification
    with vertex update": "it's highly recommended to include texture coordinates ... for
    texture coordinates, a weight of 1.0 is usually sufficient in this case (although a
    higher or mesh dependent weight could be used)"; the density weight is that mesh
    dependent one). The result takes the updated positions and UVs; updated normals are
    renormalised, as the README asks ("Attributes that have specific constraints like
    normals ... should be renormalized"), and kept only when the input had normals (else
    they are derived from the result, as for every other method).
    """

    name = "meshopt-update"
    version = "1"
    summary = "meshoptimizer's edge collapse that solves for and writes back positions and UVs"
    reference = ("A. Kapoulkine, meshoptimizer 1.3 (software), meshopt_simplifyWithUpdate; "
                 "after Hoppe, New quadric metric for simplifying meshes with appearance "
                 "attributes, IEEE Visualization 1999")
    Params = MeshoptAttributesParams

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        return _with_attributes("update", _checked(self.params), mesh, target_faces)


class MeshoptPermissive(_Node):
    """meshoptimizer's ``simplifyWithAttributes`` in ``Permissive`` mode with
    ``Regularize``: collapses may cross attribute seams, except at vertices flagged
    ``Vertex_Protect``.

    The README ("Permissive simplification") highly recommends permissive mode together
    with attribute-aware simplification and protecting chosen seams through
    ``vertex_lock``; here the UV-seam vertices whose charts meet with opposite UV
    winding are protected, and material boundaries always (see
    :class:`MeshoptPermissiveParams` and :func:`protected_vertices`). 'Regularize'
    (README, "Advanced simplification") makes triangle sizes and shapes more regular
    "at some cost to geometric quality". Attributes and weights as in
    ``meshopt-attributes``.
    """

    name = "meshopt-permissive"
    version = "1"
    summary = "meshoptimizer's permissive edge collapse across unprotected seams, regularized"
    reference = ("A. Kapoulkine, meshoptimizer 1.3 (software), meshopt_simplifyWithAttributes "
                 "with meshopt_SimplifyPermissive and meshopt_SimplifyVertex_Protect")
    Params = MeshoptPermissiveParams

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        p = _checked(self.params)
        if p.protect not in PROTECT_CHOICES:
            raise ParamError(f"protect={p.protect!r}: expected one of "
                             f"{', '.join(PROTECT_CHOICES)}")
        attributes, weights, stats = vertex_attributes(mesh, p)
        lock = protected_vertices(mesh, p.protect)
        flags = _flags(p) + ["Permissive"] + (["Regularize"] if p.regularize else [])
        result = simplify_index_buffer(mesh, target_faces, "attributes", _error_bound(p),
                                       flags=flags, absolute=p.error_absolute,
                                       attributes=attributes, weights=weights, lock=lock)
        result.stats.update(stats, protected_vertices=int(np.count_nonzero(lock)))
        return result


class MeshoptSloppy(_Node):
    """meshoptimizer's ``simplifySloppy``: grid vertex clustering, topology ignored.

    Seams and borders are not kept (README: "it doesn't preserve attribute seams or
    borders"; cracks and merged sheets are expected). With no error bound the result
    never exceeds the target; the grid search often stops below it.
    """

    name = "meshopt-sloppy"
    version = "2"  # 2: meshoptimizer 1.3.0 replaces the 0.22 core
    summary = "meshoptimizer's sloppy grid clustering (fast, ignores seams and topology)"
    reference = ("A. Kapoulkine, meshoptimizer 1.3 (software), meshopt_simplifySloppy; after "
                 "Lindstrom, Out-of-core simplification of large polygonal models, "
                 "SIGGRAPH 2000")
    Params = MeshoptSloppyParams

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        return simplify_index_buffer(mesh, target_faces, "sloppy", _error_bound(self.params),
                                     absolute=False, below=SLOPPY_BELOW)


@dataclass
class GltfpackParams:
    """gltfpack's simplification options (``gltfpack -h``, "Simplification").

    The face target becomes ``-si R`` with R = target / faces (gltfpack keeps at most
    floor(R x faces) of each primitive). target_error is ``-se`` ("limit simplification
    error to E (default: 0.01 = 1% deviation ...)"), gltfpack's default: unlike the
    meshopt rows, gltfpack also prunes ('Prune': components under the error limit are
    removed), so a limit near 1 removes whole models (measured: bunny-textured and
    two-materials at 2 % left no triangle at -se 0.99). attributes is ``-sv`` ("simplify
    with vertex position and attribute optimization"), permissive ``-sp``, aggressive
    ``-sa`` ("aggressively simplify to the target ratio disregarding quality"),
    lock_border ``-slb`` ("lock border vertices during simplification to avoid gaps on
    connected meshes"; it also turns gltfpack's pruning off).
    quantize=false passes ``-noq`` ("disable quantization"), so positions, UVs and
    normals come back as 32-bit floats, as the suite wrote them.
    """

    target_error: float = bounded(0.01, ge=0)
    attributes: bool = True
    permissive: bool = False
    aggressive: bool = False
    lock_border: bool = False
    quantize: bool = False


class Gltfpack(_Node):
    """gltfpack 1.3.0 on the model written as GLB (one primitive per material),
    simplified with ``-si`` and read back as any GLB a user gives.

    gltfpack is the library's own glTF pipeline: it welds, simplifies each primitive
    with meshoptimizer (attribute-aware and updating vertices with ``-sv``), optimises
    the vertex order and writes the file. See :class:`GltfpackParams` for the flags.
    No library error is reported (gltfpack does not print it).
    """

    name = "gltfpack"
    version = "1"
    summary = "gltfpack (meshoptimizer's glTF optimiser) with -si on the model as GLB"
    reference = "A. Kapoulkine, gltfpack 1.3 (software), part of meshoptimizer"
    Params = GltfpackParams
    package = "gltfpack"

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        from bench.io.meshio import glb_bytes, load_mesh

        p = self.params
        if not 0 <= p.target_error <= 1:
            raise ParamError(f"target_error={p.target_error}: gltfpack's -se takes 0 to 1")
        ratio = (int(target_faces) + 0.5) / mesh.n_faces  # float32 in gltfpack: floor safe
        args = ["-si", repr(ratio), "-se", repr(float(p.target_error))]
        args += (["-sv"] if p.attributes else []) + (["-sp"] if p.permissive else []) + \
            (["-sa"] if p.aggressive else []) + (["-slb"] if p.lock_border else []) + \
            ([] if p.quantize else ["-noq"])
        with tempfile.TemporaryDirectory(prefix="bench-gltfpack-") as tmp:
            source, packed = Path(tmp) / "in.glb", Path(tmp) / "out.glb"
            source.write_bytes(glb_bytes(mesh, name=mesh.name))
            start = time.perf_counter()
            _node([str(NODE_DIR / "node_modules" / "gltfpack" / "cli.js"), "-i", str(source),
                   "-o", str(packed), *args], b"", None)
            seconds = time.perf_counter() - start
            if not _glb_has_meshes(packed.read_bytes()):
                raise MethodError(
                    f"{mesh.name}: gltfpack left no triangles for a target of {target_faces} "
                    f"faces (with -se {p.target_error:g} its pruning removed every component); "
                    "ask for more faces or a lower target_error")
            # what the reader would warn a user about (a non-manifold edge gltfpack
            # made, a zero-area face dropped) describes the result: kept in its stats
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", MeshWarning)
                out = load_mesh(packed, name=mesh.name)
        notes = [str(w.message).replace(str(packed), "gltfpack's output") for w in caught
                 if issubclass(w.category, MeshWarning)]
        for w in caught:  # anything else is passed on as it came
            if not issubclass(w.category, MeshWarning):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        stats = {"backend": f"gltfpack {GLTFPACK_VERSION} (npm, WebAssembly on Node)",
                 "library_version": GLTFPACK_VERSION, "gltfpack_args": " ".join(args),
                 "gltfpack_seconds": seconds, "read_back_notes": notes}
        reason = None
        if abs(out.n_faces - target_faces) > target_tolerance(target_faces):
            reason = (f"gltfpack stopped at {out.n_faces} faces for a target of "
                      f"{target_faces} (tolerance {target_tolerance(target_faces)}): it "
                      "simplifies each primitive to floor(R x its faces) at most, within its "
                      f"error limit -se {p.target_error:g}, keeping seams"
                      + ("" if p.permissive else " (-sp not given)") + " and pruning "
                      "small components")
        # the input's metadata, with the material table of what came back (gltfpack may
        # reorder primitives) and not the temporary file as a source
        meta = {k: v for k, v in mesh.metadata.items() if k != "atlas"}
        if "atlas" in out.metadata:
            meta["atlas"] = _sources_from(out.metadata["atlas"], mesh.metadata.get("atlas"))
        return SimplifyResult(out.replace(metadata=meta), stats, stop_reason=reason)


def _sources_from(table: dict, original: dict | None) -> dict:
    """The material table read back from gltfpack's output, each texture's ``source``
    the input material's of that name (not the temporary file it was read from)."""
    sources = {m.get("name"): (m.get("texture") or {}).get("source")
               for m in (original or {}).get("materials", [])}
    table = {**table, "materials": [dict(m) for m in table["materials"]]}
    for m in table["materials"]:
        if m.get("texture") and sources.get(m.get("name")):
            m["texture"] = {**m["texture"], "source": sources[m["name"]]}
    return table


def _glb_has_meshes(data: bytes) -> bool:
    """Whether a GLB's JSON chunk lists a mesh (gltfpack writes none when it removed
    every triangle)."""
    try:
        (length,) = struct.unpack_from("<I", data, 12)
        return bool(json.loads(data[20:20 + length]).get("meshes"))
    except (struct.error, ValueError):
        return True  # not ours to judge: load_mesh says what is wrong with the file


# -- the shared pipeline ------------------------------------------------------------------

def simplify_index_buffer(mesh: Mesh, target_faces: int, op: str, target_error: float, *,
                          flags=(), absolute: bool = False, attributes=None, weights=(),
                          lock=None, below: str = "") -> SimplifyResult:
    """The pipeline shared by the meshopt rows: index buffer in, compacted mesh out.

    Parameters
    ----------
    mesh : Mesh
    target_faces : int
    op : str
        The library function (see :func:`call_library`).
    target_error : float
        The library's error bound (``UNBOUNDED_ERROR`` for none).
    flags, attributes, weights, lock
        Passed to the library as they are.
    absolute : bool
        Whether ``target_error`` and the library's result error are in model units
        ('ErrorAbsolute') rather than relative to the mesh's extent.
    below : str
        Why this simplifier may stop below the target, for the stop reason.

    Returns
    -------
    SimplifyResult
        With ``stop_reason`` set when the library stopped outside the suite's tolerance.
    """
    indices = mesh.faces.reshape(-1)
    positions = mesh.positions.astype(np.float32)

    def call(target_index_count: int, bound: float) -> LibraryResult:
        return call_library(op, indices, positions, attributes=attributes, weights=weights,
                            lock=lock, target_index_count=target_index_count,
                            target_error=bound, flags=flags)

    lib = call(3 * int(target_faces), target_error)
    if len(lib.kept) == 0:  # no LOD to degrade to: say so instead of returning nothing
        raise MethodError(f"{mesh.name}: meshoptimizer left no triangles for a target of "
                          f"{target_faces} faces (its result error {lib.error:.4g}); ask for "
                          "more faces")
    result = _compact(mesh, lib, op, attributes)

    # The library's error both ways: relative to the extent (its default unit) and in
    # model units; getScale is the factor between them.
    relative = lib.error / lib.scale if absolute else lib.error
    stats = {"backend": f"meshoptimizer {lib.version} (npm, WebAssembly on Node {lib.node})",
             "library_version": lib.version,
             "result_error": lib.error, "result_error_units": "absolute" if absolute else "relative",
             "library_error": relative, "library_error_absolute": relative * lib.scale,
             "error_scale": lib.scale, "library_seconds": lib.seconds,
             "target_error": None if target_error == UNBOUNDED_ERROR else target_error}
    reason = _stop_reason(call, result.n_faces, target_faces, target_error, lib.error, below)
    return SimplifyResult(result, stats, stop_reason=reason)


def vertex_attributes(mesh: Mesh, p: MeshoptAttributesParams):
    """Per-vertex attributes (n, 2 + 3) or (n, 3) float32, their weights, and stats.

    UVs come first (when the mesh has them), then the vertex normals.
    """
    columns, weights, stats = [], [], {"normal_weight": float(p.normal_weight)}
    if mesh.uv is not None:
        uv_weight = float(p.uv_weight_scale * uv_density_weight(mesh))
        columns.append(mesh.uv)
        weights += [uv_weight, uv_weight]
        stats["uv_weight"] = uv_weight
    columns.append(mesh.vertex_normals)
    weights += [float(p.normal_weight)] * 3
    attributes = np.ascontiguousarray(np.hstack(columns), dtype=np.float32)
    return attributes, weights, stats


def uv_density_weight(mesh: Mesh) -> float:
    """The UV weight the meshoptimizer README recommends: the reciprocal of the average
    UV density, 1 / sqrt(sum |UV area| / triangle count); 0 when the UVs have no area.
    """
    uv = mesh.uv[mesh.faces]
    a, b = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    mean_area = float(np.abs(0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])).mean())
    return float(1.0 / np.sqrt(mean_area)) if mean_area > 0 else 0.0


def protected_vertices(mesh: Mesh, protect: str = "orientation") -> np.ndarray:
    """``vertex_lock`` for permissive mode: VERTEX_PROTECT on the render vertices to keep
    as seams, 0 elsewhere; shape (n,) uint8.

    A render vertex is on a UV seam when another render vertex at the same position has
    a different UV. ``orientation`` protects those of them where the faces around the
    position have UV triangles of both windings (the charts meeting there differ in
    orientation: a mirrored chart); ``seams`` protects every UV-seam vertex; ``none``
    none. Vertices on a material boundary (another vertex at the position lies in
    another material's atlas tile) are protected in every case.
    """
    from bench.io.atlas import wedge_tiles

    n = mesh.n_vertices
    lock = np.zeros(n, np.uint8)
    if mesh.uv is None:
        return lock
    group = mesh.welded.vertex_of
    k = mesh.welded.n_vertices

    def differs(values: np.ndarray) -> np.ndarray:
        """Render vertices whose position is shared with a different value of ``values``."""
        values = np.ascontiguousarray(values)
        first = np.full(k, -1, np.int64)
        first[group[::-1]] = np.arange(n)[::-1]  # the first render vertex of each position
        other = np.any(values != values[first[group]], axis=1)
        mixed = np.zeros(k, bool)
        np.logical_or.at(mixed, group, other)
        return mixed[group]

    seam = differs(mesh.uv)
    tiles = wedge_tiles(mesh)
    material = differs(tiles) if tiles is not None else np.zeros(n, bool)
    if protect == "seams":
        chosen = seam
    elif protect == "orientation":
        uv = mesh.uv[mesh.faces]
        a, b = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
        signed = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        winding = np.zeros(k, np.uint8)  # bit 1: a counter-clockwise UV face, bit 2: clockwise
        for corner in range(3):
            w = mesh.welded.faces[:, corner]
            np.bitwise_or.at(winding, w[signed > 0], 1)
            np.bitwise_or.at(winding, w[signed < 0], 2)
        chosen = seam & (winding[group] == 3)
    else:
        chosen = np.zeros(n, bool)
    lock[chosen | material] = VERTEX_PROTECT
    return lock


def _compact(mesh: Mesh, lib: LibraryResult, op: str, attributes) -> Mesh:
    """The kept triangles over only the vertices they use, attributes carried along
    (for ``update``, the library's updated positions, UVs and normals)."""
    used, faces = compact(lib.kept, mesh.n_vertices)
    pick = {attr: getattr(mesh, attr)[used] for attr in ("uv", "normals", "colors")
            if getattr(mesh, attr) is not None}
    positions = mesh.positions[used]
    if op == "update":
        positions = lib.positions[used].astype(np.float64)
        updated = lib.attributes[used].astype(np.float64)
        if mesh.uv is not None:
            pick["uv"], updated = updated[:, :2], updated[:, 2:]
        if mesh.normals is not None:
            length = np.linalg.norm(updated[:, :3], axis=1, keepdims=True)
            pick["normals"] = np.where(length > 0, updated[:, :3] / np.where(length > 0, length, 1),
                                       mesh.normals[used])
    return mesh.replace(positions=positions, faces=faces, **pick)


def _stop_reason(call, reached: int, target: int, target_error: float, error: float,
                 below: str) -> str | None:
    """Why the library stopped outside the tolerance, or None when it is within.

    Above the target the cause is the error bound or the topology rules; the library
    does not say which, so with a bound the call is repeated without one (only on this
    path): the bound was the cause if that run gets further.
    """
    tolerance = target_tolerance(target)
    if abs(reached - target) <= tolerance:
        return None
    if reached < target:
        return (f"stopped at {reached} faces, below the target of {target} (tolerance "
                f"{tolerance})" + (f": {below}" if below else ""))
    if target_error != UNBOUNDED_ERROR:
        unbounded = call(3 * target, UNBOUNDED_ERROR)
        if len(unbounded.kept) < reached:
            return (f"stopped at {reached} faces above the target of {target}: the "
                    f"error bound target_error={target_error:g} allows no coarser result "
                    f"(library error {error:.4g})")
    return (f"stopped at {reached} faces above the target of {target}: no collapse "
            f"left that keeps the seams and borders the library preserves (library error "
            f"{error:.4g})")


def _checked(p: MeshoptParams) -> MeshoptParams:
    """The parameters, refused when they ask for what the library cannot do sensibly."""
    if p.prune and not p.bound_error:
        # Pruning drops any component whose removal stays under the error bound; with
        # no bound that is every component (measured: bunny-textured to 0 faces at 2 %).
        raise ParamError("prune=true removes components under target_error and, with no "
                         "error bound, can remove the whole mesh: also set bound_error=true")
    return p


def _error_bound(p) -> float:
    return float(p.target_error) if p.bound_error else UNBOUNDED_ERROR


def _flags(p: MeshoptParams) -> list[str]:
    return ((["LockBorder"] if p.lock_border else []) + (["Prune"] if p.prune else [])
            + (["ErrorAbsolute"] if p.error_absolute else []))
