"""Slow, obviously-correct keyframe search: the oracle of the keyframe tests.

Straight from docs/method.md §5: enumerate every tuple of frames t_1 ≤ … ≤ t_n of a document
with the features at t_j matching keyframe j and dmin_j ≤ t_{j+1} − t_j ≤ dmax_j
(recursion over frames, no intervals, no index), mark the frames of every chain's span
[t_1, t_n], and report the maximal runs of marked frames. Windows are widened frame by frame.
"""

from __future__ import annotations

import numpy as np


def matches(X, names, query, j, t):
    """Does frame t of X (features × frames, rows ``names``) match keyframe j?"""
    kf = query.keyframes[j]
    feats = query.groups[kf.group]
    wrong = 0
    for k, c in enumerate(kf.vector):
        if c != "*" and int(X[names.index(feats[k]), t]) != int(c):
            wrong += 1
    return wrong <= kf.mismatches


def chains_naive(X, names, query):
    """Every chain (t_1, …, t_n) of the query in one document, in lexicographic order."""
    L = X.shape[1]
    n = query.n
    out = []

    def rec(j, prefix):
        if j == n:
            out.append(tuple(prefix))
            return
        if j == 0:
            cand = range(L)
        else:
            g = query.gaps[j - 1]
            hi = prefix[-1] + (L if g.dmax is None else g.dmax)
            cand = range(prefix[-1] + g.dmin, min(L - 1, hi) + 1)
        for t in cand:
            if matches(X, names, query, j, t):
                rec(j + 1, prefix + [t])

    rec(0, [])
    return out


def runs(mask):
    out = []
    t = 0
    while t < len(mask):
        if mask[t]:
            u = t
            while u + 1 < len(mask) and mask[u + 1]:
                u += 1
            out.append((t, u))
            t = u + 1
        else:
            t += 1
    return out


def hits_naive(X, names, query):
    """Maximal runs (first, last) of frames covered by some chain's span."""
    mask = [False] * X.shape[1]
    for ch in chains_naive(X, names, query):
        for t in range(ch[0], ch[-1] + 1):
            mask[t] = True
    return runs(mask)


def windows_naive(X, names, query, left, right):
    """Hits widened frame by frame, clipped to the document, as maximal runs."""
    L = X.shape[1]
    mask = [False] * L
    for a, b in hits_naive(X, names, query):
        for t in range(max(0, a - left), min(L - 1, b + right) + 1):
            mask[t] = True
    return runs(mask)


def random_query(rng, groups, *, n_max=4, K=30):
    """A random keyframe query over ``groups`` (name → features)."""
    from mtanno.keyframes import Gap, Keyframe, KeyframeQuery

    n = int(rng.integers(1, n_max + 1))
    pos = np.sort(rng.integers(1, K + 1, size=n))
    kfs, gaps = [], []
    gnames = list(groups)
    for j in range(n):
        g = gnames[int(rng.integers(len(gnames)))]
        vec = "".join("01*"[int(x)] for x in rng.integers(0, 3, size=len(groups[g])))
        if set(vec) == {"*"}:
            vec = "1" + vec[1:]
        fixed = sum(c != "*" for c in vec)
        tol = int(rng.integers(0, 2)) if fixed >= 4 else 0
        kfs.append(Keyframe(g, vec, int(pos[j]), tol))
        if j:
            lo = int(rng.integers(0, 4))
            hi = None if rng.random() < 0.15 else lo + int(rng.integers(0, 6))
            gaps.append(Gap(lo, hi))
    return KeyframeQuery("c", "custom", groups, kfs, gaps, K)
