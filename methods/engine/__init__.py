"""The shared edge-collapse engine: welded topology, wedge attributes carried along,
validity checks, a lazily re-evaluated priority queue, and a collapse log.

Every method of the suite that removes edges runs on this engine. The pipeline, in
:func:`simplify_mesh`, for a mesh and a face target::

    _prepare                    welded positions/faces at unit diagonal, wedge per
                                corner, corner lists (Morton-renumbered with images)
    _quadrics                   vertex planes, or per-wedge 5-D quadrics
    _rules, _terms              the policy as codes; the cost terms' inputs
    _image_state                the image term's state, original rendered
    _canny_units                with canny_units="base-cost": the base cost's scale
                                from every edge's first cost (first_costs)
    first_costs (initial.py)    every edge costed once, on the job's threads
    views_shared (views.py)     with rendered costs and threads to spare: helper threads
                                that take views of each evaluation and commit
    _run (numba, loop.py)       _collect_candidates; then _pop_current, _check_candidate
                                (or _block), _take (log, collapse, images),
                                _requeue (the kept vertex's and the apexes' edges)
    _extract, _statistics       render vertices again from the surviving wedges; counts
    _log_in_input_numbering     the collapse log in the input's ids and units

The kernels pass a few named structures (:mod:`methods.engine.state`: MeshArrays,
Rules, Terms, Scratch, Queue, Blocked, Log, Images), never loose positional arrays.

Policies are data, not callbacks (the Python layer never runs per collapse). A
:class:`Policy` names a *placement* (where the surviving vertex goes) and a weighted sum
of *cost terms*; the numba kernel dispatches on those codes. This is CGAL
Surface_mesh_simplification's split into cost, placement and stop, with the stop being
the face target.

============  =========================================================================
placement     where the kept vertex goes
============  =========================================================================
optimal       the quadric minimiser, falling back to the best of the endpoints and the
              midpoint when the quadric is singular (Garland & Heckbert 1997)
endpoints     half-edge collapse: both directions are tried, the cheaper is kept
midpoint      the middle of the edge
memoryless    Lindstrom & Turk 1998 constraints (methods.engine.terms.lindstrom_turk)
============  =========================================================================

============  =========================================================================
cost term     what it measures
============  =========================================================================
quadric       Garland & Heckbert 1997 planes; with ``texture_weight`` > 0 on meshes with
              UVs, their 1998 quadrics over (x, y, z, u, v), one per wedge
memoryless    Lindstrom & Turk 1998 volume and boundary change at the new position
canny         González et al. 2007: incident area / total area if the edge's UV segment
              crosses a texture border, as it is or (``canny_units="base-cost"``) in
              the base cost's units, measured before the first collapse
============  =========================================================================

Topology rules (each rejection is counted and reported):

- *link condition*: the endpoints' common neighbours are exactly the apexes of the
  edge's faces (1 on a boundary edge, 2 inside); otherwise the collapse pinches the
  surface;
- an interior edge between two boundary vertices is not collapsed (it would join two
  boundary loops into a non-manifold vertex);
- no collapse may create a face that duplicates an existing one (this is what stops a
  tetrahedron at 4 faces);
- *fold-over*: no surviving face may rotate its normal by more than
  ``max_normal_rotation`` degrees (default 90°, i.e. flip) or lose its area;
- non-manifold edges (more than two faces) are never collapsed; the collapses around
  them go ahead under the rules above (the non-manifold edge survives as it is, as in
  MeshLab's quadric decimation), so a mesh with a few such edges still reaches its
  target;
- with ``boundary_lock`` no boundary vertex moves or disappears;
- *capacity*: a collapse that would not fit one of the engine's fixed workspaces (a
  UV sphere's pole) is refused and tried again once its neighbourhood shrank
  (:mod:`methods.engine.capacity`);
- *last faces of a part*: with ``keep_parts`` (the default) no collapse removes the
  last faces of a connected component or of a material (:mod:`methods.engine.parts`);
- *move bound*: with a finite ``max_move``, the new position lies no farther than that
  fraction of the diagonal from the plane of a face around either end
  (``loop._beyond_reach``); with ``move_memory``, no farther than what is left of the
  bound after the ends' past moves (their sums, ``MeshArrays.drift``).

When no valid collapse remains above the target, the stall rule goes on in phases
(``Policy.stall_rotations``): the seam rule released (``stall_seams``), the fold-over
limit widened to each of ``stall_rotations``, the move memory dropped, the move bound
lifted.

The placements are guarded (``cost._near_ring``): the quadric's minimiser must lie
within the bounding box of the edge's one-ring enlarged by a quarter of the edge's
length, else the best of the endpoints and the midpoint is taken; Lindstrom & Turk's
point within one edge length of that box, else the guarded quadric point (on a
multi-part asset both otherwise threw vertices far outside their part).

Wedges (render vertices) are carried along: the two faces removed by a collapse pair
each wedge of the removed vertex with the wedge of the kept vertex on the same side of
the edge; paired wedges merge, and the merged attribute (UV) is interpolated along the
edge at the new position. A seam edge has different wedges on its two sides, so both
pairs survive separately and the seam stays closed; it never opens, because the welded
topology is never split.

Lazy evaluation (Lindstrom & Turk 2000, §4.2.2): every vertex has a version stamp. A
collapse bumps the stamps of the kept vertex and its neighbours and pushes fresh entries
for the kept vertex's edges; other entries whose stamps changed are re-costed only when
they reach the top of the queue, and pushed back. An entry popped with current stamps is
taken at its stored cost (``verify=True`` checks that this equals a fresh evaluation).
"""

from __future__ import annotations

from methods.engine.policy import PLACEMENTS, REJECTIONS, STOP_REASONS, EngineResult, Policy
from methods.engine.simplify import simplify_mesh
from methods.engine.terms.quadric import (
    face_quadrics,
    initial_quadrics,
    quadric_error,
    wedge_quadrics,
)
from methods.engine.wedges import barycentric_uv, corner_wedges

__all__ = ["Policy", "EngineResult", "simplify_mesh", "PLACEMENTS", "STOP_REASONS", "REJECTIONS",
           "face_quadrics", "initial_quadrics", "quadric_error", "wedge_quadrics",
           "barycentric_uv", "corner_wedges"]
