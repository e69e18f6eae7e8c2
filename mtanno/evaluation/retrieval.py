"""Evaluation of retrieval against ground truth ([MR06] §5.4–5.5, docs/method.md §8): hits
and relevant hits per τ, top-k recall, the separation quotient, per class.

:func:`evaluate_retrieval_to` is the whole ``mtanno evaluate-retrieval`` run.

Frames are 1-based inclusive at 30 Hz (:class:`mtanno.labels.segments.Segment`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mtanno.evaluation.metrics import overlaps, ratio
from mtanno.labels.segments import Segment
from mtanno.templates.params import RETRIEVAL_DELTA

#: Hit cap per class and document of the retrieval table (the reference driver's).
DEFAULT_MAX_HITS = 2000
#: τ grid of the retrieval table (docs/method.md §8, [MR06] Table 2).
TAU_GRID = (0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.09, 0.1)


@dataclass
class RetrievalRow:
    """One class at one τ ([MR06] Table 2): hits, relevant hits, occurrences, P, R."""

    label: str
    tau: float
    hits: int
    relevant: int
    occurrences: int

    P = property(lambda self: ratio(self.relevant, self.hits), doc="Precision relevant / hits.")
    R = property(lambda self: ratio(self.relevant, self.occurrences),
                 doc="Recall relevant / occurrences.")


def retrieval_rows(label: str, hits: Sequence[Segment], costs: Sequence[float],
                   truth: Sequence[Segment], *, taus: Sequence[float] = TAU_GRID,
                   ) -> list[RetrievalRow]:
    """|H_τ|, |H_τ⁺| per τ for one class (docs/method.md §8).

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
    adj = [[k for k, t in enumerate(occ) if overlaps(h, t)] for h in hits]
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
    return sum(any(overlaps(h, t) for h in top) for t in occ) / len(occ)


def separation_quotient(delta_median: float, hits: Sequence[Segment], costs: Sequence[float],
                        truth: Sequence[Segment], label: str, *, top: int = 10) -> float:
    """s = median(Δ) / median(cost of the correct hits among the ``top`` best) ([MR06] Table 4).

    Large values mean the correct hits stand out from the distance curve; ∞ when the best
    correct hit has cost 0, NaN when no correct hit is among the top.
    """
    occ = [t for t in truth if t.label == label]
    good = [c for h, c in list(zip(hits, costs))[:top] if any(overlaps(h, t) for t in occ)]
    if not good:
        return float("nan")
    m = float(np.median(good))
    return float("inf") if m == 0 else float(delta_median) / m


@dataclass
class ClassRetrieval:
    """The retrieval evaluation of one class over a set of documents ([MR06] Tables 2, 4)."""

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
                         *, taus: Sequence[float] = TAU_GRID, max_hits: int = DEFAULT_MAX_HITS,
                         variant: str = "reference") -> ClassRetrieval:
    """Retrieve one class (quantized template) in every document and score the hits.

    One retrieval run per document at the largest τ (hit rules of docs/method.md §3.5), hits
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


@dataclass
class RetrievalRun:
    """What :func:`evaluate_retrieval_files` measured: one :class:`ClassRetrieval` per
    template, the feature files used (path, SHA-256), and one message per file that could
    not be used (it was left out; the others were measured)."""

    results: list
    files: list[dict]
    failed: list[str]
    missing: list[str] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        """0 when every input was measured, else 1 (:func:`evaluate_retrieval_to`)."""
        return 1 if self.failed or self.missing else 0


def evaluate_retrieval_files(models, layout, paths, truth: Sequence[Segment], *,
                             max_hits: int, truth_path: str | None = None,
                             progress=None) -> RetrievalRun:
    """:func:`retrieval_evaluation` of every class model (quantized templates,
    :func:`mtanno.annotate.load_class_models`, with their feature ``layout``) over the
    feature files ``paths`` ([MR06] Tables 2 and 4). A file that cannot be read or has
    another layout is recorded in ``failed`` and left out; ``progress(message)`` is called
    with each such message. A truth segment past the end of its document is an error
    naming ``truth_path``."""
    from mtanno.errors import MtannoError
    from mtanno.features.store import check_layout, read_features
    from mtanno.labels.truth import check_within

    documents, files, failed = [], [], []
    for p in paths:
        try:
            ff = read_features(p, sha256=True)
            check_layout(ff, layout)
        except MtannoError as exc:
            failed.append(str(exc))
            if progress:
                progress(str(exc))
            continue
        documents.append((ff.document, ff.X))
        files.append({"path": str(p), "sha256": ff.sha256})
    check_within(truth, {name: X.shape[1] for name, X in documents}, path=truth_path)
    results = [retrieval_evaluation(m.name, m.values, m.weights, documents, truth,
                                    max_hits=max_hits) for m in models]
    return RetrievalRun(results, files, failed)


def evaluate_retrieval_to(features: Sequence[str | os.PathLike], mt_dir: str | os.PathLike,
                          truth_path: str, *, delta: float = RETRIEVAL_DELTA,
                          max_hits: int = DEFAULT_MAX_HITS, classes: Sequence[str] = (),
                          json_path: str | None = None, table_path: str | None = None,
                          on_start: Callable[[list[str]], None] | None = None,
                          progress: Callable[[str], None] | None = None) -> RetrievalRun:
    """The whole ``mtanno evaluate-retrieval`` run ([MR06] Tables 2 and 4): the templates of
    ``mt_dir`` (a folder or one template; only ``classes``, if given) quantized with
    ``delta``, each retrieved in every feature file ``features`` names (files, folders
    searched recursively) with at most ``max_hits`` hits per document
    (:func:`evaluate_retrieval_files`), measured against the truth table ``truth_path``.
    The table as text on standard output unless ``json_path`` or ``table_path`` is ``-``,
    the results as JSON (schema ``mtanno.retrieval-evaluation/1``) to ``json_path`` and as
    a table (one row per class and τ) to ``table_path``, each with its provenance. Every
    output is checked against the inputs first.

    ``on_start(missing)`` is called before the first document is read, with the messages
    of the inputs that named no feature file; ``progress(message)`` with each feature file
    that could not be used."""
    from mtanno.annotate import load_class_models
    from mtanno.evaluation.metrics import check_one_stdout
    from mtanno.features.inputs import document_files
    from mtanno.labels.truth import read_truth
    from mtanno.templates.store import template_files
    from mtanno.util.output import write_stdout
    from mtanno.util.preflight import check_outputs
    from mtanno.util.provenance import provenance
    from mtanno.util.tables import output_files, table_format, write_json, write_table

    if table_path is not None:
        table_format(table_path)
    check_one_stdout(json_path, table_path)
    missing: list[str] = []  # inputs naming no feature file: reported, the batch goes on
    paths = document_files(features, failures=missing)
    check_outputs([json_path, *output_files(table_path)],
                  [mt_dir, *template_files(mt_dir), truth_path, *paths],
                  scanned={f: (".parquet",) for f in features if Path(f).is_dir()})
    models, key = load_class_models(mt_dir, delta=delta, classes=tuple(classes))
    truth = read_truth(truth_path)
    if on_start:
        on_start(missing)
    run = evaluate_retrieval_files(models, key, paths, truth, max_hits=max_hits,
                                   truth_path=truth_path, progress=progress)
    run.missing = missing
    if json_path != "-" and table_path != "-":
        write_stdout(retrieval_report(run.results) + "\n")
    prov = provenance(inputs=[*run.files, truth_path], templates=[m.record() for m in models],
                      delta=delta, max_hits=max_hits, feature_set=key.feature_set)
    if json_path:
        write_json(json_path, {"schema": "mtanno.retrieval-evaluation/1",
                               "classes": [r.as_dict() for r in run.results],
                               "provenance": prov})
    if table_path:
        write_table(table_path, retrieval_table(run.results), provenance=prov)
    return run
