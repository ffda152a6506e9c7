"""The per-view kernels count no references (methods.imaging.region's docstring): the
helper threads' structures come from Python, counted, so a kernel on that path compiled
with reference counting pays an atomic pair per array and call."""

from __future__ import annotations

import pytest

from methods.imaging import entropy, raster, region, tiles

PER_VIEW = (region._take_views, region._cost_view, region._unchanged, region._render_view,
            region._open_holes, region._scan_changed, region._fill_holes, region._commit_ids,
            region._shade_changes, region._grow, region._faces_around, raster.scan_row,
            raster.wins_any, tiles._gather, entropy._entropy_change)


@pytest.mark.parametrize("kernel", PER_VIEW, ids=lambda k: k.py_func.__qualname__)
def test_a_per_view_kernel_is_compiled_without_reference_counting(kernel):
    assert kernel.targetoptions.get("_nrt") is False
