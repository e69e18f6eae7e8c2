"""Real-valued measures behind the relational features, vectorised over frames.

Spec: ``features.md`` §2 (body units), §3 (velocities) and §5 (one measure per feature).
Positions are (frames × 3) arrays in the rig's length unit (cm for ASF), at the native frame
rate; velocities are in length units per second. Each measure function takes the dict of
canonical joint trajectories, the feature's joint tuple, the frame rate and the velocity
window, and returns one value per frame (or several for features whose tests must all pass).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from mtanno.io.rigs import CANONICAL_JOINTS


def body_units(P: dict[str, np.ndarray]) -> dict[str, float]:
    """Body measures from frame 1 (features.md §2), in the positions' length unit.

    ``hl`` right humerus, ``hlL`` left humerus, ``sw`` shoulder width, ``hw`` hip width,
    ``cl`` chest–neck length, ``BL`` body length (sum of seven segments).
    """

    def d(a: str, b: str) -> float:
        v = P[a][0] - P[b][0]
        return float(np.sqrt(v @ v))

    return {
        "hl": d("relbow", "rshoulder"),
        "hlL": d("lshoulder", "lelbow"),
        "sw": d("rshoulder", "lshoulder"),
        "hw": d("rhip", "lhip"),
        "cl": d("chest", "neck"),
        "BL": (d("rankle", "rknee") + d("rknee", "rhip") + d("root", "belly")
               + d("belly", "chest") + d("chest", "neck") + d("neck", "head")
               + d("head", "headtop")),
    }


def window_samples(window_ms: float, fps: float) -> int:
    """Moving-average length ``ceil(window_ms/1000 · fps)``, at least 1, in exact arithmetic.

    (In floats 0.1·120 = 12.000000000000002, whose ceiling would be 13.)
    """
    if window_ms <= 0:
        return 1
    exact = Fraction(window_ms) * Fraction(fps).limit_denominator(10**6) / 1000
    return max(1, math.ceil(exact))


def velocity(x: np.ndarray, fps: float, window_ms: float) -> np.ndarray:
    """Smoothed velocity of a (frames × d) trajectory (features.md §3), units per second.

    Forward differences with the last one repeated, symmetric padding of ``h = ceil(L/2)``
    samples at both ends, box average of ``L`` samples ``[t−h+1, t−h+L]``, times ``fps``.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    L = window_samples(window_ms, fps)
    h = (L + 1) // 2
    if n < 2:
        u = np.zeros_like(x)
    else:
        u = np.empty_like(x)
        u[:-1] = x[1:] - x[:-1]
        u[-1] = u[-2]
    if n < L:
        u = np.pad(u, ((0, L - n), (0, 0)), mode="symmetric")
    if L == 1:
        return fps * u[:n]
    padded = np.pad(u, ((h, h), (0, 0)), mode="symmetric")
    c = np.zeros((padded.shape[0] + 1, x.shape[1]))
    np.cumsum(padded, axis=0, out=c[1:])
    # sum over padded rows t+1 .. t+L (0-based t)
    s = c[L + 1:L + 1 + n] - c[1:1 + n]
    return s * (fps / L)


def _unit(v: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.sqrt(np.einsum("ij,ij->i", v, v))[:, None]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _plane_normal(P, a, b, c) -> np.ndarray:
    """unit((P_a − P_c) × (P_b − P_c)): normal of the oriented plane(a, b, c)."""
    return _unit(np.cross(P[a] - P[c], P[b] - P[c]))


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle between row vectors in degrees (real part of acos: clipped to [−1, 1])."""
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = _dot(u, v) / (np.sqrt(_dot(u, u)) * np.sqrt(_dot(v, v)))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def m_plane(P, j, fps, win):
    """Signed distance of q from plane(a, b, c) (F15, F16, F31)."""
    a, b, c, q = j
    return _dot(_plane_normal(P, a, b, c), P[q] - P[c])


def m_plane_diff(P, j, fps, win):
    """Signed distance of q1 minus that of q2 from plane(a, b, c) (F35, F36)."""
    a, b, c, q1, q2 = j
    n = _plane_normal(P, a, b, c)
    return _dot(n, P[q1] - P[c]) - _dot(n, P[q2] - P[c])


def m_nplane(P, j, fps, win):
    """unit(P_b − P_a) · (P_q − P_p) (F03, F04)."""
    a, b, q, p = j
    return _dot(_unit(P[b] - P[a]), P[q] - P[p])


def m_nplane_abs(P, j, fps, win):
    """|unit(P_b − P_a) · (P_q − P_p)| (F09, F19)."""
    return np.abs(m_nplane(P, j, fps, win))


def m_move_plane(P, j, fps, win):
    """Velocity of q relative to c along the normal of plane(a, b, c) (F01, F02)."""
    a, b, c, q = j
    return _dot(_plane_normal(P, a, b, c), velocity(P[q] - P[c], fps, win))


def m_move_dir(P, j, fps, win):
    """unit(P_b − P_a) · vel(P_q − P_p) (F05, F06, F10–F12)."""
    a, b, q, p = j
    return _dot(_unit(P[b] - P[a]), velocity(P[q] - P[p], fps, win))


def m_move_diff(P, j, fps, win):
    """n·vel(P_q1 − P_b) − n·vel(P_q2 − P_b) with n = unit(P_b − P_a) (F23, F24)."""
    a, b, q1, q2 = j
    n = _unit(P[b] - P[a])
    return _dot(n, velocity(P[q1] - P[b], fps, win)) - _dot(n, velocity(P[q2] - P[b], fps, win))


def m_crossover(P, j, fps, win):
    """d_R − d_L along unit(P_rhip − P_lhip), both measured from lhip (F22)."""
    lhip, rhip, lankle, rankle = j
    n = _unit(P[rhip] - P[lhip])
    return _dot(n, P[rankle] - P[lhip]) - _dot(n, P[lankle] - P[lhip])


def m_angle(P, j, fps, win):
    """Angle in degrees between (P_a − P_b) and (P_c − P_d)."""
    a, b, c, d = j
    return _angle(P[a] - P[b], P[c] - P[d])


def m_angle_up(P, j, fps, win):
    """Angle in degrees between (P_a − P_b) and the world up axis (F32)."""
    a, b = j
    up = np.zeros_like(P[a])
    up[:, 1] = 1.0
    return _angle(P[a] - P[b], up)


def m_fast(P, j, fps, win):
    """Speed of each joint; every one must pass the test (F13, F14, F25, F26, F39)."""
    return [np.sqrt(np.einsum("ij,ij->i", v, v)) for v in (velocity(P[q], fps, win) for q in j)]


def m_raised(P, j, fps, win):
    """Y(q) − min Y over the canonical joints except ``j[1:]`` (F17, F18, F33, F34)."""
    q, excluded = j[0], set(j[1:])
    ys = np.stack([P[k][:, 1] for k in CANONICAL_JOINTS if k not in excluded])
    return P[q][:, 1] - ys.min(axis=0)


def m_extent_y(P, j, fps, win):
    """Y_max − Y_min over all canonical joints (F37)."""
    ys = np.stack([P[k][:, 1] for k in CANONICAL_JOINTS])
    return ys.max(axis=0) - ys.min(axis=0)


def m_extent_xz(P, j, fps, win):
    """Largest pairwise distance in the floor (XZ) plane among the joints j (F38)."""
    xz = np.stack([P[k][:, [0, 2]] for k in j])
    best = np.zeros(xz.shape[1])
    for s in range(len(j)):
        for t in range(s + 1, len(j)):
            d = xz[s] - xz[t]
            np.maximum(best, np.sqrt(np.einsum("ij,ij->i", d, d)), out=best)
    return best


def heading_rate(heading: np.ndarray, fps: float) -> np.ndarray:
    """Root yaw rate in degrees per second (F40): angle between the XZ projections of the
    heading vector at frames t and t+1, times ``fps``; 0 at the last frame."""
    xz = heading[:, [0, 2]]
    out = np.zeros(heading.shape[0])
    if heading.shape[0] > 1:
        out[:-1] = _angle(xz[:-1], xz[1:]) * fps
    return out


MEASURES = {
    "plane": m_plane, "plane_diff": m_plane_diff, "nplane": m_nplane,
    "nplane_abs": m_nplane_abs, "move_plane": m_move_plane, "move_dir": m_move_dir,
    "move_diff": m_move_diff, "crossover": m_crossover, "angle": m_angle,
    "angle_up": m_angle_up, "fast": m_fast, "raised": m_raised, "extent_y": m_extent_y,
    "extent_xz": m_extent_xz,
}
