"""The second way of a half-edge collapse stops once it is sure to lose
(methods.engine.terms.rendered._both_ways): the verdict and the cheaper cost are those of
rendering every view of both ways."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from conftest import blob


def _captured_state(monkeypatch, entropy, image):
    """The engine's state as the first pass gets it, for the entropy term (and the image
    term with weight ``image``) on the blob."""
    from methods.engine import simplify
    from methods.engine.policy import Policy
    from methods.imaging.raster import rasterize_luminance
    from methods.imaging.state import ImageTerm
    from metrics.views import silhouette_cameras

    mesh = blob()
    cameras = silhouette_cameras(mesh)
    term = ImageTerm(tuple(cameras), rasterize_luminance(mesh, cameras, 40, 40),
                     weight=image, entropy_weight=entropy)
    seen = []

    def capture(*state, threads=None):
        seen.append(state)
        raise KeyboardInterrupt  # stop simplify_mesh here

    monkeypatch.setattr(simplify, "first_costs", capture)
    policy = Policy(placement="endpoints", quadric_weight=0.0, memoryless_weight=0.0,
                    boundary_weight=0.0)
    try:
        simplify.simplify_mesh(mesh, mesh.n_faces // 2, policy, image=term)
    except KeyboardInterrupt:
        pass
    return seen[0]


def test_the_losing_way_stops_early_with_the_same_verdict(monkeypatch):
    from methods.engine.initial import candidate_edges
    from methods.engine.terms import rendered

    mesh, rules, terms, scratch, images = _captured_state(monkeypatch, 1.0, 0.0)
    edges = candidate_edges(mesh, scratch)
    P = mesh.P
    stopped = 0
    for a, b in edges:
        full_a = rendered._view_cost((b, a, P[a]), mesh, rules, terms, scratch, images, np.inf)
        full_b = rendered._view_cost((a, b, P[b]), mesh, rules, terms, scratch, images, np.inf)
        ca, cb = rendered._both_ways(a, b, (0.0, 0.0), mesh, rules, terms, scratch, images)
        assert (ca < cb) == (full_a < full_b)
        assert min(ca, cb) == min(full_a, full_b)
        for got, full in ((ca, full_a), (cb, full_b)):
            assert got == full or (got == np.inf and full > min(full_a, full_b))
        stopped += np.isinf(ca) or np.isinf(cb)
    assert stopped > len(edges) // 4  # the early stop happens


def test_no_early_stop_with_the_image_term(monkeypatch):
    """Equation 8's views can lower the cost, so no sum of them is a bound."""
    from methods.engine.terms import rendered

    _, rules, _, _, _ = _captured_state(monkeypatch, 1.0, 1.0)
    assert rendered._losing_sum(0.5, 0.0, rules.weights) == np.inf


finite = st.floats(min_value=0.0, max_value=1e6, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(ca=finite, base=finite, weight=st.floats(min_value=1e-3, max_value=1e3),
       sums=st.lists(st.floats(min_value=0.0, max_value=1e3), min_size=1, max_size=20),
       split=st.integers(min_value=0, max_value=20))
@example(ca=5e-324, base=5e-324, weight=0.5, sums=[5e-324], split=0)  # subnormal costs
def test_a_sum_past_the_losing_sum_loses_in_any_order(ca, base, weight, sums, split):
    """Whatever order the threads add the views' |dH| in, a running sum past the bound
    means the cost summed in view order is above ``ca``."""
    from methods.engine.state import Weights
    from methods.engine.terms import rendered

    weights = Weights(0.0, 0.0, 0.0, 0.0, weight)
    bound = rendered._losing_sum(ca, base, weights)
    threads = [0.0, 0.0]  # two threads' running sums, as the views' helpers keep them
    for i, s in enumerate(sums):
        threads[i >= split] += s
    in_order = 0.0
    for s in sums:
        in_order += s
    if threads[0] + threads[1] > bound:
        assert base + weight * in_order > ca
