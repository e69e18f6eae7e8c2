"""Mocap readers: motion files → world joint positions (docs/method.md §1).

:func:`read_motion` is the entry point: it finds the file's format in the format table
(:mod:`~mtanno.io.formats`: suffix → reader) and returns a
:class:`~mtanno.io.skeleton.Motion` with Y up.

Modules: :mod:`~mtanno.io.formats` (the table of motion formats, :class:`ReadOptions`),
:mod:`~mtanno.io.rigmotion` (the rig formats: channels, skeleton map, kinematics; an AMC's
ASF), :mod:`~mtanno.io.asf`, :mod:`~mtanno.io.amc` and :mod:`~mtanno.io.bvh` (the
parsers, text → channel arrays, with file:line errors), ``_numparse`` (their numba number
parser, private), ``_limits`` (the bounds on every number a header declares, private),
:mod:`~mtanno.io.skeleton` (rig graph and forward kinematics, vectorised over frames),
:mod:`~mtanno.io.rigs` (skeleton map files: rig nodes → the 22 canonical joints),
:mod:`~mtanno.io.guess` (skeleton maps made from joint names and the tree, for BVH rigs no
map file fits), :mod:`~mtanno.io.topology` (made from the hierarchy and pose alone, where
the names say nothing), :mod:`~mtanno.io.c3d` (C3D marker files, read with the ``c3d``
package), :mod:`~mtanno.io.markerset` (marker sets: which markers make which joint;
recognition, ``markers guess``) and :mod:`~mtanno.io.markerjoints` (markers → joints: gap
filling, the joint recipes, per-frame validity).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.io.formats import SUFFIXES, ReadOptions, format_of, read_motion
from mtanno.io.guess import choose_map
from mtanno.io.rigmotion import find_asf
from mtanno.io.rigs import CANONICAL_JOINTS, SkeletonMap
from mtanno.io.skeleton import Channels, Motion, Rig
from mtanno.util.lazy import submodule_getattr

__all__ = ["MOCAP_SUFFIXES", "read_channels", "read_motion", "canonical_positions",
           "find_asf", "Motion", "Rig", "Channels", "CANONICAL_JOINTS", "ReadOptions"]

#: File suffixes (lower case) that hold motions (:data:`mtanno.io.formats.SUFFIXES`).
MOCAP_SUFFIXES = SUFFIXES


def read_channels(path: str | os.PathLike, *, asf: str | os.PathLike | None = None,
                  sha256: bool = False) -> tuple[Rig, Channels]:
    """Parse a rig motion file (AMC, BVH) into its rig and per-frame channels (no
    kinematics yet); with ``sha256`` the channels carry the SHA-256 of the file's bytes as
    parsed. A format without a rig (C3D) is an error."""
    path = Path(path)
    fmt = format_of(path)
    if not path.is_file():
        raise MtannoError("motion file not found" if not path.exists() else
                          "not a file", path=str(path))
    return fmt.load("channels")(path, asf=asf, sha256=sha256)


def canonical_positions(motion: Motion, smap: SkeletonMap | None = None,
                        joints: tuple[str, ...] = CANONICAL_JOINTS) -> np.ndarray:
    """(frames × len(joints) × 3) positions of the canonical joints, in ``joints`` order."""
    smap = smap if smap is not None else motion.smap
    if smap is None:
        smap = choose_map(motion.rig)
    # np.take copies whole (x, y, z) rows into a C-contiguous array (fancy indexing of
    # the middle axis gives a strided copy, several times slower, that the kernels copy
    # again)
    return np.take(motion.positions, smap.indices(motion.rig, joints), axis=1)


__getattr__ = submodule_getattr(__name__)  # the modules not imported above, on first use
