"""Numba kernels of time alignment ([MRC05] §7): DTW inside a staircase area, its backtracking,
and the area spanned by matched segment pairs.

An *area* of an n × m cost matrix is given per row a (a frame, or a segment, of motion A) by
the columns ``lo[a] .. hi[a]`` (inclusive) of motion B that are computed; the cells of row a
are stored one after another from ``offsets[a]`` on (``offsets[a + 1] - offsets[a] ==
hi[a] - lo[a] + 1``). The full matrix is the area lo = 0, hi = m − 1.

DTW recursion (see :mod:`mtanno.align.dtw`), with a weight per row ``wa`` and per column
``wb`` (1 for frames, which gives classical DTW; segment lengths for stage 1)::

    D(0, 0) = c(0, 0) · max(wa[0], wb[0])
    D(a, b) = min( D(a-1, b-1) + c(a, b) · max(wa[a], wb[b]),  step 0 (diagonal)
                   D(a-1, b)   + c(a, b) · wa[a],              step 1 (A advances)
                   D(a, b-1)   + c(a, b) · wb[b] )             step 2 (B advances)

ties going to the first step listed; cells outside the area are +∞. Only two rows of D are
kept (streaming over the rows of A); the step chosen for every computed cell (one byte, 3 =
unreachable) is kept for the backtracking.

Local costs: ``kind`` 0 is the pose distance — the mean over joints of the Euclidean
distance between two rows of ``PA`` (n × 3J) and ``PB`` (m × 3J) holding normalised joint
positions x, y, z per joint; ``kind`` 1 is the Hamming distance of the feature codes ``CA``,
``CB`` (int64 bit sets) divided by ``nfeat`` (the number of features) plus ``tie`` times the
difference of ``PA[a, 0]`` and ``PB[b, 0]`` (the frames' relative positions in their
segments).

Private: :mod:`mtanno.align.dtw` and :mod:`mtanno.align.coarse` validate inputs and call
these. A kernel calls kernels of this file only (numba's cache does not see changes across
files).
"""

from __future__ import annotations

import numba
import numpy as np

from mtanno.util._bits import popcount64 as _popcount

POSE = 0
CODES = 1
UNREACHED = 3


@numba.njit(cache=True, inline="always")
def _cost(kind, PA, PB, CA, CB, nfeat, tie, a, b):
    """Local cost of cell (a, b) (module docstring)."""
    if kind == CODES:
        return _popcount(CA[a] ^ CB[b]) / nfeat + tie * abs(PA[a, 0] - PB[b, 0])
    d = PA.shape[1]
    s = 0.0
    for k in range(0, d, 3):
        dx = PA[a, k] - PB[b, k]
        dy = PA[a, k + 1] - PB[b, k + 1]
        dz = PA[a, k + 2] - PB[b, k + 2]
        s += np.sqrt(dx * dx + dy * dy + dz * dz)
    return s / (d // 3)


@numba.njit(cache=True)
def dtw_area(lo, hi, offsets, wa, wb, kind, PA, PB, CA, CB, nfeat, tie, steps):
    """DTW over the area (module docstring); writes the chosen step of every computed cell
    into ``steps`` (length offsets[-1]) and returns D(n − 1, hi[n − 1]) (+∞ when that cell
    is not reached). Needs non-empty rows."""
    n = lo.shape[0]
    width = 1
    for a in range(n):
        width = max(width, hi[a] - lo[a] + 1)
    inf = np.inf
    prev = np.full(width, inf)
    cur = np.full(width, inf)
    plo = 0
    phi = -1
    for a in range(n):
        l = lo[a]
        h = hi[a]
        off = offsets[a]
        for b in range(l, h + 1):
            c = _cost(kind, PA, PB, CA, CB, nfeat, tie, a, b)
            wd = max(wa[a], wb[b])
            if a == 0 and b == 0:
                cur[0] = c * wd
                steps[off] = 0
                continue
            best = inf
            step = UNREACHED
            if a > 0 and plo <= b - 1 <= phi:
                x = prev[b - 1 - plo] + c * wd
                if x < best:
                    best = x
                    step = 0
            if a > 0 and plo <= b <= phi:
                x = prev[b - plo] + c * wa[a]
                if x < best:
                    best = x
                    step = 1
            if b > l:
                x = cur[b - 1 - l] + c * wb[b]
                if x < best:
                    best = x
                    step = 2
            cur[b - l] = best
            steps[off + b - l] = step
        prev, cur = cur, prev
        plo = l
        phi = h
    return prev[hi[n - 1] - lo[n - 1]]


@numba.njit(cache=True)
def backtrack(lo, offsets, steps, last_col, out_a, out_b):
    """Follow the chosen steps back from (n − 1, ``last_col``) to (0, 0); writes the cells
    into ``out_a``, ``out_b`` from the end backwards (room for n + m − 1 cells) and returns
    the index of the first cell written (−1 if a cell on the way was unreachable)."""
    a = lo.shape[0] - 1
    b = last_col
    k = out_a.shape[0] - 1
    while True:
        out_a[k] = a
        out_b[k] = b
        if a == 0 and b == 0:
            return k
        s = steps[offsets[a] + b - lo[a]]
        if s == 0:
            a -= 1
            b -= 1
        elif s == 1:
            a -= 1
        elif s == 2:
            b -= 1
        else:
            return -1
        k -= 1


@numba.njit(cache=True)
def pair_area(pa, pb, start_a, end_a, start_b, end_b, band, lo, hi):
    """Union of the rectangles [start_a[pa[k]] − band, end_a[pa[k]] + band] ×
    [start_b[pb[k]] − band, end_b[pb[k]] + band] over the pairs k, clipped to the matrix
    (n = len(lo) rows, m = ``end_b[-1] + 1`` columns): per row the smallest and largest
    column covered, written into ``lo`` and ``hi`` (rows no rectangle covers keep lo = m,
    hi = −1)."""
    n = lo.shape[0]
    m = end_b[end_b.shape[0] - 1] + 1
    lo[:] = m
    hi[:] = -1
    for k in range(pa.shape[0]):
        r0 = max(0, start_a[pa[k]] - band)
        r1 = min(n - 1, end_a[pa[k]] + band)
        c0 = max(0, start_b[pb[k]] - band)
        c1 = min(m - 1, end_b[pb[k]] + band)
        for r in range(r0, r1 + 1):
            if c0 < lo[r]:
                lo[r] = c0
            if c1 > hi[r]:
                hi[r] = c1
