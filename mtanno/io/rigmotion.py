"""Rig motion files (ASF/AMC and BVH): channels → skeleton map → forward kinematics.

The readers the format table (:mod:`mtanno.io.formats`) names for the two rig formats, and
how an AMC file finds its ASF skeleton (:func:`find_asf`; parsed skeletons and folder
listings are remembered, so a batch parses each skeleton once).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.io.formats import ReadOptions, format_of
from mtanno.io.guess import choose_map
from mtanno.io.rigs import SkeletonMap
from mtanno.io.skeleton import Channels, Motion, Rig, forward_kinematics, to_y_up

__all__ = ["amc_channels", "bvh_channels", "find_asf", "rig_motion"]


_LISTING_CACHE: dict[tuple[str, int], list[Path]] = {}


def _asf_files(folder: Path) -> list[Path]:
    """The ASF files of a folder, sorted; listings are remembered per folder modification
    time, so a batch of AMC files in one folder lists it once."""
    try:
        key = (str(folder), folder.stat().st_mtime_ns)
    except OSError:
        return []
    if key not in _LISTING_CACHE:
        if len(_LISTING_CACHE) > 256:
            _LISTING_CACHE.clear()
        _LISTING_CACHE[key] = sorted(p for p in folder.glob("*")
                                     if p.suffix.lower() == ".asf" and p.is_file())
    return _LISTING_CACHE[key]


def find_asf(amc_path: str | os.PathLike) -> Path:
    """The ASF skeleton belonging to an AMC file when none is given.

    Looks in the AMC's folder, then each ancestor folder in turn, and takes the first folder
    that has ASF files: the ASF whose stem begins the AMC's stem (``HDM_bd.asf`` for
    ``HDM_bd_squat1Reps_001_120.amc``, ``02.asf`` for ``02_05.amc``; the longest such
    stem wins), else the only ASF there. Raises :class:`MtannoError` when none or several fit.
    """
    amc = Path(amc_path)
    stem = amc.stem
    for folder in _asf_folders(amc):
        asfs = _asf_files(folder)
        if not asfs:
            continue
        prefixed = [p for p in asfs if stem.startswith(p.stem)]
        if prefixed:
            best = max(len(p.stem) for p in prefixed)
            winners = [p for p in prefixed if len(p.stem) == best]
            if len(winners) == 1:
                return winners[0]
        if len(asfs) == 1:
            return asfs[0]
        raise MtannoError(f"several ASF files in {folder} and none is named like the AMC "
                          f"({', '.join(p.name for p in asfs[:5])}); pass {{asf}} FILE",
                          path=str(amc_path), options=("asf",))
    raise MtannoError("no ASF skeleton found in the AMC's folder or above it; pass {asf} FILE",
                      path=str(amc_path), options=("asf",))


def _asf_folders(amc: Path):
    """Where :func:`find_asf` looks, in order: the AMC's folder as named, then the folders
    above the folder of the file it resolves to (symbolic links followed only when the
    first has no ASF)."""
    yield amc.parent
    yield from amc.resolve().parent.parents


_ASF_CACHE: dict[tuple, object] = {}


def _cached_asf(path: Path):
    """read_asf, remembered per (path, file identity, size, mtime): a batch parses each
    skeleton once."""
    from mtanno.io.asf import read_asf

    try:
        st = os.stat(path)
        key = (str(path), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
    except OSError:
        return read_asf(path)  # raises the "file not found" error
    if key not in _ASF_CACHE:
        if len(_ASF_CACHE) > 64:
            _ASF_CACHE.clear()
        _ASF_CACHE[key] = read_asf(path)
    return _ASF_CACHE[key]


def amc_channels(path: Path, *, asf: str | os.PathLike | None = None,
                 sha256: bool = False) -> tuple[Rig, Channels]:
    """The rig (from its ASF: ``asf``, else :func:`find_asf`) and channels of an AMC file."""
    from mtanno.io.amc import read_amc

    asf_path = Path(asf) if asf is not None else find_asf(path)
    skel = _cached_asf(asf_path)
    return skel.rig, read_amc(path, skel, sha256=sha256)


def bvh_channels(path: Path, *, asf: str | os.PathLike | None = None,
                 sha256: bool = False) -> tuple[Rig, Channels]:
    """The rig and channels of a BVH file (``asf`` is not used)."""
    from mtanno.io.bvh import read_bvh

    return read_bvh(path, sha256=sha256)


def rig_motion(path: Path, options: ReadOptions) -> Motion:
    """A rig format's motion (:data:`mtanno.io.formats.FORMATS`): channels, the skeleton
    map (``options.skeleton``, else the first map file that fits, else for a BVH rig one
    made from its joint names and tree, or from its hierarchy and pose:
    :func:`mtanno.io.guess.choose_map`), forward
    kinematics, and the result turned so that Y is up (``options.up``, default "y")."""
    rig, ch = format_of(path).load("channels")(path, asf=options.asf, sha256=options.sha256)
    smap = choose_map(rig, options.skeleton, ch)
    _check_needed_bones(rig, ch, smap, str(path))
    positions, heading = forward_kinematics(
        rig, ch.angles, ch.trans, ch.has_trans,
        heading_node=smap.heading_index(rig), heading_axis=smap.heading_axis)
    if not (np.isfinite(positions).all() and np.isfinite(heading).all()):
        # (the readers bound every value, so this is a last safeguard)
        raise MtannoError("joint positions contain NaN or infinite values after forward "
                          "kinematics", path=str(path))
    up = options.up or "y"
    return Motion(rig=rig, positions=to_y_up(positions, up), heading=to_y_up(heading, up),
                  fps=ch.fps, source=str(path), smap=smap, source_sha256=ch.sha256, up=up)


def _check_needed_bones(rig: Rig, ch: Channels, smap: SkeletonMap, path: str) -> None:
    """Refuse a motion that gives no values, in any frame, for a bone with rotation dofs
    that a canonical joint of the skeleton map (or its heading) hangs from: its rotation
    would silently be zero and every feature of the joints below it wrong."""
    if not ch.absent:
        return
    for joint, node in [*smap.joints.items(), ("heading", smap.heading_node)]:
        if node not in rig.names:
            continue  # (a map that lacks the node is reported where the joint is used)
        j = rig.names.index(node)
        while j >= 0:  # the node and its ancestors place the joint
            bone = rig.names[j]
            if bone in ch.absent:
                raise MtannoError(f"bone '{bone}' has rotation dofs in the ASF but no values "
                                  f"in any frame; the skeleton map '{smap.name}' needs it "
                                  f"for joint '{joint}'", path=path, line=ch.absent[bone])
            j = int(rig.parents[j])
