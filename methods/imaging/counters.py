"""Counters of the image term (by name) and the CPU cycle counter used to split run
time by part."""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

#: Counters kept in the state's ``stats`` array.
STAT_NAMES = ("image_evaluations", "pixels_shaded", "face_rows", "raster_cycles",
              "run_cycles", "tile_rebuilds", "commits", "gather_cycles", "shade_cycles",
              "setup_cycles", "helper_views")

#: Indices into ``stats``, by name (``STAT_NAMES[STAT_COMMITS] == "commits"``).
STAT_IMAGE_EVALUATIONS = 0  # image-cost evaluations (region re-renders for a candidate)
STAT_PIXELS_SHADED = 1  # pixels shaded by region re-renders
STAT_FACE_ROWS = 2  # face rows set up for scan conversion
STAT_RASTER_CYCLES = 3  # cycles spent in the rasterizer
STAT_RUN_CYCLES = 4  # cycles of the whole engine loop
STAT_TILE_REBUILDS = 5  # tile-index rebuilds after an overflow
STAT_COMMITS = 6  # collapses committed to the images
STAT_GATHER_CYCLES = 7  # cycles gathering a region's candidate faces
STAT_SHADE_CYCLES = 8  # cycles shading pixels
STAT_SETUP_CYCLES = 9  # cycles setting up face rows
STAT_HELPER_VIEWS = 10  # views re-rendered by the threads that share them (methods.engine.views)


@intrinsic
def cycles(typingctx):
    """The CPU cycle counter (``llvm.readcyclecounter``), to split run time by part."""
    sig = types.int64()

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.IntType(64), [])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.readcyclecounter")
        return builder.call(fn, [])

    return sig, codegen

assert all(STAT_NAMES[globals()["STAT_" + n.upper()]] == n for n in STAT_NAMES)
