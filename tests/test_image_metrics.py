"""Image metrics against hand computations and exact values on constructed images."""

import numpy as np
import pytest

from metrics import image
from metrics.image import FLIP_VIEWS, d_rms, flip_mean, luminance, ssim_mean


def random_views(seed, shape=(3, 16, 20, 3)):
    return np.random.default_rng(seed).integers(0, 256, size=shape, dtype=np.uint8)


def gray(value, shape=(1, 4, 5)):
    return np.full((*shape, 3), value, dtype=np.uint8)


# -- luminance -----------------------------------------------------------------------------

def test_luminance_of_primaries_is_the_weights():
    rgb = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255], [0, 0, 0]],
                   np.uint8)
    np.testing.assert_allclose(luminance(rgb), [0.299 * 255, 0.587 * 255, 0.114 * 255,
                                                255.0, 0.0])


def test_luminance_keeps_leading_shape():
    assert luminance(random_views(0)).shape == (3, 16, 20)


@pytest.mark.parametrize("bad, match", [
    (np.zeros((4, 4, 4), np.uint8), "alpha"),
    (np.zeros((4, 4, 3), np.float64), "uint8"),
])
def test_luminance_rejects_bad_input(bad, match):
    with pytest.raises(ValueError, match=match):
        luminance(bad)


# -- d_RMS (equation 2) --------------------------------------------------------------------

def test_d_rms_matches_a_hand_computation():
    a, b = random_views(1), random_views(2)
    ya = 0.299 * a[..., 0] + 0.587 * a[..., 1] + 0.114 * a[..., 2]
    yb = 0.299 * b[..., 0] + 0.587 * b[..., 1] + 0.114 * b[..., 2]
    sq = (ya - yb) ** 2
    d, per_view = d_rms(a, b)
    assert d == pytest.approx(np.sqrt(sq.mean()), rel=1e-12)
    np.testing.assert_allclose(per_view, np.sqrt(sq.mean(axis=(1, 2))), rtol=1e-12)


def test_d_rms_is_a_mosaic_rms_not_a_mean_of_view_rms():
    # One view differs by exactly 10 in luminance (gray 100 vs 110), the other not at
    # all: equation 2 gives sqrt((100 + 0) / 2) = 10/√2, not the mean of 10 and 0.
    a = np.concatenate([gray(100), gray(100)])
    b = np.concatenate([gray(110), gray(100)])
    d, per_view = d_rms(a, b)
    assert d == pytest.approx(10 / np.sqrt(2), rel=1e-12)
    np.testing.assert_allclose(per_view, [10.0, 0.0], atol=1e-12)


def test_d_rms_of_a_constant_offset_is_the_offset():
    d, per_view = d_rms(gray(100), gray(110))
    assert d == pytest.approx(10.0, rel=1e-12)
    np.testing.assert_allclose(per_view, [10.0])


def test_d_rms_is_zero_for_identical_and_symmetric():
    a, b = random_views(3), random_views(4)
    assert d_rms(a, a)[0] == 0.0
    assert d_rms(a, b)[0] == pytest.approx(d_rms(b, a)[0], rel=1e-12)


@pytest.mark.parametrize("a, b, match", [
    (np.zeros((2, 8, 8, 3), np.uint8), np.zeros((3, 8, 8, 3), np.uint8), "differ in shape"),
    (np.zeros((8, 8, 3), np.uint8), np.zeros((8, 8, 3), np.uint8), r"\(V, H, W, 3\)"),
    (np.zeros((1, 8, 8, 4), np.uint8), np.zeros((1, 8, 8, 4), np.uint8), "alpha"),
    (np.zeros((1, 8, 8, 3)), np.zeros((1, 8, 8, 3)), "uint8"),
    (np.zeros((0, 8, 8, 3), np.uint8), np.zeros((0, 8, 8, 3), np.uint8), "empty"),
])
def test_d_rms_rejects_bad_input(a, b, match):
    with pytest.raises(ValueError, match=match):
        d_rms(a, b)


# -- SSIM ----------------------------------------------------------------------------------

def hand_ssim(x, y, sigma=1.5, radius=5, data_range=255.0):
    """SSIM of Wang et al. 2004 (equation 13) written out: an 11×11 Gaussian window at
    every pixel whose window fits in the image, population statistics, mean of the map."""
    t = np.arange(-radius, radius + 1)
    g = np.exp(-t ** 2 / (2 * sigma ** 2))
    window = np.outer(g, g) / np.outer(g, g).sum()
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    values = []
    for i in range(radius, x.shape[0] - radius):
        for j in range(radius, x.shape[1] - radius):
            px = x[i - radius:i + radius + 1, j - radius:j + radius + 1]
            py = y[i - radius:i + radius + 1, j - radius:j + radius + 1]
            mx, my = (window * px).sum(), (window * py).sum()
            vx = (window * (px - mx) ** 2).sum()
            vy = (window * (py - my) ** 2).sum()
            cov = (window * (px - mx) * (py - my)).sum()
            values.append((2 * mx * my + c1) * (2 * cov + c2)
                          / ((mx ** 2 + my ** 2 + c1) * (vx + vy + c2)))
    return np.mean(values)


def test_ssim_matches_a_hand_written_gaussian_window_ssim():
    a, b = random_views(5, (2, 20, 23, 3)), random_views(6, (2, 20, 23, 3))
    b[1] = np.clip(a[1].astype(int) + 20, 0, 255)  # a similar view as well as a random one
    s, per_view = ssim_mean(a, b)
    expected = [hand_ssim(luminance(a[v]), luminance(b[v])) for v in range(2)]
    np.testing.assert_allclose(per_view, expected, rtol=1e-6)
    assert s == pytest.approx(np.mean(expected), rel=1e-6)


def test_ssim_is_one_for_identical_images_and_symmetric():
    a, b = random_views(7, (2, 16, 16, 3)), random_views(8, (2, 16, 16, 3))
    s, per_view = ssim_mean(a, a)
    assert s == pytest.approx(1.0) and np.allclose(per_view, 1.0)
    assert ssim_mean(a, b)[0] == pytest.approx(ssim_mean(b, a)[0], rel=1e-12)


def test_ssim_decreases_with_noise():
    rng = np.random.default_rng(9)
    yy, xx = np.mgrid[0:32, 0:32]
    smooth = np.repeat(((xx + yy) * 4).astype(np.uint8)[None, ..., None], 3, axis=3)
    scores = []
    for amplitude in (0, 5, 20, 60):
        noise = rng.normal(0, amplitude, smooth.shape) if amplitude else 0
        noisy = np.clip(smooth + noise, 0, 255).astype(np.uint8)
        scores.append(ssim_mean(smooth, noisy)[0])
    assert scores[0] == pytest.approx(1.0)
    assert all(later < earlier for earlier, later in zip(scores, scores[1:]))
    assert all(s <= 1.0 for s in scores)


def patched_views(seed, boxes, size=96):
    """A smooth textured view and copies differing from it only inside ``boxes``
    ((y0, y1, x0, x1) each), one view per box, on a flat grey ground as the renders
    have it."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size]
    base = np.full((size, size, 3), 128, dtype=np.uint8)
    base[16:80, 20:70] = ((xx[16:80, 20:70, None] * 3 + yy[16:80, 20:70, None] * 2
                           + np.array([0, 40, 80])) % 256).astype(np.uint8)
    a = np.repeat(base[None], len(boxes), axis=0)
    b = a.copy()
    for v, (y0, y1, x0, x1) in enumerate(boxes):
        b[v, y0:y1, x0:x1] = rng.integers(0, 256, size=(y1 - y0, x1 - x0, 3), dtype=np.uint8)
    return a, b


# Differences in the middle, touching each edge and corner, and everywhere: the cases
# where the metrics' differing box is clipped by the image or is the whole image.
PATCHES = [(40, 44, 40, 47), (0, 3, 50, 52), (93, 96, 10, 30), (30, 60, 0, 2),
           (20, 21, 95, 96), (0, 5, 0, 5), (90, 96, 91, 96), (0, 96, 0, 96), (11, 12, 12, 13)]


def test_ssim_on_the_differing_box_is_skimages_whole_view_ssim_bit_for_bit():
    from skimage.metrics import structural_similarity

    a, b = patched_views(20, PATCHES)
    _, per_view = ssim_mean(a, b)
    whole = [structural_similarity(luminance(a[v]), luminance(b[v]), **image._SSIM_SETTINGS)
             for v in range(len(a))]
    assert per_view.tolist() == whole
    assert all(s < 1 for s in whole)


def test_ssim_rejects_images_smaller_than_its_window():
    with pytest.raises(ValueError, match="at least 11"):
        ssim_mean(gray(0, (1, 10, 30)), gray(0, (1, 10, 30)))


def test_ssim_rejects_shape_mismatch():
    with pytest.raises(ValueError, match="differ in shape"):
        ssim_mean(gray(0, (1, 16, 16)), gray(0, (1, 16, 17)))


# -- FLIP ----------------------------------------------------------------------------------

def test_flip_views_are_three_antipodal_pairs_near_the_axes():
    from metrics.views import rhombicuboctahedron_directions

    a = 1 + np.sqrt(2)
    half = np.array([[a, 1, -1], [-1, a, 1], [1, -1, a]])
    wanted = np.concatenate([half, -half]) / np.sqrt(a * a + 2)
    assert len(set(FLIP_VIEWS)) == 6
    np.testing.assert_allclose(rhombicuboctahedron_directions()[list(FLIP_VIEWS)], wanted,
                               atol=1e-12)


def test_flip_is_zero_for_identical_images():
    a = random_views(10, (2, 32, 32, 3))
    f, per_view, seconds = flip_mean(a, a, views="all")
    assert f == 0.0 and per_view.shape == (2,) and np.all(per_view == 0) and seconds >= 0


def test_flip_on_the_differing_box_is_the_librarys_whole_view_mean_bit_for_bit():
    import flip_evaluator

    a, b = patched_views(21, PATCHES)
    _, per_view, _ = flip_mean(a, b, views="all")
    whole = [flip_evaluator.evaluate(a[v].astype(np.float32) / 255.0,
                                     b[v].astype(np.float32) / 255.0, "LDR", inputsRGB=True,
                                     applyMagma=False, computeMeanError=True,
                                     parameters={"ppd": image.FLIP_PPD})[1]
             for v in range(len(a))]
    assert per_view.tolist() == whole
    assert all(f > 0 for f in whole)


def test_flip_grows_with_the_perturbation():
    a = random_views(11, (1, 32, 32, 3))
    small = np.clip(a.astype(int) + 8, 0, 255).astype(np.uint8)
    large = np.clip(a.astype(int) + 64, 0, 255).astype(np.uint8)
    f_small, f_large = flip_mean(a, small, views="all")[0], flip_mean(a, large, views="all")[0]
    assert 0 < f_small < f_large <= 1


def test_flip_defaults_to_the_flip_views_and_keeps_their_order():
    a = random_views(12, (24, 16, 16, 3))
    b = a.copy()
    b[FLIP_VIEWS[2]] = 255 - b[FLIP_VIEWS[2]]  # only one chosen view differs
    f, per_view, _ = flip_mean(a, b)
    assert per_view.shape == (6,)
    assert per_view[2] > 0 and np.all(np.delete(per_view, 2) == 0)
    assert f == pytest.approx(per_view.mean())
    explicit = flip_mean(a, b, views=[FLIP_VIEWS[2], 0])[1]
    assert explicit[0] == per_view[2] and explicit[1] == 0


@pytest.mark.parametrize("views, n, match", [
    (None, 5, "pass views='all'"),
    ("some", 24, "'all'"),
    ([0, 24], 24, "out of range"),
    ([], 24, "empty"),
])
def test_flip_rejects_bad_views(views, n, match):
    a = np.zeros((n, 8, 8, 3), np.uint8)
    with pytest.raises(ValueError, match=match):
        flip_mean(a, a, views=views)


def test_flip_rejects_shape_mismatch():
    with pytest.raises(ValueError, match="differ in shape"):
        flip_mean(gray(0, (1, 8, 8)), gray(0, (2, 8, 8)), views="all")


# -- registered metrics ----------------------------------------------------------------------

def test_metrics_read_images_from_ctx():
    a = gray(100, (24, 16, 16))
    b = a.copy()
    b[0] = 110
    ctx = {"original_images": a, "simplified_images": b}
    assert image.D_RMS.compute(None, None, ctx) == pytest.approx(np.sqrt(100 / 24))
    assert image.SSIM.compute(None, None, ctx) < 1
    assert image.FLIP.compute(None, None, {**ctx, "flip_views": "all"}) > 0
    assert image.D_RMS.higher_is_better is False and image.SSIM.higher_is_better is True
    assert image.FLIP.higher_is_better is False
    assert image.D_RMS.unit == "luminance (0-255)"


def test_flip_metric_follows_the_protocols_view_choice():
    from types import SimpleNamespace

    a = gray(100, (24, 16, 16))
    b = a.copy()
    b[0] = 160  # view 0 is not among FLIP_VIEWS
    assert 0 not in FLIP_VIEWS
    ctx = {"original_images": a, "simplified_images": b}
    assert image.FLIP.compute(None, None, ctx) == 0
    ctx["protocol"] = SimpleNamespace(flip_views="all")
    assert image.FLIP.compute(None, None, ctx) > 0
