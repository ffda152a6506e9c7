"""methods.engine.borrow: a borrowed structure is the same arrays without reference
counts (same data, same type), so writes through it land in the owner's arrays."""

from collections import namedtuple

import numpy as np
from numba import njit

from methods.engine.borrow import borrowed

Inner = namedtuple("Inner", "a b")
Outer = namedtuple("Outer", "x inner k")


@njit
def _write_through(outer):
    view = borrowed(outer)
    view.x[1] = 7.0
    view.inner.b[0, 2] = -1
    return view.x.shape[0], view.inner.a.shape, view.k, view.x.ctypes.data


def test_a_borrowed_structure_shares_its_owners_arrays():
    outer = Outer(np.zeros(3), Inner(np.ones((2, 2)), np.zeros((1, 3), np.int64)), 5)
    n, shape, k, address = _write_through(outer)
    assert (n, shape, k) == (3, (2, 2), 5)
    assert address == outer.x.ctypes.data
    assert outer.x.tolist() == [0.0, 7.0, 0.0]
    assert outer.inner.b.tolist() == [[0, 0, -1]]


@njit
def _sum_many(x):
    total = 0.0
    for _ in range(1000):
        view = borrowed(x)
        total += view[0]
    return total


def test_borrowing_in_a_loop_leaves_the_owner_alive_and_unchanged():
    x = np.array([0.5, 2.0])
    assert _sum_many(x) == 500.0
    assert x.tolist() == [0.5, 2.0]
