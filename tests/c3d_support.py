"""C3D files for the tests, written with the ``c3d`` package into temporary folders (no
C3D file is kept in the repository)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np


def write_c3d(path: str | Path, labels, points: np.ndarray, *, fps: float = 120.0,
              units: str = "mm", y_screen: str | None = None) -> Path:
    """Write markers ``points`` (frames × markers × 3, in ``units``; NaN: missing, written
    with the residual −1 the format uses) labelled ``labels`` as a float C3D file."""
    import c3d

    points = np.asarray(points, dtype=np.float64)
    w = c3d.Writer(point_rate=float(fps), point_units=units.ljust(4))
    missing = ~np.isfinite(points).all(axis=2)
    frames = []
    for f in range(points.shape[0]):
        p = np.zeros((points.shape[1], 5), np.float32)
        p[:, :3] = np.where(missing[f][:, None], 0.0, points[f])
        p[missing[f], 3] = -1.0
        frames.append((p, np.empty((0, 0), np.float32)))
    w._frames.extend(frames)  # (add_frames refuses frames of no markers)
    # labels packed by bytes (the package pads by characters, which breaks labels in
    # other scripts): each label's UTF-8 bytes padded with blanks to the longest
    # (at most 255 labels a parameter: LABELS, LABELS2, LABELS3, … as the standard has it)
    labels = [str(x) for x in labels]
    for k in range(0, max(len(labels), 1), 255):
        chunk = labels[k:k + 255]
        raw = [x.encode("utf-8") for x in chunk]
        width = max([len(b) for b in raw] + [1])
        text = "".join(x + " " * (width - len(b)) for x, b in zip(chunk, raw))
        name = "LABELS" if k == 0 else f"LABELS{k // 255 + 1}"
        w.point_group.add_str(name, "Point labels.", text, width, len(raw))
    w.point_group.add_str("DESCRIPTIONS", "", " ", 1, 1)  # (one per marker would not fit
    # the parameter section of a file of tens of thousands of markers)
    if y_screen is not None:
        w.point_group.add_str("Y_SCREEN", "", y_screen, len(y_screen))
    path = Path(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with open(path, "wb") as fh:
            w.write(fh)
    return path
