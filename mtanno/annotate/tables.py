"""Annotation tables: the segments of an annotation as a table (``doc, start, end, label,
cost, confidence``, native frames), written and read in the I/O convention of :mod:`mtanno.util.tables`
(CSV, Parquet or JSON Lines by suffix, provenance beside).

Frames are 0-based in :class:`~mtanno.labels.segments.Annotation` (the row type, with
:func:`~mtanno.labels.segments.to_segments`, re-exported here) and 1-based inclusive in
every table; the conversion of whole tables happens here only (:func:`annotation_table`,
:func:`_annotation_rows`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.labels.segments import Annotation, to_segments

__all__ = ["ANNOTATION_COLUMNS", "ANNOTATION_SUFFIXES", "Annotation", "annotation_files",
           "annotation_table", "merge_annotation_tables", "read_annotation_table",
           "read_annotation_tables", "read_annotations", "to_segments", "write_annotations"]


ANNOTATION_COLUMNS = ("doc", "start", "end", "label", "cost", "confidence", "start_native",
                      "end_native")


def annotation_table(rows: Sequence[Annotation], native: dict[str, np.ndarray] | None = None):
    """The annotation table of ``rows`` as a :class:`pyarrow.Table`: doc, start, end
    (1-based inclusive 30 Hz frames), label, cost (null where infinite), confidence (null
    where not given), and start_native,
    end_native (1-based native frames) when ``native`` maps each document to its feature
    file's native_frame column."""
    pairs = None
    if native is not None:
        pairs = [(int(native[r.doc][r.start]), int(native[r.doc][r.end])) for r in rows]
    return _annotation_arrow(rows, pairs)


def _annotation_arrow(rows: Sequence[Annotation], pairs: Sequence[tuple[int, int]] | None):
    """:func:`annotation_table` with each row's native start and end given (or None)."""
    import pyarrow as pa

    from mtanno.util.tables import arrow_table

    cols: dict[str, list] = {"doc": [r.doc for r in rows], "start": [r.start + 1 for r in rows],
                             "end": [r.end + 1 for r in rows], "label": [r.label for r in rows],
                             "cost": [r.cost if math.isfinite(r.cost) else None for r in rows],
                             "confidence": [None if math.isnan(r.confidence) else r.confidence
                                            for r in rows]}
    if pairs is not None:
        cols["start_native"] = [a for a, _ in pairs]
        cols["end_native"] = [b for _, b in pairs]
    types = {"doc": pa.string(), "label": pa.string(), "cost": pa.float64(),
             "confidence": pa.float64()}
    return arrow_table(cols, types)  # (names of non-UTF-8 files written as text)


def write_annotations(path: str | os.PathLike, rows: Sequence[Annotation],
                      native: dict[str, np.ndarray] | None = None, *,
                      provenance: dict | None = None) -> None:
    """Write an annotation table (:func:`annotation_table`) atomically, in the format of
    its suffix (``.csv``, ``.parquet``, ``.jsonl``; ``-`` for standard output), with its
    provenance (:mod:`mtanno.util.tables`)."""
    from mtanno.util.tables import write_table

    write_table(path, annotation_table(rows, native), provenance=provenance)


def read_annotations(path: str | os.PathLike) -> list[Annotation]:
    """Read an annotation table written by :func:`write_annotations` (frames → 0-based).

    Every row is checked: a doc and a label, integer frames 1 ≤ start ≤ end, a cost that is
    a number or empty, a confidence in [0, 1] or empty (or no such column); a bad row is
    an error naming its line."""
    return read_annotation_table(path)[0]


def read_annotation_table(path: str | os.PathLike) -> tuple[list[Annotation], dict | None]:
    """:func:`read_annotations` and the table's provenance (None when it has none)."""
    from mtanno.util.tables import read_table

    table = read_table(path, what="annotation table")
    return _annotation_rows(table, native=False)[0], table.provenance


def _annotation_rows(table, *, native: bool = True
                     ) -> tuple[list[Annotation], list[tuple[int, int]] | None]:
    """The checked rows of an annotation table (:func:`read_annotations`) and, with
    ``native`` and when it has the columns start_native and end_native, each row's native
    start and end (checked too; else None)."""
    from mtanno.labels.truth import MAX_FRAME
    from mtanno.util.tables import parse_int, parse_text

    table.require(["doc", "start", "end", "label"])
    native = native and "start_native" in table.columns and "end_native" in table.columns
    out, pairs = [], []
    for i, row in enumerate(table.rows):
        doc, label = parse_text(table, i, "doc"), parse_text(table, i, "label")
        start = parse_int(table, i, "start", minimum=1, maximum=MAX_FRAME)
        end = parse_int(table, i, "end", minimum=1, maximum=MAX_FRAME)
        if end < start:
            raise table.error(i, f"start {start} is after end {end}")
        cost = row.get("cost")
        if cost is None:
            cost = float("inf")
        else:
            try:
                cost = float(cost)
            except (TypeError, ValueError):
                raise table.error(i, f"cost must be a number, got {cost!r}") from None
            if math.isnan(cost):
                raise table.error(i, "cost is NaN")
        conf = row.get("confidence")
        if conf is None:
            conf = math.nan
        else:
            try:
                conf = float(conf)
            except (TypeError, ValueError):
                raise table.error(i, f"confidence must be a number, got {conf!r}") from None
            if not 0.0 <= conf <= 1.0:
                raise table.error(i, f"confidence must be in [0, 1], got {conf!r}")
        out.append(Annotation(doc, start - 1, end - 1, label, cost, conf))
        if native:
            pairs.append((parse_int(table, i, "start_native", minimum=1),
                          parse_int(table, i, "end_native", minimum=1)))
    return out, (pairs if native else None)


#: Suffixes of the annotation tables a folder given to evaluate or report is searched for.
ANNOTATION_SUFFIXES = (".csv", ".parquet", ".jsonl")


def annotation_files(inputs: Sequence[str | os.PathLike]) -> list[str]:
    """Annotation tables named by ``inputs``: files (and ``-``) as given; a folder (the
    per-document tables of ``annotate --output-dir``) gives every table below it
    (``*.csv``, ``*.parquet``, ``*.jsonl``, sorted; hidden files and folders — locks,
    temporaries — skipped). A folder without tables is an error."""
    out: list[str] = []
    for item in inputs:
        p = Path(item)
        if str(item) != "-" and p.is_dir():
            found = sorted(q for q in p.rglob("*") if q.suffix.lower() in ANNOTATION_SUFFIXES
                           and not any(part.startswith(".") for part in q.relative_to(p).parts)
                           and q.is_file())
            if not found:
                raise MtannoError("no annotation tables (*.csv, *.parquet, *.jsonl) in this "
                                  "folder", path=str(p))
            out.extend(str(q) for q in found)
        else:
            out.append(str(item))
    return out


def merge_annotation_tables(paths: Sequence[str | os.PathLike]):
    """One annotation table (:class:`pyarrow.Table`) of the rows of several, each document
    in one of them only, sorted by document, start, end and label — what ``annotate -o``
    writes for the same documents — and the documents' frame counts their provenances
    record. The native columns are kept when every table has them."""
    from mtanno.util.tables import read_table

    rows: list[Annotation] = []
    pairs: list[tuple[int, int]] | None = []
    frames: dict[str, int] = {}
    where: dict[str, str] = {}
    for path in paths:
        table = read_table(path, what="annotation table")
        part, native = _annotation_rows(table)
        _claim_documents(where, part, path)
        rows.extend(part)
        pairs = None if pairs is None or native is None else pairs + native
        frames.update(_recorded_frames(table.provenance))
    order = sorted(range(len(rows)), key=lambda i: (rows[i].doc, rows[i].start, rows[i].end,
                                                    rows[i].label))
    return (_annotation_arrow([rows[i] for i in order],
                              None if pairs is None else [pairs[i] for i in order]), frames)


def _claim_documents(where: dict[str, str], rows: Sequence[Annotation], path) -> None:
    """Each document in one table only: else an error naming both files."""
    for d in sorted({a.doc for a in rows}):
        if d in where:
            raise MtannoError(f"document {d!r} is annotated in {where[d]} too; give each "
                              "document's annotation once", path=str(path))
        where[d] = str(path)


def _recorded_frames(prov: dict | None) -> dict[str, int]:
    from mtanno.util.tables import text

    recorded = (prov or {}).get("documents")
    if not isinstance(recorded, dict):
        return {}
    # named as the rows name them (a non-UTF-8 file name's bytes as \xNN: tables.text)
    return {text(str(k)): int(v) for k, v in recorded.items()
            if isinstance(v, int) and not isinstance(v, bool)}


def read_annotation_tables(paths: Sequence[str | os.PathLike]
                           ) -> tuple[list[Annotation], dict[str, int], list[dict]]:
    """The rows of several annotation tables (a run split over machines, or the
    per-document tables of ``annotate --output-dir``: :func:`annotation_files`), each
    document in one of them only (else an error naming both files); the documents' frame
    counts their provenance records (``annotate`` records them) and the provenances."""
    rows: list[Annotation] = []
    frames: dict[str, int] = {}
    provs: list[dict] = []
    where: dict[str, str] = {}
    for path in paths:
        part, prov = read_annotation_table(path)
        _claim_documents(where, part, path)
        rows.extend(part)
        provs.append(prov or {})
        frames.update(_recorded_frames(prov))
    return rows, frames, provs
