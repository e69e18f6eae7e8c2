"""The numba kernel of segment verification (issue 26; :mod:`mtanno.confidence.verify`): the
subsequence DTW cost of a query sequence inside each item of a bank (private; wrapped by
:func:`mtanno.confidence.verify.subsequence_costs`, tested against a slow reference in
``tests/naive_verify.py``).

Sequences are (frames × dims) float32 rows. The local cost of two rows is their mean
absolute difference over the dims: for normalised poses the mean coordinate difference in
leg lengths (an L1 pose distance: five times cheaper than the mean joint distance, whose
square roots do not vectorise), for 0/1 features the Hamming distance over the number of
features. The DTW
of query Q (n rows) inside item B (m rows), with a free start and end in B::

    D(0, j) = c(0, j)
    D(i, j) = c(i, j) + min(D(i-1, j-1), D(i-1, j), D(i, j-1))

and the item's cost is min_j D(n − 1, j) / n (per query frame). Only one column of D is
kept (streaming over B): memory independent of the bank's length.
"""

from __future__ import annotations

import numba
import numpy as np

#: "no item row yet" (fastmath assumes finite numbers: no ∞ inside the kernel)
_BIG = 1e300


@numba.njit(cache=True, fastmath=True, inline="always")
def _local(Q, B, i, j, dims):
    s = 0.0
    for d in range(dims):
        s += abs(Q[i, d] - B[j, d])
    return s / dims


@numba.njit(cache=True, fastmath=True)
def _item_cost(Q, B, a, b, col):
    """Cost of ``Q`` inside rows ``a:b`` of ``B`` times n (``col``: a buffer of n)."""
    n, dims = Q.shape
    best = _BIG
    for j in range(a, b):
        first = j == a
        above_old = 0.0  # D(i-1, j-1): col[i-1] before this column overwrote it
        for i in range(n):
            c = _local(Q, B, i, j, dims)
            old = col[i]  # D(i, j-1)
            if i == 0:
                v = c  # free start in every column
            elif first:
                v = c + col[i - 1]
            else:
                m = above_old if above_old < col[i - 1] else col[i - 1]
                v = c + (m if m < old else old)
            above_old = old
            col[i] = v
        if col[n - 1] < best:
            best = col[n - 1]
    return best


@numba.njit(cache=True, fastmath=True)
def _subsequence_costs(Q, B, offsets, out):
    """Cost of ``Q`` inside each item k of ``B`` (rows ``offsets[k]:offsets[k+1]``) into
    ``out[k]`` (module docstring); an empty item gets
    :data:`_BIG` / n (the caller makes it ∞)."""
    n = Q.shape[0]
    col = np.empty(n)
    for k in range(offsets.shape[0] - 1):
        out[k] = _item_cost(Q, B, offsets[k], offsets[k + 1], col) / n
