"""Several templates per class: the examples of a class split into groups of similar
motions (mirrored or stylistic variants), one template learned per group (issue 10).

The distance of two examples is their classical DTW cost (the alignment of [MR06] §4.1
learning, :func:`mtanno.templates.dtw.dtw`) divided by the length of the warping path — a
mean disagreement per aligned frame pair, in [0, 1]. Groups are k-medoids of these
distances, deterministic: the first medoid is the example with the smallest distance sum,
each further one the example farthest from the medoids chosen so far, then medoids and
assignments alternate until nothing changes (ties: the smaller example index). A split
that would leave a group with fewer than ``min_size`` examples is not made: one group
fewer is tried instead.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mtanno.errors import MtannoError
from mtanno.templates.training import TrainingExample

__all__ = ["MIN_GROUP", "example_distances", "group_examples"]

#: Smallest number of examples a group of its own needs.
MIN_GROUP = 3


def example_distances(examples: Sequence[TrainingExample]) -> np.ndarray:
    """(n × n) symmetric matrix of DTW costs per warping-path step (module docstring)."""
    from mtanno.templates.dtw import dtw

    n = len(examples)
    D = np.zeros((n, n))
    mats = [np.asarray(ex.X, dtype=np.float64) for ex in examples]
    for i in range(n):
        for j in range(i + 1, n):
            cost, path = dtw(mats[i], mats[j])
            D[i, j] = D[j, i] = cost / len(path)
    return D


def _kmedoids(D: np.ndarray, k: int, iterations: int = 50) -> np.ndarray:
    med = [int(np.argmin(D.sum(axis=1)))]
    while len(med) < k:
        med.append(int(np.argmax(D[:, med].min(axis=1))))
    for _ in range(iterations):
        lab = np.argmin(D[:, med], axis=1)
        new = []
        for c in range(k):
            idx = np.flatnonzero(lab == c)
            new.append(int(idx[np.argmin(D[np.ix_(idx, idx)].sum(axis=1))]) if idx.size
                       else med[c])
        if new == med:
            break
        med = new
    return np.argmin(D[:, med], axis=1)


def group_examples(distances: np.ndarray, k: int, *, min_size: int = MIN_GROUP) -> np.ndarray:
    """Group index (0…k'−1, k' ≤ k) of every example: k-medoids of ``distances`` with the
    largest k' ≤ k whose groups all hold at least ``min_size`` examples (1 group: all
    zeros). Groups are numbered by their smallest example index."""
    D = np.asarray(distances, dtype=np.float64)
    if D.ndim != 2 or D.shape[0] != D.shape[1]:
        raise MtannoError("distances must be a square matrix")
    if not isinstance(k, (int, np.integer)) or k < 1:
        raise MtannoError(f"number of groups must be an integer ≥ 1, got {k!r}")
    n = D.shape[0]
    for kk in range(min(int(k), n // max(1, min_size)), 1, -1):
        lab = _kmedoids(D, kk)
        if np.bincount(lab, minlength=kk).min() >= min_size:
            order = {g: i for i, g in enumerate(dict.fromkeys(lab.tolist()))}
            return np.array([order[g] for g in lab.tolist()], dtype=np.int64)
    return np.zeros(n, dtype=np.int64)
