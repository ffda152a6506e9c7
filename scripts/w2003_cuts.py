"""How perceptual-mt's per-view cuts differ from the screen-space error's at a budget
(the w2003-98 claim): per model, over the 24 protocol views and the representative
view, the nodes refined by each error, how many the two cuts do not share, the rank
correlation of the two node errors over the visible nodes and over the nodes that
decide the cut, and the share of silhouette nodes among the refined ones; then the
checks that the cut does not depend on where refinement starts (two queues from the
previous view's cut against a from-scratch cut), on ``ppd`` or on the resolution.

Usage: .venv/bin/python scripts/w2003_cuts.py [RATIO] [CACHE_DIR] [MODEL,...]
(RATIO of each model's faces, default 0.02; CACHE_DIR a run folder's ``cache/`` to
reuse its Multi-Triangulations, e.g. reports/reproduce/w2003/cache).
"""

import sys

import numpy as np
from scipy.stats import spearmanr

import bench  # noqa: F401  (the BLAS kernel pin comes first)
from bench.catalog import resolve_model
from methods.mt.cache import mt_and_bounds
from methods.mt.csf import ContrastSensitivity
from methods.mt.errors import node_errors
from methods.mt.refine import Refiner, refine
from methods.perceptual_mt import PerceptualMT
from metrics.views import REPRESENTATIVE_VIEW, protocol_cameras

MODELS = ("torus-puzzle", "bunny")
RESOLUTION = 512


def refined(mt, err, budget):
    """The refined nodes (collapses not applied) of the cut at ``budget`` by ``err``,
    refined from the coarsest cut."""
    cut = mt.cut("coarsest")
    refine(cut, err, budget)
    return ~cut.applied, cut.n_faces


def relative_visibility(bounds, camera, own):
    """f_vis(c) / f_vis(1) of every node from its own perceptual error (1: the contrast
    bound is maximal, as on a silhouette): the error over its feature size."""
    d = bounds.center - camera.eye
    dist = np.linalg.norm(d, axis=1)
    tan_half = np.tan(np.radians(camera.fov_y_deg) / 2)
    dmin = np.maximum(dist - bounds.radius, camera.near)
    extent_deg = 2 * bounds.radius * (0.5 * RESOLUTION / tan_half) / dmin / 32.0
    with np.errstate(divide="ignore", invalid="ignore"):
        return own / (2 * extent_deg) / CSF.visible_frequency(1.0)


CSF = ContrastSensitivity()


def _median_ratio(bounds, pick):
    if not pick.any():
        return float("nan")
    with np.errstate(divide="ignore"):
        return float(np.median(bounds.radius[pick] / bounds.deviation[pick]))


def compare_view(mt, bounds, camera, budget):
    own, _ = node_errors(bounds, camera, RESOLUTION, "perceptual", "gouraud", True,
                         subtree_max=False)
    ep, status = node_errors(bounds, camera, RESOLUTION, "perceptual", "gouraud", True)
    es, _ = node_errors(bounds, camera, RESOLUTION, "screen", "gouraud", True)
    p, fp = refined(mt, ep, budget)
    s, fs = refined(mt, es, budget)
    visible = status > 0
    # the nodes that decide the cut: refined by either error, or on either cut's frontier
    decide = p | s
    rho_visible = spearmanr(ep[visible], es[visible]).statistic
    rho_decide = spearmanr(ep[decide], es[decide]).statistic
    return {"refined_p": int(p.sum()), "refined_s": int(s.sum()),
            "faces_p": fp, "faces_s": fs,
            "only_p": int((p & ~s).sum()), "only_s": int((s & ~p).sum()),
            "jaccard": float((p & s).sum() / max(1, (p | s).sum())),
            "rho_visible": float(rho_visible), "rho_refined": float(rho_decide),
            "sil_p": float((status[p] == 2).mean()) if p.any() else 0.0,
            "sil_s": float((status[s] == 2).mean()) if s.any() else 0.0,
            "sil_nodes": float((status[visible] == 2).mean()),
            "zero_p": float((ep[visible] == 0).mean()),
            # what the nodes only one cut refines look like: sphere radius over deviation
            "r/dev_onlyP": _median_ratio(bounds, p & ~s),
            "r/dev_onlyS": _median_ratio(bounds, s & ~p),
            # how saturated the contrast of the front-facing nodes that decide the cut is
            "fvis_front": float(np.median(relative_visibility(bounds, camera, own)[
                decide & (status == 1)])) if (decide & (status == 1)).any() else float("nan")}


def same_cuts(mt, bounds, cameras, budget, **kwargs):
    """Views (of ``cameras``) where the default refinement's cut differs from the one
    with ``kwargs`` changed (refinement, ppd, resolution)."""
    resolution = kwargs.pop("resolution", RESOLUTION)
    a = Refiner(mt, bounds, "perceptual", "gouraud", True)
    b = Refiner(mt, bounds, "perceptual", "gouraud", True, **kwargs)
    differ = 0
    for camera in cameras:
        a.refine_view(camera, budget, RESOLUTION)
        b.refine_view(camera, budget, resolution)
        differ += int(not np.array_equal(a.cut.applied, b.cut.applied))
    return differ


def main():
    ratio = float(sys.argv[1]) if len(sys.argv) > 1 else 0.02
    cache = sys.argv[2] if len(sys.argv) > 2 else None
    models = sys.argv[3].split(",") if len(sys.argv) > 3 else MODELS
    for name in models:
        mesh = resolve_model(name)
        budget = round(ratio * mesh.n_faces)
        mt, bounds, _, _ = mt_and_bounds(mesh, 1.0, PerceptualMT.version, cache)
        cameras = protocol_cameras(mesh)
        rows = [compare_view(mt, bounds, c, budget) for c in cameras]
        print(f"\n{name}: {budget} faces of {mesh.n_faces}, {mt.n_nodes} MT nodes, "
              f"coarsest cut {mt.coarsest_faces} faces")
        keys = list(rows[0])
        print("  " + "".join(f"{k:>12}" for k in ["view"] + keys))
        for label, row in [("median24", {k: np.median([r[k] for r in rows]) for k in keys}),
                           (f"repr({REPRESENTATIVE_VIEW})", rows[REPRESENTATIVE_VIEW])]:
            print("  " + f"{label:>12}" + "".join(
                f"{row[k]:>12.4g}" if isinstance(row[k], float) else f"{row[k]:>12}"
                for k in keys))
        print(f"  cuts differing, two queues vs from scratch: "
              f"{same_cuts(mt, bounds, cameras, budget, refinement='scratch')} of 24 views; "
              f"ppd 10 vs 32: {same_cuts(mt, bounds, cameras, budget, ppd=10.0)}; "
              f"1024 vs 512 px: {same_cuts(mt, bounds, cameras, budget, resolution=1024)}")


if __name__ == "__main__":
    main()
