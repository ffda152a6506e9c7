"""Viewpoint entropy (González et al. 2008, §3 "Error metric"; Vázquez et al. 2001),
kept incrementally from per-view face pixel counts."""

from __future__ import annotations

import numpy as np
from numba import njit

from methods.corners import corners


@njit(cache=True)
def _xlogx(a):
    return a * np.log(a) if a > 0.0 else 0.0


@njit(cache=True)
def view_entropy(s, a):
    """H = log A - S / A, with S = sum a_i log a_i and A = sum a_i: the viewpoint
    entropy -sum (a_i / A) log(a_i / A) (natural logarithm); 0 for an empty view."""
    return np.log(a) - s / a if a > 0.0 else 0.0


@njit(cache=True)
def entropy_init(IDS, ent):
    """Set the per-view face pixel counts, their sum of a log a and total from ``IDS``
    (``ent``: methods.imaging.state.Entropy)."""
    CNT, SUM, TOT = ent.counts, ent.sums, ent.totals
    n_views, height, width = IDS.shape
    first = 0 if ent.background else 1  # the background is entry 0
    for h in range(n_views):
        for x in range(CNT.shape[1]):
            CNT[h, x] = 0
        for r in range(height):
            for c in range(width):
                CNT[h, IDS[h, r, c] + 1] += 1
        s = 0.0
        a = 0
        for x in range(first, CNT.shape[1]):
            if CNT[h, x] > 0:
                s += _xlogx(float(CNT[h, x]))
                a += CNT[h, x]
        SUM[h] = s
        TOT[h] = a


@njit(cache=True, _nrt=False)
def _entropy_change(h, rect, ids, IDS, ent, commit):
    """Change of view ``h``'s entropy when the faces seen in ``rect`` become ``ids``
    (rectangle-relative) instead of ``IDS``: only the faces whose pixel count changes
    enter S = sum a log a and A. With ``commit`` the counts, S and A are updated."""
    CNT, SUM, TOT, dcnt, emark, touched = (ent.counts, ent.sums, ent.totals, ent.dcnt,
                                           ent.emark, ent.touched)
    etick = ent.etick
    c0, c1, r0, r1 = rect[0], rect[1], rect[2], rect[3]
    etick[0] += 1
    tk = etick[0]
    n = 0
    cols = c1 - c0 + 1
    for r in range(r0, r1 + 1):
        before, after = IDS[h, r, c0:c1 + 1], ids[r - r0]  # rows indexed from 0
        for j in range(cols):
            old = before[j] + 1
            new = after[j] + 1
            if old == new:
                continue
            if emark[old] != tk:
                emark[old] = tk
                touched[n] = old
                n += 1
            if emark[new] != tk:
                emark[new] = tk
                touched[n] = new
                n += 1
            dcnt[old] -= 1
            dcnt[new] += 1
    s = SUM[h]
    a = TOT[h]
    for i in range(n):
        x = touched[i]
        d = dcnt[x]
        dcnt[x] = 0
        cur = CNT[h, x]
        if commit:
            CNT[h, x] = cur + d
        if d == 0 or (x == 0 and not ent.background):
            continue
        s += _xlogx(float(cur + d)) - _xlogx(float(cur))
        a += d
    dh = view_entropy(s, float(a)) - view_entropy(SUM[h], float(TOT[h]))
    if commit:
        SUM[h] = s
        TOT[h] = a
    return dh


@njit(cache=True)
def fan_pixels(x, vhead, cnext, falive, ent):
    """The pixels the live faces around vertex ``x`` cover, over every view (0 without
    the entropy's counts): how much of the images a collapse removing ``x`` redraws."""
    if not ent.on:
        return 0
    counts = ent.counts
    total = 0
    for c in corners(x, vhead, cnext):
        f = c // 3
        if falive[f]:
            for h in range(counts.shape[0]):
                total += counts[h, f + 1]
    return total
