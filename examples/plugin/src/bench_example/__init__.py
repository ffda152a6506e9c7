"""An example plug-in for bench: the ``vertex-clustering`` method and the
``area_ratio`` metric (docs/plugin-tutorial.md walks through it)."""
