"""Slow, obviously-correct versions of mtanno's kernels, used as test oracles."""

from __future__ import annotations

import math

import numpy as np


def hysteresis_naive(on, off):
    """docs/method/features.md §4, written out literally (frames 1-based as in the spec)."""
    n = len(on)
    s = [0] * (n + 1)
    for t in range(1, n + 1):
        prev_on = on[t - 2] if t >= 2 else 0
        rise = bool(on[t - 1]) and not prev_on
        fall = t >= 2 and bool(off[t - 2]) and not off[t - 1]
        s[t] = int((not fall) and (s[t - 1] or rise))
    return np.array(s[1:], dtype=np.uint8)


def velocity_naive(x, fps, window_ms):
    """docs/method/features.md §3 literally: differences, mirror padding, explicit window sums."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    L = max(1, math.ceil(round(window_ms * fps) / 1000)) if window_ms else 1
    h = math.ceil(L / 2)
    u = [x[t + 1] - x[t] for t in range(n - 1)]
    u.append(u[-1] if u else np.zeros(x.shape[1]))
    while len(u) < L:  # extend by mirroring at the end
        u = u + u[::-1]
        u = u[:max(L, len(u))]
    u = u[:max(L, n)]

    def at(m):  # 1-based index into u with symmetric padding, repeated if needed
        m0 = m - 1
        size = len(u)
        while m0 < 0 or m0 >= size:
            m0 = -m0 - 1 if m0 < 0 else 2 * size - m0 - 1
        return u[m0]

    out = np.zeros((n, x.shape[1]))
    for t in range(1, n + 1):
        acc = np.zeros(x.shape[1])
        for m in range(t - h + 1, t - h + L + 1):
            acc = acc + at(m)
        out[t - 1] = fps * acc / L
    return out


def reduce_naive(n_native, fps, target=30.0):
    """Nearest native frame for each analysis frame time k/target, while k/target ≤ last."""
    out = []
    k = 0
    while k * fps / target <= n_native - 1 + 1e-9:
        out.append(min(int(math.floor(k * fps / target + 0.5 + 1e-9)), n_native - 1))
        k += 1
    return np.array(out)


def rot(axis, a):
    c, s = math.cos(a), math.sin(a)
    if axis == 0:
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == 1:
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def fk_naive(rig, ch):
    """Per frame, per node, plain matrices: the model of mtanno.io.skeleton's docstring."""
    F, J = ch.angles.shape[:2]
    P = np.zeros((F, J, 3))
    for f in range(F):
        G = [None] * J
        for j in range(J):
            L = rig.pre[j].copy()
            for k in range(3):
                L = L @ rot(int(rig.axes[j, k]), ch.angles[f, j, k])
            L = L @ rig.post[j]
            t = ch.trans[f, j] if ch.has_trans[j] else rig.offsets[j]
            p = rig.parents[j]
            if p < 0:
                G[j] = L
                P[f, j] = t
            else:
                G[j] = G[p] @ L
                P[f, j] = P[f, p] + (G[j] if rig.end_point else G[p]) @ t
    return P
