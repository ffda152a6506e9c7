"""``bench run``: simplify every model with every method at every budget, evaluate each
result under the protocol, and write records, results.csv and an HTML report to DIR."""

from __future__ import annotations

import math
import os
import re
import sys
from datetime import datetime
from pathlib import Path

from bench.catalog import resolve_model
from bench.core.errors import InputError
from bench.core.method import canonical_params, method_label, resolve_target
from bench.core.registry import registry
from bench.records.results import OFF_TARGET, OFF_TARGET_STATUS
from bench.records.suites import evaluation_protocols, get_suite
from bench.run.runner import (
    EXECUTORS,
    default_threads,
    execute,
    plan,
    remaining,
    usable_cores,
)
from metrics.protocol import Protocol

DEFAULT_RATIOS = (0.02, 0.01)


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="run the benchmark and write a report", description=__doc__)
    p.add_argument("--models", help="comma-separated model names or mesh files (default: "
                   "bunny,torus); MODEL::texture=IMAGE gives a model a texture")
    p.add_argument("--methods", help="comma-separated method names; NAME[key=value,...] sets "
                   "parameters (default: every available method)")
    budget = p.add_mutually_exclusive_group()
    budget.add_argument("--faces", help="comma-separated face budgets, e.g. 1332,654")
    budget.add_argument("--ratios", help="comma-separated fractions of each model's faces "
                        "(default: 0.02,0.01)")
    p.add_argument("--shading", choices=["flat", "gouraud"], default=None,
                   help="evaluation shading (default: flat, or the suite's protocols; "
                   "given, it replaces them)")
    p.add_argument("--specular", action="store_true", help="add Blinn-Phong specular "
                   "(to every protocol of a suite)")
    p.add_argument("--screen-sizes", metavar="S1,S2,...|default",
                   help="also measure each result at these screen sizes (pixels spanned by "
                   "the model's bounding sphere, 1-4096; 'default' = 512,256,128,64,32) and "
                   "its switch size switch_px (docs/screen.md; on in the lod suite)")
    p.add_argument("--suite", help="a named experiment (sets models, methods, budgets and "
                   "evaluation protocols; the options above override them)")
    p.add_argument("--out", help="run directory (default: reports/run-YYYYmmdd-HHMMSS)")
    p.add_argument("--jobs", "-j", default=str(usable_cores()), metavar="N",
                   help="worker processes, at least 1, here or in the LocalCluster of "
                   "--executor dask without --scheduler (default: CPU count)")
    p.add_argument("--threads", metavar="T",
                   help="threads each job's parallel kernels may use, at least 1 (default: "
                   "the CPU count divided by --jobs, so jobs x threads <= cores; 1 on a "
                   "--scheduler's workers); results do not depend on it")
    p.add_argument("--executor", choices=EXECUTORS, default="local",
                   help="what runs the jobs: a pool of processes here (local, the default) "
                   "or a Dask cluster (dask; docs/cluster.md)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="a running Dask scheduler, e.g. tcp://HOST:8786 (with --executor "
                   "dask; without it a LocalCluster of --jobs workers is started)")
    p.add_argument("--resume", action="store_true", help="skip the jobs DIR holds a finished "
                   "record of (ok or skipped); failed jobs run again")
    p.add_argument("--timeout", default="900", metavar="S",
                   help="seconds a job's method may take, finite and above 0 (default "
                   "900; loading, warm-up and evaluation have 30 min each of their own)")
    p.add_argument("--no-report", action="store_true", help="skip the HTML report")
    p.add_argument("--single-file", action="store_true", help="inline every image in "
                   "index.html (one self-contained file, for small runs) instead of "
                   "linking image files of DIR")
    p.set_defaults(run=run)


def _split(text: str | None) -> list[str]:
    return [t.strip() for t in (text or "").split(",") if t.strip()]


def parse_variants(text: str | None) -> list[tuple[str, dict]]:
    """'a,b[x=1,y=2]' -> [('a', {}), ('b', {'x': '1', 'y': '2'})] (brackets may hold commas).

    An unclosed or unmatched bracket is an error, not a variant that swallows the rest of
    the list.
    """
    variants, depth, current = [], 0, ""
    for ch in (text or "") + ",":
        if ch == "," and depth == 0:
            if current.strip():
                variants.append(current.strip())
            current = ""
            continue
        depth += (ch == "[") - (ch == "]")
        if depth not in (0, 1):
            raise InputError(f"--methods: {'unmatched ]' if depth < 0 else 'nested ['} in "
                             f"{(current + ch).strip()!r}; parameters are written "
                             "NAME[key=value,...]")
        current += ch
    if depth:
        raise InputError(f"--methods: '[' not closed in {current.rstrip(',').strip()!r}; "
                         "parameters are written NAME[key=value,...]")
    out = []
    for v in variants:
        name, bracket, rest = v.partition("[")
        if not name.strip() or (bracket and not rest.endswith("]")):
            raise InputError(f"--methods {v!r}: parameters are written NAME[key=value,...]")
        params = {}
        for item in _split(rest[:-1]):
            key, sep, value = item.partition("=")
            if not sep:
                raise InputError(f"--methods {v!r}: parameters are written NAME[key=value,...]")
            params[key.strip()] = value.strip()
        out.append((name.strip(), params))
    return out


def whole_number(text: str, option: str) -> int:
    """A positive whole number given on the command line (no sign, point or exponent)."""
    if not re.fullmatch(r"\s*[0-9]+\s*", text) or int(text) < 1:
        raise InputError(f"{option} must be a whole number of at least 1, got {text!r}")
    return int(text)


def _seconds(text: str, option: str) -> float:
    """A finite number of seconds above 0 (NaN would never time out, 0 or less at once)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{option} must be a number of seconds above 0, got {text!r}")
    return value


def _ratio(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0 < value <= 1:  # NaN fails too
        raise InputError(f"--ratios: each must be a fraction in (0, 1], got {text!r}")
    return value


def _budgets(text: str | None, option: str, parse) -> list:
    if text is None:
        return []
    values = [parse(t) for t in _split(text)]
    if not values:
        raise InputError(f"{option}: no budget given in {text!r}")
    return values


def _check_out(out: Path) -> None:
    """Fail before any work when the run directory cannot be made or written."""
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a directory")
    existing = next(p for p in (out, *out.absolute().parents) if p.exists())
    if not existing.is_dir():
        raise InputError(f"--out {out}: {existing} is not a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"--out {out}: {existing} is not writable")


def run(args) -> int:
    if args.scheduler and args.executor != "dask":
        raise InputError("--scheduler is the address of a Dask scheduler: it needs "
                         "--executor dask")
    workers, timeout = whole_number(args.jobs, "--jobs"), _seconds(args.timeout, "--timeout")
    threads = _threads(args, workers)
    faces = _budgets(args.faces, "--faces", lambda t: whole_number(t, "--faces"))
    ratios = _budgets(args.ratios, "--ratios", _ratio)
    out = Path(args.out or f"reports/run-{datetime.now():%Y%m%d-%H%M%S}")
    _check_out(out)
    suite = get_suite(args.suite) if args.suite else None
    models = _models(args, suite)
    methods = registry("method")
    variants = _variants(args, suite, methods)
    meshes = {m: resolve_model(m) for m in models}
    if not args.methods and not (suite and suite.variants is not None):
        print(_default_methods_line(methods, [n for n, _ in variants], meshes), file=sys.stderr)
    budgets = {m: _targets(mesh, m, faces, ratios, suite) for m, mesh in meshes.items()}

    protocols = evaluation_protocols(suite, args.shading, args.specular)
    if getattr(args, "screen_sizes", None) is not None:
        protocols = with_screen_sizes(protocols, args.screen_sizes)
    jobs = plan(models, variants, budgets, protocols)
    if args.resume:
        jobs = remaining(jobs, out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot create it ({exc.strerror or exc})") from None
    print(f"bench: {len(jobs)} jobs ({len(models)} models x {len(variants)} methods x budgets"
          f"{_shadings(protocols)}) {_where(args, workers, threads)} -> {out}", file=sys.stderr)
    try:
        execute(jobs, out, workers=workers, timeout=timeout, executor=args.executor,
                scheduler=args.scheduler, threads=threads)
    except KeyboardInterrupt:  # every finished job's record is already on disk
        kept = len(list((out / "records").glob("*.json")))
        print(f"bench: interrupted; {kept} records kept in {out}; --resume continues",
              file=sys.stderr)
        return 130
    return finish(out, build_report=not args.no_report, single_file=args.single_file)


def _threads(args, workers: int) -> int:
    """Threads per job (``--threads``, else the default for ``workers``), with a note when
    jobs x threads is more than the cores here."""
    threads = whole_number(args.threads, "--threads") if args.threads else \
        default_threads(workers, args.scheduler)
    cores = usable_cores()
    if not args.scheduler and workers * threads > cores:
        print(f"bench: --jobs {workers} x {threads} thread{'s' if threads > 1 else ''} per job"
              f"{'' if args.threads else ' (the least)'} is more than the {cores} cores here: "
              "jobs compete for them and their times grow", file=sys.stderr)
    return threads


def _models(args, suite) -> list[str]:
    """The models of the run: ``--models``, else the suite's (with the real assets found),
    else bunny and torus."""
    models = _split(args.models) or list(suite.models if suite else ("bunny", "torus"))
    if suite and suite.assets and not args.models:
        present, missing = suite.present_assets()
        models += present
        if missing:
            print(f"bench: note: {len(missing)} real asset(s) of the suite not found, left "
                  f"out: {', '.join(missing)} (set BENCH_ASSETS to their folder)",
                  file=sys.stderr)
    return models


def _variants(args, suite, methods) -> list[tuple[str, dict]]:
    """The (method, parameters) of the run, one per distinct job: ``--methods``, else the
    suite's, else every available method. A typo fails here, before any work starts."""
    if args.methods:
        variants = parse_variants(args.methods)
    elif suite and suite.variants is not None:
        variants = list(suite.variants)
    else:
        variants = [(e.name, {}) for e in methods if e.available]
    distinct = {}
    for name, params in variants:
        params = canonical_params(methods.load(name).Params, params)
        distinct.setdefault(method_label(name, params), (name, params))
    return list(distinct.values())


def _targets(mesh, model: str, faces: list, ratios: list, suite) -> list[int]:
    """The face budgets of one model: ``--faces``, else the suite's for it, else the
    ratios (``--ratios``, the suite's or the default) of its faces."""
    if faces:
        return [resolve_target(mesh.n_faces, faces=f) for f in faces]
    if suite and model in suite.faces:
        return list(suite.faces[model])
    return [resolve_target(mesh.n_faces, ratio=r) for r in ratios or (
        suite.ratios if suite and suite.ratios else DEFAULT_RATIOS)]


def _shadings(protocols) -> str:
    return " x " + "/".join(
        p.shading + ("+specular" if p.specular else "")
        + (f" at {p.resolution}px" if p.resolution != Protocol().resolution else "")
        + (f" on the {p.views} view set" if p.views != Protocol().views else "")
        + (f" at screen sizes {','.join(map(str, p.screen_sizes))}" if p.screen_sizes else "")
        for p in protocols) + " shading"


def _where(args, workers: int, threads: int) -> str:
    return (f"on the Dask cluster at {args.scheduler}" if args.scheduler else
            f"with {workers} workers" + (" (Dask LocalCluster)" if args.executor == "dask"
                                           else "")) + \
        f", {threads} thread{'s' if threads > 1 else ''} per job"


def with_screen_sizes(protocols: list, text: str) -> list:
    """The protocols with ``--screen-sizes`` set (:func:`metrics.screen.parse_screen_sizes`);
    a bad size is a one-line InputError."""
    from dataclasses import replace

    from metrics.screen import parse_screen_sizes

    try:
        sizes = parse_screen_sizes(text)
    except ValueError as exc:
        raise InputError(f"--screen-sizes: {exc}") from None
    return list(dict.fromkeys(replace(p, screen_sizes=sizes) for p in protocols))


def _default_methods_line(methods, names: list[str], meshes: dict) -> str:
    """The first line of a run with no ``--methods``: every available method, and which
    were left out (unavailable) or will be skipped on some models (they need UVs)."""
    notes = [f"{e.name} (unavailable: {e.problem})" for e in methods if not e.available]
    no_uv = [m for m, mesh in meshes.items() if mesh.uv is None]
    for name in names:
        if methods.load(name).needs_uv and no_uv:
            notes.append(f"{name} on {', '.join(no_uv)} (needs texture coordinates)")
    return (f"bench: every available method ({len(names)})"
            + (f"; skipped: {'; '.join(notes)}" if notes else ""))


def finish(out: Path, build_report: bool = True, single_file: bool = False) -> int:
    """Write results.csv (and the report, in one file with ``single_file``) from every
    record in ``out``; print a summary.

    A record that cannot be used (damaged, or not a record) is left out with a warning
    and a note in the report, so one bad file does not hide the rest of a run. The
    summary printed comes from records that may be someone else's: its text is shown
    with control characters escaped.
    """
    import warnings

    from bench.commands import one_line
    from bench.core.errors import RecordWarning
    from bench.records.results import load_records, records_table, write_table

    skipped = []
    records = load_records(out, skipped=skipped)
    for note in skipped:
        warnings.warn(note, RecordWarning, stacklevel=2)
    written = [_writing(out / "results.csv", lambda: write_table(out, records))]
    if build_report:  # every file is written before anything is said about the run
        from bench.report.page import write_report

        written.append(_writing(out / "index.html", lambda: write_report(
            out, records, skipped, single_file=single_file)))
    table = records_table(records)
    for column in ("model", "method", "status"):
        table[column] = table[column].map(one_line)
    cols = ["model", "method", "target_faces", "faces", "d_rms", "hausdorff_mean",
            "seam_cracks", "seconds", "status"]
    if table.shading.nunique() > 1:
        cols.insert(2, "shading")
    if table.exterior_share.notna().any():
        cols.insert(cols.index("seconds"), "exterior_share")
    with_pd_options(lambda: print(table[cols].to_string(index=False)))
    failed = table[table.status == "failed"]
    off = table[table.status == OFF_TARGET_STATUS]
    for path in written:
        print(f"bench: wrote {path}", file=sys.stderr)
    if len(off):
        print(f"bench: {len(off)} of {len(table)} results ended more than "
              f"{OFF_TARGET * 100:g} % from their "
              "target (status 'ok, off target'; the report's Failures section says why)",
              file=sys.stderr)
    if len(failed):
        print(f"bench: {len(failed)} of {len(table)} jobs failed (see the report or "
              f"{out}/records)", file=sys.stderr)
        return 1
    return 0


def _writing(path: Path, write):
    """``write()``, with a file-system error (a read-only run folder, ``index.html`` made
    a directory) as a one-line error naming ``path``."""
    try:
        return write()
    except OSError as exc:
        raise InputError(f"{path}: cannot write it ({exc.strerror or exc})") from None


def with_pd_options(fn):
    import pandas as pd

    with pd.option_context("display.width", 200, "display.max_columns", 20,
                           "display.float_format", "{:.4g}".format):
        fn()
