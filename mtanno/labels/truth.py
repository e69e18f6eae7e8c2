"""Truth tables — the labelled segments of documents a user gives (ground truth, reviewed
annotations) — read and written, and converters into them.

A segment table (CSV, Parquet or JSON Lines: :mod:`mtanno.util.tables`) has one row per
labelled segment: ``doc`` (document name = feature file
stem), ``start`` and ``end`` (1-based inclusive frames), ``label`` and optionally ``fps``
(the rate the frames are given at; 30 when absent). Inside mtanno every table is at the
30 Hz analysis rate: frames given at another rate are converted with
``ceil(frame / ratio)`` (docs/method.md §8), ratio = fps / 30.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from fractions import Fraction

from mtanno.errors import MtannoError, read_json
from mtanno.labels.segments import Segment
from mtanno.util.units import ANALYSIS_FPS


def to_analysis_frame(frame: int, fps: float) -> int:
    """A 1-based frame at ``fps`` → the 1-based 30 Hz frame ``ceil(frame / ratio)``."""
    ratio = Fraction(fps).limit_denominator(10**6) / Fraction(ANALYSIS_FPS)
    return max(1, math.ceil(Fraction(frame) / ratio))


#: Largest frame number a table may hold (2³¹ − 1: 2.3 years at 30 Hz).
MAX_FRAME = 2**31 - 1


def read_truth(path: str | os.PathLike) -> list[Segment]:
    """Read a segment table (columns doc, start, end, label[, fps]; CSV, Parquet or JSON
    Lines by suffix, ``-`` for standard input) into 30 Hz segments. Each bad row is an
    error naming its line: a non-integer or non-positive frame, start after end, an fps
    that is not a positive number, an empty doc or label."""
    from mtanno.util.tables import parse_float, parse_int, parse_text, read_table

    table = read_table(path, what="truth file")
    table.require(["doc", "start", "end", "label"])
    out: list[Segment] = []
    for i in range(len(table.rows)):
        doc, label = parse_text(table, i, "doc"), parse_text(table, i, "label")
        start = parse_int(table, i, "start", minimum=1, maximum=MAX_FRAME)
        end = parse_int(table, i, "end", minimum=1, maximum=MAX_FRAME)
        fps = parse_float(table, i, "fps", default=ANALYSIS_FPS, positive=True)
        if end < start:
            raise table.error(i, f"start {start} is after end {end} (frames are 1-based, "
                                 f"inclusive)")
        out.append(Segment(doc, to_analysis_frame(start, fps), to_analysis_frame(end, fps),
                           label))
    return out


def truth_table(segments: Iterable[Segment]):
    """The truth table of ``segments`` (30 Hz) as a :class:`pyarrow.Table`."""
    import pyarrow as pa

    segs = list(segments)
    return pa.table({"doc": pa.array([s.doc for s in segs], pa.string()),
                     "start": pa.array([s.start for s in segs], pa.int64()),
                     "end": pa.array([s.end for s in segs], pa.int64()),
                     "label": pa.array([s.label for s in segs], pa.string()),
                     "fps": pa.array([int(ANALYSIS_FPS)] * len(segs), pa.int64())})


def write_truth(path: str | os.PathLike, segments: Iterable[Segment], *,
                provenance: dict | None = None) -> None:
    """Write a segment table at 30 Hz (columns doc, start, end, label, fps), atomically, in
    the format of its suffix (:func:`mtanno.util.tables.write_table`)."""
    from mtanno.util.tables import write_table

    write_table(path, truth_table(segments), provenance=provenance)


def truth_from_mocap6(path: str | os.PathLike) -> list[Segment]:
    """Segments of the CMU mocap6 ``labels.json`` (frames at its ``fps``) at 30 Hz.

    The file is checked, not trusted: ``fps`` must be a positive number, every document
    needs its frame count, every segment 1 ≤ start ≤ end ≤ that count and a label from the
    file's ``classes`` list (when it has one); each problem is one error naming the
    document and segment.
    """
    spath = str(path)
    data, _ = read_json(path, what="labels file")

    def bad(msg: str) -> MtannoError:
        return MtannoError(f"not a mocap6 labels file: {msg}", path=spath)

    if not isinstance(data, dict):
        raise bad(f"the top level must be an object, got {type(data).__name__}")
    fps = data.get("fps", 120)
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not math.isfinite(fps) \
            or fps <= 0:
        raise bad(f"fps must be a positive number, got {fps!r}")
    classes = data.get("classes")
    if classes is not None and not (isinstance(classes, list)
                                    and all(isinstance(c, str) and c for c in classes)):
        raise bad("classes must be a list of names")
    docs = data.get("documents")
    if not isinstance(docs, dict) or not docs:
        raise bad("documents must be a non-empty object of document name → segments")
    out = []
    for doc, d in docs.items():
        if not isinstance(d, dict) or not isinstance(d.get("segments"), list):
            raise bad(f"document {doc!r} needs a list of segments")
        n = d.get("frames")
        if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
            raise bad(f"document {doc!r}: frames must be a positive integer, got {n!r}")
        for k, seg in enumerate(d["segments"], 1):
            where = f"document {doc!r} segment {k}"
            if not isinstance(seg, dict):
                raise bad(f"{where} must be an object")
            start, end, label = seg.get("start"), seg.get("end"), seg.get("label")
            if not all(isinstance(x, int) and not isinstance(x, bool) for x in (start, end)):
                raise bad(f"{where}: start and end must be integers, got {start!r}, {end!r}")
            if not 1 <= start <= end:
                raise bad(f"{where}: frames {start}..{end} are not 1 ≤ start ≤ end")
            if n is not None and end > n:
                raise bad(f"{where}: end {end} is past the document's {n} frames")
            if end > MAX_FRAME:
                raise bad(f"{where}: end {end} is too large")
            if not isinstance(label, str) or not label:
                raise bad(f"{where}: label must be a non-empty string")
            if classes is not None and label not in classes:
                raise bad(f"{where}: label {label!r} is not in the file's classes")
            out.append(Segment(str(doc), to_analysis_frame(start, fps),
                               to_analysis_frame(end, fps), label))
    return sorted(out)


def mocap6_to(labels: str | os.PathLike, output: str | os.PathLike) -> list[Segment]:
    """The run of ``mtanno truth mocap6``: :func:`truth_from_mocap6` of ``labels`` written
    as a truth table to ``output`` (suffix picks the format, ``-`` is CSV on standard
    output) with its provenance, the output checked against the input first; returns the
    segments."""
    from mtanno.util.preflight import check_outputs
    from mtanno.util.provenance import provenance
    from mtanno.util.tables import output_files, table_format

    table_format(output)
    check_outputs(output_files(output), [labels])
    segs = truth_from_mocap6(labels)
    write_truth(output, segs, provenance=provenance(inputs=[labels]))
    return segs


def check_within(segments: Iterable[Segment], frames: dict[str, int], *,
                 path: str | os.PathLike | None = None) -> None:
    """Every segment of a document whose length is known (``frames``: document → number
    of 30 Hz frames) must end inside it: a segment past the end means a truth table at the
    wrong frame rate or for other documents, and would be scored as missed frames."""
    for s in segments:
        n = frames.get(s.doc)
        if n is not None and s.end > n:
            raise MtannoError(f"segment {s.start}..{s.end} ({s.label}) of document {s.doc!r} "
                              f"ends after its {n} frames (wrong fps column, or truth of "
                              f"another document?)", path=None if path is None else str(path))
