"""The action-segmentation measures the literature reports: frame accuracy, the Edit score
and F1@{10, 25, 50} (Lea et al., "Temporal Convolutional Networks for Action Segmentation and
Detection", CVPR 2017; as computed by MS-TCN, Farha & Gall, CVPR 2019, and its successors).

They complement [MBS09]'s P1/R1/F1 and P2/R2/F2 (:mod:`mtanno.evaluation.metrics`): P2/R2
count a segment right when it shares one frame with a truth segment of its label, with no
one-to-one matching; F1@k matches one to one by intersection over union, and the Edit
score penalises over-segmentation and wrong order.

All frames are 1-based inclusive at 30 Hz (:class:`~mtanno.labels.segments.Segment`). The
measures are computed on the segments as the tables list them — adjacent segments of one
label are not merged. Definitions (``docs/annotation.md``, "mtanno evaluate"):

* **Frame accuracy** — per document every frame 1 … n has one true and one predicted label,
  "none" where no segment covers it; n is the document's length when known, else its last
  frame covered by a truth or output segment. Where segments of one table overlap, a frame
  takes the label of the covering segment that starts last; at equal starts the one that
  ends first; at equal starts and ends the label first in alphabetical order
  (:func:`frame_labels`). Accuracy = frames whose two labels are equal ("none" = "none"
  counts) / all frames, pooled over the documents. Per class c: the frames whose true label
  is c and predicted label is c / the frames whose true label is c (a recall of c in the one
  label per frame view; undefined when no frame is truly c).
* **Edit score** — per document, the labels of its truth segments and of its output
  segments, each sorted by (start, end, label), give two sequences t and p; Edit =
  1 − D(t, p) / max(|t|, |p|) with D the Levenshtein distance (insertions, deletions,
  substitutions of cost 1). Averaged over the documents with at least one segment; 0–1
  (MS-TCN prints × 100). Overall only: restricted to one class both sequences repeat one
  label, and the score degenerates to min(|t|, |p|) / max(|t|, |p|), a ratio of counts that
  ignores order and position.
* **F1@k**, k ∈ {10, 25, 50} — per document, the output segments in (start, end, label)
  order: each takes the truth segment of its label with the highest IoU (intersection /
  union of their frame ranges; at equal IoU the earlier truth segment). It is a true
  positive when IoU ≥ k / 100 and that truth segment was not taken before, else a false
  positive (also when the best one is taken and another would qualify — the greedy rule of
  MS-TCN). False negatives: truth segments never taken. TP, FP, FN are summed over the
  documents (and over the classes for the overall figure); P = TP / (TP + FP), R = TP / (TP +
  FN), F1@k = 2PR / (P + R), 0 when TP = 0, undefined when TP + FP + FN = 0.

Undefined values are ``None``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from mtanno.labels.segments import Segment

#: The IoU thresholds of F1@k, in percent (Lea et al. 2017; MS-TCN).
OVERLAPS = (10, 25, 50)


@dataclass
class OverlapCounts:
    """True positives, false positives and false negatives of F1@k (segments)."""

    tp: int = 0
    fp: int = 0
    fn: int = 0

    @property
    def P(self) -> float | None:
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else None

    @property
    def R(self) -> float | None:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else None

    @property
    def F(self) -> float | None:
        """2PR / (P + R) = 2 TP / (2 TP + FP + FN); None when there is no segment at all."""
        n = 2 * self.tp + self.fp + self.fn
        return 2 * self.tp / n if n else None

    def add(self, other: OverlapCounts) -> None:
        self.tp += other.tp
        self.fp += other.fp
        self.fn += other.fn

    def as_dict(self) -> dict[str, int]:
        return {"tp": self.tp, "fp": self.fp, "fn": self.fn}


def _per_k() -> dict[int, OverlapCounts]:
    return {k: OverlapCounts() for k in OVERLAPS}


@dataclass
class SegmentationScores:
    """Frame accuracy, Edit and F1@k of an evaluation, overall and per class, with the
    counts they come from (module docstring)."""

    #: frames evaluated (all documents) and those whose true and predicted labels agree
    frames: int = 0
    correct: int = 0
    #: per class: frames whose true label is the class, and those also predicted so
    class_frames: dict[str, int] = field(default_factory=dict)
    class_correct: dict[str, int] = field(default_factory=dict)
    #: Edit score of each document with at least one segment
    edit_per_document: dict[str, float] = field(default_factory=dict)
    #: F1@k counts, k in percent: overall and per class
    overlap: dict[int, OverlapCounts] = field(default_factory=_per_k)
    class_overlap: dict[str, dict[int, OverlapCounts]] = field(default_factory=dict)

    @property
    def accuracy(self) -> float | None:
        """Frame accuracy, 0–1; None when no frame was evaluated."""
        return self.correct / self.frames if self.frames else None

    @property
    def edit(self) -> float | None:
        """Mean Edit score over the documents with segments, 0–1; None without any."""
        v = self.edit_per_document
        return sum(v.values()) / len(v) if v else None

    def f1(self, k: int) -> float | None:
        """F1@k overall, 0–1."""
        return self.overlap[k].F

    def class_accuracy(self, label: str) -> float | None:
        """Frames of ``label`` in the truth also predicted ``label`` / its truth frames."""
        n = self.class_frames.get(label, 0)
        return self.class_correct.get(label, 0) / n if n else None

    def class_f1(self, label: str, k: int) -> float | None:
        """F1@k of one class, 0–1."""
        c = self.class_overlap.get(label)
        return c[k].F if c else None


def frame_labels(segments: Iterable[Segment], n: int, rank: dict[str, int]) -> np.ndarray:
    """One label per frame of a document of ``n`` frames: ``rank[label]`` at 0-based index
    frame − 1, −1 where no segment covers the frame. Overlaps: the covering segment that
    starts last wins; at equal starts the one that ends first; then the label of smaller
    rank (``rank`` numbers the labels in alphabetical order). Segments are painted in the
    reverse of that priority, so the winner is painted last."""
    out = np.full(n, -1, dtype=np.int64)
    for s in sorted(segments, key=lambda s: (s.start, -s.end, -rank[s.label])):
        lo, hi = max(s.start, 1), min(s.end, n)
        if lo <= hi:
            out[lo - 1:hi] = rank[s.label]
    return out


def levenshtein(a: Sequence, b: Sequence) -> int:
    """Edit distance between two sequences: the fewest insertions, deletions and
    substitutions (each of cost 1) that turn ``a`` into ``b``. The dynamic programme of
    Wagner–Fischer, one row at a time and each row in numpy: with
    base[j] = min(D[i−1][j] + 1, D[i−1][j−1] + [a_i ≠ b_j]) and base[0] = i, the insertion
    term makes D[i][j] = min over k ≤ j of base[k] + (j − k), a running minimum of
    base − j. O(|a|·|b|) time."""
    if len(a) < len(b):
        a, b = b, a
    if not b:
        return len(a)
    codes: dict = {}
    x = np.array([codes.setdefault(v, len(codes)) for v in a], dtype=np.int64)
    y = np.array([codes.setdefault(v, len(codes)) for v in b], dtype=np.int64)
    j = np.arange(len(y) + 1, dtype=np.int64)
    prev = j.copy()
    base = np.empty_like(prev)
    for i, xi in enumerate(x, 1):
        base[0] = i
        np.minimum(prev[1:] + 1, prev[:-1] + (y != xi), out=base[1:])
        prev = np.minimum.accumulate(base - j) + j
    return int(prev[-1])


def edit_score(truth_labels: Sequence[str], output_labels: Sequence[str]) -> float | None:
    """1 − D / max(|truth|, |output|) (Lea et al. 2017), 0–1; None when both are empty."""
    m = max(len(truth_labels), len(output_labels))
    return 1.0 - levenshtein(truth_labels, output_labels) / m if m else None


def _order(segments: Iterable[Segment]) -> list[Segment]:
    return sorted(segments, key=lambda s: (s.start, s.end, s.label))


def overlap_counts(truth: Sequence[Segment], output: Sequence[Segment],
                   k: int) -> OverlapCounts:
    """F1@k counts of one document and one label (the segments all share both): the greedy
    one-to-one matching of the module docstring. IoU ≥ k / 100 is tested exactly, in
    integers (100 · intersection ≥ k · union)."""
    t = _order(truth)
    starts = np.array([s.start for s in t], dtype=np.int64)
    ends = np.array([s.end for s in t], dtype=np.int64)
    taken = np.zeros(len(t), dtype=bool)
    c = OverlapCounts()
    for s in _order(output):
        if not len(t):
            c.fp += 1
            continue
        inter = np.maximum(0, np.minimum(ends, s.end) - np.maximum(starts, s.start) + 1)
        union = (ends - starts + 1) + s.length - inter
        iou = inter / union
        best = int(np.argmax(iou))  # the first of equal IoUs: the earlier truth segment
        # iou[best] is a ratio of integers; compare the integers so that IoU = k/100 counts
        if 100 * inter[best] >= k * union[best] and not taken[best]:
            c.tp += 1
            taken[best] = True
        else:
            c.fp += 1
    c.fn = int((~taken).sum())
    return c


def _grouped(segments: Iterable[Segment]) -> dict[str, list[Segment]]:
    out: dict[str, list[Segment]] = {}
    for s in segments:
        out.setdefault(s.doc, []).append(s)
    return out


def segmentation_scores(truth: Sequence[Segment], output: Sequence[Segment],
                        documents: Iterable[str], *,
                        frames: dict[str, int] | None = None) -> SegmentationScores:
    """Frame accuracy, Edit and F1@{10, 25, 50} of ``output`` against ``truth`` over
    ``documents`` (segments of other documents are ignored); ``frames`` gives documents'
    lengths in 30 Hz frames (a document's last covered frame when absent or shorter)."""
    frames = frames or {}
    docs = sorted(set(documents))
    T, O = _grouped(truth), _grouped(output)
    labels = sorted({s.label for d in docs for s in (*T.get(d, ()), *O.get(d, ()))})
    rank = {lab: i for i, lab in enumerate(labels)}
    r = SegmentationScores()
    r.class_frames = dict.fromkeys(labels, 0)
    r.class_correct = dict.fromkeys(labels, 0)
    r.class_overlap = {lab: _per_k() for lab in labels}
    for d in docs:
        t, o = T.get(d, []), O.get(d, [])
        n = max([frames.get(d, 0), *(s.end for s in t), *(s.end for s in o)])
        tl, ol = frame_labels(t, n, rank), frame_labels(o, n, rank)
        same = tl == ol
        r.frames += n
        r.correct += int(same.sum())
        tf = np.bincount(tl[tl >= 0], minlength=len(labels))
        cf = np.bincount(tl[same & (tl >= 0)], minlength=len(labels))
        for lab, i in rank.items():
            r.class_frames[lab] += int(tf[i])
            r.class_correct[lab] += int(cf[i])
        e = edit_score([s.label for s in _order(t)], [s.label for s in _order(o)])
        if e is not None:
            r.edit_per_document[d] = e
        for lab in sorted({s.label for s in t} | {s.label for s in o}):
            ts = [s for s in t if s.label == lab]
            os_ = [s for s in o if s.label == lab]
            for k in OVERLAPS:
                c = overlap_counts(ts, os_, k)
                r.class_overlap[lab][k].add(c)
                r.overlap[k].add(c)
    return r
