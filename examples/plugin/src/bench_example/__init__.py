"""An example plug-in for bench: the ``vertex-clustering`` method and the
``area_change`` metric (docs/plugin-tutorial.md walks through it)."""
