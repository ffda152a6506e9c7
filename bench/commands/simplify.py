"""``bench simplify IN_OR_MODEL OUT --method NAME (--faces N[,N2,...] | --ratio R[,R2,...])``:
simplify one mesh and write the result (with its texture) to OUT; the format follows
OUT's extension.

With several levels (``--faces 5000,2500,600`` or ``--ratios 0.1,0.05``) it writes an
LOD chain. LOD0 is the input itself (the full-detail mesh, as engines count) and LOD1,
LOD2, ... are the levels in the order given, which must have strictly decreasing face
counts, below the input's. A .glb or .gltf OUT holds every level as one mesh (and
node) named LOD0, LOD1, ...; in any other format each level is a file named after
OUT: x.obj -> x_LOD0.obj, x_LOD1.obj, ... (with x_LOD1.mtl and x_LOD1.png when
textured; x.obj itself is not written). Every level is simplified from the input, or
with --chain from the previous level. x.obj.lods.json (OUT + .lods.json) lists per
level the target, the faces obtained, the level it was made from, the method with its
version and parameters, its stop reason, its own error where it reports one
(meshoptimizer's result_error, against the level's source), the seconds and, with
--evaluate, the protocol's figures (d_rms, FLIP, Hausdorff, ...) against the input.
Existing files are overwritten, as for a single level, which writes OUT alone, except
the input's own: a file the input is read from (the mesh, its MTL, a glTF's buffers) is
written over only with --force, and one of its textures never (choose another OUT: the
written textures are named after it). Nothing is written then.
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from pathlib import Path

from bench.catalog import parse_model_spec, resolve_model
from bench.commands.progress_bar import terminal_progress
from bench.core.errors import InputError
from bench.core.method import parse_params, resolve_target, run_method
from bench.core.registry import registry
from bench.io.meshio import (
    SCENE_FORMATS,
    check_not_inputs,
    check_output_path,
    input_files,
    lod_path,
    save_lods,
    save_mesh,
)


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="simplify one mesh and write the result (or an LOD chain)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", metavar="IN_OR_MODEL", help="a mesh file or a model name (bench list "
                   "models), with options as MODEL::texture=IMAGE")
    p.add_argument("output", metavar="OUT", help="output file (.obj, .ply, .glb, .gltf, .off, .stl)")
    p.add_argument("--method", "-m", required=True, help="method name (bench list methods)")
    target = p.add_mutually_exclusive_group(required=True)
    target.add_argument("--faces", "-f", metavar="N[,N2,...]",
                        help="target triangle count; several, comma-separated and decreasing, "
                        "write an LOD chain")
    target.add_argument("--ratios", "--ratio", "-r", dest="ratios", metavar="R[,R2,...]",
                        help="target as a fraction in (0, 1] of the input's faces; several, "
                        "comma-separated and decreasing, write an LOD chain")
    target.add_argument("--halving", nargs="?", const="auto", metavar="FLOOR",
                        help="LOD chain of 50 %%, 25 %%, ... of the input's faces down to FLOOR "
                        "faces (default: 100 or 1/256 of the input, the larger), as engines "
                        "build chains")
    p.add_argument("--switch", action="store_true",
                   help="LOD chain: measure each level's switch size (the largest screen size "
                   "at which it is indistinguishable from the input, docs/screen.md) and write "
                   "it into OUT.lods.json, also as Unreal ScreenSize and Unity screen-relative "
                   "height at 1080 pixels; implies --evaluate")
    p.add_argument("--chain", action="store_true",
                   help="LOD chain: simplify each level from the previous one (default: "
                   "each from the input)")
    p.add_argument("--evaluate", action="store_true",
                   help="LOD chain: evaluate each level against the input under the protocol "
                   "(d_rms, FLIP, Hausdorff, ...) into OUT.lods.json; renders 24 views per "
                   "level, slow on a CPU-only machine")
    p.add_argument("--texture", metavar="IMAGE", help="the input's texture image, in place of "
                   "its own (an OBJ with UVs and no mtllib has none); the same as "
                   "IN_OR_MODEL::texture=IMAGE")
    p.add_argument("--param", "-p", action="append", default=[], metavar="KEY=VALUE",
                   help="method parameter (repeatable)")
    p.add_argument("--force", action="store_true",
                   help="write over the input's mesh and material files if OUT names them "
                   "(its textures are never written over)")
    p.add_argument("--threads", metavar="T", help="threads the method's parallel kernels "
                   "may use, at least 1 (default: every core); results do not depend on it")
    p.set_defaults(run=run)


def parse_levels(text: str, flag: str, kind: type) -> list:
    """``"5000,2500"`` -> ``[5000, 2500]``; InputError naming ``flag`` if malformed."""
    items = [t.strip() for t in text.split(",")]
    try:
        if not all(items):
            raise ValueError
        return [kind(t) for t in items]
    except ValueError:
        example = "5000,2500,600" if kind is int else "0.1,0.05,0.01"
        raise InputError(f"{flag} {text!r}: expected {'a face count' if kind is int else 'a ratio'}"
                         f" or a comma-separated list such as {example}") from None


def run(args) -> int:
    if args.threads is not None:
        from bench.commands.run import whole_number
        from bench.run.jobs import use_threads

        use_threads(whole_number(args.threads, "--threads"))
    method_cls = registry("method").load(args.method)
    check_output_path(args.output)  # fail before the work, not after
    if args.texture is not None:
        if "texture" in parse_model_spec(args.input)[1]:
            raise InputError(f"--texture {args.texture}: the input {args.input!r} names a "
                             "texture already; give it once")
        args.input = f"{args.input}::texture={args.texture}"
    params = parse_params(method_cls.Params, args.param)
    faces = parse_levels(args.faces, "--faces", int) if args.faces is not None else None
    ratios = parse_levels(args.ratios, "--ratios", float) if args.ratios is not None else None
    if getattr(args, "halving", None) is not None:
        faces = _halving(args)
    if getattr(args, "switch", False):
        args.evaluate = True
    if len(faces or ratios) > 1:
        return run_chain(args, method_cls, params, faces, ratios)
    if args.chain or args.evaluate:
        flag = "chain" if args.chain else "switch" if getattr(args, "switch", False) else \
            "evaluate"
        raise InputError(f"--{flag} applies to LOD chains: give "
                         "two or more levels (--faces N1,N2,... or --ratios r1,r2,...)"
                         + ("" if args.chain else "; `bench run` evaluates a single result"))
    mesh = resolve_model(args.input)
    inputs = _inputs(mesh, [Path(args.output)], args.force)
    target = resolve_target(mesh.n_faces, faces[0] if faces else None,
                            ratios[0] if ratios else None)
    with terminal_progress(f"{mesh.name}: {method_cls.name}"):
        result = run_method(method_cls(params), mesh, target)
    written = save_mesh(_surfaced(result.mesh, mesh), args.output, inputs=inputs,
                        force=args.force)
    seconds = result.stats.get("wall_seconds", 0.0)
    print(f"{mesh.name}: {mesh.n_faces} -> {result.mesh.n_faces} faces "
          f"({result.mesh.n_vertices} vertices) with {method_cls.name} in {seconds:.3f} s; "
          f"wrote {', '.join(str(Path(w)) for w in written)}")
    if result.stop_reason:
        print(f"bench: note: stopped short: {result.stop_reason}", file=sys.stderr)
    return 0


def run_chain(args, method_cls, params, faces, ratios) -> int:
    """Write the LOD chain of ``bench simplify`` with several levels (module docstring)."""
    from bench.records.results import write_record
    from bench.run.lods import build_levels, level_name, level_targets, sidecar, sidecar_path
    from metrics.protocol import Protocol

    out = Path(args.output)
    if out.suffix.lower() not in SCENE_FORMATS:  # every level's file, before the work
        for path in [lod_path(out, level_name(i)) for i in range(len(faces or ratios) + 1)]:
            check_output_path(path)
    if sidecar_path(out).is_dir():
        raise InputError(f"{sidecar_path(out)}: is a directory; the chain's sidecar goes there")
    mesh = resolve_model(args.input)
    inputs = _inputs(mesh, [out] if out.suffix.lower() in SCENE_FORMATS else
                     [lod_path(out, level_name(i)) for i in range(len(faces or ratios) + 1)],
                     args.force)
    targets = level_targets(mesh.n_faces, faces, ratios)
    method = method_cls(params)
    protocol = Protocol() if args.evaluate else None
    if getattr(args, "switch", False):
        from metrics.screen import DEFAULT_SCREEN_SIZES

        protocol = Protocol(screen_sizes=DEFAULT_SCREEN_SIZES)

    report = functools.partial(_report_level, mesh.name, method_cls.name, args.chain)
    start = time.perf_counter()
    with terminal_progress(f"{mesh.name}: {method_cls.name}"):
        levels = build_levels(method, mesh, targets, chain=args.chain, protocol=protocol,
                              progress=True, on_level=report)
    seconds = time.perf_counter() - start
    files = save_lods([(level_name(0), mesh)] + [(lv.name, _surfaced(lv.result.mesh, mesh))
                                                 for lv in levels],
                      out, inputs=inputs, force=args.force)
    record = sidecar(mesh, method, levels, args.chain, files, protocol, seconds=seconds,
                     source=args.input)
    side = write_record(sidecar_path(out), record, sort_keys=False)
    written = []
    for paths in files.values():
        written.extend(str(p) for p in paths if str(p) not in written)
    print(f"wrote {', '.join(written + [str(side)])}")
    for level in levels:
        if level.result.stop_reason:
            print(f"bench: note: {level.name} stopped short: {level.result.stop_reason}",
                  file=sys.stderr)
    return 0


def _report_level(model: str, method: str, chain: bool, level) -> None:
    """One line per LOD level as it is made: faces, time and, evaluated, its figures."""
    from tqdm import tqdm

    r = level.result
    source = f" (from {level.source})" if chain else ""
    line = (f"{model} {level.name}{source}: {level.source_faces} -> {r.mesh.n_faces} "
            f"faces ({r.mesh.n_vertices} vertices) with {method} in "
            f"{r.stats.get('wall_seconds', 0.0):.3f} s")
    if level.evaluation is not None and level.evaluation.screen is not None:
        from metrics.screen import describe_bound

        line += f"; switch {describe_bound(level.evaluation.screen['switch_px'])} px"
    if level.evaluation is not None:
        m = level.evaluation.metrics
        line += "; " + ", ".join(f"{key} {m[key]:.4g}" for key in
                                 ("d_rms", "flip", "hausdorff_mean", "hausdorff_max")
                                 if m.get(key) is not None)
    tqdm.write(line, file=sys.stdout)


def _halving(args) -> list[int]:
    """The face counts of ``--halving [FLOOR]`` for the input (metrics.screen)."""
    from bench.commands.run import whole_number
    from metrics.screen import halving_faces

    floor = None if args.halving == "auto" else whole_number(args.halving, "--halving")
    n_faces = resolve_model(args.input).n_faces
    try:
        return halving_faces(n_faces, floor)
    except ValueError as exc:
        raise InputError(f"--halving: {exc}") from None


def _surfaced(result, mesh):
    """``result`` with the input ``mesh``'s material finish (its roughness, as the loader
    recorded it), which a method need not carry over, so the output is written with it."""
    if "material" not in mesh.metadata:
        return result
    return result.replace(metadata={**result.metadata, "material": mesh.metadata["material"]})


def _inputs(mesh, outputs: list[Path], force: bool) -> list:
    """The files ``mesh`` was read from (:func:`bench.io.meshio.input_files`), after
    refusing, before the work, an output mesh file that is one of them; the writer
    checks every file it writes (materials, textures) again."""
    inputs = input_files(mesh.metadata.get("source"))
    if mesh.metadata.get("texture"):  # given as MODEL::texture=IMAGE: never written over
        inputs.append((Path(mesh.metadata["texture"]), "texture"))
    check_not_inputs(outputs, inputs, force)
    return inputs
