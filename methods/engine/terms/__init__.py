"""The cost terms of the engine, apart from the machine that weighs them.

A policy (:class:`methods.engine.policy.Policy`) is a weighted sum of these terms at a
placement. The machine (:mod:`methods.engine.cost`) asks each term with a non-zero
weight for its value, always in the same form: a numba function of the candidate edge
(or its two ways), the point where the kept vertex goes, and the engine's named
structures (:mod:`methods.engine.state`). No term reads the queue, the log or the loop;
they read the mesh's primitives (:mod:`methods.engine.topology`,
:mod:`methods.engine.wedges`) and nothing above them (an import-linter contract in
``pyproject.toml`` keeps it so).

================  ================================  =====================================
module            term                              what the machine calls
================  ================================  =====================================
quadric           Garland & Heckbert 1997 planes;   ``_edge_quadric`` (the summed quadric
                  their 1998 (x, y, z, u, v)        of an edge), ``quadric_error``,
                  quadrics per wedge                ``_optimal_point`` (the placement)
lindstrom_turk    Lindstrom & Turk 1998 volume,     ``lt_cost``, ``lt_placement`` over the
                  boundary and shape terms          edge's profile
r5                Lindstrom & Turk 2000 §4.1.1:     ``_r5_compute`` (costing),
                  texture coordinates from R^5      ``_r5_update`` (the collapse)
                  oriented volumes
canny             González et al. 2007: a texture   ``_canny_penalty`` (of the edge only)
                  border crossed by the edge
rendered          Lindstrom & Turk 2000 eq. 8 and   ``_view_cost`` (one way),
                  González et al. 2008's viewpoint  ``_both_ways`` (a half-edge collapse)
                  entropy, from re-rendered views
================  ================================  =====================================

The rendered terms are asked for only when :func:`methods.engine.state.renders` says one
of them has a weight; that one test is all the loop knows of them.
"""
