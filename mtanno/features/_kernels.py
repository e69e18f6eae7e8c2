"""Numba kernel that evaluates a compiled feature table on one document.

The feature tables (:mod:`mtanno.features.table`, :mod:`mtanno.features.table31`) are
compiled by :mod:`mtanno.features` into integer and float arrays (measure code, joint
indices, measure parameters, velocity window, interval bounds of the two tests); this kernel
interprets them row by row: the measure for every frame (docs/method/features.md §5,
docs/method/features31.md §3–4), both tests, and the hysteresis (docs/method/features.md
§4). It performs the same floating-point operations in the same order as the readable numpy
versions in ``tests/naive_features.py``, which the tests hold it to, bit for bit.

Capsule ("touch") rows (docs/method/features31.md §4) are special: their threshold k scales
a per-frame radius k·c·ℓ(t), so the measure is evaluated once per test, as min over the
row's capsule tests of d − (k·c)·ℓ, and a test holds where that value is ≤ 0 (the sign of
a float difference is exact, so this is the same as d ≤ k·c·ℓ).
"""

from __future__ import annotations

import math

import numba
import numpy as np

# measure codes (see mtanno.features.compute.MEASURE_CODES)
PLANE, PLANE_DIFF, NPLANE, NPLANE_ABS, MOVE_PLANE, MOVE_DIR, MOVE_DIFF, CROSSOVER = range(8)
ANGLE, ANGLE_UP, FAST, RAISED, EXTENT_Y, EXTENT_XZ, HEADING_RATE = range(8, 15)
HEIGHT, ANGLE_MAX, TOUCH = range(15, 18)

_RAD2DEG = 180.0 / math.pi


@numba.njit(cache=True, inline="always")
def _reflect(i, m):
    while i < 0 or i >= m:
        i = -i - 1 if i < 0 else 2 * m - i - 1
    return i


@numba.njit(cache=True)
def _velocity(J, q, p, fps, L, out, u, c):
    """Velocity of P_q − P_p (p < 0: of P_q) into ``out`` (frames × 3);
    docs/method/features.md §3.

    ``u`` and ``c`` are scratch arrays of at least max(frames, L) + L + 2 rows."""
    n = J.shape[0]
    h = (L + 1) // 2
    for k in range(3):
        for t in range(n - 1):
            a = J[t + 1, q, k] - J[t + 1, p, k] if p >= 0 else J[t + 1, q, k]
            b = J[t, q, k] - J[t, p, k] if p >= 0 else J[t, q, k]
            u[t] = a - b
        if n >= 2:
            u[n - 1] = u[n - 2]
        else:
            u[0] = 0.0
        if L == 1:
            for t in range(n):
                out[t, k] = fps * u[t]
            continue
        m = n
        if n < L:
            for i in range(n, L):
                u[i] = u[_reflect(i, n)]
            m = L
        # c[j] = sum of the first j padded samples; padded[j] = u[reflect(j − h, m)]
        c[0] = 0.0
        for j in range(n + L):
            c[j + 1] = c[j] + u[_reflect(j - h, m)]
        scale = fps / L
        for t in range(n):
            out[t, k] = (c[t + L + 1] - c[t + 1]) * scale


@numba.njit(cache=True, inline="always")
def _dot3(a0, a1, a2, b0, b1, b2):
    return a0 * b0 + a1 * b1 + a2 * b2


@numba.njit(cache=True, inline="always")
def _angle(u0, u1, u2, v0, v1, v2):
    cos = _dot3(u0, u1, u2, v0, v1, v2) / (math.sqrt(_dot3(u0, u1, u2, u0, u1, u2))
                                            * math.sqrt(_dot3(v0, v1, v2, v0, v1, v2)))
    if cos > 1.0:
        cos = 1.0
    elif cos < -1.0:
        cos = -1.0
    return math.acos(cos) * _RAD2DEG


@numba.njit(cache=True, inline="always")
def _normal(J, t, a, b, c):
    """unit((P_a − P_c) × (P_b − P_c)) at frame t."""
    x0 = J[t, a, 0] - J[t, c, 0]
    x1 = J[t, a, 1] - J[t, c, 1]
    x2 = J[t, a, 2] - J[t, c, 2]
    y0 = J[t, b, 0] - J[t, c, 0]
    y1 = J[t, b, 1] - J[t, c, 1]
    y2 = J[t, b, 2] - J[t, c, 2]
    n0 = x1 * y2 - x2 * y1
    n1 = x2 * y0 - x0 * y2
    n2 = x0 * y1 - x1 * y0
    s = math.sqrt(_dot3(n0, n1, n2, n0, n1, n2))
    return n0 / s, n1 / s, n2 / s


@numba.njit(cache=True, inline="always")
def _direction(J, t, a, b):
    """unit(P_b − P_a) at frame t."""
    d0 = J[t, b, 0] - J[t, a, 0]
    d1 = J[t, b, 1] - J[t, a, 1]
    d2 = J[t, b, 2] - J[t, a, 2]
    s = math.sqrt(_dot3(d0, d1, d2, d0, d1, d2))
    return d0 / s, d1 / s, d2 / s


@numba.njit(cache=True, inline="always")
def _rel(J, t, q, c):
    return J[t, q, 0] - J[t, c, 0], J[t, q, 1] - J[t, c, 1], J[t, q, 2] - J[t, c, 2]


@numba.njit(cache=True, error_model="numpy")
def _measure_row(J, heading, fps, kind, jx, L, val, v1, v2, u, c):
    """Fill ``val`` (frames) with the row's measure (NaN where undefined).

    ``error_model="numpy"``: a zero-length direction or normal gives NaN (whose tests are
    false, docs/method/features.md §5) instead of raising ZeroDivisionError; other values
    are the same."""
    # one kernel: every measure kind in one pass over the frames; split by kind, each
    # frame's joints would be loaded once per kind in the stage's hottest loop
    n = J.shape[0]
    if kind == MOVE_PLANE:
        _velocity(J, jx[3], jx[2], fps, L, v1, u, c)
    elif kind == MOVE_DIR:
        _velocity(J, jx[2], jx[3], fps, L, v1, u, c)
    elif kind == MOVE_DIFF:
        _velocity(J, jx[2], jx[1], fps, L, v1, u, c)
        _velocity(J, jx[3], jx[1], fps, L, v2, u, c)
    elif kind == FAST:
        _velocity(J, jx[0], -1, fps, L, v1, u, c)
        if jx[1] >= 0:
            _velocity(J, jx[1], -1, fps, L, v2, u, c)
    for t in range(n):
        if kind == PLANE:
            n0, n1, n2 = _normal(J, t, jx[0], jx[1], jx[2])
            d0, d1, d2 = _rel(J, t, jx[3], jx[2])
            val[t] = _dot3(n0, n1, n2, d0, d1, d2)
        elif kind == PLANE_DIFF:
            n0, n1, n2 = _normal(J, t, jx[0], jx[1], jx[2])
            d0, d1, d2 = _rel(J, t, jx[3], jx[2])
            e0, e1, e2 = _rel(J, t, jx[4], jx[2])
            val[t] = _dot3(n0, n1, n2, d0, d1, d2) - _dot3(n0, n1, n2, e0, e1, e2)
        elif kind == NPLANE or kind == NPLANE_ABS:
            n0, n1, n2 = _direction(J, t, jx[0], jx[1])
            d0, d1, d2 = _rel(J, t, jx[2], jx[3])
            x = _dot3(n0, n1, n2, d0, d1, d2)
            val[t] = abs(x) if kind == NPLANE_ABS else x
        elif kind == MOVE_PLANE:
            n0, n1, n2 = _normal(J, t, jx[0], jx[1], jx[2])
            val[t] = _dot3(n0, n1, n2, v1[t, 0], v1[t, 1], v1[t, 2])
        elif kind == MOVE_DIR:
            n0, n1, n2 = _direction(J, t, jx[0], jx[1])
            val[t] = _dot3(n0, n1, n2, v1[t, 0], v1[t, 1], v1[t, 2])
        elif kind == MOVE_DIFF:
            n0, n1, n2 = _direction(J, t, jx[0], jx[1])
            val[t] = (_dot3(n0, n1, n2, v1[t, 0], v1[t, 1], v1[t, 2])
                      - _dot3(n0, n1, n2, v2[t, 0], v2[t, 1], v2[t, 2]))
        elif kind == CROSSOVER:
            n0, n1, n2 = _direction(J, t, jx[0], jx[1])
            r0, r1, r2 = _rel(J, t, jx[3], jx[0])
            l0, l1, l2 = _rel(J, t, jx[2], jx[0])
            val[t] = _dot3(n0, n1, n2, r0, r1, r2) - _dot3(n0, n1, n2, l0, l1, l2)
        elif kind == ANGLE:
            a0, a1, a2 = _rel(J, t, jx[0], jx[1])
            b0, b1, b2 = _rel(J, t, jx[2], jx[3])
            val[t] = _angle(a0, a1, a2, b0, b1, b2)
        elif kind == ANGLE_UP:
            a0, a1, a2 = _rel(J, t, jx[0], jx[1])
            val[t] = _angle(a0, a1, a2, 0.0, 1.0, 0.0)
        elif kind == FAST:
            s = math.sqrt(_dot3(v1[t, 0], v1[t, 1], v1[t, 2], v1[t, 0], v1[t, 1], v1[t, 2]))
            if jx[1] >= 0:
                s2 = math.sqrt(_dot3(v2[t, 0], v2[t, 1], v2[t, 2],
                                     v2[t, 0], v2[t, 1], v2[t, 2]))
                if s2 < s or s2 != s2:
                    s = s2
            val[t] = s
        elif kind == RAISED:
            lo = np.inf
            for k in range(J.shape[1]):
                skip = False
                for e in range(1, jx.shape[0]):
                    if jx[e] == k:
                        skip = True
                if not skip and J[t, k, 1] < lo:
                    lo = J[t, k, 1]
            val[t] = J[t, jx[0], 1] - lo
        elif kind == EXTENT_Y:
            lo = np.inf
            hi = -np.inf
            for k in range(J.shape[1]):
                y = J[t, k, 1]
                lo = min(lo, y)
                hi = max(hi, y)
            val[t] = hi - lo
        elif kind == EXTENT_XZ:
            best = -np.inf
            m = 0
            while m < jx.shape[0] and jx[m] >= 0:
                m += 1
            for s_ in range(m):
                for t_ in range(s_ + 1, m):
                    dx = J[t, jx[s_], 0] - J[t, jx[t_], 0]
                    dz = J[t, jx[s_], 2] - J[t, jx[t_], 2]
                    best = max(best, math.sqrt(dx * dx + dz * dz))
            val[t] = best
        elif kind == HEIGHT:
            val[t] = J[t, jx[0], 1] - J[t, jx[1], 1]
        elif kind == ANGLE_MAX:
            a0, a1, a2 = _rel(J, t, jx[0], jx[1])
            b0, b1, b2 = _rel(J, t, jx[2], jx[3])
            x = _angle(a0, a1, a2, b0, b1, b2)
            a0, a1, a2 = _rel(J, t, jx[4], jx[5])
            b0, b1, b2 = _rel(J, t, jx[6], jx[7])
            y = _angle(a0, a1, a2, b0, b1, b2)
            if x != x or y != y:
                val[t] = np.nan
            else:
                val[t] = x if x >= y else y
        elif kind == HEADING_RATE:
            if t + 1 < n:
                val[t] = _angle(heading[t, 0], 0.0, heading[t, 2],
                                heading[t + 1, 0], 0.0, heading[t + 1, 2]) * fps
            else:
                val[t] = 0.0


@numba.njit(cache=True, inline="always")
def _capsule(J, t, a, b, q, c, ball_a, ball_b, k):
    """d − (k·c)·ℓ for point q and the capsule around segment a→b
    (docs/method/features31.md §4).

    ℓ = |P_b − P_a| at frame t; d is the distance of P_q from the segment's line, or from
    an end ball where q projects before a / beyond b (∞ without a ball there)."""
    r0, r1, r2 = _rel(J, t, b, a)
    ell = math.sqrt(_dot3(r0, r1, r2, r0, r1, r2))
    u0 = r0 / ell
    u1 = r1 / ell
    u2 = r2 / ell
    w0, w1, w2 = _rel(J, t, q, a)
    x0 = w1 * u2 - w2 * u1
    x1 = w2 * u0 - w0 * u2
    x2 = w0 * u1 - w1 * u0
    d = math.sqrt(_dot3(x0, x1, x2, x0, x1, x2))
    if _dot3(u0, u1, u2, w0, w1, w2) < 0.0:
        d = math.sqrt(_dot3(w0, w1, w2, w0, w1, w2)) if ball_a != 0.0 else np.inf
    e0, e1, e2 = _rel(J, t, q, b)
    if _dot3(u0, u1, u2, e0, e1, e2) > 0.0:
        d = math.sqrt(_dot3(e0, e1, e2, e0, e1, e2)) if ball_b != 0.0 else np.inf
    return d - (k * c) * ell


@numba.njit(cache=True, error_model="numpy")
def _touch_row(J, jx, prm, k, val):
    """Fill ``val`` with min over the row's capsule tests of d − (k·c)·ℓ (NaN tests are
    skipped; NaN if all are NaN, e.g. a rig whose fingertip is its wrist has ℓ = 0). ``jx``
    holds (a, b, q) triples, ``prm`` (c, ball_a, ball_b) triples."""
    m = 0
    while 3 * m + 2 < jx.shape[0] and jx[3 * m] >= 0:
        m += 1
    for t in range(J.shape[0]):
        best = np.nan
        for i in range(m):
            x = _capsule(J, t, jx[3 * i], jx[3 * i + 1], jx[3 * i + 2],
                         prm[3 * i], prm[3 * i + 1], prm[3 * i + 2], k)
            if x == x and (best != best or x < best):
                best = x
        val[t] = best


@numba.njit(cache=True, inline="always")
def _inside(x, lo, lo_inc, hi, hi_inc):
    above = x >= lo if lo_inc else x > lo
    below = x <= hi if hi_inc else x < hi
    return above and below


@numba.njit(cache=True)
def features_kernel(J, heading, fps, kinds, joints, params, windows, on_b, on_inc, off_b,
                    off_inc, out):
    """Evaluate every row of a compiled table: measure, tests, hysteresis → ``out``.

    ``on_b``/``off_b`` are (rows × 2) lower/upper bounds, ``*_inc`` whether each is
    inclusive; ``params`` are (rows × p) measure parameters (touch rows only); ``out`` is
    (rows × frames) uint8. A touch row's tests are ``value ≤ k`` with k = the upper bound;
    the measure is evaluated with each k and compared with 0.
    """
    n = J.shape[0]
    rows = kinds.shape[0]
    size = max(n, int(windows.max())) + int(windows.max()) + 2
    u = np.empty(size)
    c = np.empty(size + 1)
    v1 = np.empty((n, 3))
    v2 = np.empty((n, 3))
    val = np.empty(n)
    val2 = np.empty(n)
    for r in range(rows):
        touch = kinds[r] == TOUCH
        if touch:
            _touch_row(J, joints[r], params[r], on_b[r, 1], val)
            _touch_row(J, joints[r], params[r], off_b[r, 1], val2)
        else:
            _measure_row(J, heading, fps, kinds[r], joints[r], windows[r], val, v1, v2, u, c)
        s = False
        prev_on = False
        prev_off = False
        for t in range(n):
            if touch:
                on = val[t] <= 0.0
                off = val2[t] <= 0.0
            else:
                on = _inside(val[t], on_b[r, 0], on_inc[r, 0], on_b[r, 1], on_inc[r, 1])
                off = _inside(val[t], off_b[r, 0], off_inc[r, 0], off_b[r, 1],
                              off_inc[r, 1])
            rise = on and not prev_on
            fall = t >= 1 and prev_off and not off
            s = (not fall) and (s or rise)
            out[r, t] = s
            prev_on = on
            prev_off = off
