"""What a caller chooses: the :class:`Policy` (placement, cost-term weights, rules) and
what comes back (:class:`EngineResult`), with the names of placements, rejections and
stop reasons."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench.core.mesh import Mesh

#: Placement codes, as the numba kernels see them.
PLACE_OPTIMAL = 0
PLACE_ENDPOINTS = 1
PLACE_MIDPOINT = 2
PLACE_MEMORYLESS = 3

PLACEMENTS = {"optimal": PLACE_OPTIMAL, "endpoints": PLACE_ENDPOINTS,
              "midpoint": PLACE_MIDPOINT, "memoryless": PLACE_MEMORYLESS}

#: Units of the Canny penalty (``Policy.canny_units``): ``area`` adds González et al.
#: 2007's area ratio (equation 2) to the cost as it is, which suits a dimensionless
#: base cost (entropy-twin's viewpoint entropy); ``base-cost`` expresses it in the base
#: cost's own units, measured on the mesh before the first collapse
#: (:func:`methods.engine.simplify._canny_units`), so that the balance between the
#: penalty and a length-dependent cost (quadrics) does not depend on the mesh's size or
#: on the engine's normalisation.
CANNY_UNITS = ("area", "base-cost")


# The validity rules, checked in this order by methods.engine.topology._check (the seam
# rule is the cost function's verdict, an infinite cost). A candidate collapse of u into
# v is rejected when
#   - non-manifold edge: the edge has more than two faces;
#   - link condition: u and v share a neighbour that is not an apex of the edge's faces
#     (the collapse would pinch the surface);
#   - boundary lock: with ``boundary_lock``, either end is on the boundary;
#   - boundary pinch: an interior edge joins two boundary vertices (two boundary loops
#     would meet at one vertex);
#   - duplicate face: a face of u, renamed to v, would coincide with a face of v;
#   - fold-over: a moved face turns its normal by more than ``max_normal_rotation`` or
#     loses its area;
#   - seam rule (and boundary rule): the vertex-kind tables below (an infinite cost);
#   - capacity: the collapse would not fit one of the engine's fixed workspaces (a fan
#     of a hundred faces at a UV sphere's pole; methods.engine.capacity), also an
#     infinite cost;
#   - last faces of a part: with ``keep_parts``, the collapse would remove the last
#     faces of a connected component or of a material (methods.engine.parts);
#   - move bound: with a finite ``max_move``, the new position lies farther than that
#     fraction of the model's bounding-box diagonal from the plane of a face around
#     either end (methods.engine.loop._beyond_reach), or with ``move_memory`` farther
#     than what the ends' past moves left of it.
# Each code is 1 + its name's index in REJECTIONS, the order of the ``rejects`` counts.
VALID = 0
REJECT_LINK_CONDITION = 1
REJECT_BOUNDARY_PINCH = 2
REJECT_DUPLICATE_FACE = 3
REJECT_FOLD_OVER = 4
REJECT_NON_MANIFOLD = 5
REJECT_BOUNDARY_LOCK = 6
REJECT_SEAM_RULE = 7
REJECT_CAPACITY = 8
REJECT_LAST_OF_PART = 9
REJECT_MOVE_BOUND = 10

#: Rejection counters by name, in the order of the kernel's ``rejects`` array.
REJECTIONS = ("link condition", "boundary pinch", "duplicate face", "fold-over",
              "non-manifold edge", "boundary lock", "seam rule", "capacity",
              "last faces of a part", "move bound")


STOP_REASONS = {0: "reached the target", 1: "no valid collapse remains"}

#: The fold-over limits of the stall rule (``Policy.stall_rotations``) for methods that
#: use it: widened in steps, so a stalled run first takes the collapses that turn a
#: face least.
STALL_ROTATIONS = (120.0, 150.0, 180.0)

#: The move bound of the methods that use one (``Policy.max_move``): before the stall
#: rule's last phase, a collapse leaves the planes of the faces it replaces by at most
#: this fraction of the model's bounding-box diagonal (docs/maintainers.md, "The move
#: bound measures the way off the surface", has the measurements that chose it).
MAX_MOVE = 0.1


# Vertex kinds and the rules over them (methods.engine.cost._forced_end reads the
# tables; row = the kind of an edge's first end, column = its second end's):
#   - seam rule (``seam_rule``): a seam vertex (its faces use two or more wedges) may
#     only move along its seam. An edge from a seam vertex to an ordinary one is a
#     half-edge collapse that keeps the seam vertex where it is; an edge between two
#     seam vertices must itself be a seam edge (else it would cut a UV chart in two),
#     and is then placed freely;
#   - boundary rule (``boundary_rule``): a boundary vertex is never merged into an
#     interior one (the hole would grow into the surface); the boundary end stays.
# When both rules apply and keep different ends, the collapse is forbidden.
VERTEX_ORDINARY = 0
VERTEX_SEAM = 1
VERTEX_INTERIOR = 0
VERTEX_BOUNDARY = 1

#: What a rule says about an edge's ends.
END_FREE = 0          # either end may go, placed by the policy
END_KEEP_FIRST = 1    # the first end stays where it is
END_KEEP_SECOND = 2   # the second end stays
END_SEAM_EDGE = 3     # free if the edge is a seam edge, else forbidden

SEAM_RULE = np.array([[END_FREE, END_KEEP_SECOND],          # ordinary, (ordinary, seam)
                      [END_KEEP_FIRST, END_SEAM_EDGE]])      # seam,     (ordinary, seam)
BOUNDARY_RULE = np.array([[END_FREE, END_KEEP_SECOND],      # interior, (interior, boundary)
                          [END_KEEP_FIRST, END_FREE]])       # boundary, (interior, boundary)


_N_REJECTIONS = len(REJECTIONS)


@dataclass(frozen=True)
class Policy:
    """How edges are costed and where the kept vertex goes.

    Attributes
    ----------
    placement : str
        A key of :data:`PLACEMENTS`.
    quadric_weight : float
        Weight of the Garland–Heckbert quadric error.
    memoryless_weight : float
        Weight of the Lindstrom–Turk cost (methods.engine.terms.lindstrom_turk).
    canny_weight : float
        Weight of the González 2007 texture-border penalty (needs ``borders``).
    canny_units : str
        One of :data:`CANNY_UNITS`: what one unit of ``canny_weight`` is worth.
    boundary_weight : float
        Weight of the boundary-preserving planes added to the quadrics (Garland &
        Heckbert 1997 §6.1); 1000 is QSlim's default.
    max_normal_rotation : float
        Degrees a surviving face's normal may turn in one collapse.
    boundary_lock : bool
        Keep boundary vertices fixed.
    texture_weight : float
        > 0: the quadric term uses Garland & Heckbert 1998 wedge quadrics over position
        and ``texture_weight`` × UV (meshes with UVs only); new UVs minimise them.
    r5_uv : bool
        With ``memoryless`` placement, new UVs by the R^5 oriented volumes of Lindstrom
        & Turk 2000 §4.1.1, per texture patch (κ per patch); otherwise UVs of merged
        wedges are interpolated along the collapsed edge.
    seam_rule : bool
        Seam vertices move only along their seam (see ``_evaluate``), so every UV chart
        survives; without it seams stay closed but may drift across charts.
    uv_correction : bool
        González et al. 2008's texture-coordinate correction (§3, the α, β equations):
        a wedge whose vertex moves takes the UV that the texture map of one of its own
        triangles (before the collapse) gives the new position; see ``_uv_correction``.
    boundary_rule : bool
        A boundary vertex is never merged into an interior one (see ``_evaluate``).
    keep_parts : bool
        Never remove the last faces of a connected component (welded) or of a
        material (:func:`bench.io.atlas.face_materials`): a collapse that would is
        rejected under the rule "last faces of a part" (:mod:`methods.engine.parts`).
    stall_rotations : tuple of float
        The stall rule: when no valid collapse remains above the target, the engine
        goes on from where it stopped with the fold-over limit widened to each of these
        angles in turn (degrees, increasing, above ``max_normal_rotation``), every live
        edge costed afresh and the quadrics kept. On a coarse multi-part mesh the
        quadric's point can turn some face by more than 90° for every candidate left
        (the glTF milk truck stopped at 164 faces for a target of 109); a wider limit
        lets the cheapest of them go. The phases in order: the seam rule released
        (``stall_seams``), each of these angles, the move memory dropped
        (``move_memory``), the move bound lifted (a finite ``max_move``); each goes on
        only if the one before stopped. Results that reached
        the target are unchanged by it; the collapses each phase took are in
        ``stats["stall_collapses"]``, the phases' names in ``stats["stall_phases"]``.
        Empty, without ``stall_seams`` and ``max_move`` (the default): stop.
    max_move : float
        The move bound: the new position may lie no farther than this fraction of the
        model's bounding-box diagonal from the plane of any face around either end of
        the edge, before the collapse (a collapse that would is rejected under the rule
        "move bound"). A move within those planes, across a flat panel, is never
        bounded. On a coarse multi-part asset the cheapest collapses left under the seam
        rule can drag a corner across its part, though no face folds. The stall rule
        lifts the bound in its last phase, so the target is still reached. ``inf`` (the
        default): no bound.
    move_memory : bool
        The move bound holds for the sum of a vertex's moves: each vertex carries how
        far its collapses have moved the surface (the largest plane offset of each,
        added up; a merged vertex takes the larger of its two ends' sums), and a
        collapse whose sum would pass ``max_move`` is rejected under "move bound".
        Without it, collapses each within the bound can still walk a vertex across a
        part, step by step (a face across the `vehicle` analogue's cab).
    stall_seams : bool
        The stall rule's first phase releases the seam rule: seam vertices then move
        like any other, their UVs from the wedge quadrics (``texture_weight``) or
        interpolated, each kept in its material's tile. Under the seam rule a coarse
        textured part runs out of collapses that keep every chart long before its
        geometry does.
    """

    placement: str = "optimal"
    quadric_weight: float = 1.0
    memoryless_weight: float = 0.0
    canny_weight: float = 0.0
    canny_units: str = "area"
    boundary_weight: float = 1000.0
    max_normal_rotation: float = 90.0
    boundary_lock: bool = False
    seam_rule: bool = True
    r5_uv: bool = True
    texture_weight: float = 0.0
    uv_correction: bool = False
    boundary_rule: bool = False
    keep_parts: bool = True
    stall_rotations: tuple[float, ...] = ()
    max_move: float = float("inf")
    move_memory: bool = False
    stall_seams: bool = False

    def __post_init__(self):
        if self.placement not in PLACEMENTS:
            raise ValueError(f"unknown placement {self.placement!r}; choose one of "
                             f"{', '.join(PLACEMENTS)}")
        if not 0 < self.max_normal_rotation <= 180:
            raise ValueError("max_normal_rotation must be in (0, 180] degrees")
        widening = (self.max_normal_rotation, *self.stall_rotations)
        if any(not a < b <= 180 for a, b in zip(widening, widening[1:])):
            raise ValueError("stall_rotations must increase from max_normal_rotation to at "
                             "most 180 degrees")
        if not self.max_move > 0:
            raise ValueError("max_move must be positive (a fraction of the model's diagonal), "
                             "or inf for no bound")
        if self.canny_units not in CANNY_UNITS:
            raise ValueError(f"unknown canny_units {self.canny_units!r}; choose one of "
                             f"{', '.join(CANNY_UNITS)}")


@dataclass
class EngineResult:
    """What :func:`simplify_mesh` returns.

    Attributes
    ----------
    mesh : Mesh
        The simplified mesh, render vertices rebuilt from the surviving wedges.
    stop_reason : str or None
        None when the target was reached; otherwise why the engine stopped.
    stats : dict
        collapses, cost evaluations, rejections by rule, seconds.
    log : dict of ndarray
        The collapse sequence: ``removed`` (c,) welded vertex removed by collapse i,
        ``kept`` (c,) the vertex it merged into, ``position`` (c, 3) the kept vertex's
        new position, ``removed_faces`` (c, 2) faces deleted (-1 when only one),
        ``changed_start`` (c + 1,) and ``changed_faces``: CSR lists of the faces whose
        corner moved from ``removed`` to ``kept`` (each is one face removed and one
        created, under the same id); ``pair_start`` (c + 1,) and ``wedge_pairs`` (k, 2):
        CSR lists of the distinct wedge pairs (removed's wedge, kept's wedge) merged
        across the removed faces; ``wedge_start`` (c + 1,), ``wedges`` and ``wedge_uv``
        (k, 2): CSR lists of the merged vertex's distinct wedges (the removed vertex's
        corners first, then the kept one's, removed faces included) and their UVs after
        the collapse (zeros without UVs). Wedge ids are the input's render vertices.
    """

    mesh: Mesh
    stop_reason: str | None
    stats: dict = field(default_factory=dict)
    log: dict = field(default_factory=dict)
    #: final per-vertex quadrics (nv, 10) and which welded vertices survive (nv,), for
    #: inspection and tests
    quadrics: np.ndarray | None = None
    vertex_alive: np.ndarray | None = None
    #: with an image term that shades: the maintained luminance images of the result
    #: (V, H, W); None with the entropy alone, which keeps no luminance
    images: np.ndarray | None = None
