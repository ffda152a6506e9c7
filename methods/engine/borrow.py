"""Borrowed views: the engine's state without reference counts on its hot path.

numba counts references to every array with atomic increments and decrements, and a
structure of :mod:`methods.engine.state` is a tuple of arrays, so each call of a helper
that takes one pays an atomic pair per array it holds unless LLVM inlines the call and
prunes the pair. On the engine's loop that was most of the time of a geometric run.
:func:`borrowed` returns the same structure whose arrays carry no reference count (a
null ``meminfo``, which numba's increments and decrements skip): same type, same data,
same strides, so every result is unchanged.

A borrowed array does not keep its memory alive. Borrow only what an owner outlives
(the loop's arguments, or a structure the loop still reads after its last use of the
borrowed copy), never return a borrowed array to Python, and let any buffer that is
grown or rebuilt inside the loop be an ordinary (counted) array.
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


def _borrow(context, builder, ty, value):
    """``value`` of numba type ``ty`` with every array in it borrowed (recursively
    through tuples); other members are new references, as an intrinsic's result is."""
    if isinstance(ty, types.Array):
        ary = context.make_array(ty)(context, builder, value=value)
        ary.meminfo = cgutils.get_null_value(ary.meminfo.type)
        ary.parent = cgutils.get_null_value(ary.parent.type)
        return ary._getvalue()
    if isinstance(ty, types.BaseTuple):
        out = value
        for i, member in enumerate(ty):
            item = builder.extract_value(value, i)
            out = builder.insert_value(out, _borrow(context, builder, member, item), i)
        return out
    context.nrt.incref(builder, ty, value)
    return value


@intrinsic
def borrowed(typingctx, structure):
    """``structure`` (an array, or a tuple or named tuple of arrays, tuples and
    scalars) with its arrays borrowed: see the module's docstring for the rule."""

    def codegen(context, builder, signature, args):
        return _borrow(context, builder, signature.args[0], args[0])

    return structure(structure), codegen
