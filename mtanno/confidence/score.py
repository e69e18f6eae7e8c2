"""The confidence of every row of an annotated document (issue 26): the tuned model's
calibrated probability of its evidence, or without one a monotone score of its cost
(:func:`mtanno.confidence.calibration.uncalibrated_confidence`, marked uncalibrated in the
provenance); overlapping rows resolved by confidence."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from mtanno.confidence.calibration import uncalibrated_confidence
from mtanno.confidence.evidence import LabelFacts, document_evidence, label_facts
from mtanno.confidence.model import ConfidenceModel
from mtanno.labels.segments import Annotation

__all__ = ["annotation_facts", "score_document", "single_label_by_confidence",
           "with_confidence"]


def with_confidence(rows: Sequence[Annotation], confidence: Sequence[float]) -> list[Annotation]:
    """The rows with their confidence (rounded to 6 digits: the tables hold what was
    computed, the same on every machine to that precision)."""
    return [r._replace(confidence=round(float(c), 6)) for r, c in zip(rows, confidence)]


def annotation_facts(models, config) -> LabelFacts:
    """The label facts of an annotation's class models under its configuration: the base
    template of each class (``extra`` models, the configuration's further templates, are
    left out), τ and superclasses from the configuration."""
    frames = {m.name: int(m.values.shape[1]) for m in models if not getattr(m, "extra", False)}
    return label_facts(frames, tau_for=config.tau_for, superclasses=config.superclasses)


def score_document(rows: Sequence[Annotation], *, X: np.ndarray, poses: np.ndarray | None,
                   models, config, confidence: ConfidenceModel | None) -> list[Annotation]:
    """The rows of one document (features ``X``, poses or None) with their confidence:
    the tuned ``confidence`` (evidence, calibrator), or :func:`uncalibrated_confidence`
    without one."""
    facts = annotation_facts(models, config)
    if confidence is None:
        taus = facts.taus
        return with_confidence(rows, uncalibrated_confidence(np.array(
            [r.cost / taus[r.label] if taus.get(r.label, 0) > 0 else math.inf for r in rows])))
    if not rows:
        return []
    E = document_evidence(rows, facts, X=X, poses=poses, bank=confidence.bank,
                          names=confidence.evidence)
    return with_confidence(rows, confidence.probabilities(E))


def single_label_by_confidence(rows: Sequence[Annotation]) -> list[Annotation]:
    """Overlapping segments of one document resolved into a partition by confidence: each
    frame keeps the label of the most confident segment covering it (ties: the earlier
    row); adjacent pieces of one label join (their largest confidence, least cost)."""
    if not rows:
        return []
    L = max(r.end for r in rows) + 1
    owner = np.full(L, -1, dtype=np.int64)
    order = sorted(range(len(rows)), key=lambda i: (-np.nan_to_num(rows[i].confidence,
                                                                   nan=-1.0), i))
    for i in order:
        r = rows[i]
        span = owner[r.start:r.end + 1]
        span[span < 0] = i
    out: list[Annotation] = []
    change = np.flatnonzero(np.diff(owner)) + 1
    for s, e in zip(np.r_[0, change].tolist(), np.r_[change, L].tolist()):
        i = int(owner[s])
        if i < 0:
            continue
        r = rows[i]
        if out and out[-1].label == r.label and out[-1].end == s - 1:
            p = out[-1]
            out[-1] = p._replace(end=e - 1, cost=min(p.cost, r.cost),
                                 confidence=max(p.confidence, r.confidence))
        else:
            out.append(r._replace(start=s, end=e - 1))
    return out
