"""LOD chains: one mesh simplified by one method to several face counts, as engines ship
levels of detail (``bench simplify IN OUT --faces N1,N2,...``).

Naming follows the engines: LOD0 is the full-detail mesh, the input itself, and LOD1,
LOD2, ... are the requested levels, most detailed first (Unreal's and Unity's LOD groups
and glTF's MSFT_lod all count from the full mesh). Requested face counts must decrease
strictly, starting below the input's.

Each level is simplified from the original by default. With ``chain`` each is simplified
from the previous level's result, as engines build chains to keep the levels consistent
and cheap (a level costs only the reduction from its predecessor). A method's own error
(meshoptimizer's ``result_error``) is then measured against that predecessor, not the
original, while the protocol's figures (``protocol`` given) always compare a level with
the ORIGINAL input, so direct and chained levels can be compared.

The sidecar (:func:`sidecar`, written to :func:`sidecar_path`) records per level what
was asked, what was obtained and how; its schema is :data:`SIDECAR_SCHEMA`::

    {"schema": 1, "created": ISO time, "input": {"name", "source", "hash", "faces",
     "render_vertices"}, "method": {"name", "version", "params"},
     "levels_from": "original" | "previous", "protocol": {...} | null,
     "files": [file names beside the sidecar],
     "seconds": wall time of building the levels (simplifying and evaluating, not writing),
     "levels": [{"name": "LOD0", "file", "source": null, "requested": null,
                 "target_faces": null, "faces", "render_vertices", ...},
                {"name": "LOD1", "file", "source": "LOD0", "source_faces",
                 "requested": {"faces": N} | {"ratio": r}, "target_faces", "faces",
                 "render_vertices", "stop_reason", "method_error",
                 "method_error_units", "seconds", "stats": {...},
                 "metrics": {...} | null, "evaluation_seconds"}, ...],
     "environment": {"versions", "git_commit", "python", "machine"}}
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from bench.core.errors import InputError
from bench.core.mesh import Mesh
from bench.core.method import Method, SimplifyResult, run_method
from bench.run.jobs import environment, evaluate_result
from metrics.protocol import Evaluation, Protocol

__all__ = ["SIDECAR_SCHEMA", "Level", "build_levels", "level_name", "level_targets", "sidecar",
           "sidecar_path"]

SIDECAR_SCHEMA = 1


def level_name(index: int) -> str:
    """``LOD<index>``: LOD0 is the input, LOD1 the first requested level."""
    return f"LOD{index}"


@dataclass
class Level:
    """One simplified level of a chain.

    ``requested`` is what the user asked for (``{"faces": N}`` or ``{"ratio": r}``),
    ``source`` the level it was simplified from (``LOD0`` unless chained).
    """

    name: str
    target_faces: int
    requested: dict
    source: str
    source_faces: int
    result: SimplifyResult
    evaluation: Evaluation | None = None
    evaluation_seconds: float | None = None


def level_targets(n_faces: int, faces: list[int] | None = None,
                  ratios: list[float] | None = None) -> list[tuple[int, dict]]:
    """The face target of each requested level, checked, as (target, requested) pairs.

    A ratio is a fraction of the input's ``n_faces``, rounded as ``--ratio`` rounds it.

    Raises
    ------
    InputError
        A count below 1, a ratio outside (0, 1], a first level not below the input's
        faces (LOD0 is the input), or counts that do not decrease strictly (two ratios
        that round to one count included).
    """
    if (faces is None) == (ratios is None):
        raise InputError("give the levels as --faces N1,N2,... or --ratios r1,r2,...")
    levels = []
    for f in faces or ():
        if f < 1:
            raise InputError(f"--faces must be at least 1, got {f}")
        levels.append((int(f), {"faces": int(f)}))
    for r in ratios or ():
        if not 0 < r <= 1:
            raise InputError(f"--ratios: every ratio must be in (0, 1], got {r}")
        levels.append((max(1, round(r * n_faces)), {"ratio": r}))

    def asked(i: int) -> str:
        target, requested = levels[i]
        ratio = f" (ratio {requested['ratio']:g})" if "ratio" in requested else ""
        return f"{level_name(i + 1)} asks for {target} faces{ratio}"

    if levels[0][0] >= n_faces:
        raise InputError(f"{asked(0)}, not fewer than the input's {n_faces} (LOD0 is the "
                         "input itself; every level must have fewer faces than the one before)")
    for i in range(1, len(levels)):
        if levels[i][0] >= levels[i - 1][0]:
            raise InputError(f"levels must have strictly decreasing face counts: {asked(i)}, "
                             f"not fewer than {level_name(i)}'s {levels[i - 1][0]}")
    return levels


def build_levels(method: Method, mesh: Mesh, targets: list[tuple[int, dict]],
                 chain: bool = False, protocol: Protocol | None = None,
                 progress: bool = False,
                 on_level: Callable[[Level], None] | None = None) -> list[Level]:
    """Simplify ``mesh`` to each of ``targets`` (from :func:`level_targets`).

    Parameters
    ----------
    chain : bool
        Simplify each level from the previous level's result instead of from ``mesh``.
    protocol : Protocol, optional
        Evaluate each level against ``mesh`` under it (the original's images come
        from the disk cache of :func:`metrics.protocol.original_images`).
    progress : bool
        Show a progress bar on stderr, one step per level (the runner's bar).
    on_level : callable, optional
        Called with each level as it is done (the CLI prints a line per level).
    """
    from tqdm import tqdm

    reference = None
    if protocol is not None:
        from metrics.protocol import original_images

        reference = original_images(mesh, protocol)
    levels: list[Level] = []
    bar = tqdm(total=len(targets), unit="level", desc=mesh.name, disable=not progress,
               dynamic_ncols=True, file=sys.stderr)
    try:
        for index, (target, requested) in enumerate(targets, 1):
            name = level_name(index)
            source = levels[-1] if chain and levels else None
            source_mesh = source.result.mesh if source else mesh
            bar.set_postfix_str(f"{name}: simplifying to {target} faces")
            result = run_method(method, source_mesh, target)
            level = Level(name, target, requested, source.name if source else level_name(0),
                          source_mesh.n_faces, result)
            if protocol is not None:
                bar.set_postfix_str(f"{name}: evaluating")
                start = time.perf_counter()
                level.evaluation, view_stats = evaluate_result(mesh, result, protocol, reference)
                result.stats.update(view_stats)
                level.evaluation_seconds = time.perf_counter() - start
            levels.append(level)
            bar.update(1)
            if on_level is not None:
                on_level(level)
        bar.set_postfix_str("done")
    finally:
        bar.close()
    return levels


def sidecar_path(out: str | Path) -> Path:
    """The sidecar of an LOD chain written to ``out``: ``<out>.lods.json`` (``x.glb`` ->
    ``x.glb.lods.json``), so chains of one stem in two formats do not collide."""
    out = Path(out)
    return out.with_name(out.name + ".lods.json")


def sidecar(mesh: Mesh, method: Method, levels: list[Level], chain: bool,
            files: dict[str, list[Path]], protocol: Protocol | None = None,
            seconds: float | None = None, source: str | None = None) -> dict:
    """The sidecar record of a chain (schema in the module docstring).

    ``files`` maps each level's name (LOD0 included) to the files written for it, as
    :func:`bench.io.meshio.save_lods` returns them; they are recorded by name, as they
    sit beside the sidecar. ``source`` is the input as the user named it (a model name
    or a file); by default the file the mesh was read from.
    """
    def file_of(name: str) -> str:
        return files[name][0].name

    first = {"name": level_name(0), "file": file_of(level_name(0)), "source": None,
             "source_faces": None, "requested": None, "target_faces": None,
             "faces": mesh.n_faces, "render_vertices": mesh.n_vertices, "stop_reason": None,
             "method_error": None, "method_error_units": None, "seconds": None, "stats": {},
             "metrics": None, "evaluation_seconds": None}
    entries = [first]
    for level in levels:
        stats = level.result.stats
        entry = {"name": level.name, "file": file_of(level.name), "source": level.source,
                 "source_faces": level.source_faces, "requested": level.requested,
                 "target_faces": level.target_faces, "faces": level.result.mesh.n_faces,
                 "render_vertices": level.result.mesh.n_vertices,
                 "stop_reason": level.result.stop_reason,
                 # the method's own error estimate where it reports one (meshoptimizer's
                 # result_error, against the level's source); None for the others
                 "method_error": stats.get("result_error"),
                 "method_error_units": stats.get("result_error_units"),
                 "seconds": stats.get("wall_seconds"), "stats": stats,
                 "metrics": level.evaluation.metrics if level.evaluation else None,
                 "evaluation_seconds": level.evaluation_seconds}
        if level.evaluation is not None and level.evaluation.errors:
            entry["metric_errors"] = level.evaluation.errors
        if level.evaluation is not None and level.evaluation.screen is not None:
            from metrics.screen import switch_entry  # bench simplify --switch

            entry["switch"] = switch_entry(level.evaluation.screen, mesh, stats)
        entries.append(entry)
    names = []
    for written in files.values():
        names.extend(p.name for p in written if p.name not in names)
    return {"schema": SIDECAR_SCHEMA,
            "created": datetime.now(UTC).isoformat(timespec="seconds"),
            "input": {"name": mesh.name, "source": source or mesh.metadata.get("source"),
                      "hash": mesh.content_hash, "faces": mesh.n_faces,
                      "render_vertices": mesh.n_vertices},
            "method": {"name": method.name, "version": method.version,
                       "params": dataclasses.asdict(method.params)},
            "levels_from": "previous" if chain else "original",
            "protocol": protocol.as_dict() if protocol is not None else None,
            "files": names, "seconds": seconds, "levels": entries,
            "environment": environment()}
