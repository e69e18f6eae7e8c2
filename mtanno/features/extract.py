"""Feature extraction of one motion file: mocap file → Parquet feature file
(:func:`extract_file`; docs/method.md §1–2), the 30 Hz analysis frames, the per-frame
validity of marker files and the pose block. Batches of files (``mtanno features``):
:mod:`mtanno.features.batch`.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from mtanno._version import __version__
from mtanno.errors import MtannoError
from mtanno.features.compute import FeatureSet, compute_features, get_feature_set
from mtanno.features.hysteresis import ANALYSIS_FPS
from mtanno.features.store import write_features
from mtanno.features.table import FEATURE_SET
from mtanno.io import canonical_positions, find_asf, read_motion
from mtanno.io.formats import format_of
from mtanno.io.skeleton import Motion, to_y_up
from mtanno.util.provenance import sha256_file

#: Version of the extraction code (kinematics, measures, hysteresis, frame selection) apart
#: from the feature tables; raised when a change alters features. Feature files record it,
#: and outputs of another version are not up to date.
EXTRACTOR_VERSION = 1


def features_from_motion(motion: Motion, *, target_fps: float = ANALYSIS_FPS,
                         feature_set: str | FeatureSet = FEATURE_SET, up: str = "y",
                         ) -> tuple[np.ndarray, np.ndarray]:
    """(features × analysis frames) uint8 features and the 1-based native frame of each
    column; ``feature_set`` names the table (default the 40 annotation features); ``up``
    is the up axis of the motion's positions (:func:`to_y_up`; a motion from
    :func:`mtanno.io.read_motion` is already Y up)."""
    X, keep, _ = _motion_features(motion, get_feature_set(feature_set), up, target_fps)
    return X, keep + 1


def _named(exc: MtannoError, motion: Motion) -> MtannoError:
    """``exc`` naming the motion's file when it names none ("motion has no frames", …)."""
    if exc.path is None and motion.source:
        return MtannoError(exc.message, path=motion.source)
    return exc


def _motion_features(motion: Motion, fs: FeatureSet, up: str,
                     target_fps: float = ANALYSIS_FPS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Features at the analysis rate, their 0-based kept native frames and the canonical
    joint positions (native frames × 22 × 3, Y up) they were computed from."""
    P = to_y_up(canonical_positions(motion), up)
    try:
        X, keep = compute_features(P, to_y_up(motion.heading, up), motion.fps,
                                   target_fps=target_fps, features=fs.features)
    except MtannoError as exc:
        raise _named(exc, motion) from None
    return X, keep, P


def analysis_validity(valid: np.ndarray | None, keep: np.ndarray, fps: float) -> np.ndarray:
    """Validity of the analysis frames (kept native frames ``keep``, 0-based) of a motion
    whose native frames are ``valid`` (None: all valid): a frame is valid when no native
    frame within the longest velocity window (250 ms, docs/method/features.md §3) of it is invalid, so
    that no valid frame's features read interpolated joints."""
    if valid is None:
        return np.ones(keep.shape[0], dtype=bool)
    from mtanno.features.measures import window_samples

    reach = window_samples(250.0, fps)
    bad = np.convolve(~np.asarray(valid, bool), np.ones(2 * reach + 1), mode="same") > 0
    return ~bad[keep]


def invalid_runs(valid: np.ndarray) -> list[list[int]]:
    """The invalid rows of a feature file as [first, last] pairs, 1-based inclusive (the
    ``invalid`` entry of its metadata, docs/formats.md)."""
    m = np.concatenate([[False], ~np.asarray(valid, bool), [False]])
    edges = np.flatnonzero(m[1:] != m[:-1])
    return [[int(a) + 1, int(b)] for a, b in zip(edges[::2], edges[1::2])]


def poses_at(positions: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """The pose block of a feature file: (analysis frames × 22 × 3) float32 poses in leg
    lengths, :func:`mtanno.features.poses.normalize_poses` of the canonical joint
    positions (native frames × 22 × 3, Y up) at the kept native frames ``keep`` (0-based),
    as the alignment module normalises a motion's analysis frames."""
    from mtanno.features.poses import normalize_poses

    return normalize_poses(positions[keep]).astype(np.float32)


def extract_file(src: str | os.PathLike, dst: str | os.PathLike | None = None, *,
                 asf: str | os.PathLike | None = None,
                 skeleton: str | os.PathLike | None = None,
                 feature_set: str | FeatureSet = FEATURE_SET,
                 up: str | None = None, poses: bool = False,
                 markers: str | os.PathLike | None = None) -> tuple[np.ndarray, dict]:
    """Compute the features of one motion file; write them to ``dst`` if given.

    ``feature_set``: ``mr06-ak40`` (alias ``ak40``, default), ``mrc05`` or
    ``mrc05-reference``; its name is stored in the metadata. ``up``: the file's up axis,
    "y" or "z" (:func:`to_y_up`; None: the format's rule, Y for AMC and BVH, the file's
    for C3D), stored in the metadata. ``markers``: the marker set of a C3D file (TOML
    file or name; default the built-in set that fits). A motion with invalid frames (a
    marker file whose joints cannot all be computed) records them in the metadata's
    ``invalid`` rows (:func:`analysis_validity`). ``poses``: also store
    the normalised poses of the analysis frames (:func:`poses_at`; the file's pose block,
    described by the metadata's ``poses`` entry, ``docs/formats.md``); without it the file
    holds the features only. Returns the (features × frames) matrix and the metadata
    stored with it.
    """
    fs = get_feature_set(feature_set)
    src = Path(src)
    fmt = format_of(src)
    if fmt.skeleton_file is not None and asf is None:
        asf = find_asf(src)
    motion = read_motion(src, asf=asf, skeleton=skeleton, markers=markers, up=up,
                         sha256=True)
    X, keep, positions = _motion_features(motion, fs, "y")
    native = keep + 1
    block = None
    if poses:
        try:
            block = poses_at(positions, keep)
        except MtannoError as exc:  # legs of no length: say which motion
            raise _named(exc, motion) from None
    meta = {
        "document": src.stem,
        "source": str(src),
        "source_sha256": motion.source_sha256,
        "skeleton_file": None if asf is None else str(asf),
        "skeleton_file_sha256": None if asf is None else skeleton_digest(Path(asf)),
        "rig": motion.rig.kind,
        "native_fps": motion.fps,
        "native_frames": motion.n_frames,
        "analysis_fps": ANALYSIS_FPS,
        "analysis_frames": int(X.shape[1]),
        "frame_mapping": "native_frame = floor(k * native_fps / analysis_fps + 1/2) + 1 "
                         "for analysis frame k = 0, 1, ... (column native_frame)",
        "skeleton_map": motion.smap.name,
        "skeleton_map_file": motion.smap.path,
        "skeleton_map_sha256": motion.smap.digest,
        "rig_nodes": list(motion.rig.names) if motion.markers is None else
        list(motion.markers.markers.values()),
        "up": motion.up,
        "feature_set": fs.name,
        "feature_set_version": fs.version,
        "feature_table_sha256": fs.digest,
        "extractor_version": EXTRACTOR_VERSION,
        "feature_ids": [f.id for f in fs.features],
        "groups": {g: [fs.names[i] for i in rows] for g, rows in fs.groups.items()},
        "mtanno_version": __version__,
    }
    if up is None and fmt.up == "file":
        meta["up_from"] = "file"
    if motion.markers is not None or motion.valid is not None:
        valid = analysis_validity(motion.valid, keep, motion.fps)
        meta["invalid"] = invalid_runs(valid)
        if motion.markers is not None:
            meta["markers"] = _marker_meta(motion.markers)
    if block is not None:
        from mtanno.features.poses import pose_metadata

        meta["poses"] = pose_metadata()
    if dst is not None:
        write_features(dst, X, fs.names, native, meta, poses=block)
    return X, meta


def _marker_meta(report) -> dict:
    """What a marker file's feature file records of its markers (docs/formats.md)."""
    return {"set": report.set_name, "subject": report.subject, "units": report.units,
            "filled": report.filled, "lost": report.lost,
            "invalid_native_frames": report.n_invalid}


_DIGESTS: dict[tuple, str] = {}


def skeleton_digest(path: Path) -> str:
    """SHA-256 of a skeleton file, hashed once per batch: every AMC of an actor names the
    same ASF. Keyed by (device, inode, size, modification time), so a changed file is
    hashed again."""
    st = path.stat()
    key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
    digest = _DIGESTS.get(key)
    if digest is None:
        if len(_DIGESTS) > 256:
            _DIGESTS.clear()
        digest = _DIGESTS[key] = sha256_file(path)
    return digest
