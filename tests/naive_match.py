"""Slow, obviously-correct template matching and hit extraction: the oracles of the tests.

Written straight from the text of docs/method.md §3.4–3.5, docs/method/features.md §A and
the retrieval README: full cost matrix, full accumulated-cost matrix with the chosen step of
every cell, starts found by backtracking (not propagated), hits by repeated argmin over a
copy of Δ.
Pure Python loops over Python floats; no packing, no streaming.
"""

from __future__ import annotations

import math

import numpy as np


def expand_naive(values, weights):
    """Reference expansion: column i repeated max(1, round(w_i)) times (half away from zero),
    each copy of weight w_i / copies."""
    cols, ws = [], []
    for i in range(values.shape[1]):
        w = float(weights[i])
        r = max(1, math.floor(w + 0.5))  # weights are non-negative
        for _ in range(r):
            cols.append(values[:, i])
            ws.append(w / r)
    return np.array(cols).T, ws


def cost_matrix_naive(values, weights, X, variant):
    """Local cost C[k][l] as a list of lists (docs/method.md §3.4,
    docs/method/features.md §A)."""
    if variant == "reference":
        V, ws = expand_naive(values, weights)
    else:
        V, ws = values, [1.0] * values.shape[1]
    f, K = V.shape
    L = X.shape[1]
    C = [[0.0] * L for _ in range(K)]
    for k in range(K):
        rows = [i for i in range(f) if V[i, k] != 0.5]
        for j in range(L):
            m = sum(1 for i in rows if int(V[i, k]) != int(X[i, j]))
            if variant == "reference":
                C[k][j] = m / K * ((ws[k] + 1) / (2 * max(1, len(rows))))
            else:
                C[k][j] = m / len(rows) if rows else 0.0
    return C


def match_naive(values, weights, X, *, variant="reference", steps=((1, 1), (1, 2), (2, 1)),
                step_weights=(1, 1, 2)):
    """(delta, start) like match_template, from the full matrices."""
    values = np.asarray(values, dtype=float)
    X = np.asarray(X)
    C = cost_matrix_naive(values, weights, X, variant)
    K, L = len(C), X.shape[1]
    inf = math.inf
    D = [[inf] * L for _ in range(K)]
    choice = [[-1] * L for _ in range(K)]
    for j in range(L):
        D[0][j] = C[0][j]
    for j in range(L):  # columns left to right, rows bottom to top: every predecessor is done
        for k in range(1, K):
            best_key, best_val, best_s = inf, inf, -1
            for s, ((di, dj), w) in enumerate(zip(steps, step_weights)):
                pk, pj = k - di, j - dj
                if pk < 0 or pj < 0 or D[pk][pj] == inf:
                    continue
                val = D[pk][pj] + w * C[k][j]
                # reference: the smallest predecessor wins; paper: the smallest sum wins
                key = D[pk][pj] if variant == "reference" else val
                if key < best_key:
                    best_key, best_val, best_s = key, val, s
            D[k][j] = best_val
            choice[k][j] = best_s
    delta = np.full(L, inf)
    start = np.full(L, -1, dtype=np.int64)
    for e in range(L):
        if D[K - 1][e] == inf:
            continue
        delta[e] = D[K - 1][e] / (1 if variant == "reference" else K)
        k, j = K - 1, e
        while k > 0 and j > 0:  # backtrack the stored choices until row 1 or column 1
            di, dj = steps[choice[k][j]]
            k, j = k - di, j - dj
        start[e] = j  # then straight up to row 1
    return delta, start


def hits_naive(delta, start, *, tau, mode, max_hits, end_excl=(0.5, 0.1), start_excl=(0.1, 0.5)):
    """Greedy hits as the retrieval README describes them (plus the reference code's rule that a
    dropped candidate's end zone is measured with the covering hit's length); returns
    (hits, truncated) with hits as (start, end, cost) tuples. ``truncated``: the cap stopped a
    hit that would have been recorded."""
    work = [math.inf if not (x <= tau) else float(x) for x in delta]
    n = len(work)
    covering_len = [0] * n  # length of the latest recorded hit whose start zone covers t
    hits = []
    while True:
        c = min(work) if work else math.inf
        if not c <= tau:
            return hits, False
        e = work.index(c)  # lowest frame on ties
        s = int(start[e])
        length = e - s + 1
        if mode == "retrieval":
            record = covering_len[s] == 0
            if not record:  # the dropped candidate's end zone uses the covering hit's length
                length = covering_len[s]
            lo, hi = e - math.ceil(end_excl[0] * length), e + math.ceil(end_excl[1] * length)
        else:
            record = True
            lo, hi = s, e
        if record and len(hits) == max_hits:
            return hits, True
        for t in range(max(0, lo), min(n - 1, hi) + 1):
            work[t] = math.inf
        if record:
            hits.append((s, e, c))
            if mode == "retrieval":
                lo = s - math.ceil(start_excl[0] * length)
                hi = s + math.ceil(start_excl[1] * length)
                for t in range(max(0, lo), min(n - 1, hi) + 1):
                    covering_len[t] = length
