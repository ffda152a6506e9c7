"""The named structures the engine's numba loop threads through its helpers.

Each is a ``collections.namedtuple`` of arrays (numba types them as heterogeneous
tuples and reads fields by name at no cost). They are built once per run, in Python
(:func:`methods.engine.simplify.simplify_mesh`) or at the start of
:func:`methods.engine.loop._run`:

============  ==========================================================================
structure     what it holds
============  ==========================================================================
MeshArrays    the welded mesh being simplified and its wedges (changed by collapses)
Rules         the policy as codes: placement, weights, rule switches
Terms         read-only inputs of the cost terms (texture borders, κ per face, ...)
Scratch       per-candidate scratch, overwritten by every evaluation and collapse
Queue         the lazy priority queue's bookkeeping (stamps, last keys)
Blocked       rejected candidates waiting for an endpoint's stamp to change
Log           the collapse log (one row per collapse; CSR lists of changed faces,
              merged wedge pairs and the merged vertex's wedges with their UVs)
============  ==========================================================================

Capacities are named here with what they bound; where a capacity can be exceeded, the
helper that fills it says what happens (an error, a grown buffer, or a documented
fallback).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

#: Faces around one edge kept by ``_edge_faces`` (it still returns the true count; an
#: edge with more than two faces is rejected as non-manifold before it is used).
EDGE_FACES_CAP = 8
#: Wedge pairs across one collapse: at most one per face of the edge.
WEDGE_PAIRS_CAP = EDGE_FACES_CAP
#: Distinct wedges of a merged vertex (``_wedge_targets`` raises beyond it).
WEDGE_TARGETS_CAP = 64
#: Triangles, boundary edges and link vertices of a Lindstrom–Turk profile; a larger
#: profile falls back to the quadric's placement and cost (as it always has).
PROFILE_CAP = 256
#: Floats of a Garland–Heckbert 1998 wedge quadric over (x, y, z, u, v).
WEDGE_QUADRIC_SIZE = 31
#: Floats of a vertex quadric (the upper triangle of a symmetric 4 × 4 matrix).
QUADRIC_SIZE = 10
#: Initial blocked-edge records; the table doubles when full.
BLOCKED_INITIAL = 64
#: Minimum length of the changed-faces log; it doubles when fewer than
#: ``LOG_CHANGED_HEADROOM`` slots remain before a collapse.
LOG_CHANGED_MIN = 16
#: Slots the changed-faces log keeps free before a collapse (a vertex has far fewer
#: faces than this).
LOG_CHANGED_HEADROOM = 4096

#: Counters of the ``kinds`` array (methods.engine.wedges._count_kinds): collapses that
#: took a twin edge along, collapses that stranded wedges, and the wedges stranded.
KIND_TWIN = 0
KIND_STRANDED = 1
KIND_STRANDED_WEDGES = 2
N_KINDS = 3

#: Cost-term weights of a run (all floats; 0 switches a term off).
Weights = namedtuple("Weights", "quadric memoryless canny image entropy")


@njit(cache=True, inline="always")
def renders(weights):
    """Whether a rendered cost term is on: Lindstrom & Turk 2000's image term or
    González et al. 2008's viewpoint entropy, both kept up to date in the views."""
    return weights.image != 0.0 or weights.entropy != 0.0

#: The mesh under simplification: welded positions ``P`` (nv, 3), quadrics ``Q`` (nv,
#: 10), faces ``F`` (m, 3) and their wedges ``FW`` (m, 3), ``falive`` (m,), corner
#: lists ``vhead`` (nv,) / ``cnext`` (3m,), ``valive`` (nv,), ``vboundary`` (nv,),
#: ``wedge_vertex`` (n_wedges,), ``uv`` (n_wedges, 2), ``moved`` (nv,) bool (a vertex
#: whose position changed), ``WQ`` (n_wedges, 31) wedge quadrics or (1, 31), ``group``
#: (m,) each face's part (methods.engine.parts), ``group_live`` (g,) the live faces
#: of each part and ``drift`` (nv,) how far each vertex's moves have taken the surface
#: around it, summed over its collapses (the accumulated move bound; Rules.move_memory).
MeshArrays = namedtuple("MeshArrays", "P Q F FW falive vhead cnext valive vboundary "
                                      "wedge_vertex uv moved WQ group group_live drift")

#: The policy as codes: ``placement`` (a value of PLACEMENTS), ``weights``
#: (:data:`Weights`), ``cos_limit`` (fold-over), and booleans ``boundary_lock``,
#: ``seam_rule``, ``boundary_rule``, ``verify``, ``has_uv``, ``use_r5`` (R^5 UVs),
#: ``uv_fix`` (González 2008's UV correction), ``keep_parts`` (methods.engine.parts),
#: ``target`` faces, ``max_collapses``, ``max_move`` (the move bound at unit diagonal;
#: infinite: none), ``move_memory`` (the bound holds for the sum of a vertex's moves).
Rules = namedtuple("Rules", "placement weights cos_limit boundary_lock seam_rule "
                            "boundary_rule verify has_uv use_r5 uv_fix keep_parts target "
                            "max_collapses max_move move_memory")

#: Read-only inputs of the cost terms: Canny ``borders`` (h, w) bool,
#: ``canny_per_area`` (the Canny penalty per unit of an edge's face area, before the
#: weight: 1 / total area, or in the base cost's units; see Policy.canny_units),
#: ``face_kappa`` (m,) κ of each face's texture patch.
Terms = namedtuple("Terms", "borders canny_per_area face_kappa")

#: Lindstrom–Turk profile of an edge (:mod:`methods.engine.terms.lindstrom_turk`): the
#: corners ``tri_a``, ``tri_b``, ``tri_c`` of the triangles around either end, the
#: boundary edges ``bnd_a``, ``bnd_b`` there and the other corners, ``link``, each
#: (rows, 3) float64 (PROFILE_CAP rows in the engine), and ``counts`` (3,) int64: how many
#: rows of each are valid (triangles, boundary edges, link vertices).
Profile = namedtuple("Profile", "tri_a tri_b tri_c bnd_a bnd_b link counts")

#: Wedge-quadric scratch: wedge pairs ``gfrom``/``gto`` (WEDGE_PAIRS_CAP,), merged
#: ``targets`` (WEDGE_TARGETS_CAP,), one group quadric ``g`` (31,).
WedgeScratch = namedtuple("WedgeScratch", "gfrom gto targets g")

#: The triangles of one texture patch around an edge
#: (:func:`methods.engine.terms.lindstrom_turk.r5_texture_coordinates`): corners
#: ``tri_a``, ``tri_b``, ``tri_c`` (rows, 3) and their UVs ``uv_a``, ``uv_b``, ``uv_c``
#: (rows, 2), float64 (PROFILE_CAP rows in the engine).
Patch = namedtuple("Patch", "tri_a tri_b tri_c uv_a uv_b uv_c")

#: R^5 scratch: the ``patch`` (:data:`Patch`); the merged vertex's wedge ``targets``
#: (WEDGE_TARGETS_CAP,) and their ``new_uv`` (WEDGE_TARGETS_CAP, 2).
R5Scratch = namedtuple("R5Scratch", "patch targets new_uv")

#: Per-candidate scratch: ``mark``/``tick`` (dedup without clearing), neighbour lists
#: ``nbr_u``/``nbr_v`` (nv,), ``efaces`` (EDGE_FACES_CAP,), wedge pairs
#: ``wmap_from``/``wmap_to`` (WEDGE_PAIRS_CAP,), the summed quadric ``qsum`` (10,), the
#: candidate position ``p`` (3,), ``profile`` (:data:`Profile`), ``wq``
#: (:data:`WedgeScratch`), ``r5`` (:data:`R5Scratch`), ``no_record`` (0, 2) for the
#: Canny walk.
Scratch = namedtuple("Scratch", "mark tick nbr_u nbr_v efaces wmap_from wmap_to qsum p "
                                "profile wq r5 no_record")

#: Lazy queue bookkeeping: per-vertex ``stamp`` (nv,) and ``pushed_at`` (nv,), the
#: ``last_key`` dict (edge key -> last cost) and ``tally`` (2,) int64 counters indexed
#: by EVALUATIONS and MISMATCHES.
Queue = namedtuple("Queue", "stamp pushed_at last_key tally")

#: Counters of :data:`Queue`'s ``tally``.
EVALUATIONS = 0
MISMATCHES = 1

#: Blocked edges: ``end`` (cap, 2) endpoints, ``next`` (cap, 2) links in each end's list,
#: ``live`` (cap,), ``head`` (nv,) first record of each vertex, ``count`` (1,) used.
Blocked = namedtuple("Blocked", "end next live head count")

#: The collapse log: ``cost``, ``removed``, ``kept`` (c,), ``pos`` (c, 3), ``faces`` (c,
#: 2) removed faces (-1: none); three CSR lists, each grown as needed: ``start`` (c + 1,)
#: and ``changed``, the faces that changed; ``pair_start`` (c + 1,) and ``pairs`` (k, 2),
#: the distinct wedge pairs (u's wedge, v's wedge) merged across the removed faces;
#: ``wedge_start`` (c + 1,), ``wedges`` (k,) and ``wedge_uv`` (k, 2), the merged vertex's
#: distinct wedges (u's corners first, then v's, the removed faces included) with their
#: UVs after the collapse (0 without UVs). ``count`` (4,) indexed by LOG_*. With the
#: positions, this is everything a consumer needs to replay the collapses without the
#: engine's rules (:mod:`methods.mt.dag`).
Log = namedtuple("Log", "cost removed kept pos faces start changed pair_start pairs "
                        "wedge_start wedges wedge_uv count")

#: Entries of :data:`Log`'s ``count``: collapses, and the used length of each CSR list.
LOG_COLLAPSES = 0
LOG_CHANGED = 1
LOG_PAIRS = 2
LOG_WEDGES = 3
N_LOG_COUNTS = 4


def new_scratch(nv):
    """A :data:`Scratch` for a mesh of ``nv`` welded vertices."""
    cap = PROFILE_CAP
    profile = Profile(*(np.empty((cap, 3)) for _ in range(6)), counts=np.zeros(3, np.int64))
    wq = WedgeScratch(gfrom=np.empty(WEDGE_PAIRS_CAP, np.int64),
                      gto=np.empty(WEDGE_PAIRS_CAP, np.int64),
                      targets=np.empty(WEDGE_TARGETS_CAP, np.int64),
                      g=np.empty(WEDGE_QUADRIC_SIZE))
    patch = Patch(tri_a=np.empty((cap, 3)), tri_b=np.empty((cap, 3)), tri_c=np.empty((cap, 3)),
                  uv_a=np.empty((cap, 2)), uv_b=np.empty((cap, 2)), uv_c=np.empty((cap, 2)))
    r5 = R5Scratch(patch=patch, targets=np.empty(WEDGE_TARGETS_CAP, np.int64),
                   new_uv=np.empty((WEDGE_TARGETS_CAP, 2)))
    return Scratch(mark=np.zeros(nv, np.int64), tick=np.zeros(1, np.int64),
                   nbr_u=np.empty(nv, np.int64), nbr_v=np.empty(nv, np.int64),
                   efaces=np.empty(EDGE_FACES_CAP, np.int64),
                   wmap_from=np.empty(WEDGE_PAIRS_CAP, np.int64),
                   wmap_to=np.empty(WEDGE_PAIRS_CAP, np.int64), qsum=np.empty(QUADRIC_SIZE),
                   p=np.empty(3), profile=profile, wq=wq, r5=r5,
                   no_record=np.empty((0, 2), np.int64))

#: The image term's state as the cost and commit functions see it: ``img`` (the image
#: state of methods.imaging.state), ``tiles`` (its tile index, rebuilt when a commit
#: overflows it) and ``iws`` (the image scratch).
Images = namedtuple("Images", "img tiles iws")
