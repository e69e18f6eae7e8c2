"""Evaluation of annotations and retrieval against ground truth (MBS09 §7; MR06 §5.4–5.5).

All frames are 1-based inclusive at 30 Hz in the tables (:class:`mtanno.truth.Segment`,
:class:`mtanno.annotate.Annotation` uses 0-based frames and is converted on entry).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from mtanno.truth import Segment

#: Schema name of the evaluation JSON (``mtanno evaluate --json``).
EVALUATION_SCHEMA = "mtanno.evaluation/1"
#: τ grid of the retrieval table (algorithms.md §8, MR06 Table 2).
TAU_GRID = (0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.09, 0.1)


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


def _overlaps(a: Segment, b: Segment) -> bool:
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
        ok = any(_overlaps(s, t) for t in by_key.get((s.doc, s.label), ()))
        for x in (per.setdefault(s.label, PRF()), total):
            x.n_p += 1
            x.tp_p += ok
    for t in truth:
        found = any(_overlaps(s, t) for s in out_by_key.get((t.doc, t.label), ()))
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


@dataclass
class RetrievalRow:
    """One class at one τ (MR06 Table 2): hits, relevant hits, occurrences, P, R."""

    label: str
    tau: float
    hits: int
    relevant: int
    occurrences: int

    @property
    def P(self) -> float:
        return self.relevant / self.hits if self.hits else 0.0

    @property
    def R(self) -> float:
        return self.relevant / self.occurrences if self.occurrences else 0.0


def retrieval_rows(label: str, hits: Sequence[Segment], costs: Sequence[float],
                   truth: Sequence[Segment], *, taus: Sequence[float] = TAU_GRID,
                   ) -> list[RetrievalRow]:
    """|H_τ|, |H_τ⁺| per τ for one class (algorithms.md §8).

    ``hits`` are one retrieval run at the largest τ, ranked by cost; since hits are taken
    greedily by increasing cost, the hits with cost ≤ τ are exactly the run at τ. A hit is
    relevant if it overlaps a truth occurrence of the class, each occurrence counted once:
    |H_τ⁺| is the size of a largest one-to-one pairing of hits with occurrences they
    overlap, so |H_τ⁺| ≤ min(|H_τ|, occurrences).
    """
    occ = [t for t in truth if t.label == label]
    rows = []
    for tau in taus:
        sel = [h for h, c in zip(hits, costs) if c <= tau + 1e-12]
        rows.append(RetrievalRow(label, tau, len(sel), _max_pairing(sel, occ), len(occ)))
    return rows


def _max_pairing(hits: Sequence[Segment], occ: Sequence[Segment]) -> int:
    """Largest one-to-one pairing of hits with overlapping occurrences (augmenting paths)."""
    adj = [[k for k, t in enumerate(occ) if _overlaps(h, t)] for h in hits]
    owner = [-1] * len(occ)

    def augment(i: int, seen: list[bool]) -> bool:
        for k in adj[i]:
            if not seen[k]:
                seen[k] = True
                if owner[k] < 0 or augment(owner[k], seen):
                    owner[k] = i
                    return True
        return False

    return sum(augment(i, [False] * len(occ)) for i in range(len(hits)) if adj[i])


def top_k_recall(hits: Sequence[Segment], truth: Sequence[Segment], label: str,
                 k: int) -> float:
    """Share of the class's occurrences overlapped by one of the ``k`` best hits."""
    occ = [t for t in truth if t.label == label]
    if not occ:
        return 0.0
    top = list(hits)[:k]
    return sum(any(_overlaps(h, t) for h in top) for t in occ) / len(occ)


def separation_quotient(delta_median: float, hits: Sequence[Segment], costs: Sequence[float],
                        truth: Sequence[Segment], label: str, *, top: int = 10) -> float:
    """s = median(Δ) / median(cost of the correct hits among the ``top`` best) (MR06 Table 4).

    Large values mean the correct hits stand out from the distance curve; ∞ when the best
    correct hit has cost 0, NaN when no correct hit is among the top.
    """
    occ = [t for t in truth if t.label == label]
    good = [c for h, c in list(zip(hits, costs))[:top] if any(_overlaps(h, t) for t in occ)]
    if not good:
        return float("nan")
    m = float(np.median(good))
    return float("inf") if m == 0 else float(delta_median) / m


@dataclass
class ClassRetrieval:
    """The retrieval evaluation of one class over a set of documents (MR06 Tables 2, 4)."""

    label: str
    rows: list[RetrievalRow]
    top_recall: dict[int, float]
    separation: float
    delta_median: float
    truncated: bool

    def as_dict(self) -> dict:
        return {"class": self.label, "delta_median": self.delta_median,
                "separation_quotient": self.separation, "cap_reached": self.truncated,
                "top_recall": {str(k): v for k, v in self.top_recall.items()},
                "taus": [{"tau": r.tau, "hits": r.hits, "relevant": r.relevant,
                          "occurrences": r.occurrences, "P": r.P, "R": r.R} for r in self.rows]}


def retrieval_evaluation(label: str, values: np.ndarray, weights: np.ndarray,
                         documents: Sequence[tuple[str, np.ndarray]], truth: Sequence[Segment],
                         *, taus: Sequence[float] = TAU_GRID, max_hits: int = 2000,
                         variant: str = "reference") -> ClassRetrieval:
    """Retrieve one class (quantized template) in every document and score the hits.

    One retrieval run per document at the largest τ (hit rules of algorithms.md §3.5), hits
    of all documents ranked together by cost. Reports |H_τ|, |H_τ⁺|, P, R per τ, the
    top-5/10/20 recall and the separation quotient with the median of all finite Δ.
    """
    from mtanno.retrieve import extract_hits
    from mtanno.templates.match import match_template

    hits, finite, truncated = [], [], False
    for name, X in documents:
        delta, start = match_template(values, weights, X, variant=variant)
        finite.append(delta[np.isfinite(delta)])
        h = extract_hits(delta, start, tau=max(taus), mode="retrieval", max_hits=max_hits,
                         doc=name)
        truncated |= bool(getattr(h, "truncated", False))
        hits.extend(h)
    hits.sort(key=lambda h: (h.cost, str(h.doc), h.end))
    segs = [Segment(str(h.doc), h.start + 1, h.end + 1, label) for h in hits]
    costs = [h.cost for h in hits]
    all_finite = np.concatenate(finite) if finite else np.zeros(0)
    med = float(np.median(all_finite)) if all_finite.size else float("nan")
    return ClassRetrieval(
        label=label, rows=retrieval_rows(label, segs, costs, truth, taus=taus),
        top_recall={k: top_k_recall(segs, truth, label, k) for k in (5, 10, 20)},
        separation=separation_quotient(med, segs, costs, truth, label), delta_median=med,
        truncated=truncated)


def retrieval_report(results: Sequence[ClassRetrieval]) -> str:
    """A readable table: one line per class and τ, then top-k recall and s."""
    lines = [f"{'class':<30} {'tau':>5} {'|H|':>5} {'|H+|':>5} {'occ':>4} {'P':>6} {'R':>6}"]
    for r in results:
        for row in r.rows:
            lines.append(f"{r.label:<30} {row.tau:5.2f} {row.hits:5d} {row.relevant:5d} "
                         f"{row.occurrences:4d} {row.P:6.3f} {row.R:6.3f}")
        tk = "  ".join(f"top-{k} recall {v:.2f}" for k, v in r.top_recall.items())
        cap = "  (hit cap reached)" if r.truncated else ""
        lines.append(f"{r.label:<30} {tk}  separation {r.separation:.2f}{cap}")
    return "\n".join(lines)


def retrieval_table(results: Sequence[ClassRetrieval]):
    """The retrieval table (``evaluate-retrieval -o``) as a :class:`pyarrow.Table`: one row
    per class and τ with hits, relevant hits, occurrences, P, R, and per class its top-k
    recall and separation quotient (repeated on each of its rows)."""
    import pyarrow as pa

    rows = []
    for r in results:
        for row in r.rows:
            rows.append({"class": r.label, "tau": row.tau, "hits": row.hits,
                         "relevant": row.relevant, "occurrences": row.occurrences,
                         "P": row.P, "R": row.R,
                         **{f"top{k}_recall": v for k, v in r.top_recall.items()},
                         "separation": r.separation, "cap_reached": r.truncated})
    if not rows:
        return pa.table({c: pa.array([], pa.string()) for c in ("class",)})
    return pa.Table.from_pylist(rows)
