"""Relational features: joint positions → 40 boolean features per frame (algorithms.md §2).

:func:`compute_features` evaluates every row of :data:`~mtanno.features.table.FEATURES` at
the native frame rate (velocities and hysteresis included) and reduces the result to the
30 Hz analysis rate.
"""

from __future__ import annotations

import operator

import numpy as np

from mtanno.errors import MtannoError
from mtanno.features.hysteresis import ANALYSIS_FPS, analysis_frames, hysteresis
from mtanno.features.measures import MEASURES, body_units, heading_rate
from mtanno.features.table import (
    FEATURE_NAMES,
    FEATURE_SET,
    FEATURE_SET_VERSION,
    FEATURES,
    GROUPS,
    MIRROR_PAIRS,
    Feature,
    feature_index,
    mirror_permutation,
)
from mtanno.io.rigs import CANONICAL_JOINTS

__all__ = [
    "ANALYSIS_FPS", "FEATURES", "FEATURE_NAMES", "FEATURE_SET", "FEATURE_SET_VERSION",
    "GROUPS", "MIRROR_PAIRS", "Feature", "analysis_frames", "compute_features",
    "compute_features_native", "feature_index", "hysteresis", "mirror_permutation",
]

_OPS = {">": operator.gt, ">=": operator.ge, "<": operator.lt, "<=": operator.le}


def _test(values: np.ndarray, spec: tuple, unit: float) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        if spec[0] == "in":
            return (values >= spec[1] * unit) & (values <= spec[2] * unit)
        return _OPS[spec[0]](values, spec[1] * unit)


def compute_features_native(joints: np.ndarray, heading: np.ndarray, fps: float, *,
                            features: tuple[Feature, ...] = FEATURES) -> np.ndarray:
    """(features × native frames) uint8 feature matrix at the native rate (features.md §4–5).

    Parameters
    ----------
    joints:
        (frames × 22 × 3) canonical joint positions in :data:`CANONICAL_JOINTS` order, any
        length unit (thresholds are relative to body measures of frame 1), Y up.
    heading:
        (frames × 3) heading vector of the root (see :class:`~mtanno.io.skeleton.Motion`).
    fps:
        Native frame rate in frames per second.
    """
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (len(CANONICAL_JOINTS), 3):
        raise MtannoError(f"joints must be (frames × {len(CANONICAL_JOINTS)} × 3), "
                          f"got {joints.shape}")
    n = joints.shape[0]
    if n == 0:
        raise MtannoError("motion has no frames")
    P = {name: joints[:, k, :] for k, name in enumerate(CANONICAL_JOINTS)}
    units = body_units(P)
    on = np.empty((len(features), n), dtype=np.bool_)
    off = np.empty((len(features), n), dtype=np.bool_)
    cache: dict[tuple, object] = {}
    for r, f in enumerate(features):
        key = (f.measure, f.joints, f.window_ms)
        if key not in cache:
            if f.measure == "heading_rate":
                cache[key] = heading_rate(np.asarray(heading, dtype=np.float64), fps)
            else:
                cache[key] = MEASURES[f.measure](P, f.joints, fps, f.window_ms)
        values = cache[key]
        u = 1.0 if f.unit is None else units[f.unit]
        if isinstance(values, list):  # every value must pass (F25/F26)
            on[r] = np.logical_and.reduce([_test(v, f.on, u) for v in values])
            off[r] = np.logical_and.reduce([_test(v, f.off, u) for v in values])
        else:
            on[r] = _test(values, f.on, u)
            off[r] = _test(values, f.off, u)
    return hysteresis(on, off)


def compute_features(joints: np.ndarray, heading: np.ndarray, fps: float, *,
                     target_fps: float = ANALYSIS_FPS) -> tuple[np.ndarray, np.ndarray]:
    """Features at the analysis rate: ((40 × frames) uint8, kept native frame per column).

    The kept native frames are 0-based (see :func:`analysis_frames`).
    """
    native = compute_features_native(joints, heading, fps)
    keep = analysis_frames(native.shape[1], fps, target_fps)
    return np.ascontiguousarray(native[:, keep]), keep
