"""The numba kernels of the frame classifier evidence (issue 35;
:mod:`mtanno.confidence.frames`): bit-packed feature windows and the k nearest training
windows by Hamming distance (private; wrapped by :class:`mtanno.confidence.frames.
FrameBank`, tested against the slow reference in ``tests/naive_frames.py``).

A window of frame t of a (features × frames) 0/1 matrix is the features of frames
t − half … t + half (frames beyond the ends repeat the first or last frame), feature by
feature within a frame, frame by frame, packed 64 bits to a word (bit b of the window in
word b // 64 at bit b % 64).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _pack_at(X, frames, half, out):
    """Pack the window of every frame of ``frames`` (0-based) of ``X`` into ``out``
    (len(frames) × words, zeroed by the caller)."""
    f, L = X.shape
    for q in range(frames.shape[0]):
        t = frames[q]
        bit = 0
        for o in range(-half, half + 1):
            s = min(max(t + o, 0), L - 1)
            for i in range(f):
                if X[i, s]:
                    out[q, bit >> 6] |= np.uint64(1) << np.uint64(bit & 63)
                bit += 1


@numba.njit(cache=True, inline="always")
def _popcount(x):
    x = x - ((x >> np.uint64(1)) & np.uint64(0x5555555555555555))
    x = (x & np.uint64(0x3333333333333333)) + ((x >> np.uint64(2)) & np.uint64(0x3333333333333333))
    x = (x + (x >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return (x * np.uint64(0x0101010101010101)) >> np.uint64(56)


@numba.njit(cache=True)
def _neighbours(queries, train, labels, allowed, k, out):
    """The labels of the ``k`` nearest training windows of every query whose label is
    ``allowed`` (Hamming distance; the earlier training window first among equals), into
    ``out`` (queries × k; −1 where fewer are allowed)."""
    n, words = queries.shape
    m = train.shape[0]
    best_d = np.empty(k, np.int64)
    best_i = np.empty(k, np.int64)
    for q in range(n):
        best_d[:] = 1 << 40
        best_i[:] = -1
        for j in range(m):
            if not allowed[labels[j]]:
                continue
            d = 0
            limit = best_d[k - 1]
            for w in range(words):
                d += _popcount(queries[q, w] ^ train[j, w])
                if d > limit:
                    break
            if d < limit:
                p = k - 1
                while p > 0 and best_d[p - 1] > d:
                    best_d[p] = best_d[p - 1]
                    best_i[p] = best_i[p - 1]
                    p -= 1
                best_d[p] = d
                best_i[p] = j
        for r in range(k):
            out[q, r] = labels[best_i[r]] if best_i[r] >= 0 else -1


@numba.njit(cache=True)
def _vote(queries, train, labels, allowed, k, n_labels, out):
    """Label of every query window: the majority among its ``k`` nearest training
    windows whose label is ``allowed`` (Hamming distance; the earlier training window
    first among equals; ties of votes: the smaller distance sum, then the label of the
    nearest). ``labels`` index ``allowed`` (0 … n_labels − 1); ``out[q]`` = −1 when no
    training window is allowed. Early abandon once a partial distance exceeds the
    current k-th best."""
    n, words = queries.shape
    m = train.shape[0]
    best_d = np.empty(k, np.int64)
    best_i = np.empty(k, np.int64)
    votes = np.zeros(n_labels, np.int64)
    dsum = np.zeros(n_labels, np.int64)
    for q in range(n):
        best_d[:] = 1 << 40
        best_i[:] = -1
        for j in range(m):
            if not allowed[labels[j]]:
                continue
            d = 0
            limit = best_d[k - 1]
            for w in range(words):
                d += _popcount(queries[q, w] ^ train[j, w])
                if d > limit:
                    break
            if d < limit:  # strictly nearer: insert, keeping earlier equals first
                p = k - 1
                while p > 0 and best_d[p - 1] > d:
                    best_d[p] = best_d[p - 1]
                    best_i[p] = best_i[p - 1]
                    p -= 1
                best_d[p] = d
                best_i[p] = j
        if best_i[0] < 0:
            out[q] = -1
            continue
        votes[:] = 0
        dsum[:] = 0
        for r in range(k):
            if best_i[r] >= 0:
                c = labels[best_i[r]]
                votes[c] += 1
                dsum[c] += best_d[r]
        lab = labels[best_i[0]]
        for c in range(n_labels):
            if votes[c] > votes[lab] or (votes[c] == votes[lab] and dsum[c] < dsum[lab]):
                lab = c
        out[q] = lab
