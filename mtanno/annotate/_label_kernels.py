"""The numba kernels of labels and extended runs of a Δ̄ matrix ([MBS09] §4, docs/method.md
§7 steps 3–4; private, wrapped by :func:`mtanno.annotate.label.segments_from_labels`, which
validates its input, and tested against a slow reference in ``tests/naive*.py``). Frames are
0-based.

The kernels here call only each other (numba's on-disk cache keys a kernel on its own
file: a family of kernels that call each other stays in one file).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _extend(dbar, s, t, lo, hi):
    """Walk outward from [s, t] while Δ̄ does not rise (docs/method.md §7 step 4), inside
    frames lo … hi (where the row holds Δ̄: outside, it would be ∞ and stop the walk)."""
    r = s
    while r > lo and dbar[r - 1] <= dbar[r]:
        r -= 1
    u = t
    while u < hi and dbar[u + 1] <= dbar[u]:
        u += 1
    return r, u


@numba.njit(cache=True)
def _extend_unclaimed(dbar, labels, p, s, t, lo, hi):
    """:func:`_extend` that walks only over frames whose label is none or ``p`` (boundary
    refinement, issue 10: the extension never runs into another class's frames)."""
    r = s
    while r > lo and dbar[r - 1] <= dbar[r] and (labels[r - 1] < 0 or labels[r - 1] == p):
        r -= 1
    u = t
    while u < hi and dbar[u + 1] <= dbar[u] and (labels[u + 1] < 0 or labels[u + 1] == p):
        u += 1
    return r, u


@numba.njit(cache=True)
def _frame_labels(dbars, firsts, lasts, offsets, labels):
    """Each frame's label: the row with the smallest Δ̄ (ties → smaller row), −1 where
    every Δ̄ is ∞. Row p holds Δ̄ only in its spans [firsts[i], lasts[i]], i in
    offsets[p] … offsets[p + 1] − 1 (sorted, disjoint; elsewhere it counts as ∞ and is not
    read). Rows are read in order, a block of frames at a time (contiguous loads instead of
    one load per row and frame)."""
    P, L = dbars.shape
    block = 1024
    best = np.empty(block)
    at = offsets[:-1].copy()  # each row's first span not yet behind the block
    for j0 in range(0, L, block):
        j1 = min(L, j0 + block)
        best[:j1 - j0] = np.inf
        lab = labels[j0:j1]
        lab[:] = -1
        for p in range(P):
            i = at[p]
            while i < offsets[p + 1] and lasts[i] < j0:
                i += 1
            at[p] = i
            while i < offsets[p + 1] and firsts[i] < j1:
                a = max(firsts[i], j0) - j0
                row = dbars[p, j0:j1]
                for j in range(a, min(lasts[i] + 1, j1) - j0):  # selects: it vectorizes
                    v = row[j]
                    b = best[j]
                    t = v < b
                    best[j] = v if t else b
                    lab[j] = p if t else lab[j]
                i += 1


@numba.njit(cache=True, inline="always")
def _span_of(firsts, lo, hi, frame):
    """The index in lo … hi − 1 of the last span starting at or before ``frame``."""
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if firsts[mid] <= frame:
            lo = mid
        else:
            hi = mid
    return lo


@numba.njit(cache=True)
def _label_runs(dbars, firsts, lasts, offsets, extend, rank, out_p, out_s, out_t, out_cost):
    """Segments of a Δ̄ matrix (labels × frames; row p valid in its spans only, as for
    :func:`_frame_labels`): each frame's label is the smallest Δ̄ (ties → smaller label,
    none where all are ∞); maximal runs of one label, extended while Δ̄ of the label does
    not rise (``extend`` 1; 2: only over frames of no other label; 0: not extended),
    merged per label where they overlap, with the smallest Δ̄ inside. Writes (label,
    start, end, cost) sorted by start, end and ``rank`` of the label (the order of the
    label names); returns their number."""
    P, L = dbars.shape
    labels = np.empty(L, np.int64)
    _frame_labels(dbars, firsts, lasts, offsets, labels)
    n = 0
    prev = -2
    s0 = 0
    for j in range(L + 1):
        lab = labels[j] if j < L else -1
        if j == L or lab != prev:
            if j > 0 and prev >= 0:
                s, t = s0, j - 1
                if extend:  # the walk stays inside the row's spans around the run
                    lo = firsts[_span_of(firsts, offsets[prev], offsets[prev + 1], s)]
                    hi = lasts[_span_of(firsts, offsets[prev], offsets[prev + 1], t)]
                    if extend == 2:
                        s, t = _extend_unclaimed(dbars[prev], labels, prev, s, t, lo, hi)
                    else:
                        s, t = _extend(dbars[prev], s, t, lo, hi)
                out_p[n] = prev
                out_s[n] = s
                out_t[n] = t
                n += 1
            prev = lab
            s0 = j
    order = np.argsort(out_p[:n] * (L + 1) + out_s[:n])
    sp = out_p[:n][order]
    ss = out_s[:n][order]
    st = out_t[:n][order]
    m = 0
    # numba twin of keyframes/_kernels.py dilate (and merge_sorted): here runs merge per
    # label and only where they overlap (touching runs stay two), and a kernel calls
    # kernels of its own file only (numba's cache does not see changes to another file;
    # util/_bits.py)
    for i in range(n):
        if m > 0 and out_p[m - 1] == sp[i] and ss[i] <= out_t[m - 1]:  # overlapping: merge
            if st[i] > out_t[m - 1]:
                out_t[m - 1] = st[i]
        else:
            out_p[m] = sp[i]
            out_s[m] = ss[i]
            out_t[m] = st[i]
            m += 1
    by_rank = np.argsort(rank[out_p[:m]], kind="mergesort")
    key = out_s[:m] * (L + 1) + out_t[:m]
    order = by_rank[np.argsort(key[by_rank], kind="mergesort")]
    sp = out_p[:m][order]
    ss = out_s[:m][order]
    st = out_t[:m][order]
    for i in range(m):
        out_p[i] = sp[i]
        out_s[i] = ss[i]
        out_t[i] = st[i]
        c = np.inf
        for j in range(ss[i], st[i] + 1):
            if dbars[sp[i], j] < c:
                c = dbars[sp[i], j]
        out_cost[i] = c
    return m
