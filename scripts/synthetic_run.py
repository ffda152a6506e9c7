"""Make a big run folder from a real one, to measure and test the report at scale.

    python scripts/synthetic_run.py SOURCE_RUN DEST --jobs 500 --models 10

Every record of SOURCE_RUN is copied again and again, with its images and meshes, until
DEST holds at least ``--jobs`` records: copy k goes to model ``<model>-m<k mod models>``
(a model hash of its own, so each model has its own original's views) and, after the first
round, to the method label ``<label>-c<k div models>``; job keys and file names follow.
Nothing is simplified or rendered: the figures are the source's.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import shutil
from pathlib import Path


def synthesise(source: Path, dest: Path, jobs: int, models: int) -> int:
    """Fill ``dest`` (made here, must not exist) from ``source``; returns the number of
    records written."""
    records = [(p.stem, json.loads(p.read_text()))
               for p in sorted((source / "records").glob("*.json"))]
    if not records:
        raise SystemExit(f"{source}: no records")
    (dest / "records").mkdir(parents=True)
    copies = math.ceil(jobs / len(records))
    for k in range(copies):
        for stem, record in records:
            _copy(source, dest, stem, record, model=k % models, copy=k // models)
    return copies * len(records)


def _copy(source: Path, dest: Path, stem: str, record: dict, model: int, copy: int) -> None:
    """One copy of ``record`` (filed as ``stem``.json, its job key), its images and its
    meshes."""
    job = record["job"]
    old_key = job.get("key") or stem
    old_hash = (record.get("model") or {}).get("hash")
    name = f"{job['model']}-m{model}"
    label = job["label"] + (f"-c{copy}" if copy else "")
    parts = old_key.split("__")
    key = "__".join([name, label, *parts[2:]])
    new_hash = hashlib.sha1(name.encode()).hexdigest()
    shading = job["protocol"]["shading"] + ("-spec" if job["protocol"].get("specular") else "")
    r = json.loads(json.dumps(record))
    r["job"].update(model=name, label=label, key=key)
    if r.get("model"):
        r["model"].update(name=name, hash=new_hash)
    r["artifacts"] = [a.replace(old_key, key) for a in record.get("artifacts") or []]
    (dest / "records" / f"{key}.json").write_text(json.dumps(r))
    _copy_folder(source / "images" / old_key, dest / "images" / key)
    _copy_file(source / "meshes" / f"{old_key}.glb", dest / "meshes" / f"{key}.glb")
    if old_hash:
        _copy_folder(source / "images" / f"original__{old_hash[:12]}__{shading}",
                     dest / "images" / f"original__{new_hash[:12]}__{shading}")
        _copy_file(source / "meshes" / f"original__{old_hash[:12]}.glb",
                   dest / "meshes" / f"original__{new_hash[:12]}.glb")


def _copy_folder(src: Path, dst: Path) -> None:
    if src.is_dir() and not dst.exists():
        shutil.copytree(src, dst)


def _copy_file(src: Path, dst: Path) -> None:
    if src.is_file() and not dst.exists():
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, dst)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("source", type=Path)
    p.add_argument("dest", type=Path)
    p.add_argument("--jobs", type=int, default=500)
    p.add_argument("--models", type=int, default=10)
    args = p.parse_args()
    n = synthesise(args.source, args.dest, args.jobs, args.models)
    print(f"{args.dest}: {n} records")


if __name__ == "__main__":
    main()
