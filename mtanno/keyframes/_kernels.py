"""Numba kernels of keyframe search (algorithms.md §5): operations on interval lists.

An *interval list* is three int64 arrays ``doc, start, end`` (frames 0-based, ``end``
inclusive), sorted by (doc, start), with intervals of one document disjoint and not
touching (``start > previous end + 1``). Keyframe search propagates such lists level by
level; every kernel here is one linear pass (two-pointer merges), so a query costs time
linear in the total length of the lists involved, and memory bounded by them.

Private: :mod:`mtanno.keyframes.search` validates inputs and calls these. A kernel calls
kernels of this file only (numba's cache does not see changes across files).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def dilate(doc, start, end, lo, hi, out_doc, out_start, out_end):
    """Minkowski sum of an interval list with [lo, hi] (``lo ≤ hi``): every interval
    [s, e] becomes [s + lo, e + hi]; overlapping or touching results of one document are
    merged. Returns the number of intervals written."""
    cnt = 0
    for i in range(doc.shape[0]):
        s = start[i] + lo
        e = end[i] + hi
        if cnt > 0 and out_doc[cnt - 1] == doc[i] and s <= out_end[cnt - 1] + 1:
            if e > out_end[cnt - 1]:
                out_end[cnt - 1] = e
        else:
            out_doc[cnt] = doc[i]
            out_start[cnt] = s
            out_end[cnt] = e
            cnt += 1
    return cnt


@numba.njit(cache=True)
def intersect(a_doc, a_start, a_end, b_doc, b_start, b_end, out_doc, out_start, out_end):
    """Intersection of two interval lists (two pointers). The output needs room for
    ``len(a) + len(b)`` intervals; returns the number written."""
    i = 0
    j = 0
    cnt = 0
    na = a_doc.shape[0]
    nb = b_doc.shape[0]
    while i < na and j < nb:
        if a_doc[i] < b_doc[j]:
            i += 1
            continue
        if b_doc[j] < a_doc[i]:
            j += 1
            continue
        s = max(a_start[i], b_start[j])
        e = min(a_end[i], b_end[j])
        if s <= e:
            out_doc[cnt] = a_doc[i]
            out_start[cnt] = s
            out_end[cnt] = e
            cnt += 1
        if a_end[i] < b_end[j]:
            i += 1
        else:
            j += 1
    return cnt


@numba.njit(cache=True)
def pair_spans(a_doc, a_start, a_end, b_doc, b_start, b_end, dmin, dmax,
               out_doc, out_start, out_end):
    """For every pair of an interval [p, q] of ``a`` and [r, s] of ``b`` in one document
    that holds frames a ∈ [p, q], b ∈ [r, s] with dmin ≤ b − a ≤ dmax, the span
    [min a, max b] of those pairs = [max(p, r − dmax), min(s, q + dmax)] (every frame in it
    lies between such a pair, see ``docs/keyframes.md``). Writes while room is left and
    returns the total number (call again with a larger output if it exceeds the room)."""
    cnt = 0
    room = out_doc.shape[0]
    nb = b_doc.shape[0]
    k0 = 0
    for i in range(a_doc.shape[0]):
        d = a_doc[i]
        p = a_start[i]
        q = a_end[i]
        while k0 < nb and (b_doc[k0] < d or (b_doc[k0] == d and b_end[k0] < p + dmin)):
            k0 += 1
        k = k0
        while k < nb and b_doc[k] == d and b_start[k] <= q + dmax:
            r = b_start[k]
            s = b_end[k]
            lo = max(p, r - dmax)
            hi = min(s, q + dmax)
            if lo <= min(q, s - dmin) and hi >= max(r, p + dmin):
                if cnt < room:
                    out_doc[cnt] = d
                    out_start[cnt] = lo
                    out_end[cnt] = hi
                cnt += 1
            k += 1
    return cnt


@numba.njit(cache=True)
def merge_sorted(doc, start, end, out_doc, out_start, out_end):
    """Union of intervals sorted by (doc, start) (they may overlap or touch): the maximal
    runs of covered frames. Returns the number written."""
    cnt = 0
    for i in range(doc.shape[0]):
        if cnt > 0 and out_doc[cnt - 1] == doc[i] and start[i] <= out_end[cnt - 1] + 1:
            if end[i] > out_end[cnt - 1]:
                out_end[cnt - 1] = end[i]
        else:
            out_doc[cnt] = doc[i]
            out_start[cnt] = start[i]
            out_end[cnt] = end[i]
            cnt += 1
    return cnt


@numba.njit(cache=True)
def docs_with_chain(lv_doc, lv_start, lv_end, lv_off, dmin, dmax, n_docs, out):
    """Which documents hold at least one chain of the query (GA fitness, MBS09 §6).

    Level j's interval list is ``lv_*[lv_off[j]:lv_off[j+1]]``; the forward pass keeps the
    frames t_j reachable from level 1 (F_{j+1} = I_{j+1} ∩ (F_j ⊕ [dmin_j, dmax_j])).
    ``out[d]`` is set to 1 for every document with a frame left at the last level.
    """
    n = lv_off.shape[0] - 1
    cap = lv_off[n] + 1  # |F_j| ≤ |F_{j-1}| + |I_j| ≤ all intervals of the levels so far
    fd = np.empty(cap, np.int64)
    fs = np.empty(cap, np.int64)
    fe = np.empty(cap, np.int64)
    gd = np.empty(cap, np.int64)
    gs = np.empty(cap, np.int64)
    ge = np.empty(cap, np.int64)
    m = lv_off[1] - lv_off[0]
    for i in range(m):
        fd[i] = lv_doc[i]
        fs[i] = lv_start[i]
        fe[i] = lv_end[i]
    for j in range(n - 1):
        if m == 0:
            break
        k = dilate(fd[:m], fs[:m], fe[:m], dmin[j], dmax[j], gd, gs, ge)
        a = lv_off[j + 1]
        b = lv_off[j + 2]
        m = intersect(gd[:k], gs[:k], ge[:k], lv_doc[a:b], lv_start[a:b], lv_end[a:b],
                      fd, fs, fe)
    for i in range(n_docs):
        out[i] = 0
    for i in range(m):
        out[fd[i]] = 1
