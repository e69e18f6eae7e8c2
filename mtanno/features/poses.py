"""Normalised poses: canonical joint positions made comparable across actors and rigs
([MRC05] §7, the pose distance of the alignment module; issue 26 part 3).

Every pose is moved so that its root stands at the origin of the floor plane (x = z = 0;
the height y is kept, so squatting and lying differ from standing), turned about the
vertical axis so that the body faces one way (the floor projection of the sum of the hip
axis lhip→rhip and the shoulder axis lshoulder→rshoulder along +x), and scaled by the
actor's leg length (mean over both legs of hip–knee plus knee–ankle in the first frame), so
that actors of different size and rigs of different length units compare. Positions are then
in leg lengths. This follows the 3D point-cloud distance of Kovar and Gleicher without its
search for the best rigid transformation.

It lives with the features because feature files may carry these poses at the analysis
frames (``mtanno features --poses``, ``docs/formats.md``); :mod:`mtanno.align.poses`
re-exports it for the pose distance.
"""

from __future__ import annotations

import numpy as np

from mtanno.errors import MtannoError
from mtanno.io.rigs import CANONICAL_JOINTS

__all__ = ["POSE_NORMALISATION", "POSE_UNIT", "body_scale", "normalize_poses",
           "pose_metadata"]

_J = {name: i for i, name in enumerate(CANONICAL_JOINTS)}

#: Length unit of normalised poses (the ``unit`` of a feature file's pose block).
POSE_UNIT = "leg lengths"
#: What the normalisation does, in words (the ``normalisation`` of a feature file's pose
#: block): a reader can tell poses normalised another way from these.
POSE_NORMALISATION = (
    "root at x = z = 0 (height kept), turned about the vertical so that the floor projection "
    "of (rhip - lhip) + (rshoulder - lshoulder) points along +x, divided by the leg length "
    "(mean of hip-knee + knee-ankle over both legs in the first frame); Y up")


def pose_metadata() -> dict:
    """The ``poses`` entry of a feature file's ``mtanno`` metadata for poses normalised by
    :func:`normalize_poses`: joint names (column order), unit and normalisation."""
    return {"joints": list(CANONICAL_JOINTS), "unit": POSE_UNIT,
            "normalisation": POSE_NORMALISATION}


def body_scale(joints: np.ndarray) -> float:
    """Leg length of a pose sequence in its length unit: the mean over both legs of the
    hip–knee plus knee–ankle distances in the first frame (``joints``: frames × 22 × 3,
    canonical order)."""
    P = np.asarray(joints, dtype=np.float64)[0]
    legs = [np.linalg.norm(P[_J[h]] - P[_J[k]]) + np.linalg.norm(P[_J[k]] - P[_J[a]])
            for h, k, a in (("lhip", "lknee", "lankle"), ("rhip", "rknee", "rankle"))]
    return float(np.mean(legs))


def normalize_poses(joints: np.ndarray) -> np.ndarray:
    """Poses normalised for root translation, heading and body size (module docstring).

    ``joints``: (frames × 22 × 3) canonical joint positions, Y up. Returns the same shape
    (float64) in leg lengths: root at x = z = 0, the body's left-to-right axis along +x. A
    frame whose hip and shoulder axes are vertical keeps the previous frame's turn.
    """
    P = np.asarray(joints, dtype=np.float64)
    if P.ndim != 3 or P.shape[1:] != (len(CANONICAL_JOINTS), 3) or P.shape[0] == 0:
        raise MtannoError(f"joints must be (frames × {len(CANONICAL_JOINTS)} × 3) with at "
                          f"least one frame, got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise MtannoError("joint positions contain NaN or infinite values")
    scale = body_scale(P)
    if not scale > 0:
        raise MtannoError("the legs have no length in the first frame (hip, knee and ankle "
                          "at one point): poses of this rig cannot be compared")
    axis = (P[:, _J["rhip"]] - P[:, _J["lhip"]]) + (P[:, _J["rshoulder"]] - P[:, _J["lshoulder"]])
    ux, uz = axis[:, 0].copy(), axis[:, 2].copy()
    norm = np.hypot(ux, uz)
    ok = norm > 1e-9 * scale
    if not ok.all():  # carry the last good direction forward (+x before the first one)
        idx = np.where(ok, np.arange(len(ok)), -1)
        np.maximum.accumulate(idx, out=idx)
        good = idx >= 0
        ux = np.where(good, ux[np.maximum(idx, 0)], 1.0)
        uz = np.where(good, uz[np.maximum(idx, 0)], 0.0)
        norm = np.where(good, norm[np.maximum(idx, 0)], 1.0)
    ux /= norm
    uz /= norm
    x = P[:, :, 0] - P[:, :1, 0]
    z = P[:, :, 2] - P[:, :1, 2]
    out = np.empty_like(P)
    # new axes: u = (ux, 0, uz) as x, y as y, u × y = (−uz, 0, ux) as z (a proper rotation)
    out[:, :, 0] = x * ux[:, None] + z * uz[:, None]
    out[:, :, 1] = P[:, :, 1]
    out[:, :, 2] = -x * uz[:, None] + z * ux[:, None]
    return out / scale
