"""Peer check: world joint positions of a BVH file computed by pybvh (PyPI ``pybvh`` 0.9).

Used by ``tests/test_bvh.py`` and the benchmarks to validate :mod:`mtanno.io.bvh` against an
independent reader. pybvh's conventions (read from its source, ``pybvh/io.py`` and
``pybvh/spatial_coord.py``):

* angles in degrees in the file, radians in memory; per-joint Euler order from the CHANNELS
  line, ``R = R1 · R2 · R3`` in listed order (``rotations.euler_to_rotmat``), column vectors;
* joint origins: ``P_j = P_parent + G_parent · offset_j``, ``G_j = G_parent · L_j``; an End
  Site is a node named ``EndSite<parent>`` placed the same way;
* the root's position channels *replace* its offset (``P_root = root_pos``);
* ``Frame Time`` is snapped to ``1/N`` when within 0.01 % of it;
* it **rejects** position channels on any joint but the root, and a root without exactly
  3 position + 3 rotation channels.

The Bandai Namco files put 6 channels on every joint, so pybvh cannot read them as they are.
:func:`pybvh_compatible` rewrites such a file into an equivalent one pybvh accepts:

* position channels that only repeat the joint's OFFSET (every joint below Hips in the Bandai
  files, equal to it within 1e-5) are dropped;
* varying position channels on a child of an unrotated root (Bandai ``Hips`` under
  ``joint_Root``, whose rotation channels are all zero) are moved into the root translation:
  ``root_pos += t_child − offset_child``, which leaves every node below the root where it was
  but moves the root node itself, so the root is reported as not comparable.

Anything else raises ValueError. Run as a script to compare one file with mtanno::

    .venv/bin/python scripts/pybvh_peer.py FILE.bvh
"""

from __future__ import annotations

import os
import sys
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass
class _Joint:
    name: str
    parent: int
    offset: np.ndarray
    channels: list[str]
    channels_line: int  # 0-based line index of the CHANNELS line, -1 if none
    first_col: int


def _scan(lines: list[str]) -> tuple[list[_Joint], int]:
    """ROOT/JOINT blocks (End Sites skipped) and the index of the MOTION line."""
    joints: list[_Joint] = []
    stack: list[int] = []  # open blocks: joint index, or -1 for an End Site
    col = 0
    for k, line in enumerate(lines):
        t = line.split()
        if not t:
            continue
        if t[0] in ("ROOT", "JOINT"):
            joints.append(_Joint(" ".join(t[1:]), next((s for s in reversed(stack) if s >= 0),
                                                       -1), np.zeros(3), [], -1, col))
            stack.append(len(joints) - 1)
        elif t[0] == "End":
            stack.append(-1)
        elif t[0] == "OFFSET" and stack and stack[-1] >= 0:
            joints[stack[-1]].offset = np.array([float(v) for v in t[1:4]])
        elif t[0] == "CHANNELS" and stack and stack[-1] >= 0:
            j = joints[stack[-1]]
            j.channels, j.channels_line, j.first_col = t[2:], k, col
            col += len(j.channels)
        elif t[0] == "}":
            stack.pop()
        elif t[0] == "MOTION":
            return joints, k
    raise ValueError("no MOTION line")


def pybvh_compatible(path: str | os.PathLike, out: str | os.PathLike,
                     const_tol: float = 1e-4) -> list[str]:
    """Write an equivalent BVH to ``out`` with position channels on the root only.

    Returns the names of nodes whose position is *not* preserved (the root, when a child's
    translation was folded into it). ``const_tol`` (file length unit) decides when position
    channels merely repeat the OFFSET.
    """
    lines = Path(path).read_text(encoding="latin-1").replace("\r\n", "\n").split("\n")
    joints, motion = _scan(lines)
    # the two non-blank lines after MOTION are "Frames:" and "Frame Time:"
    ft_line = [k for k in range(motion + 1, len(lines)) if lines[k].strip()][1]
    data = np.loadtxt(lines[ft_line + 1:], ndmin=2)
    root = joints[0]
    root_cols = {c.lower(): root.first_col + i for i, c in enumerate(root.channels)}
    if sorted(root_cols) != ["xposition", "xrotation", "yposition", "yrotation",
                             "zposition", "zrotation"]:
        raise ValueError("pybvh needs a root with 3 position and 3 rotation channels")
    root_pos = data[:, [root_cols[a + "position"] for a in "xyz"]].copy()
    root_rot = data[:, [root_cols[a + "rotation"] for a in "xyz"]]
    not_comparable: list[str] = []
    keep = np.ones(data.shape[1], dtype=bool)
    for j in joints[1:]:
        pos_idx = [i for i, c in enumerate(j.channels) if c.lower().endswith("position")]
        if not pos_idx:
            continue
        if len(pos_idx) != 3:
            raise ValueError(f"joint {j.name}: partial position channels")
        cols = [j.first_col + i for i in pos_idx]
        order = ["xyz".index(j.channels[i][0].lower()) for i in pos_idx]
        t = np.empty((data.shape[0], 3))
        t[:, order] = data[:, cols]
        if np.abs(t - j.offset).max() <= const_tol:
            pass  # channels repeat the offset: drop them
        elif j.parent == 0 and not np.any(root_rot):
            root_pos += t - j.offset  # P_j = root_pos + I·(t_j) = (root_pos + t_j − o_j) + o_j
            not_comparable.append(root.name)
        else:
            raise ValueError(f"joint {j.name}: varying position channels pybvh cannot model")
        keep[cols] = False
        rots = [c for c in j.channels if not c.lower().endswith("position")]
        indent = lines[j.channels_line][: len(lines[j.channels_line])
                                        - len(lines[j.channels_line].lstrip())]
        lines[j.channels_line] = f"{indent}CHANNELS {len(rots)} {' '.join(rots)}"
    data[:, [root_cols[a + "position"] for a in "xyz"]] = root_pos
    data = data[:, keep]
    with open(out, "w", encoding="latin-1") as f:
        f.write("\n".join(lines[: ft_line + 1]) + "\n")
        np.savetxt(f, data, fmt="%.10g")
    return sorted(set(not_comparable))


def pybvh_read(path: str | os.PathLike) -> tuple[list[str], np.ndarray, float, list[str]]:
    """pybvh's world positions of every node of a BVH file.

    Returns ``(names, positions, fps, not_comparable)``: node names in file order with End
    Sites renamed to mtanno's ``<parent>_End``, positions (frames × nodes × 3, file length
    unit), pybvh's frame rate, and the nodes whose position the pybvh-compatible rewrite
    did not preserve (empty when pybvh read the file as it is).
    """
    import pybvh

    def load(p: str | os.PathLike):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return pybvh.read_bvh_file(p, world_up="+y")

    not_comparable: list[str] = []
    try:
        bvh = load(path)
    except ValueError as exc:
        if "position channels" not in str(exc):
            raise
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "pybvh_compatible.bvh"
            not_comparable = pybvh_compatible(path, out)
            bvh = load(out)
    names = []
    for node in bvh.nodes:
        if node.is_end_site():
            names.append(f"{node.parent.name}_End")
        else:
            names.append(node.name)
    return names, np.asarray(bvh.node_positions(), dtype=np.float64), float(bvh.fps), \
        not_comparable


def pybvh_read_positions(path: str | os.PathLike) -> np.ndarray:
    """(frames × nodes × 3) world positions of every node (joints and End Sites, file order)
    as computed by pybvh's public API (:func:`pybvh.read_bvh_file`,
    :meth:`pybvh.Bvh.node_positions`); see :func:`pybvh_read` for names."""
    return pybvh_read(path)[1]


def main(argv: list[str]) -> int:
    from mtanno.io.bvh import read_bvh
    from mtanno.io.skeleton import forward_kinematics

    for path in argv:
        names, peer, fps, skip = pybvh_read(path)
        rig, ch = read_bvh(path)
        pos, _ = forward_kinematics(rig, ch.angles, ch.trans, ch.has_trans)
        idx = [rig.index(n) for n in names]
        ok = [i for i, n in enumerate(names) if n not in skip]
        err = np.abs(pos[:, idx][:, ok] - peer[:, ok]).max()
        print(f"{path}: {len(ok)} nodes, max |mtanno - pybvh| = {err:.3g}, fps {ch.fps} vs "
              f"{fps}, not comparable: {skip or '-'}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    raise SystemExit(main(sys.argv[1:]))
