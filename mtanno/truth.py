"""Ground-truth and annotation segment tables (CSV), and converters into them.

A segment table has one row per labelled segment: ``doc`` (document name = feature file
stem), ``start`` and ``end`` (1-based inclusive frames), ``label`` and optionally ``fps``
(the rate the frames are given at; 30 when absent). Inside mtanno every table is at the
30 Hz analysis rate: frames given at another rate are converted with
``ceil(frame / ratio)`` (algorithms.md §8), ratio = fps / 30.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

from mtanno.errors import MtannoError, read_input
from mtanno.store import atomic_path

ANALYSIS_FPS = 30.0


@dataclass(frozen=True, order=True)
class Segment:
    """A labelled frame range of one document: 1-based inclusive frames at 30 Hz."""

    doc: str
    start: int
    end: int
    label: str

    @property
    def length(self) -> int:
        return self.end - self.start + 1


def to_analysis_frame(frame: int, fps: float) -> int:
    """A 1-based frame at ``fps`` → the 1-based 30 Hz frame ``ceil(frame / ratio)``."""
    ratio = Fraction(fps).limit_denominator(10**6) / Fraction(ANALYSIS_FPS)
    return max(1, math.ceil(Fraction(frame) / ratio))


def read_truth(path: str | os.PathLike) -> list[Segment]:
    """Read a segment table (columns doc, start, end, label[, fps]) into 30 Hz segments."""
    spath = str(path)
    try:
        text = read_input(path, what="truth file").decode("utf-8-sig")
    except UnicodeDecodeError:
        raise MtannoError("not a UTF-8 text file", path=spath) from None
    reader = csv.DictReader(io.StringIO(text))
    need = {"doc", "start", "end", "label"}
    if reader.fieldnames is None or not need <= set(reader.fieldnames):
        raise MtannoError(f"needs the columns {', '.join(sorted(need))} (found "
                          f"{', '.join(reader.fieldnames or [])})", path=spath, line=1)
    out: list[Segment] = []
    for lineno, row in enumerate(reader, 2):
        try:
            start, end = int(row["start"]), int(row["end"])
            fps = float(row.get("fps") or ANALYSIS_FPS)
        except (TypeError, ValueError):
            raise MtannoError("start, end and fps must be numbers", path=spath,
                              line=lineno) from None
        if not row["doc"] or not row["label"]:
            raise MtannoError("empty doc or label", path=spath, line=lineno)
        if start < 1 or end < start or not fps > 0:
            raise MtannoError(f"bad frame range {start}..{end} (1-based, start ≤ end)",
                              path=spath, line=lineno)
        out.append(Segment(row["doc"], to_analysis_frame(start, fps),
                           to_analysis_frame(end, fps), row["label"]))
    return out


def write_truth(path: str | os.PathLike, segments: Iterable[Segment]) -> None:
    """Write a segment table at 30 Hz (columns doc, start, end, label, fps), atomically."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["doc", "start", "end", "label", "fps"])
        for s in segments:
            w.writerow([s.doc, s.start, s.end, s.label, int(ANALYSIS_FPS)])


def truth_from_mocap6(path: str | os.PathLike) -> list[Segment]:
    """Segments of the CMU mocap6 ``labels.json`` (frames at its ``fps``) at 30 Hz."""
    spath = str(path)
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        fps = float(data.get("fps", 120))
        out = []
        for doc, d in data["documents"].items():
            for seg in d["segments"]:
                out.append(Segment(doc, to_analysis_frame(int(seg["start"]), fps),
                                   to_analysis_frame(int(seg["end"]), fps), str(seg["label"])))
        return sorted(out)
    except FileNotFoundError:
        raise MtannoError("labels file not found", path=spath) from None
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
        raise MtannoError(f"not a mocap6 labels file ({exc})", path=spath) from None


def by_document(segments: Iterable[Segment]) -> dict[str, list[Segment]]:
    """Segments grouped by document, each list sorted by start frame."""
    out: dict[str, list[Segment]] = {}
    for s in segments:
        out.setdefault(s.doc, []).append(s)
    for v in out.values():
        v.sort()
    return out
