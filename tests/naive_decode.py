"""Slow, obviously-correct segment decoding (mtanno.annotate.decode): the oracles of the tests.

``decode_naive`` is the dynamic programme of the module docstring written with Python
lists and floats, with the same tie rules (and its total cost); ``least_cost_exhaustive``
tries every partition of a short document and returns the least total cost, without any
dynamic programming.
``best_column_naive`` is the frame evidence from its definition.
"""

from __future__ import annotations

import math


def _first(L, boundaries):
    first, cur = [], 0
    cuts = set(boundaries)
    for j in range(L):
        if j in cuts:
            cur = j
        first.append(cur)
    return first


def _options(deltas, starts, tau, reject, slack, first, ell):
    """(label, start frame, cost per frame) of every segment that may end at ``ell``."""
    out = []
    for p in range(len(deltas)):
        d = deltas[p][ell]
        if not (d <= reject[p]) or starts[p][ell] < 0:
            continue
        a = starts[p][ell]
        for k in range(max(first[ell], a - slack), min(ell, a + slack) + 1):
            out.append((p, k, d * (1.0 / tau[p])))  # the kernel's rounding: Δ · (1/τ)
    return out


def _segment_cost(k, ell, p, per, evidence, weight, segment_cost=0.0):
    c = (ell - k + 1) * per + segment_cost
    if weight:
        c += weight * sum(evidence[p][k:ell + 1])
    return c


def decode_naive(deltas, starts, tau, reject=None, slack=0, evidence=None, weight=0.0,
                 boundaries=(), segment_cost=0.0):
    """([(label, first, last, Δ at the end)] of the least-cost partition, its total cost);
    ties: unlabelled frame, then smaller label, then earlier start; touching segments of a
    label merged within a document."""
    P, L = len(deltas), len(deltas[0]) if deltas else 0
    reject = reject if reject is not None else [math.inf] * P
    first = _first(L, boundaries)
    # prefix sums of the evidence, added in frame order (as the kernel's cumulative sums):
    # ties between partitions are decided by the same floating-point values
    prefix = []
    for p in range(P):
        acc, row = 0.0, [0.0]
        for t in range(L):
            acc += evidence[p][t] if weight else 0.0
            row.append(acc)
        prefix.append(row)
    best = [0.0] + [math.inf] * L
    back = [None] * (L + 1)
    for ell in range(L):
        b, choice = best[ell] + 1.0, (ell, -1)
        for p, k, per in _options(deltas, starts, tau, reject, slack, first, ell):
            c = best[k] + (ell - k + 1) * per + segment_cost
            if weight:
                c += weight * (prefix[p][ell + 1] - prefix[p][k])
            if c < b:
                b, choice = c, (k, p)
        best[ell + 1], back[ell + 1] = b, choice
    segs, j = [], L
    while j > 0:
        k, p = back[j]
        if p >= 0:
            segs.append((p, k, j - 1, float(deltas[p][j - 1])))
        j = k
    segs.reverse()
    out = []
    for s in segs:
        if out and out[-1][0] == s[0] and out[-1][2] + 1 == s[1] and first[s[1]] == first[out[-1][2]]:
            out[-1] = (s[0], out[-1][1], s[2], min(out[-1][3], s[3]))
        else:
            out.append(s)
    return out, best[L]


def least_cost_exhaustive(deltas, starts, tau, reject=None, slack=0, evidence=None, weight=0.0,
                          boundaries=(), segment_cost=0.0):
    """The least total cost over every partition of the frames into unlabelled frames
    (cost 1) and admissible segments, by trying them all (short documents only)."""
    P, L = len(deltas), len(deltas[0]) if deltas else 0
    reject = reject if reject is not None else [math.inf] * P
    first = _first(L, boundaries)
    segments = []  # (first frame, last frame, cost)
    for ell in range(L):
        for p, k, per in _options(deltas, starts, tau, reject, slack, first, ell):
            segments.append((k, ell, _segment_cost(k, ell, p, per, evidence, weight,
                                                   segment_cost)))

    def rest(j):
        if j == L:
            return 0.0
        best = 1.0 + rest(j + 1)
        for k, ell, c in segments:
            if k == j:
                best = min(best, c + rest(ell + 1))
        return best

    return rest(0)


def best_column_naive(X, values):
    """Per frame: the least fraction of disagreeing fixed entries over the columns of the
    quantized template ``values`` that fix at least one entry (0 if none does)."""
    f, L = len(X), len(X[0])
    cols = [[i for i in range(f) if values[i][k] != 0.5] for k in range(len(values[0]))]
    cols = [(k, rows) for k, rows in enumerate(cols) if rows]
    out = []
    for t in range(L):
        if not cols:
            out.append(0.0)
            continue
        out.append(min(sum(1 for i in rows if int(values[i][k]) != int(X[i][t])) / len(rows)
                       for k, rows in cols))
    return out
