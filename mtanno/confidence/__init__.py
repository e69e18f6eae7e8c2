"""The confidence of annotation segments (issue 26): the probability that a label is right,
from evidence about its segment, calibrated by ``mtanno tune`` and applied by ``mtanno
annotate``. One package owns the concept; tune's cross-validated fitting over its folds is
:mod:`mtanno.tuning.confidence`, the measures of how good it is (AUROC, ECE, rightness)
:mod:`mtanno.evaluation.calibration`.

* :mod:`~mtanno.confidence.evidence` — the kinds of evidence, one function each registered
  by name, and the one builder of their inputs (:func:`label_facts`) for tune and annotate;
* :mod:`~mtanno.confidence.verify` — verification of a segment against the training
  examples and background motions (the bank; subsequence DTW, kernel in
  ``_verify_kernels``);
* :mod:`~mtanno.confidence.calibration` — Platt and isotonic calibration of the evidence,
  fitted by grouped cross-validation, and the uncalibrated score;
* :mod:`~mtanno.confidence.model` — :class:`ConfidenceModel`, the ``[confidence]`` table of a
  class configuration read and written;
* :mod:`~mtanno.confidence.score` — the confidence of an annotated document's rows.
"""

from mtanno.util.lazy import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "calibration": ("CALIBRATION_FOLDS", "CALIBRATION_L2", "CALIBRATION_METHODS",
                    "DEFAULT_CALIBRATION", "NEWTON_MAX_ITER", "UNCALIBRATED",
                    "CalibrationResult", "Calibrator", "IsotonicModel", "LogisticModel",
                    "fit_calibrated", "fit_isotonic", "fit_logistic",
                    "uncalibrated_confidence"),
    "evidence": ("BANK_EVIDENCE", "EVIDENCE", "LabelFacts", "SegmentFacts",
                 "document_evidence", "label_facts", "register_evidence", "segment_evidence",
                 "verification_query"),
    "model": ("CONFIDENCE_KEYS", "ConfidenceModel", "check_min_confidence",
              "confidence_record"),
    "score": ("annotation_facts", "score_document", "single_label_by_confidence",
              "with_confidence"),
    "verify": ("Bank", "build_bank", "read_bank", "write_bank"),
})


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
