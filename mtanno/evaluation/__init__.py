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
* :mod:`~mtanno.evaluation.compose` — long evaluation documents composed from labelled
  clips (``mtanno compose``);
* :mod:`~mtanno.evaluation.report` — the HTML report and its tables (``mtanno report``).

Every module's public names are importable from the package, except those of ``compose``
(it reads motion files: import :mod:`mtanno.evaluation.compose` for them), so that reading a
truth table does not load the feature extractor.
"""

from mtanno.evaluation.metrics import (
    EVALUATION_SCHEMA,
    PRF,
    Report,
    evaluate_annotations,
    frame_level,
    segment_level,
)
from mtanno.evaluation.report import ReportResult, confusion_matrix, write_report
from mtanno.evaluation.retrieval import (
    TAU_GRID,
    ClassRetrieval,
    RetrievalRow,
    retrieval_evaluation,
    retrieval_report,
    retrieval_rows,
    retrieval_table,
    separation_quotient,
    top_k_recall,
)
from mtanno.evaluation.segmentation import (
    OVERLAPS,
    OverlapCounts,
    SegmentationScores,
    edit_score,
    levenshtein,
    segmentation_scores,
)
from mtanno.evaluation.truth import Segment, check_within, read_truth, truth_table, write_truth

__all__ = ["EVALUATION_SCHEMA", "OVERLAPS", "PRF", "TAU_GRID", "ClassRetrieval", "OverlapCounts",
           "Report", "ReportResult", "RetrievalRow", "Segment", "SegmentationScores",
           "check_within", "confusion_matrix", "edit_score", "evaluate_annotations",
           "frame_level", "levenshtein", "read_truth", "segmentation_scores",
           "retrieval_evaluation", "retrieval_report", "retrieval_rows", "retrieval_table",
           "segment_level", "separation_quotient", "top_k_recall", "truth_table",
           "write_report", "write_truth"]
