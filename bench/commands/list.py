"""``bench list [methods|models|metrics|suites|claims]``: what is registered, from where,
and whether it can run here; the named experiment suites and the papers' claims they test
(with how each claim's class is decided: ``wilcoxon over views``, ``interval over views``,
or ``no test`` for a metric without per-view values)."""

from __future__ import annotations

import warnings

from bench.core.registry import registry

KINDS = {"methods": "method", "models": "model", "metrics": "metric"}


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="list registered methods, models and metrics, the suites and the claims",
                       description=__doc__)
    p.add_argument("what", nargs="?", choices=list(KINDS) + ["suites", "claims"],
                   help="only this kind (default: all)")
    p.set_defaults(run=run)


def run(args) -> int:
    kinds = [args.what] if args.what else list(KINDS) + ["suites", "claims"]
    for i, plural in enumerate(kinds):
        if i:
            print()
        if plural == "suites":
            rows = _suite_rows()
        elif plural == "claims":
            rows = _claim_rows()
        else:
            rows = [_row(KINDS[plural], e) for e in registry(KINDS[plural])]
        print(f"{plural} ({len(rows)})")
        _table(rows)
    return 0


def _suite_rows() -> list[dict]:
    from bench.records.suites import SUITES

    return [{"name": s.name, "models": ",".join(s.models), "claims": len(s.claims),
             "detail": s.description} for s in SUITES.values()]


def _claim_rows() -> list[dict]:
    from bench.records.suites import SUITES

    return [{"name": c.name, "suite": c.suite, "source": c.source, "test": c.test,
             "class by": claim_class_test(c), "paper": c.paper or "qualitative",
             "detail": c.statement}
            for s in SUITES.values() for c in s.claims]


def claim_class_test(claim) -> str:
    """How ``claim``'s class is decided (:mod:`bench.records.claims`): a paired test
    over the views, an interval over the views, or no test when its metric has no
    per-view values (a metric registered as needing the images has them)."""
    from bench.core.registry import registry

    metrics = registry("metric")
    per_view = False
    if claim.metric in metrics and metrics.entry(claim.metric).available:
        per_view = "images" in metrics.load(claim.metric).needs
    if not per_view:
        return "no test"
    return "wilcoxon over views" if claim.against else "interval over views"


def _row(kind: str, entry) -> dict:
    row = {"name": entry.name}
    if not entry.available:
        row.update(status="unavailable", detail=entry.problem)
    else:
        obj = entry.load()
        if kind == "method":
            row.update(version=obj.version, view="dependent" if obj.view_dependent else "",
                       detail=obj.summary)
        elif kind == "metric":
            needs = sorted(set(getattr(obj, "needs", ())) - {"meshes"}) or ["meshes"]
            row.update(unit=obj.unit, direction=obj.direction, needs=",".join(needs),
                       detail=obj.summary)
        elif getattr(obj, "derived_faces", None):  # listing it must not build it
            row.update(faces=obj.derived_faces, texture="", detail=f"{obj.description}; "
                       f"made by {getattr(obj, 'derived_by', 'simplification')} when first used")
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    s = obj.load().summary()
                except Exception as exc:  # a broken model is listed, not fatal
                    row.update(status="unavailable", detail=str(exc))
                    return row | {"origin": entry.origin}
            row.update(faces=s["faces"], vertices=s["render_vertices"],
                       welded=s["welded_vertices"], texture="yes" if s["texture"] else "no",
                       detail=obj.source)
    row["origin"] = entry.origin
    return row


def _table(rows: list[dict]) -> None:
    if not rows:
        print("  (none)")
        return
    cols = list(dict.fromkeys(k for r in rows for k in r if k != "detail")) + ["detail"]
    width = {c: max(len(c), *(len(str(r.get(c, ""))) for r in rows)) for c in cols}
    print("  " + "  ".join(c.ljust(width[c]) for c in cols).rstrip())
    for r in rows:
        print("  " + "  ".join(str(r.get(c, "")).ljust(width[c]) for c in cols).rstrip())
