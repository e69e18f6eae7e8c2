"""Readable numpy versions of the feature measures: the oracle for the numba kernel.

Real-valued measures behind the relational features, vectorised over frames and features.

Spec: ``docs/method/features.md`` §2 (body units), ``docs/method/features.md`` §3
(velocities) and ``docs/method/features.md`` §5 (one measure per feature).
``J`` is the (frames × 22 × 3) array of canonical joint positions (``CANONICAL_JOINTS``
order) at the native frame rate, in the rig's length unit; velocities are in length units
per second. A measure function evaluates *several features of the same kind at once*:
``idx`` is a (k × m) array of joint indices, one row per feature in the meaning its
docstring gives, and the result is (frames × k). Batching keeps the number of numpy calls
per document small, which is what matters for short clips.
"""

from __future__ import annotations

import numpy as np

from mtanno.features.measures import window_samples
from mtanno.io.rigs import CANONICAL_JOINTS

_J = {name: k for k, name in enumerate(CANONICAL_JOINTS)}


def velocity(x: np.ndarray, fps: float, window_ms: float) -> np.ndarray:
    """Smoothed velocity of a trajectory (frames × …) (docs/method/features.md §3), units
    per second.

    Forward differences with the last one repeated, symmetric padding of ``h = ceil(L/2)``
    samples at both ends, box average of ``L`` samples ``[t−h+1, t−h+L]``, times ``fps``.
    Any trailing shape is allowed (one row per frame).
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    L = window_samples(window_ms, fps)
    h = (L + 1) // 2
    if n < 2:
        u = np.zeros_like(x)
    else:
        u = np.empty_like(x)
        np.subtract(x[1:], x[:-1], out=u[:-1])
        u[-1] = u[-2]
    if L == 1:
        return fps * u
    pad = [(0, 0)] * x.ndim
    if n < L:
        pad[0] = (0, L - n)
        u = np.pad(u, pad, mode="symmetric")
    pad[0] = (h, h)
    padded = np.pad(u, pad, mode="symmetric")
    c = np.zeros((padded.shape[0] + 1, *x.shape[1:]))
    np.cumsum(padded, axis=0, out=c[1:])
    # sum over padded rows t+1 .. t+L (0-based t)
    return (c[L + 1:L + 1 + n] - c[1:1 + n]) * (fps / L)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _unit(v: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.sqrt(_dot(v, v))[..., None]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def _plane_normal(J, a, b, c) -> np.ndarray:
    """unit((P_a − P_c) × (P_b − P_c)): normal of the oriented plane(a, b, c)."""
    return _unit(_cross(J[:, a] - J[:, c], J[:, b] - J[:, c]))


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle between vectors (last axis) in degrees; real part of acos (clipped to [−1, 1])."""
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = _dot(u, v) / (np.sqrt(_dot(u, u)) * np.sqrt(_dot(v, v)))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def m_plane(J, idx, fps, win):
    """Signed distance of q from plane(a, b, c); rows (a, b, c, q) (F15, F16, F31)."""
    a, b, c, q = idx.T
    return _dot(_plane_normal(J, a, b, c), J[:, q] - J[:, c])


def m_plane_diff(J, idx, fps, win):
    """Distance of q1 minus that of q2 from plane(a, b, c); rows (a, b, c, q1, q2) (F35, F36)."""
    a, b, c, q1, q2 = idx.T
    n = _plane_normal(J, a, b, c)
    return _dot(n, J[:, q1] - J[:, c]) - _dot(n, J[:, q2] - J[:, c])


def m_nplane(J, idx, fps, win):
    """unit(P_b − P_a) · (P_q − P_p); rows (a, b, q, p) (F03, F04)."""
    a, b, q, p = idx.T
    return _dot(_unit(J[:, b] - J[:, a]), J[:, q] - J[:, p])


def m_nplane_abs(J, idx, fps, win):
    """|unit(P_b − P_a) · (P_q − P_p)|; rows (a, b, q, p) (F09, F19)."""
    return np.abs(m_nplane(J, idx, fps, win))


def m_move_plane(J, idx, fps, win):
    """Velocity of q relative to c along the normal of plane(a, b, c); rows (a, b, c, q)
    (F01, F02)."""
    a, b, c, q = idx.T
    return _dot(_plane_normal(J, a, b, c), velocity(J[:, q] - J[:, c], fps, win))


def m_move_dir(J, idx, fps, win):
    """unit(P_b − P_a) · vel(P_q − P_p); rows (a, b, q, p) (F05, F06, F10–F12)."""
    a, b, q, p = idx.T
    return _dot(_unit(J[:, b] - J[:, a]), velocity(J[:, q] - J[:, p], fps, win))


def m_move_diff(J, idx, fps, win):
    """n·vel(P_q1 − P_b) − n·vel(P_q2 − P_b), n = unit(P_b − P_a); rows (a, b, q1, q2)
    (F23, F24)."""
    a, b, q1, q2 = idx.T
    n = _unit(J[:, b] - J[:, a])
    return (_dot(n, velocity(J[:, q1] - J[:, b], fps, win))
            - _dot(n, velocity(J[:, q2] - J[:, b], fps, win)))


def m_crossover(J, idx, fps, win):
    """d_R − d_L along unit(P_rhip − P_lhip), both from lhip; rows (lhip, rhip, lankle,
    rankle) (F22)."""
    lhip, rhip, lankle, rankle = idx.T
    n = _unit(J[:, rhip] - J[:, lhip])
    return _dot(n, J[:, rankle] - J[:, lhip]) - _dot(n, J[:, lankle] - J[:, lhip])


def m_angle(J, idx, fps, win):
    """Angle in degrees between (P_a − P_b) and (P_c − P_d); rows (a, b, c, d)."""
    a, b, c, d = idx.T
    return _angle(J[:, a] - J[:, b], J[:, c] - J[:, d])


def m_angle_up(J, idx, fps, win):
    """Angle in degrees between (P_a − P_b) and the world up axis; rows (a, b) (F32)."""
    a, b = idx.T
    v = J[:, a] - J[:, b]
    up = np.zeros_like(v)
    up[..., 1] = 1.0
    return _angle(v, up)


def m_fast(J, idx, fps, win):
    """Smallest speed among the joints of a row: every joint must pass (F13, F14, F25, F26,
    F39); rows (q1, q2, …)."""
    v = velocity(J[:, idx.ravel()], fps, win)
    speed = np.sqrt(_dot(v, v)).reshape(J.shape[0], *idx.shape)
    return speed.min(axis=2)


def m_raised(J, idx, fps, win):
    """Y(q) − min Y over the canonical joints except ``row[1:]``; rows (q, excluded…)
    (F17, F18, F33, F34)."""
    out = np.empty((J.shape[0], idx.shape[0]))
    for r, row in enumerate(idx):
        keep = np.setdiff1d(np.arange(J.shape[1]), row[1:])
        out[:, r] = J[:, row[0], 1] - J[:, keep, 1].min(axis=1)
    return out


def m_extent_y(J, idx, fps, win):
    """Y_max − Y_min over all canonical joints (F37)."""
    y = J[:, :, 1]
    return (y.max(axis=1) - y.min(axis=1))[:, None]


def m_extent_xz(J, idx, fps, win):
    """Largest pairwise distance in the floor (XZ) plane among a row's joints (F38)."""
    out = np.empty((J.shape[0], idx.shape[0]))
    for r, row in enumerate(idx):
        s, t = np.triu_indices(len(row), 1)
        d = J[:, row[s]][..., [0, 2]] - J[:, row[t]][..., [0, 2]]
        out[:, r] = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]).max(axis=1)
    return out


def m_height(J, idx, fps, win):
    """Y(q) − Y(p); rows (q, p) (31-set entries 3, 4)."""
    q, p = idx.T
    return J[:, q, 1] - J[:, p, 1]


def m_angle_max(J, idx, fps, win):
    """Larger of angle(P_a − P_b, P_c − P_d) and angle(P_e − P_f, P_g − P_h), NaN if either
    is NaN; rows (a, b, c, d, e, f, g, h) (31-set entry 26)."""
    return np.maximum(m_angle(J, idx[:, :4], fps, win), m_angle(J, idx[:, 4:], fps, win))


def m_touch(J, idx, params, k):
    """min over capsule tests of d − (k·c)·ℓ (docs/method/features31.md §4) for one row:
    ``idx`` is the flat (a, b, q, a, b, q, …) joint list, ``params`` the (c, ball_a,
    ball_b, …) list. NaN tests are skipped (the feature is their OR)."""
    best = np.full(J.shape[0], np.nan)
    for i in range(len(idx) // 3):
        a, b, q = idx[3 * i:3 * i + 3]
        c, ball_a, ball_b = params[3 * i:3 * i + 3]
        r = J[:, b] - J[:, a]
        ell = np.sqrt(_dot(r, r))
        u = r / ell[:, None]
        w = J[:, q] - J[:, a]
        d = np.sqrt(_dot(_cross(w, u), _cross(w, u)))
        before = _dot(u, w) < 0
        d = np.where(before, np.sqrt(_dot(w, w)) if ball_a else np.inf, d)
        e = J[:, q] - J[:, b]
        beyond = _dot(u, e) > 0
        d = np.where(beyond, np.sqrt(_dot(e, e)) if ball_b else np.inf, d)
        x = d - (k * c) * ell
        better = ~np.isnan(x) & (np.isnan(best) | (x < best))
        best = np.where(better, x, best)
    return best


def heading_rate(heading: np.ndarray, fps: float) -> np.ndarray:
    """Root yaw rate in degrees per second (F40): angle between the XZ projections of the
    heading vector at frames t and t+1, times ``fps``; 0 at the last frame."""
    xz = np.zeros_like(heading)
    xz[:, [0, 2]] = heading[:, [0, 2]]
    out = np.zeros(heading.shape[0])
    if heading.shape[0] > 1:
        out[:-1] = _angle(xz[:-1], xz[1:]) * fps
    return out


MEASURES = {
    "plane": m_plane, "plane_diff": m_plane_diff, "nplane": m_nplane,
    "nplane_abs": m_nplane_abs, "move_plane": m_move_plane, "move_dir": m_move_dir,
    "move_diff": m_move_diff, "crossover": m_crossover, "angle": m_angle,
    "angle_up": m_angle_up, "fast": m_fast, "raised": m_raised, "extent_y": m_extent_y,
    "extent_xz": m_extent_xz, "height": m_height, "angle_max": m_angle_max,
}


def _interval(V, spec, unit):
    with np.errstate(invalid="ignore"):
        if spec[0] == "in":
            return (V >= spec[1] * unit) & (V <= spec[2] * unit)
        return {">": np.greater, ">=": np.greater_equal, "<": np.less,
                "<=": np.less_equal}[spec[0]](V, spec[1] * unit)


def features_numpy(joints, heading, fps, features=None):
    """(features × frames) uint8 features computed with the numpy measures above (default
    table: the 40 annotation features)."""
    from mtanno.features import FEATURES
    from mtanno.features.hysteresis import hysteresis
    from mtanno.features.measures import body_units

    features = FEATURES if features is None else features
    units = body_units(joints)
    on = np.empty((len(features), len(joints)), bool)
    off = np.empty_like(on)
    for r, f in enumerate(features):
        if f.measure == "touch":
            idx = [CANONICAL_JOINTS.index(j) for j in f.joints]
            with np.errstate(invalid="ignore", divide="ignore"):
                on[r] = m_touch(joints, idx, f.params, f.on[1]) <= 0
                off[r] = m_touch(joints, idx, f.params, f.off[1]) <= 0
            continue
        if f.measure == "heading_rate":
            v = heading_rate(heading, fps)
        else:
            idx = np.array([[CANONICAL_JOINTS.index(j) for j in f.joints]]).reshape(1, -1)
            v = MEASURES[f.measure](joints, idx, fps, f.window_ms)[:, 0]
        u = 1.0 if f.unit is None else units[f.unit]
        on[r] = _interval(v, f.on, u)
        off[r] = _interval(v, f.off, u)
    return hysteresis(on, off)
