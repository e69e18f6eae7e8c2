"""Evaluation of annotations against ground truth: [MBS09] §7's P1/R1/F1 (frames) and
P2/R2/F2 (segments), and in the same :class:`Report` the action-segmentation measures
(frame accuracy, Edit, F1@{10, 25, 50}: :mod:`mtanno.evaluation.segmentation`).

All frames are 1-based inclusive at 30 Hz in the tables (:class:`mtanno.labels.segments.Segment`,
:class:`mtanno.annotate.Annotation` uses 0-based frames and is converted on entry).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.evaluation.segmentation import (
    OVERLAPS,
    OverlapCounts,
    SegmentationScores,
    segmentation_scores,
)
from mtanno.labels.segments import Segment

#: Schema name of the evaluation JSON (``mtanno evaluate --json``).
EVALUATION_SCHEMA = "mtanno.evaluation/1"


def ratio(part: float, whole: float) -> float:
    """``part / whole``, 0.0 when ``whole`` is 0: precision and recall of nothing."""
    return part / whole if whole else 0.0


def f_measure(p: float, r: float) -> float:
    """The harmonic mean of precision ``p`` and recall ``r`` (0.0 when both are 0)."""
    return 2 * p * r / (p + r) if p + r else 0.0


@dataclass
class PRF:
    """Precision, recall and F-measure with the counts they come from."""

    tp_p: int = 0  # numerator of P
    n_p: int = 0   # denominator of P
    tp_r: int = 0  # numerator of R
    n_r: int = 0   # denominator of R

    P = property(lambda self: ratio(self.tp_p, self.n_p), doc="Precision tp_p / n_p.")
    R = property(lambda self: ratio(self.tp_r, self.n_r), doc="Recall tp_r / n_r.")
    F = property(lambda self: f_measure(self.P, self.R), doc="F-measure of P and R.")

    def as_dict(self) -> dict[str, float]:
        """P, R, F and the counts: ``support`` (truth frames or segments), ``predicted``
        (output frames or segments), ``correct`` (matched, numerator of R)."""
        return {"P": self.P, "R": self.R, "F": self.F, "support": self.n_r,
                "predicted": self.n_p, "correct": self.tp_r}


def _frame_sets(segments: Iterable[Segment]) -> dict[tuple[str, str], np.ndarray]:
    """(doc, label) → the frames covered, as sorted disjoint [start, end] intervals (k × 2;
    a frame may carry several labels, but counts once per label)."""
    acc: dict[tuple[str, str], list[tuple[int, int]]] = {}
    for s in segments:
        acc.setdefault((s.doc, s.label), []).append((s.start, s.end))
    out = {}
    for key, spans in acc.items():
        spans.sort()
        merged = [list(spans[0])]
        for a, b in spans[1:]:
            if a <= merged[-1][1] + 1:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b])
        out[key] = np.array(merged, dtype=np.int64)
    return out


def _covered(iv: np.ndarray) -> int:
    return int((iv[:, 1] - iv[:, 0] + 1).sum()) if len(iv) else 0


def _intersection(a: np.ndarray, b: np.ndarray) -> int:
    """Frames in both of two sorted disjoint interval lists."""
    i = j = total = 0
    while i < len(a) and j < len(b):
        lo, hi = max(a[i, 0], b[j, 0]), min(a[i, 1], b[j, 1])
        if lo <= hi:
            total += int(hi - lo + 1)
        if a[i, 1] < b[j, 1]:
            i += 1
        else:
            j += 1
    return total


def frame_level(truth: Sequence[Segment], output: Sequence[Segment]) -> tuple[PRF, dict[str, PRF]]:
    """P1/R1/F1 over all documents together and per class ([MBS09] §7).

    M = {(frame, label)} of the truth, A = of the output; P1 = |M∩A|/|A|, R1 = |M∩A|/|M|.
    Computed on merged frame intervals, so the cost does not grow with segment lengths.
    """
    M = _frame_sets(truth)
    A = _frame_sets(output)
    total = PRF()
    per: dict[str, PRF] = {}
    empty = np.zeros((0, 2), np.int64)
    for key in set(M) | set(A):
        m = M.get(key, empty)
        a = A.get(key, empty)
        inter = _intersection(m, a)
        c = per.setdefault(key[1], PRF())
        for x in (c, total):
            x.tp_p += inter
            x.tp_r += inter
            x.n_p += _covered(a)
            x.n_r += _covered(m)
    return total, per


def overlaps(a: Segment, b: Segment) -> bool:
    return a.doc == b.doc and a.start <= b.end and b.start <= a.end


def segment_level(truth: Sequence[Segment], output: Sequence[Segment]) -> tuple[PRF, dict[str, PRF]]:
    """P2/R2/F2: an output segment is correct if it overlaps a truth segment of its label; a
    truth segment is found if an output segment of its label overlaps it ([MBS09] §7)."""
    by_key: dict[tuple[str, str], list[Segment]] = {}
    for s in truth:
        by_key.setdefault((s.doc, s.label), []).append(s)
    out_by_key: dict[tuple[str, str], list[Segment]] = {}
    for s in output:
        out_by_key.setdefault((s.doc, s.label), []).append(s)
    total = PRF()
    per: dict[str, PRF] = {}
    for s in output:
        ok = any(overlaps(s, t) for t in by_key.get((s.doc, s.label), ()))
        for x in (per.setdefault(s.label, PRF()), total):
            x.n_p += 1
            x.tp_p += ok
    for t in truth:
        found = any(overlaps(s, t) for s in out_by_key.get((t.doc, t.label), ()))
        for x in (per.setdefault(t.label, PRF()), total):
            x.n_r += 1
            x.tp_r += found
    return total, per


#: Columns of the field's measures in :meth:`Report.rows` and the text table, and their
#: JSON keys (:mod:`mtanno.evaluation.segmentation`).
SEGMENTATION_COLUMNS = {"Acc": "accuracy", "Edit": "edit", "F1@10": "f1_10", "F1@25": "f1_25",
                        "F1@50": "f1_50"}


def _defined(prf: PRF) -> tuple[float | None, float | None, float | None]:
    """(P, R, F) with None where undefined: P without predictions, R without truth, F
    without either (with one of them, F is 0)."""
    return (prf.P if prf.n_p else None, prf.R if prf.n_r else None,
            prf.F if prf.n_p or prf.n_r else None)


@dataclass
class Report:
    """Frame- and segment-level results, overall and per class: [MBS09]'s P/R/F and the
    action-segmentation measures (``segmentation``: frame accuracy, Edit, F1@k), and
    ``warnings`` about the inputs (one sentence each, e.g. truth and annotation without a
    common label)."""

    frame: PRF
    segment: PRF
    per_class_frame: dict[str, PRF] = field(default_factory=dict)
    per_class_segment: dict[str, PRF] = field(default_factory=dict)
    documents: list[str] = field(default_factory=list)
    segmentation: SegmentationScores | None = None
    warnings: list[str] = field(default_factory=list)

    def classes(self) -> list[str]:
        return sorted(set(self.per_class_frame) | set(self.per_class_segment))

    def _field_measures(self, label: str | None) -> dict[str, float | None]:
        """The JSON keys of :data:`SEGMENTATION_COLUMNS` of one class (``None``: overall);
        Edit only overall."""
        s = self.segmentation
        if s is None:
            return dict.fromkeys(SEGMENTATION_COLUMNS.values())
        if label is None:
            out = {"accuracy": s.accuracy, "edit": s.edit}
            out.update({f"f1_{k}": s.f1(k) for k in OVERLAPS})
        else:
            out = {"accuracy": s.class_accuracy(label), "edit": None}
            out.update({f"f1_{k}": s.class_f1(label, k) for k in OVERLAPS})
        return out

    def rows(self) -> list[dict]:
        """One row per class, then ``overall``: P1 R1 F1 with frame support, P2 R2 F2 with
        segment support, then Acc, Edit (overall only), F1@10, F1@25, F1@50 (the evaluation
        table ``evaluate -o`` writes). Undefined values are None (empty in CSV): P without
        predictions, R without truth, F without either, Acc of a class without truth
        frames, F1@k of a class without segments."""
        out = []
        for c, f, s in [*((c, self.per_class_frame.get(c, PRF()),
                           self.per_class_segment.get(c, PRF())) for c in self.classes()),
                        ("overall", self.frame, self.segment)]:
            (p1, r1, f1), (p2, r2, f2) = _defined(f), _defined(s)
            row = {"class": c, "P1": p1, "R1": r1, "F1": f1, "frames": f.n_r,
                   "P2": p2, "R2": r2, "F2": f2, "segments": s.n_r}
            m = self._field_measures(None if c == "overall" else c)
            row.update({col: m[key] for col, key in SEGMENTATION_COLUMNS.items()})
            out.append(row)
        return out

    def as_dict(self) -> dict:
        """The report as JSON (``docs/annotation.md``): schema ``mtanno.evaluation/1``;
        every P/R/F with its support counts (truth frames and segments per class; P, R, F
        are 0 where undefined, the counts tell), and ``accuracy``, ``edit``, ``f1_10``,
        ``f1_25``, ``f1_50`` (0–1, null where undefined; per class without ``edit``) with
        their counts under ``segmentation``."""
        s = self.segmentation
        out = {
            "schema": EVALUATION_SCHEMA,
            "documents": sorted(self.documents),
            "frame": self.frame.as_dict(),
            "segment": self.segment.as_dict(),
            **self._field_measures(None),
            "segmentation": None if s is None else {
                "frames": s.frames, "correct_frames": s.correct,
                "edit_documents": len(s.edit_per_document),
                "f1_counts": {str(k): s.overlap[k].as_dict() for k in OVERLAPS}},
            "per_class": {},
        }
        for c in self.classes():
            m = self._field_measures(c)
            del m["edit"]
            out["per_class"][c] = {
                "frame": self.per_class_frame.get(c, PRF()).as_dict(),
                "segment": self.per_class_segment.get(c, PRF()).as_dict(), **m,
                "segmentation": None if s is None else {
                    "frames": s.class_frames.get(c, 0), "correct_frames": s.class_correct.get(c, 0),
                    "f1_counts": {str(k): (s.class_overlap[c][k] if c in s.class_overlap
                                           else OverlapCounts()).as_dict() for k in OVERLAPS}}}
        return out

    def table(self) -> str:
        """A readable table: one row per class and the overall row; "–" where a value is
        undefined (see :meth:`rows`)."""
        def num(x: float | None) -> str:
            return f"{'–':>6}" if x is None else f"{x:6.3f}"

        extra = " ".join(f"{c:>6}" for c in SEGMENTATION_COLUMNS)
        lines = [f"{'class':<32} {'P1':>6} {'R1':>6} {'F1':>6} {'frames':>7}   {'P2':>6} "
                 f"{'R2':>6} {'F2':>6} {'segs':>5}   {extra}"]
        for r in self.rows():
            lines.append(f"{r['class']:<32} {num(r['P1'])} {num(r['R1'])} {num(r['F1'])} "
                         f"{r['frames']:7d}   {num(r['P2'])} {num(r['R2'])} {num(r['F2'])} "
                         f"{r['segments']:5d}   "
                         + " ".join(num(r[c]) for c in SEGMENTATION_COLUMNS))
        return "\n".join(lines)


def label_warnings(truth: Sequence[Segment], output: Sequence[Segment],
                   n_documents: int) -> list[str]:
    """What makes every figure of an evaluation 0 for a reason other than the annotation's
    quality: truth without segments in the documents evaluated, or truth and annotation
    without a common label (a truth table of other classes or other label spellings)."""
    t, o = {s.label for s in truth}, {s.label for s in output}
    if o and not t:
        return [f"the truth has no segment in the {n_documents} document(s) evaluated"]
    if t and o and not t & o:
        def some(labels: set[str]) -> str:
            names = sorted(labels)
            return ", ".join(names[:5]) + (f", … ({len(names)} labels)" if len(names) > 5 else "")

        return [f"the truth shares no label with the annotation (truth: {some(t)}; "
                f"annotation: {some(o)}): no segment and no labelled frame can count as right"]
    return []


def evaluate_annotations(truth: Sequence[Segment], output: Sequence[Segment],
                         *, documents: Iterable[str] | None = None,
                         frames: dict[str, int] | None = None) -> Report:
    """Frame- and segment-level evaluation; ``documents`` restricts both tables to those.
    ``frames`` (document → length in 30 Hz frames, e.g. what annotation tables record)
    sets how many frames frame accuracy counts per document, the unlabelled tail included;
    without it a document ends at its last frame covered by truth or output."""
    if documents is not None:
        docs = set(documents)
        truth = [s for s in truth if s.doc in docs]
        output = [s for s in output if s.doc in docs]
    else:
        docs = {s.doc for s in truth} | {s.doc for s in output}
    f, fc = frame_level(truth, output)
    s, sc = segment_level(truth, output)
    return Report(f, s, fc, sc, sorted(docs),
                  segmentation=segmentation_scores(truth, output, docs, frames=frames),
                  warnings=label_warnings(truth, output, len(docs)))


def documents_evaluated(truth: Sequence[Segment], output: Sequence[Segment],
                        frames: dict[str, int] | None = None, *,
                        docs: Sequence[str] = (), all_docs: bool = False) -> set[str] | None:
    """The documents an evaluation counts (the one rule of ``mtanno evaluate`` and
    :func:`mtanno.api.evaluate_annotation`): ``docs`` when given (each must be in the truth
    or the output); every truth document with ``all_docs`` (None: no restriction); else the
    annotated documents — those with output segments and those ``frames`` records as
    annotated without any — or, when there are none, the truth's."""
    from mtanno.errors import MtannoError

    if docs:
        known = {s.doc for s in truth} | {s.doc for s in output}
        unknown = [d for d in docs if d not in known]
        if unknown:
            raise MtannoError(f"{{doc}} {unknown[0]} is in neither the truth nor the "
                              "annotations", options=("doc",))
        return set(docs)
    if all_docs:
        return None
    return ({s.doc for s in output} | set(frames or {})) or {s.doc for s in truth}


def evaluate_files(annotations: Sequence[str], truth: str, *, docs: Sequence[str] = (),
                   all_docs: bool = False) -> Report:
    """:func:`evaluate_annotations` of annotation table files (each document in one of
    them only) against a truth table file, over :func:`documents_evaluated`; a truth
    segment past the end of a document whose length the annotations record is an error
    naming the truth file."""
    from mtanno.annotate.tables import read_annotation_tables
    from mtanno.labels.segments import to_segments
    from mtanno.labels.truth import check_within, read_truth

    truth_segments = read_truth(truth)
    rows, frames, _ = read_annotation_tables(annotations)
    output = to_segments(rows)
    check_within(truth_segments, frames, path=truth)
    documents = documents_evaluated(truth_segments, output, frames, docs=docs,
                                    all_docs=all_docs)
    return evaluate_annotations(truth_segments, output, documents=documents, frames=frames)


def check_one_stdout(json_path: str | None, table_path: str | None) -> None:
    """The JSON and the table output of ``evaluate`` and ``evaluate-retrieval`` may not both
    be standard output (``-``)."""
    if json_path == "-" and table_path == "-":
        raise MtannoError("{json_path} - and {table_path} - would both write to standard output",
                          options=("json_path", "table_path"))


def evaluate_to(annotations: Sequence[str], truth_path: str, *,
                json_path: str | None = None, table_path: str | None = None,
                docs: Sequence[str] = (), all_docs: bool = False,
                warn: Callable[[str], None] | None = None) -> Report:
    """The whole ``mtanno evaluate`` run ([MBS09] §7): :func:`evaluate_files` of the
    annotation tables ``annotations`` names (files, folders of tables; ``-`` reads CSV from
    standard input, once) against the truth table ``truth_path``; the report as text on
    standard output unless ``json_path`` or ``table_path`` is ``-``, as JSON (schema
    :data:`EVALUATION_SCHEMA`) to ``json_path`` and as the per-class table to
    ``table_path``, each with its provenance. Every output is checked against the inputs
    first; ``warn`` receives the report's warnings (labels only one side knows)."""
    from mtanno.annotate import ANNOTATION_SUFFIXES, annotation_files
    from mtanno.util.output import write_stdout
    from mtanno.util.preflight import check_outputs
    from mtanno.util.provenance import provenance
    from mtanno.util.tables import output_files, table_format, write_json, write_table

    if table_path is not None:
        table_format(table_path)
    scanned = {a: ANNOTATION_SUFFIXES for a in annotations if a != "-" and Path(a).is_dir()}
    annotations = annotation_files(annotations)
    inputs = [*annotations, truth_path]
    if sum(str(i) == "-" for i in inputs) > 1:
        raise MtannoError("standard input (-) can be read only once")
    check_outputs([json_path, *output_files(table_path)], inputs, scanned=scanned)
    check_one_stdout(json_path, table_path)
    report = evaluate_files(annotations, truth_path, docs=docs, all_docs=all_docs)
    for warning in report.warnings:
        if warn:
            warn(warning)
    if json_path != "-" and table_path != "-":
        write_stdout(report.table() + "\n")  # a full device: one line saying so
    prov = provenance(inputs=inputs, truth=str(truth_path))
    if json_path:
        write_json(json_path, {**report.as_dict(), "provenance": prov})
    if table_path:
        import pyarrow as pa

        write_table(table_path, pa.Table.from_pylist(report.rows()), provenance=prov)
    return report
