"""The HTML report of a run folder (:mod:`bench.report.page`): its summary table
(:mod:`~bench.report.table`), comparison grids (:mod:`~bench.report.grid`), images
(:mod:`~bench.report.images`), 3D view (:mod:`~bench.report.viewer`) and the claims page of
``bench reproduce`` (:mod:`~bench.report.claims`); the pages' scripts and style sheet are
files of ``bench/report/assets/``."""

from importlib.resources import files

__all__ = ["asset", "script"]


def asset(name: str) -> str:
    """The text of the report's file ``bench/report/assets/<name>`` (package data, so an
    installed bench has it too)."""
    return files("bench.report").joinpath("assets", name).read_text(encoding="utf-8")


def script(name: str) -> str:
    """The asset ``name`` (a JavaScript file) as an inline ``<script>`` element."""
    return f"<script>\n{asset(name)}</script>"
