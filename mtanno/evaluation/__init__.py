"""The evaluation stage: annotations and retrieval measured against ground truth, the
documents with exact truth to measure on, and the report a person reads.

Modules:

* :mod:`~mtanno.evaluation.truth` — ground-truth segments (1-based frames at 30 Hz),
  truth tables and the CMU mocap6 label converter;
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
  clips (``mtanno compose``);
* :mod:`~mtanno.evaluation.report` — the report and its tables (``mtanno report``);
* :mod:`~mtanno.evaluation.page` — the report page: an archive view of every document, one
  player, review to truth (its scripts ``archive.js``, ``player.js``, ``review.js`` and
  style ``page.css`` are package data), its data files and figures;
* :mod:`~mtanno.evaluation.player` — the player's motions: poses from motion files or pose
  blocks, checked against the annotation, encoded for the page.

Every module's public names are importable from the package, attached on first use
(PEP 562), except those of ``compose``, ``page`` and ``player`` (import them): reading a
truth table loads neither the report nor the feature extractor.
"""

_MODULE_OF = {
    "ClassRetrieval": "retrieval",
    "EVALUATION_SCHEMA": "metrics",
    "OVERLAPS": "segmentation",
    "OverlapCounts": "segmentation",
    "PRF": "metrics",
    "RIGHT_IOU": "calibration",
    "ReliabilityTable": "calibration",
    "Report": "metrics",
    "ReportResult": "report",
    "RetrievalRow": "retrieval",
    "Segment": "truth",
    "SegmentationScores": "segmentation",
    "TAU_GRID": "retrieval",
    "auroc": "calibration",
    "check_within": "truth",
    "confusion_matrix": "report",
    "edit_score": "segmentation",
    "evaluate_annotations": "metrics",
    "expected_calibration_error": "calibration",
    "frame_level": "metrics",
    "levenshtein": "segmentation",
    "read_truth": "truth",
    "reliability_table": "calibration",
    "rows_right": "calibration",
    "segment_right": "calibration",
    "retrieval_evaluation": "retrieval",
    "retrieval_report": "retrieval",
    "retrieval_rows": "retrieval",
    "retrieval_table": "retrieval",
    "segment_level": "metrics",
    "segmentation_scores": "segmentation",
    "separation_quotient": "retrieval",
    "top_k_recall": "retrieval",
    "truth_table": "truth",
    "write_report": "report",
    "write_truth": "truth",
}

__all__ = ["EVALUATION_SCHEMA", "OVERLAPS", "PRF", "TAU_GRID", "ClassRetrieval", "OverlapCounts",
           "RIGHT_IOU", "ReliabilityTable", "Report", "ReportResult", "RetrievalRow", "Segment",
           "SegmentationScores", "auroc", "check_within", "confusion_matrix", "edit_score",
           "evaluate_annotations", "expected_calibration_error", "frame_level", "levenshtein",
           "read_truth", "reliability_table", "rows_right", "segment_right", "segmentation_scores",
           "retrieval_evaluation", "retrieval_report", "retrieval_rows", "retrieval_table",
           "segment_level", "separation_quotient", "top_k_recall", "truth_table",
           "write_report", "write_truth"]


def __getattr__(name: str):
    # the names are attached on first use (PEP 562), so that a module that needs one
    # of them (a truth table, the P/R/F formulas) does not load the report and the rest
    if name in _MODULE_OF:
        import importlib

        value = getattr(importlib.import_module(f"mtanno.evaluation.{_MODULE_OF[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'mtanno.evaluation' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
