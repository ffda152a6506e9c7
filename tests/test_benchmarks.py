"""Speed benchmarks (pytest-benchmark); skipped in the normal test run.

Run them with::

    .venv/bin/python -m pytest tests/test_benchmarks.py --benchmark-enable --benchmark-only

Targets (issue "protocol"): evaluating one LOD of the 56k-face bunny (render 24 views,
d_rms, ssim, Hausdorff, silhouettes; originals cached) in at most 3 s wall on a 2-core
machine; FLIP is timed on its own.
"""

import pytest

from bench.catalog import resolve_model
from bench.core.method import run_method
from methods.baselines import QSlim
from metrics import geometry, image, silhouette
from metrics.protocol import Protocol, original_images, render_views
from metrics.views import silhouette_cameras


@pytest.fixture(scope="module")
def bunny_lod():
    bunny = resolve_model("bunny")
    lod = run_method(QSlim(), bunny, 1332).mesh
    protocol = Protocol()
    return bunny, lod, protocol, original_images(bunny, protocol)


def _evaluate_without_flip(bunny, lod, protocol, reference):
    images = render_views(lod, bunny, protocol)
    image.d_rms(reference, images)
    image.ssim_mean(reference, images)
    geometry.hausdorff(bunny, lod, samples=protocol.hausdorff_samples)
    eyes = [c.eye for c in silhouette_cameras(bunny)]
    silhouette.silhouette_histogram(lod, eyes)
    return images


def test_evaluate_bunny_lod(benchmark, bunny_lod):
    benchmark.pedantic(_evaluate_without_flip, args=bunny_lod, rounds=5, warmup_rounds=1)


def test_flip_six_views(benchmark, bunny_lod):
    bunny, lod, protocol, reference = bunny_lod
    images = render_views(lod, bunny, protocol)
    benchmark.pedantic(image.flip_mean, args=(reference, images), rounds=5, warmup_rounds=1)


@pytest.mark.parametrize("method", ["qslim", "fast-simplification"])
def test_simplify_bunny_1332(benchmark, method):
    from bench.core.registry import registry

    bunny = resolve_model("bunny")
    cls = registry("method").load(method)
    benchmark.pedantic(run_method, args=(cls(), bunny, 1332), rounds=5, warmup_rounds=1)
