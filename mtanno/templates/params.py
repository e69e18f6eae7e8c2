"""The published parameters of matching a template, one name each, for every stage that
matches (retrieval, the index's ranking, annotation, tuning, the report): the quality
threshold τ on the distance Δ and the quantization δ of the template, with the one rule a τ
given anywhere must follow.

Retrieval ([MR06] §5.2, §5.4) quantizes with δ = 0.1 and keeps hits with Δ ≤ τ = 0.06;
annotation ([MBS09] §4–5) quantizes with δ = 0.05 and labels where Δ ≤ τ = 0.13.
"""

from __future__ import annotations

from mtanno.errors import MtannoError

__all__ = ["ANNOTATION_DELTA", "ANNOTATION_TAU", "RETRIEVAL_DELTA", "RETRIEVAL_TAU", "check_tau"]

#: Quality threshold of retrieval: hits have Δ ≤ τ ([MR06] §5.4).
RETRIEVAL_TAU = 0.06
#: Quantization δ of templates for retrieval ([MR06] §5.2).
RETRIEVAL_DELTA = 0.1
#: Annotation threshold τ of [MBS09] (every class without its own τ).
ANNOTATION_TAU = 0.13
#: Quantization δ of the templates for annotation ([MBS09]).
ANNOTATION_DELTA = 0.05


def check_tau(tau, *, what: str = "tau", path: str | None = None) -> float:
    """τ as a float; NaN, a negative value or a non-number is an :class:`MtannoError`
    (∞ is allowed: every match counts). The one rule for τ wherever it is given: the
    annotation, retrieval (:func:`mtanno.retrieve.extract_hits`), class configurations and
    the commands' ``--tau``."""
    try:
        value = float(tau)
    except (TypeError, ValueError):
        raise MtannoError(f"{what} must be a number ≥ 0, got {tau!r}", path=path) from None
    if not value >= 0:
        nan = " (NaN)" if value != value else ""
        raise MtannoError(f"{what} must be a number ≥ 0, got {tau!r}{nan}", path=path)
    return value
