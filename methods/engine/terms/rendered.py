"""The rendered cost terms: Lindstrom & Turk 2000's image error (equation 8) and
González et al. 2008's change of viewpoint entropy, both from one re-render of the
rectangles a collapse affects (:mod:`methods.imaging.region`).

The engine's cost (:mod:`methods.engine.cost`) asks :func:`_view_cost` for one way of a
collapse and :func:`_both_ways` for a half-edge collapse's two ways, and only when
:func:`methods.engine.state.renders` says a rendered term is on."""

from __future__ import annotations

import numpy as np
from numba import njit

from methods.engine.terms.r5 import _r5_compute
from methods.engine.wedges import _edge_parameter, _wedge_pairs
from methods.imaging.entropy import fan_pixels
from methods.imaging.region import Scene, image_cost, rank_views
from metrics.shading import BACKGROUND


@njit(cache=True, inline="always")
def _both_ways(a, b, costs, mesh, rules, terms, scratch, images):
    """``costs`` = (ca, cb) plus the rendered cost of keeping a (removing b) and of
    keeping b. The way that redraws fewer pixels goes first (:func:`_first_then_other`)."""
    ca, cb = costs
    vhead, cnext, falive, ent = mesh.vhead, mesh.cnext, mesh.falive, images.img.ent
    if fan_pixels(b, vhead, cnext, falive, ent) <= fan_pixels(a, vhead, cnext, falive, ent):
        return _first_then_other(b, a, (ca, cb), mesh, rules, terms, scratch, images)
    cb, ca = _first_then_other(a, b, (cb, ca), mesh, rules, terms, scratch, images)
    return ca, cb


@njit(cache=True, inline="always")
def _first_then_other(u, v, costs, mesh, rules, terms, scratch, images):
    """``costs`` = (first, other): ``first`` plus the rendered cost of collapsing u into
    v, and ``other`` plus that of collapsing v into u; the latter stops once it is sure
    to cost more (it is then inf: the verdict, the cheaper cost and the placement are
    those of rendering all its views), taking first the views where the first way
    changed the most."""
    P = mesh.P
    first, other = costs
    first += _view_cost((u, v, P[v]), mesh, rules, terms, scratch, images, np.inf)
    bound = _losing_sum(first, other, rules.weights)
    if bound < np.inf:
        rank_views(images.iws)
    other += _view_cost((v, u, P[u]), mesh, rules, terms, scratch, images, bound)
    return first, other


#: The smallest normal double (np.finfo(float).tiny).
_TINY = 2.2250738585072014e-308


@njit(cache=True, inline="always")
def _losing_sum(ca, base, weights):
    """The sum of |dH| past which a cost ``base`` + ``weights.entropy`` × that sum is
    sure to exceed ``ca``, with a margin far above rounding (so the sum's order does
    not matter); inf when the rendered cost is not such a sum (an image term's view
    changes can be negative)."""
    if weights.image != 0.0 or not weights.entropy > 0.0:
        return np.inf
    # relative, and never below the smallest normal double: costs of a few subnormals
    # would otherwise leave no margin at all (0.5 * 5e-324 rounds to 0)
    slack = 1e-9 * (abs(ca) + abs(base)) + _TINY
    return (ca - base + slack) / weights.entropy * (1.0 + 1e-9)


@njit(cache=True)
def _view_cost(move, mesh, rules, terms, scratch, images, bound):
    """The rendered cost terms of ``move`` = (u, v, p), collapsing u into v at p, from
    one re-render of the affected rectangles: ``weights.image`` × equation 8 of
    Lindstrom & Turk 2000 plus ``weights.entropy`` × the sum over views of |change of
    the viewpoint entropy| (González et al. 2008, §3), which
    :func:`methods.imaging.region.image_cost` leaves in the image state; inf once that
    sum passes ``bound`` (then not all views are rendered)."""
    weights = rules.weights
    cost = weights.image * _image_term(move, mesh, rules, terms, scratch, images, bound)
    if weights.entropy != 0.0:
        cost += weights.entropy * images.img.ent.delta[0]
    return cost


@njit(cache=True)
def _image_term(move, mesh, rules, terms, scratch, images, bound):
    """Equation 8 of Lindstrom & Turk 2000 for ``move`` = (u, v, p), collapsing u into
    v at p, with the texture coordinates the collapse would give
    (methods.imaging.region.image_cost, which stops once the views' |dH| passes
    ``bound``)."""
    u, v, p = move
    P, F, FW, uv, falive, vhead, cnext = (mesh.P, mesh.F, mesh.FW, mesh.uv, mesh.falive,
                                          mesh.vhead, mesh.cnext)
    wfrom, wto, efaces = scratch.wmap_from, scratch.wmap_to, scratch.efaces
    targets, new_uv = scratch.r5.targets, scratch.r5.new_uv
    npairs = 0
    nt = 0
    if rules.has_uv:
        npairs = _wedge_pairs(u, v, (F, FW, vhead, cnext, falive), efaces, wfrom, wto)
        t_edge = _edge_parameter(u, v, p, P)
        if rules.use_r5:
            nt = _r5_compute(u, v, p, t_edge, (P, F, FW, uv, falive, vhead, cnext),
                             terms.face_kappa, (wfrom, wto, npairs), scratch.r5)
        else:  # merged wedges interpolated along the edge, as _collapse does
            for i in range(npairs):
                targets[i] = wto[i]
                for d in range(2):
                    new_uv[i, d] = (1.0 - t_edge) * uv[wfrom[i], d] + t_edge * uv[wto[i], d]
            nt = npairs
    scene = Scene(P=P, F=F, FW=FW, uv=uv, falive=falive, img=images.img, tiles=images.tiles,
                  iws=images.iws, wfrom=wfrom, wto=wto, background=float(BACKGROUND))
    return image_cost(scene, u, v, p, npairs, (vhead, cnext), (targets, nt, new_uv), bound)
