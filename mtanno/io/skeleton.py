"""Rig description and forward kinematics shared by the ASF/AMC and BVH readers.

Spec: ``docs/method.md`` §1 and ``docs/method/features.md`` §1.3–1.4. Both file formats
are reduced to one model: a tree of nodes, each with a local rotation

    L_j = pre_j · R_{a0}(θ0) · R_{a1}(θ1) · R_{a2}(θ2) · post_j

(three elementary rotations in the order they are multiplied, taken from the file's channel
or dof order) and a local translation (the node's constant offset, or per-frame translation
channels when the node has them, which replace the offset as in BVH). Global rotations
compose from the root: ``G_j = G_parent · L_j``.

Positions follow the file format's convention:

* ASF ("end point" rigs): a node is a bone and its position is the bone's *distal end*,
  ``P_j = P_parent + G_j · offset_j`` (the bone's own rotation acts on its own offset).
* BVH ("joint origin" rigs): ``P_j = P_parent + G_parent · offset_j``.

Units: lengths as given by the reader (centimetres for ASF, file units for BVH), angles in
radians, Y up.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np

from mtanno.errors import MtannoError

#: Axis codes used in :attr:`Rig.axes`.
AXIS_CODES = {"x": 0, "y": 1, "z": 2}


@dataclass
class Rig:
    """The static part of a skeleton: node tree, offsets and rotation layout.

    Attributes
    ----------
    kind:
        ``"asf"`` or ``"bvh"``.
    names:
        Node names; index 0 is the root. Every parent comes before its children.
    parents:
        Parent index per node, -1 for the root.
    offsets:
        (nodes × 3) constant local translation per node.
    axes:
        (nodes × 3) axis code (0 = x, 1 = y, 2 = z) of the three elementary rotations, in the
        order they are multiplied.
    pre, post:
        (nodes × 3 × 3) fixed matrices around the elementary rotations (ASF bone axis
        conjugation ``C … C⁻¹``; identity for BVH).
    end_point:
        True when node positions are bone end points (ASF), False for joint origins (BVH).
    source:
        The file the rig was read from (for messages).
    """

    kind: str
    names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    axes: np.ndarray
    pre: np.ndarray
    post: np.ndarray
    end_point: bool
    source: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def n_nodes(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of node ``name`` (exact match)."""
        return self.names.index(name)


@dataclass
class Motion:
    """Joint trajectories of one mocap document, in world coordinates (Y up).

    Attributes
    ----------
    rig:
        The skeleton the positions belong to.
    positions:
        (frames × nodes × 3) float64 world positions at the native frame rate.
    heading:
        (frames × 3) world direction of the skeleton map's heading axis on its root node
        (``G_root · axis``), used by the root-turning feature F40.
    fps:
        Native frame rate in frames per second, as read from the file.
    source:
        Path of the motion file.
    smap:
        The :class:`~mtanno.io.rigs.SkeletonMap` used to find canonical joints.
    source_sha256:
        SHA-256 (hex) of the motion file's bytes as parsed, when the reader was asked for
        it (``read_motion(..., sha256=True)``), else None.
    up:
        The file's up axis (``"y"`` or ``"z"``); ``positions`` and ``heading`` are already
        turned so that Y is up (:func:`to_y_up`).
    valid:
        (frames,) bool: frames whose joints could all be computed (marker files with gaps,
        :mod:`mtanno.io.markerjoints`), or None when every frame is valid. Positions of
        invalid frames are interpolated from their valid neighbours and carry no evidence.
    markers:
        What a marker file's joints were made from (:class:`mtanno.io.markerjoints.MarkerReport`:
        labels, marker set, which joints each marker feeds, gaps filled), else None.
    """

    rig: Rig
    positions: np.ndarray
    heading: np.ndarray
    fps: float
    source: str
    smap: Any = None
    source_sha256: str | None = None
    up: str = "y"
    valid: np.ndarray | None = None
    markers: Any = None

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])


#: The world axes a motion file may have pointing up (``features --up``); features are
#: defined for Y up (docs/method.md §1), Z-up data is turned first.
UP_AXES = ("y", "z")


def to_y_up(points: np.ndarray, up: str = "y") -> np.ndarray:
    """World coordinates (…, 3) of data whose up axis is ``up`` ("y" or "z") turned so that
    Y is up: for Z up, (x, y, z) → (x, z, −y), a rotation of −90° about X (right-handed
    frames stay right-handed, so left and right are kept)."""
    if up not in UP_AXES:
        raise MtannoError(f"up axis must be one of {', '.join(UP_AXES)}, got {up!r}")
    if up == "y":
        return points
    return np.stack([points[..., 0], points[..., 2], -points[..., 1]], axis=-1)


def euler_matrix(axis: int, angle: float) -> np.ndarray:
    """Right-handed rotation by ``angle`` radians about axis 0/1/2 (column vectors)."""
    c, s = np.cos(angle), np.sin(angle)
    m = np.eye(3)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m[i, i] = c
    m[j, j] = c
    m[i, j] = -s
    m[j, i] = s
    return m


@numba.njit(cache=True, inline="always")
def _rotate_into(out, axis, angle):
    """Right-multiply the 3×3 matrix ``out`` in place by R_axis(angle)."""
    c = np.cos(angle)
    s = np.sin(angle)
    i = (axis + 1) % 3
    j = (axis + 2) % 3
    for r in range(3):
        a = out[r, i]
        b = out[r, j]
        out[r, i] = a * c + b * s
        out[r, j] = -a * s + b * c


@numba.njit(cache=True)
def _fk_kernel(angles, trans, has_trans, parents, offsets, axes, pre, post, end_point,
               heading_node, heading_axis, positions, heading):
    """Forward kinematics for every frame; memory per frame is one (nodes × 3 × 3) scratch.

    Identity ``pre``/``post`` matrices and zero angles are skipped (most ASF bones have no
    axis rotation, and bones without dofs have no angles)."""
    n_frames, n_nodes = angles.shape[0], angles.shape[1]
    g = np.empty((n_nodes, 3, 3))
    loc = np.empty((3, 3))
    t = np.empty(3)
    eye = np.eye(3)
    pre_id = np.empty(n_nodes, dtype=np.bool_)
    post_id = np.empty(n_nodes, dtype=np.bool_)
    for j in range(n_nodes):
        pre_id[j] = (pre[j] == eye).all()
        post_id[j] = (post[j] == eye).all()
    for f in range(n_frames):
        for j in range(n_nodes):
            for r in range(3):
                for c in range(3):
                    loc[r, c] = pre[j, r, c]
            for k in range(3):
                a = angles[f, j, k]
                if a != 0.0:
                    _rotate_into(loc, axes[j, k], a)
            if not post_id[j]:
                for r in range(3):
                    a0 = loc[r, 0]
                    a1 = loc[r, 1]
                    a2 = loc[r, 2]
                    for c in range(3):
                        loc[r, c] = a0 * post[j, 0, c] + a1 * post[j, 1, c] + a2 * post[j, 2, c]
            if has_trans[j]:
                for k in range(3):
                    t[k] = trans[f, j, k]
            else:
                for k in range(3):
                    t[k] = offsets[j, k]
            p = parents[j]
            if p < 0:
                for r in range(3):
                    for c in range(3):
                        g[j, r, c] = loc[r, c]
                    positions[f, j, r] = t[r]
            else:
                for r in range(3):
                    for c in range(3):
                        g[j, r, c] = g[p, r, 0] * loc[0, c] + g[p, r, 1] * loc[1, c] + g[p, r, 2] * loc[2, c]
                q = j if end_point else p
                for r in range(3):
                    positions[f, j, r] = positions[f, p, r] + (
                        g[q, r, 0] * t[0] + g[q, r, 1] * t[1] + g[q, r, 2] * t[2])
        for r in range(3):
            heading[f, r] = (g[heading_node, r, 0] * heading_axis[0]
                             + g[heading_node, r, 1] * heading_axis[1]
                             + g[heading_node, r, 2] * heading_axis[2])


def forward_kinematics(rig: Rig, angles: np.ndarray, trans: np.ndarray, has_trans: np.ndarray,
                       *, heading_node: int = 0,
                       heading_axis: tuple[float, float, float] = (1.0, 0.0, 0.0),
                       ) -> tuple[np.ndarray, np.ndarray]:
    """World positions of every node and the heading vector for every frame.

    Parameters
    ----------
    rig:
        Static skeleton.
    angles:
        (frames × nodes × 3) rotation angles in radians, in the multiplication order of
        ``rig.axes``.
    trans:
        (frames × nodes × 3) translation channel values; only read where ``has_trans``.
    has_trans:
        (nodes,) bool: the node's translation comes from ``trans`` instead of its offset.
    heading_node, heading_axis:
        ``heading[f] = G_heading_node(f) · heading_axis`` (F40,
        docs/method/features.md §5.3).

    Returns
    -------
    positions, heading:
        (frames × nodes × 3) and (frames × 3) float64.
    """
    n_frames = angles.shape[0]
    positions = np.empty((n_frames, rig.n_nodes, 3))
    heading = np.empty((n_frames, 3))
    _fk_kernel(np.ascontiguousarray(angles, dtype=np.float64),
               np.ascontiguousarray(trans, dtype=np.float64),
               np.ascontiguousarray(has_trans, dtype=np.bool_),
               np.ascontiguousarray(rig.parents, dtype=np.int64),
               np.ascontiguousarray(rig.offsets, dtype=np.float64),
               np.ascontiguousarray(rig.axes, dtype=np.int64),
               np.ascontiguousarray(rig.pre, dtype=np.float64),
               np.ascontiguousarray(rig.post, dtype=np.float64),
               bool(rig.end_point), int(heading_node),
               np.asarray(heading_axis, dtype=np.float64), positions, heading)
    return positions, heading


@dataclass
class Channels:
    """Per-frame channel values of one motion file, laid out for :func:`forward_kinematics`.

    Attributes
    ----------
    angles:
        (frames × nodes × 3) radians, in the multiplication order of ``Rig.axes``.
    trans:
        (frames × nodes × 3) translation channel values (same length unit as the rig).
    has_trans:
        (nodes,) bool: which nodes take their translation from ``trans``.
    fps:
        Native frame rate read from the file (frames per second).
    sha256:
        SHA-256 (hex) of the file's bytes as parsed, when the reader was asked for it.
    absent:
        Bones the skeleton gives rotation dofs but the file gives no values in any frame
        (AMC), each with the line of the file's first frame: their rotations are zero,
        which :func:`mtanno.io.read_motion` refuses for a bone the skeleton map needs.
    """

    angles: np.ndarray
    trans: np.ndarray
    has_trans: np.ndarray
    fps: float
    sha256: str | None = None
    absent: dict[str, int] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.angles.shape[0])
