"""``bench report DIR``: rebuild DIR/results.csv and DIR/index.html from DIR's records."""

from __future__ import annotations

from pathlib import Path


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="rebuild a run's report", description=__doc__)
    p.add_argument("run_dir", metavar="DIR")
    p.add_argument("--single-file", action="store_true", help="inline every image in "
                   "index.html (one self-contained file, for small runs) instead of "
                   "linking image files of DIR")
    p.set_defaults(run=run)


def run(args) -> int:
    from bench.commands.run import finish

    finish(Path(args.run_dir), single_file=args.single_file)
    return 0
