"""C3D marker files → joint positions (issue 36).

C3D is the binary format of optical motion capture (Vicon, Qualisys, OptiTrack, Motion
Analysis; the C3D.org standard): per frame the 3-D trajectory of every marker, no
skeleton. The file is parsed by the ``c3d`` package (PyPI ``c3d``, pure Python; chosen
over ezc3d by speed and install weight, docs/benchmarks.md); this module only checks what
the file declares against what it holds, converts units and axes, and hands the markers to
:mod:`mtanno.io.markerjoints`, which turns them into the 22 canonical joints through a
marker set (:mod:`mtanno.io.markerset`).

* Units: ``POINT:UNITS`` (``mm``, ``cm``, ``m``; missing: mm, the standard's default);
  markers are worked on in millimetres, joints are returned in centimetres (as ASF/AMC).
* Up axis: ``POINT:Y_SCREEN`` (``+Z`` or ``+Y``: the axis drawn upwards), else Z, the
  convention of C3D capture systems; ``features --up`` overrides it.
* Frame rate: ``POINT:RATE`` (else the header's).
* A marker is missing in a frame when the file flags it (residual word −1), when its
  coordinates are all zero (how some systems write a lost marker), or NaN, infinite or
  beyond 1 km.
"""

from __future__ import annotations

import hashlib
import io
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.io._limits import fps_in_range
from mtanno.io.formats import ReadOptions
from mtanno.io.skeleton import Motion, to_y_up

__all__ = ["MarkerData", "c3d_motion", "read_c3d"]

#: Millimetres per unit of ``POINT:UNITS``.
UNITS_MM = {"mm": 1.0, "millimeter": 1.0, "millimetre": 1.0, "cm": 10.0, "dm": 100.0,
            "m": 1000.0, "meter": 1000.0, "metre": 1000.0, "in": 25.4, "inch": 25.4}
#: A marker farther than this from the origin (mm, 1 km) is taken as missing.
MAX_MM = 1e6
#: Most markers a file may have: the c3d package counts a frame's bytes in 16 bits (4 words
#: of 4 bytes per marker), which overflows beyond this many (real captures have < 300).
MAX_MARKERS = 4095
#: Most values (frames × markers × 3) one file may give: 2 GB of float64.
MAX_VALUES = 250_000_000


@dataclass
class MarkerData:
    """The markers of one C3D file.

    ``labels``: one per marker, as in ``POINT:LABELS`` (trailing blanks removed; ``""``
    where the file names none); ``points``: (frames × markers × 3) float64 millimetres in
    the file's axes, NaN where the marker is missing; ``fps``: frames per second;
    ``units``: ``POINT:UNITS`` as written; ``up``: the up axis the file gives (``"y"`` or
    ``"z"``); ``sha256``: of the file's bytes, when asked for."""

    labels: list[str]
    points: np.ndarray
    fps: float
    units: str
    up: str
    sha256: str | None = None

    @property
    def n_frames(self) -> int:
        return int(self.points.shape[0])


def _param(reader, name: str):
    try:
        return reader.get(name)
    except Exception:  # the package raises several kinds for a malformed group
        return None


def _string(reader, name: str) -> str | None:
    p = _param(reader, name)
    if p is None:
        return None
    try:
        return str(p.string_value).strip()
    except Exception:
        return None


def _labels(reader, n: int) -> list[str]:
    """``POINT:LABELS`` (and ``LABELS2``, ``LABELS3``… for files of more than 255 markers),
    one per marker; a marker without a label gets ``""``."""
    out: list[str] = []
    for name in ("POINT:LABELS", *(f"POINT:LABELS{k}" for k in range(2, 100))):
        p = _param(reader, name)
        if p is None:
            break
        try:
            arr = p.string_array
        except Exception:
            break
        out.extend(str(s).strip() for s in np.asarray(arr).ravel())
        if len(out) >= n:
            break
    return (out + [""] * n)[:n]


def _up_axis(reader, path: str) -> str:
    """The axis the file draws upwards (``POINT:Y_SCREEN``), else Z."""
    screen = _string(reader, "POINT:Y_SCREEN")
    if not screen:
        return "z"
    axis = screen.lstrip("+").lower()
    if axis in ("y", "z"):
        return axis
    raise MtannoError(f"POINT:Y_SCREEN is {screen!r}: mtanno reads files whose up axis is "
                      f"+Y or +Z; pass {{up}} y or z to say which axis points up",
                      path=path, options=("up",))


def read_c3d(path: str | Path, *, sha256: bool = False) -> MarkerData:
    """Read the markers of a C3D file (module docstring); every problem is one
    :class:`MtannoError` naming the file: not a C3D file, a header or parameters the
    package cannot parse, counts that the file's size contradicts (a truncated file),
    unknown units, or a frame rate out of range."""
    spath = str(path)
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise MtannoError(f"cannot read motion file: {exc.strerror or exc}", path=spath) from None
    if len(data) < 512 or data[1] != 0x50:
        raise MtannoError("not a C3D file (its header does not begin with the C3D "
                          "identifier 0x50)", path=spath)
    try:
        import c3d
    except ImportError:  # (a dependency; missing only from an install without its deps)
        raise MtannoError("reading C3D files needs the c3d package: pip install c3d",
                          path=spath) from None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            reader = c3d.Reader(io.BytesIO(data))
            n_markers = int(reader.point_used)
            first, last = int(reader.first_frame), int(reader.last_frame)
            scale = float(reader.point_scale)
            fps = float(reader.point_rate)
            analog = int(reader.analog_used) * int(reader.analog_per_frame)
            start = (int(reader.header.data_block) - 1) * 512
    except MtannoError:
        raise
    except Exception as exc:
        raise MtannoError(f"not a readable C3D file ({type(exc).__name__}: {exc})",
                          path=spath) from None
    if not (np.isfinite(fps) and fps_in_range(fps)):
        raise MtannoError(f"frame rate {fps:g} (POINT:RATE) is out of range", path=spath)
    n_frames = last - first + 1
    if n_markers > MAX_MARKERS:
        raise MtannoError(f"the file declares {n_markers} markers; mtanno reads C3D files of "
                          f"at most {MAX_MARKERS} (the c3d package's frame arithmetic is 16-bit "
                          f"beyond that)", path=spath)
    if n_markers < 0 or n_frames < 0 or analog < 0:
        raise MtannoError(f"the file declares {n_markers} markers and {n_frames} frames",
                          path=spath)
    word = 4 if scale < 0 else 2
    frame_bytes = 4 * n_markers * word + analog * (4 if scale < 0 else 2)
    held = (len(data) - start) // frame_bytes if frame_bytes and start >= 0 else n_frames
    if n_markers and held < n_frames:
        raise MtannoError(f"the file declares {n_frames} frames of {n_markers} markers but "
                          f"holds {max(held, 0)} (truncated, or a header that lies about "
                          f"its counts)", path=spath)
    if n_frames * n_markers * 3 > MAX_VALUES:
        raise MtannoError(f"{n_markers} markers × {n_frames} frames is more than mtanno "
                          f"reads from one file ({MAX_VALUES:,} values)", path=spath)
    units = _string(reader, "POINT:UNITS") or "mm"
    mm = UNITS_MM.get(units.lower())
    if mm is None:
        raise MtannoError(f"POINT:UNITS is {units!r}, not a length unit mtanno knows "
                          f"({', '.join(sorted(set(UNITS_MM)))})", path=spath)
    up = _up_axis(reader, spath)
    labels = _labels(reader, n_markers)
    raw = np.empty((n_frames, n_markers, 4), np.float32)
    count = 0
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            # check_nan=False: a NaN stays NaN (missing, below) instead of the package's
            # per-frame test, which halves its speed
            for _, pts, _ in reader.read_frames(copy=False, check_nan=False):
                if count >= n_frames:
                    break
                raw[count] = pts[:, :4]
                count += 1
    except Exception as exc:
        raise MtannoError(f"not a readable C3D file: frame {count + 1}: "
                          f"{type(exc).__name__}: {exc}", path=spath) from None
    if n_markers and count < n_frames:
        raise MtannoError(f"the file declares {n_frames} frames but ends after {count} "
                          f"(truncated)", path=spath)
    # present: not flagged missing (residual −1), finite and within 1 km, not all zero (one
    # comparison per coordinate: numpy's reductions over an axis of 3 are slow)
    x, y, z = raw[..., 0], raw[..., 1], raw[..., 2]
    far = np.float32(MAX_MM / mm)
    with np.errstate(invalid="ignore"):
        ok = (raw[..., 3] >= 0) & (np.abs(x) <= far) & (np.abs(y) <= far) & (np.abs(z) <= far)
        ok &= (x != 0) | (y != 0) | (z != 0)
    points = raw[..., :3].astype(np.float64)
    if mm != 1.0:
        points *= mm
    points[~ok] = np.nan
    return MarkerData(labels=labels, points=points, fps=fps, units=units, up=up,
                      sha256=hashlib.sha256(data).hexdigest() if sha256 else None)


def c3d_motion(path: Path, options: ReadOptions) -> Motion:
    """The motion of a C3D file: its markers (:func:`read_c3d`), the marker set
    (``options.markers``, else the built-in set that fits the labels:
    :func:`mtanno.io.markerset.choose_set`), the joints, heading and per-frame validity
    (:func:`mtanno.io.markerjoints.marker_joints`), turned so that Y is up
    (``options.up``, else the file's axis) and in centimetres."""
    from mtanno.io.markerjoints import marker_joints
    from mtanno.io.markerset import canonical_rig, choose_set

    md = read_c3d(path, sha256=options.sha256)
    if not md.labels:
        raise MtannoError("the file holds no markers (POINT:USED is 0): no joints to compute",
                          path=str(path))
    up = options.up or md.up
    mset = choose_set(md.labels, options.markers, source=str(path))
    joints, heading, valid, report = marker_joints(mset, md.labels, md.points, md.fps,
                                                   source=str(path))
    report.units, report.up = md.units, up
    return Motion(rig=canonical_rig(str(path)), positions=to_y_up(joints / 10.0, up),
                  heading=to_y_up(heading, up), fps=md.fps, source=str(path),
                  smap=mset, source_sha256=md.sha256, up=up,
                  valid=None if valid.all() else valid, markers=report)
