"""``bench simplify IN_OR_MODEL OUT --method NAME (--faces N | --ratio R)``: simplify one
mesh and write the result (with its texture) to OUT; the format follows OUT's extension."""

from __future__ import annotations

import sys
from pathlib import Path

from bench.io.meshio import check_output_path, save_mesh
from bench.method import parse_params, resolve_target, run_method
from bench.models import resolve_model
from bench.registry import registry


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="simplify one mesh and write the result", description=__doc__)
    p.add_argument("input", metavar="IN_OR_MODEL", help="a mesh file or a model name (bench list models)")
    p.add_argument("output", metavar="OUT", help="output file (.obj, .ply, .glb, .gltf, .off, .stl)")
    p.add_argument("--method", "-m", required=True, help="method name (bench list methods)")
    target = p.add_mutually_exclusive_group(required=True)
    target.add_argument("--faces", "-f", type=int, help="target triangle count")
    target.add_argument("--ratio", "-r", type=float, help="target as a fraction of the input's faces")
    p.add_argument("--param", "-p", action="append", default=[], metavar="KEY=VALUE",
                   help="method parameter (repeatable)")
    p.set_defaults(run=run)


def run(args) -> int:
    method_cls = registry("method").load(args.method)
    check_output_path(args.output)  # fail before the work, not after
    params = parse_params(method_cls.Params, args.param)
    mesh = resolve_model(args.input)
    target = resolve_target(mesh.n_faces, args.faces, args.ratio)
    result = run_method(method_cls(params), mesh, target)
    written = save_mesh(result.mesh, args.output)
    seconds = result.stats.get("wall_seconds", 0.0)
    print(f"{mesh.name}: {mesh.n_faces} -> {result.mesh.n_faces} faces "
          f"({result.mesh.n_vertices} vertices) with {method_cls.name} in {seconds:.3f} s; "
          f"wrote {', '.join(str(Path(w)) for w in written)}")
    if result.stop_reason:
        print(f"bench: note: stopped short: {result.stop_reason}", file=sys.stderr)
    return 0
