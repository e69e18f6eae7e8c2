"""What alignment reads of a motion, and the pose normalisation of the pose distance ([MRC05] §7).

A :class:`Performance` is one motion prepared for alignment: its features at the analysis
rate (30 Hz) with the native frame each analysis frame was taken from, and — when it comes
from a motion file — the canonical joint positions at those same frames. Feature files
(``mtanno features`` output) give features only, so they can be aligned with the feature
cost but not with the pose distance.

The pose distance compares poses the way the original system's 3D point-cloud distance
(Kovar and Gleicher) does, without searching for the best rigid transformation: every pose
is moved so that its root stands at the origin of the floor plane, turned so that the body
faces one way and scaled by the actor's leg length (:func:`normalize_poses`, defined in
:mod:`mtanno.features.poses` since feature files may carry such poses, and re-exported
here). Distances are then in leg lengths.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.features import ANALYSIS_FPS, FEATURE_SET, FeatureSet, compute_features, get_feature_set
from mtanno.features.poses import body_scale, normalize_poses
from mtanno.features.store import FeatureLayout

__all__ = ["Performance", "body_scale", "load_performance", "normalize_poses",
           "performance_from_positions"]


@dataclass(frozen=True)
class Performance:
    """One motion prepared for alignment.

    Attributes
    ----------
    name:
        Document name (the file's stem).
    X:
        (features × n) uint8 0/1 features at the analysis rate.
    layout:
        Feature set, feature names and analysis frame rate of ``X``.
    native_frames:
        (n,) 1-based frame of the source motion file each analysis frame was taken from.
    groups:
        Feature group name → feature names (the feature set's index groups).
    joints:
        (n × 22 × 3) canonical joint positions (:data:`mtanno.io.CANONICAL_JOINTS` order) at
        the analysis frames, in the file's length unit; None for a feature file.
    path:
        The file it was read from (None when built from arrays).
    native_fps:
        Frame rate of the source motion file (None if unknown).
    """

    name: str
    X: np.ndarray
    layout: FeatureLayout
    native_frames: np.ndarray
    groups: dict[str, tuple[str, ...]] = field(default_factory=dict)
    joints: np.ndarray | None = None
    path: str | None = None
    native_fps: float | None = None

    @property
    def frames(self) -> int:
        """Number of analysis frames."""
        return int(self.X.shape[1])

    @property
    def where(self) -> str:
        """How messages name it: its path, else its name."""
        return self.path if self.path is not None else self.name


def _feature_set(feature_set: str | FeatureSet) -> FeatureSet:
    return feature_set if isinstance(feature_set, FeatureSet) else get_feature_set(feature_set)


def performance_from_positions(joints: np.ndarray, heading: np.ndarray, fps: float, *,
                               name: str, path: str | None = None,
                               feature_set: str | FeatureSet = FEATURE_SET) -> Performance:
    """A :class:`Performance` from canonical joint positions at the native rate.

    Parameters
    ----------
    joints:
        (native frames × 22 × 3) canonical joint positions, Y up, any length unit.
    heading:
        (native frames × 3) root heading vector (for the root-turning feature F40; see
        :class:`mtanno.io.Motion`).
    fps:
        Native frame rate in frames per second.
    name, path:
        Document name and source file (for messages and the output).
    feature_set:
        Feature set computed for stage 1 (default the 40 annotation features).
    """
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim == 3 and joints.shape[0] == 0:
        raise MtannoError("motion has no frames", path=path)
    fs = _feature_set(feature_set)
    try:
        X, keep = compute_features(joints, heading, fps, features=fs.features)
    except MtannoError as exc:
        if exc.path is None:
            raise MtannoError(exc.message, path=path) from None
        raise
    groups = {g: tuple(fs.names[i] for i in rows) for g, rows in fs.groups.items()}
    return Performance(name=name, X=X, layout=FeatureLayout(fs.name, tuple(fs.names),
                                                            ANALYSIS_FPS, f"motion {path or name}"),
                       native_frames=keep + 1, groups=groups,
                       joints=np.ascontiguousarray(joints[keep]), path=path,
                       native_fps=float(fps))


def load_performance(path: str | os.PathLike, *, asf: str | os.PathLike | None = None,
                     skeleton: str | os.PathLike | None = None,
                     feature_set: str | FeatureSet = FEATURE_SET) -> Performance:
    """Read a motion file (``.amc`` with its ASF, ``.bvh``) — features and canonical joint
    positions — or a feature file (``.parquet``, features only).

    ``asf``: the ASF of an AMC file (default: found beside or above it); ``skeleton``: a
    skeleton map instead of the detected one; ``feature_set``: the features computed for a
    motion file (a feature file keeps its own). Errors name the file.
    """
    spath = str(path)
    if Path(path).suffix.lower() == ".parquet":
        from mtanno.features.store import read_features

        ff = read_features(path)
        if ff.X.shape[1] == 0:
            raise MtannoError("feature file has no frames", path=spath)
        groups = {str(g): tuple(v) for g, v in (ff.meta.get("groups") or {}).items()}
        nfps = ff.meta.get("native_fps")
        return Performance(name=ff.document, X=ff.X, layout=ff.layout,
                           native_frames=ff.native_frames, groups=groups, joints=None,
                           path=spath, native_fps=float(nfps) if isinstance(
                               nfps, (int, float)) and not isinstance(nfps, bool) else None)
    from mtanno.io import canonical_positions, read_motion

    motion = read_motion(path, asf=asf, skeleton=skeleton)
    if motion.n_frames == 0:
        raise MtannoError("motion has no frames", path=spath)
    return performance_from_positions(canonical_positions(motion), motion.heading, motion.fps,
                                      name=Path(path).stem, path=spath, feature_set=feature_set)
