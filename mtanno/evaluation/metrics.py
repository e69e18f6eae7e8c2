"""Evaluation of annotations against ground truth (MBS09 §7).

All frames are 1-based inclusive at 30 Hz in the tables (:class:`mtanno.evaluation.truth.Segment`,
:class:`mtanno.annotate.Annotation` uses 0-based frames and is converted on entry).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from mtanno.evaluation.truth import Segment

#: Schema name of the evaluation JSON (``mtanno evaluate --json``).
EVALUATION_SCHEMA = "mtanno.evaluation/1"


@dataclass
class PRF:
    """Precision, recall and F-measure with the counts they come from."""

    tp_p: int = 0  # numerator of P
    n_p: int = 0   # denominator of P
    tp_r: int = 0  # numerator of R
    n_r: int = 0   # denominator of R

    @property
    def P(self) -> float:
        return self.tp_p / self.n_p if self.n_p else 0.0

    @property
    def R(self) -> float:
        return self.tp_r / self.n_r if self.n_r else 0.0

    @property
    def F(self) -> float:
        p, r = self.P, self.R
        return 2 * p * r / (p + r) if p + r else 0.0

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
    """P1/R1/F1 over all documents together and per class (MBS09 §7).

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
    truth segment is found if an output segment of its label overlaps it (MBS09 §7)."""
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


@dataclass
class Report:
    """Frame- and segment-level results, overall and per class."""

    frame: PRF
    segment: PRF
    per_class_frame: dict[str, PRF] = field(default_factory=dict)
    per_class_segment: dict[str, PRF] = field(default_factory=dict)
    documents: list[str] = field(default_factory=list)

    def rows(self) -> list[dict]:
        """One row per class, then ``overall``: P1 R1 F1 with frame support, P2 R2 F2 with
        segment support (the evaluation table ``evaluate -o`` writes)."""
        out = []
        classes = sorted(set(self.per_class_frame) | set(self.per_class_segment))
        for c, f, s in [*((c, self.per_class_frame.get(c, PRF()),
                           self.per_class_segment.get(c, PRF())) for c in classes),
                        ("overall", self.frame, self.segment)]:
            out.append({"class": c, "P1": f.P, "R1": f.R, "F1": f.F, "frames": f.n_r,
                        "P2": s.P, "R2": s.R, "F2": s.F, "segments": s.n_r})
        return out

    def as_dict(self) -> dict:
        """The report as JSON (``docs/annotation.md``): schema ``mtanno.evaluation/1``;
        every P/R/F with its support counts (truth frames and segments per class)."""
        classes = sorted(set(self.per_class_frame) | set(self.per_class_segment))
        return {
            "schema": EVALUATION_SCHEMA,
            "documents": sorted(self.documents),
            "frame": self.frame.as_dict(),
            "segment": self.segment.as_dict(),
            "per_class": {c: {"frame": self.per_class_frame.get(c, PRF()).as_dict(),
                              "segment": self.per_class_segment.get(c, PRF()).as_dict()}
                          for c in classes},
        }

    def table(self) -> str:
        """A readable table: one row per class and the overall row."""
        lines = [f"{'class':<32} {'P1':>6} {'R1':>6} {'F1':>6} {'frames':>7}   {'P2':>6} "
                 f"{'R2':>6} {'F2':>6} {'segs':>5}"]
        for r in self.rows():
            lines.append(f"{r['class']:<32} {r['P1']:6.3f} {r['R1']:6.3f} {r['F1']:6.3f} "
                         f"{r['frames']:7d}   {r['P2']:6.3f} {r['R2']:6.3f} {r['F2']:6.3f} "
                         f"{r['segments']:5d}")
        return "\n".join(lines)


def evaluate_annotations(truth: Sequence[Segment], output: Sequence[Segment],
                         *, documents: Iterable[str] | None = None) -> Report:
    """Frame- and segment-level evaluation; ``documents`` restricts both tables to those."""
    if documents is not None:
        docs = set(documents)
        truth = [s for s in truth if s.doc in docs]
        output = [s for s in output if s.doc in docs]
    else:
        docs = {s.doc for s in truth} | {s.doc for s in output}
    f, fc = frame_level(truth, output)
    s, sc = segment_level(truth, output)
    return Report(f, s, fc, sc, sorted(docs))
