"""The evaluation stage: annotations and retrieval measured against ground truth, the
documents with exact truth to measure on, and the report a person reads.

The truth it measures against is read by :mod:`mtanno.labels` (an input format, below
every stage that reads it). Modules:

* :mod:`~mtanno.evaluation.metrics` — frame- and segment-level P/R/F of annotations
  ([MBS09] §7), per class, with support counts, in one report with the measures below;
* :mod:`~mtanno.evaluation.segmentation` — the action-segmentation measures: frame
  accuracy, Edit score, F1@{10, 25, 50} (Lea et al. 2017; MS-TCN);
* :mod:`~mtanno.evaluation.retrieval` — retrieval P/R per τ, top-k recall, separation
  ([MR06] §5.4–5.5);
* :mod:`~mtanno.evaluation.calibration` — how well a segment confidence separates right
  from wrong labels and is calibrated: AUROC, expected calibration error, reliability
  table (issue 26);
* :mod:`~mtanno.evaluation.compose` — long evaluation documents composed from labelled
  clips (``mtanno compose``, :func:`compose_to`);
* :mod:`~mtanno.evaluation.report` — the report and its tables (``mtanno report``,
  :func:`report_files`, :class:`ReportOptions`);
* :mod:`~mtanno.evaluation.report_tables` — the report's tables as Markdown, LaTeX and HTML;
* :mod:`~mtanno.evaluation.page` — the report page: an archive view of every document, one
  player, review to truth (its scripts ``archive.js``, ``player.js``, ``review.js`` and
  style ``page.css`` are package data), its data files and figures;
* :mod:`~mtanno.evaluation.player` — the player's motions: poses from motion files or pose
  blocks, checked against the annotation, encoded for the page.

Every module's public names are importable from the package, attached on first use
(PEP 562), except those of ``compose``, ``page``, ``player`` and ``report_tables`` (import
them): reading a truth table loads neither the report nor the feature extractor.
"""

from mtanno.util.lazy import lazy_exports

# the names are attached on first use (PEP 562), so that a module that needs one of them
# (a truth table, the P/R/F formulas) does not load the report and the rest
__getattr__, __all__ = lazy_exports(__name__, {
    "calibration": ("RIGHT_IOU", "ReliabilityTable", "auroc", "expected_calibration_error",
                    "reliability_table", "rows_right", "segment_right"),
    "metrics": ("EVALUATION_SCHEMA", "PRF", "Report", "evaluate_annotations", "evaluate_files",
                "evaluate_to", "frame_level", "segment_level"),
    "report": ("ReportOptions", "ReportResult", "confusion_matrix", "write_report"),
    "retrieval": ("ClassRetrieval", "RetrievalRow", "RetrievalRun", "TAU_GRID",
                  "evaluate_retrieval_files", "evaluate_retrieval_to", "retrieval_evaluation",
                  "retrieval_report", "retrieval_rows", "retrieval_table", "separation_quotient",
                  "top_k_recall"),
    "segmentation": ("OVERLAPS", "OverlapCounts", "SegmentationScores", "edit_score",
                     "levenshtein", "segmentation_scores"),
})


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
