"""The HTML report of a run folder (:mod:`bench.report.page`): its summary table
(:mod:`~bench.report.table`), comparison grids (:mod:`~bench.report.grid`), images
(:mod:`~bench.report.images`), 3D view (:mod:`~bench.report.viewer`) and the claims page of
``bench reproduce`` (:mod:`~bench.report.claims`); the pages' scripts and style sheet are
files of ``bench/report/assets/``."""
