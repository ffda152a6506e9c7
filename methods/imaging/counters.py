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
              "setup_cycles")


@intrinsic
def cycles(typingctx):
    """The CPU cycle counter (``llvm.readcyclecounter``), to split run time by part."""
    sig = types.int64()

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.IntType(64), [])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.readcyclecounter")
        return builder.call(fn, [])

    return sig, codegen
