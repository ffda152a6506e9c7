"""Atomic reads, writes and additions on int64 arrays, and yielding the core: what
threads that stay inside numba's compiled code use to hand work to each other
(:mod:`methods.imaging.share`)."""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

sched_yield = types.ExternalFunction("sched_yield", types.int32())


def _pointer(context, builder, signature, args):
    aryty = signature.args[0]
    a = context.make_array(aryty)(context, builder, args[0])
    return cgutils.get_item_pointer(context, builder, aryty, a, [args[1]])


@intrinsic
def load_acquire(typingctx, ary, i):
    """``ary[i]`` (int64, 1-d) read with acquire ordering."""
    def codegen(context, builder, signature, args):
        return builder.load_atomic(_pointer(context, builder, signature, args), "acquire", 8)

    return types.int64(ary, i), codegen


@intrinsic
def store_release(typingctx, ary, i, value):
    """``ary[i] = value`` (int64, 1-d) written with release ordering."""
    def codegen(context, builder, signature, args):
        builder.store_atomic(args[2], _pointer(context, builder, signature, args), "release",
                             8)
        return context.get_dummy_value()

    return types.void(ary, i, value), codegen


@intrinsic
def fetch_add(typingctx, ary, i, value):
    """``ary[i] += value`` (int64, 1-d) as one atomic step; returns the old value."""
    def codegen(context, builder, signature, args):
        return builder.atomic_rmw("add", _pointer(context, builder, signature, args), args[2],
                                  "acq_rel")

    return types.int64(ary, i, value), codegen
