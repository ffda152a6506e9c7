"""The core: :class:`~bench.core.mesh.Mesh`, the :class:`~bench.core.method.Method` and
:class:`~bench.core.metric.Metric` interfaces, the plug-in registry and the errors. It
imports nothing else of the suite."""
