"""Slow, obviously-correct time alignment: the oracles of the alignment tests.

Written from the text of mtanno/align/dtw.py and coarse.py: the whole cost matrix as lists of
Python floats (+∞ outside the area), the accumulated costs with the chosen step of every
cell, the path by backtracking; the area as a set of cells built rectangle by rectangle.
"""

from __future__ import annotations

import math


def pose_cost_naive(PA, PB, a, b):
    """Mean over joints of the Euclidean distance between pose a of PA and pose b of PB
    (frames × joints × 3)."""
    J = len(PA[a])
    return sum(math.sqrt(sum((float(PA[a][j][k]) - float(PB[b][j][k])) ** 2 for k in range(3)))
               for j in range(J)) / J


def code_cost_naive(CA, CB, a, b, n_features, phases=None, tie=0.0):
    """Differing features / n_features (+ tie × phase difference)."""
    diff = bin(int(CA[a]) ^ int(CB[b])).count("1") / n_features
    if phases is not None:
        diff += tie * abs(float(phases[0][a]) - float(phases[1][b]))
    return diff


def dtw_naive(cost, n, m, cells=None, wa=None, wb=None):
    """(path, total) of DTW with steps diagonal, A advances, B advances (ties in that
    order), step weights max(wa, wb), wa, wb; ``cost(a, b)``; ``cells`` the set of cells
    computed (None: all)."""
    wa = wa if wa is not None else [1.0] * n
    wb = wb if wb is not None else [1.0] * m
    inf = math.inf
    D = [[inf] * m for _ in range(n)]
    step = [[None] * m for _ in range(n)]
    for a in range(n):
        for b in range(m):
            if cells is not None and (a, b) not in cells:
                continue
            c = cost(a, b)
            if a == 0 and b == 0:
                D[0][0] = c * max(wa[0], wb[0])
                step[0][0] = "start"
                continue
            options = []
            if a > 0 and b > 0:
                options.append((D[a - 1][b - 1] + c * max(wa[a], wb[b]), "diag"))
            if a > 0:
                options.append((D[a - 1][b] + c * wa[a], "up"))
            if b > 0:
                options.append((D[a][b - 1] + c * wb[b], "left"))
            best = min(v for v, _ in options)
            if best < inf:
                D[a][b] = best
                step[a][b] = next(s for v, s in options if v == best)
    path = [(n - 1, m - 1)]
    a, b = n - 1, m - 1
    while (a, b) != (0, 0):
        s = step[a][b]
        a, b = {"diag": (a - 1, b - 1), "up": (a - 1, b), "left": (a, b - 1)}[s]
        path.append((a, b))
    return path[::-1], D[n - 1][m - 1]


def area_naive(seg_a, seg_b, pairs, band, n, m):
    """The set of cells of the matched pairs' rectangles widened by ``band``; segments as
    lists of (start, end) frames, pairs as (i, j)."""
    cells = set()
    for i, j in pairs:
        (s, e), (t, u) = seg_a[i], seg_b[j]
        for a in range(max(0, s - band), min(n - 1, e + band) + 1):
            for b in range(max(0, t - band), min(m - 1, u + band) + 1):
                cells.add((a, b))
    return cells


def segments_naive(codes):
    """Maximal runs of equal codes as (start, end, code)."""
    out = []
    for t, c in enumerate(codes):
        if out and out[-1][2] == c:
            out[-1] = (out[-1][0], t, c)
        else:
            out.append((t, t, c))
    return out
