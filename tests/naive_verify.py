"""Slow, obviously correct subsequence DTW of a query inside bank items (the oracle of
:mod:`mtanno.confidence._verify_kernels`)."""

from __future__ import annotations

import numpy as np


def local_cost(q: np.ndarray, b: np.ndarray) -> float:
    """Mean absolute difference of two rows."""
    return float(np.mean([abs(float(x) - float(y)) for x, y in zip(q, b)]))


def subsequence_cost(Q: np.ndarray, B: np.ndarray) -> float:
    """min over end columns of the full DTW matrix with free start in B, per query row."""
    n, m = Q.shape[0], B.shape[0]
    if m == 0:
        return float("inf")
    D = np.full((n, m), np.inf)
    for j in range(m):
        for i in range(n):
            c = local_cost(Q[i], B[j])
            if i == 0:
                D[i, j] = c
                continue
            best = D[i - 1, j]
            if j > 0:
                best = min(best, D[i - 1, j - 1], D[i, j - 1])
            D[i, j] = c + best
    return float(D[n - 1].min() / n)


def subsequence_costs(Q: np.ndarray, B: np.ndarray, offsets) -> np.ndarray:
    return np.array([subsequence_cost(Q, B[offsets[k]:offsets[k + 1]])
                     for k in range(len(offsets) - 1)])
