"""Slow, obviously correct reference of the frame classifier's kernels
(:mod:`mtanno.confidence._frame_kernels`): windows as 0/1 vectors, every distance computed,
votes counted in Python."""

from __future__ import annotations

import numpy as np


def window(X: np.ndarray, t: int, half: int) -> np.ndarray:
    """The 0/1 window of frame t (frames beyond the ends repeat the end frames)."""
    L = X.shape[1]
    return np.concatenate([X[:, min(max(t + o, 0), L - 1)] for o in range(-half, half + 1)])


def unpack(words: np.ndarray, bits: int) -> np.ndarray:
    return np.array([(int(words[b // 64]) >> (b % 64)) & 1 for b in range(bits)], np.uint8)


def vote(query: np.ndarray, train: np.ndarray, labels, allowed, k: int) -> int:
    """The majority label of the k nearest allowed training vectors (ties: the earlier
    training vector first among equal distances; equal votes: the smaller distance sum,
    then the nearest one's label); −1 when none is allowed."""
    cand = [(int(np.sum(query != train[j])), j) for j in range(len(train)) if allowed[labels[j]]]
    if not cand:
        return -1
    near = sorted(cand)[:k]
    votes, dsum = {}, {}
    for d, j in near:
        votes[labels[j]] = votes.get(labels[j], 0) + 1
        dsum[labels[j]] = dsum.get(labels[j], 0) + d
    best = labels[near[0][1]]
    for c in sorted(votes):
        if votes[c] > votes[best] or (votes[c] == votes[best] and dsum[c] < dsum[best]):
            best = c
    return best


def neighbours(query: np.ndarray, train: np.ndarray, labels, allowed, k: int) -> list[int]:
    """The labels of the k nearest allowed training vectors (the earlier first among equal
    distances), −1 for each missing one."""
    cand = sorted((int(np.sum(query != train[j])), j) for j in range(len(train))
                  if allowed[labels[j]])[:k]
    return [labels[j] for _, j in cand] + [-1] * (k - len(cand))
