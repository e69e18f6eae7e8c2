"""The motion formats mtanno reads: one table, suffix → reader → joint positions.

Every place that asks "is this a motion file?", "which reader?" or says what is expected
(".amc, .bvh or .c3d") asks this table, so a new format (FBX, …) is one reader module and
one row here. Readers are named as ``"module:function"`` and imported only when a file of
their format is read, so ``import mtanno.io`` stays light.

A reader is called as ``reader(path, options)`` with a :class:`ReadOptions` and returns a
:class:`~mtanno.io.skeleton.Motion` whose positions are world coordinates with **Y up**
(the features' convention, docs/method.md §1): a reader turns Z-up data itself
(:func:`~mtanno.io.skeleton.to_y_up`) and records the file's up axis in ``Motion.up``.
Options a format does not use are ignored (a batch may mix formats).
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mtanno.errors import MtannoError

__all__ = ["FORMATS", "MotionFormat", "ReadOptions", "SUFFIXES", "expected", "format_of",
           "is_motion_path", "looks_like_motion", "read_motion"]


@dataclass(frozen=True)
class ReadOptions:
    """What a reader may be told besides the path.

    ``asf``: the ASF skeleton of an AMC file (default: found beside or above it);
    ``skeleton``: a skeleton map (file or name) for rig formats; ``markers``: a marker set
    (TOML file or name) for marker formats; ``up``: the file's up axis, ``"y"`` or
    ``"z"`` (None: the format's own rule — Y for AMC and BVH, the file's parameters for
    C3D); ``sha256``: also hash the file's bytes as read."""

    asf: str | os.PathLike | None = None
    skeleton: str | os.PathLike | None = None
    markers: str | os.PathLike | None = None
    up: str | None = None
    sha256: bool = False


def _text_head(*heads: bytes) -> Callable[[bytes], bool]:
    """A sniffer for text formats: the first line that is not a ``#`` comment begins
    with one of ``heads`` (case-insensitive)."""
    def sniff(data: bytes) -> bool:
        for line in bytes(memoryview(data)[:4096]).splitlines():
            line = line.strip()
            if line and not line.startswith(b"#"):
                return line.upper().startswith(heads)
        return False
    return sniff


def _c3d_head(data: bytes) -> bool:
    """C3D: the header's second byte is 0x50 (the C3D identifier)."""
    return len(data) >= 512 and data[1] == 0x50


@dataclass(frozen=True)
class MotionFormat:
    """One motion file format.

    ``suffix``: the file suffix (lower case); ``name``: as messages say it; ``reader``:
    ``"module:function"`` returning a Motion (module docstring); ``channels``: for rig
    formats, ``"module:function"`` giving the rig and its per-frame channels
    (:func:`mtanno.io.read_channels`), else None; ``skeleton_file``: the suffix of the
    separate skeleton file the format needs (AMC: ``.asf``), else None; ``sniff``: tells
    a file of the format from its first bytes (for "this is a motion file" messages);
    ``up``: the up axis a file of the format has unless told (``"file"``: the file says,
    read by the reader)."""

    suffix: str
    name: str
    reader: str
    channels: str | None = None
    skeleton_file: str | None = None
    sniff: Callable[[bytes], bool] | None = None
    up: str = "y"

    def load(self, what: str = "reader") -> Callable:
        """The reader (or ``what="channels"`` the channel reader), imported now."""
        ref = getattr(self, what)
        if ref is None:
            raise MtannoError(f"{self.name} files hold no rig and channels (only joint "
                              f"positions through mtanno.io.read_motion)")
        module, _, name = ref.partition(":")
        return getattr(importlib.import_module(module), name)


#: The table: every motion format mtanno reads.
FORMATS: tuple[MotionFormat, ...] = (
    MotionFormat(".amc", "ASF/AMC", "mtanno.io.rigmotion:rig_motion",
                 channels="mtanno.io.rigmotion:amc_channels", skeleton_file=".asf",
                 sniff=_text_head(b":FULLY-SPECIFIED", b":DEGREES", b":RADIANS")),
    MotionFormat(".bvh", "BVH", "mtanno.io.rigmotion:rig_motion",
                 channels="mtanno.io.rigmotion:bvh_channels", sniff=_text_head(b"HIERARCHY")),
    MotionFormat(".c3d", "C3D", "mtanno.io.c3d:c3d_motion", sniff=_c3d_head, up="file"),
)

_BY_SUFFIX = {f.suffix: f for f in FORMATS}
#: The suffixes of motion files (lower case), in table order.
SUFFIXES: tuple[str, ...] = tuple(_BY_SUFFIX)


def expected() -> str:
    """The suffixes as a message says them: ``.amc, .bvh or .c3d``."""
    return ", ".join(SUFFIXES[:-1]) + " or " + SUFFIXES[-1] if len(SUFFIXES) > 1 \
        else SUFFIXES[0]


def is_motion_path(path: str | os.PathLike) -> bool:
    """True if the file's suffix is a motion format's."""
    return Path(path).suffix.lower() in _BY_SUFFIX


def format_of(path: str | os.PathLike) -> MotionFormat:
    """The format of a motion file by its suffix; an unknown suffix is one
    :class:`MtannoError` saying which are known."""
    p = Path(path)
    fmt = _BY_SUFFIX.get(p.suffix.lower())
    if fmt is None:
        raise MtannoError(f"unknown motion file type '{p.suffix}' (expected {expected()})",
                          path=str(p))
    return fmt


def looks_like_motion(path: str | os.PathLike, data: bytes) -> bool:
    """True if a file is a motion file by its suffix or by its first bytes (``data``)."""
    return is_motion_path(path) or any(f.sniff is not None and f.sniff(data)
                                       for f in FORMATS)


def read_motion(path: str | os.PathLike, *, asf: str | os.PathLike | None = None,
                skeleton: str | os.PathLike | None = None,
                markers: str | os.PathLike | None = None, up: str | None = None,
                sha256: bool = False):
    """Read a motion file of any format in :data:`FORMATS` into a
    :class:`~mtanno.io.skeleton.Motion` (Y up; the options are :class:`ReadOptions`')."""
    path = Path(path)
    fmt = format_of(path)
    if not path.is_file():
        raise MtannoError("motion file not found" if not path.exists() else "not a file",
                          path=str(path))
    options = ReadOptions(asf=asf, skeleton=skeleton, markers=markers, up=up, sha256=sha256)
    return fmt.load()(path, options)
