"""Running jobs: the plan, a job and its process, the executors (a local pool, Dask),
warm-up, job keys and LOD chains. It writes records through :mod:`bench.records`."""
