"""How well a confidence separates and how well it is calibrated (issue 26, part 4d): the
area under the ROC curve of right against wrong segments, the expected calibration error
and the reliability table behind it (Guo et al. 2017, "On calibration of modern neural
networks", §2; the reliability diagram as in Niculescu-Mizil & Caruana 2005, "Predicting
good probabilities with supervised learning").

The inputs are one value per segment: a score or probability, and whether the segment's
label is right (1) or wrong (0). :func:`mtanno.plot.reliability_figure` draws the table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mtanno.confidence.calibration import check_labels
from mtanno.errors import MtannoError

__all__ = ["DEFAULT_BINS", "RIGHT_IOU", "ReliabilityTable", "auroc",
           "expected_calibration_error", "reliability_table", "rows_right", "segment_right"]

#: IoU with a truth segment of its label from which a segment's label counts as right
#: (issue 26: what the confidence is the probability of).
RIGHT_IOU = 0.5


def segment_right(seg: tuple[int, int, int], truth) -> bool:
    """Whether segment (label, first, last) overlaps a truth segment (label, first, last)
    of its label with IoU ≥ :data:`RIGHT_IOU` (inclusive frames, any base, the same for
    both)."""
    p, a, b = seg
    for q, s, e in truth:
        if q != p or e < a or s > b:
            continue
        if (min(b, e) - max(a, s) + 1) / (max(b, e) - min(a, s) + 1) >= RIGHT_IOU:
            return True
    return False


def rows_right(rows, truth) -> np.ndarray:
    """Per annotation row (0-based frames, :class:`mtanno.annotate.Annotation`) whether
    its label is right against ``truth`` (:class:`mtanno.labels.segments.Segment`,
    1-based frames): :func:`segment_right` in its document."""
    by_doc: dict[str, list] = {}
    for s in truth:
        by_doc.setdefault(s.doc, []).append((s.label, s.start - 1, s.end - 1))
    return np.array([segment_right((r.label, r.start, r.end), by_doc.get(r.doc, ()))
                     for r in rows], dtype=bool)

#: Equal-width bins on [0, 1] of the calibration error and the reliability table.
DEFAULT_BINS = 10


def _inputs(values, right, what: str) -> tuple[np.ndarray, np.ndarray]:
    """``values`` as float64 and ``right`` as bool, both 1-D of one length, no NaN."""
    v = np.asarray(values)
    r = np.asarray(right)
    for a, name in ((v, what), (r, "right")):
        if a.dtype.kind not in "biuf":
            raise MtannoError(f"{name} must be numbers, got {a.dtype} values")
        if a.ndim != 1:
            raise MtannoError(f"{name} must be one value per segment (1-D), got shape {a.shape}")
    if len(v) != len(r):
        raise MtannoError(f"{len(v)} {what} for {len(r)} right/wrong labels")
    v = v.astype(np.float64)
    bad = np.flatnonzero(np.isnan(v))
    if len(bad):
        raise MtannoError(f"{what} must not be NaN (index {bad[0]})")
    return v, check_labels(r, len(v), "right") == 1


def auroc(score, right) -> float:
    """The probability that a random right segment scores higher than a random wrong one,
    ties counting half (the Mann–Whitney U over n₁·n₀, by average ranks); NaN when no
    segment is right or none is wrong. ``score``: larger = more confident (±∞ allowed)."""
    s, r = _inputs(score, right, "scores")
    n1 = int(r.sum())
    n0 = len(r) - n1
    if n1 == 0 or n0 == 0:
        return float("nan")
    _, inv, counts = np.unique(s, return_inverse=True, return_counts=True)
    last = np.cumsum(counts)  # 1-based rank of the last of each tie group
    average = last - (counts - 1) / 2.0
    rank_sum = float(average[inv.ravel()][r].sum())
    return (rank_sum - n1 * (n1 + 1) / 2.0) / (n1 * n0)


def _bins(bins) -> int:
    if isinstance(bins, bool) or not isinstance(bins, (int, np.integer)) or bins < 1:
        raise MtannoError(f"{{bins}} must be an integer >= 1, got {bins!r}", options=("bins",))
    return int(bins)


@dataclass(frozen=True, eq=False)
class ReliabilityTable:
    """Per equal-width bin of probability: its bounds ``lo``, ``hi`` (bin k holds
    k/B ≤ p < (k+1)/B, the last one also p = 1), the ``count`` of segments in it, their
    ``mean_prob`` and the ``fraction_right`` of them (both NaN for an empty bin)."""

    lo: np.ndarray
    hi: np.ndarray
    count: np.ndarray
    mean_prob: np.ndarray
    fraction_right: np.ndarray

    @property
    def n(self) -> int:
        """Segments in the table."""
        return int(self.count.sum())

    @property
    def ece(self) -> float:
        """Σ_k (count_k / n)·|mean_prob_k − fraction_right_k| over the non-empty bins (NaN
        without segments)."""
        if self.n == 0:
            return float("nan")
        full = self.count > 0
        gap = np.abs(self.mean_prob[full] - self.fraction_right[full])
        return float(self.count[full] @ gap / self.n)

    def rows(self) -> list[tuple[float, float, int, float, float]]:
        """(lo, hi, count, mean prob, fraction right) per bin, as plain Python numbers."""
        return list(zip(self.lo.tolist(), self.hi.tolist(), self.count.tolist(),
                        self.mean_prob.tolist(), self.fraction_right.tolist()))


def reliability_table(prob, right, *, bins: int = DEFAULT_BINS) -> ReliabilityTable:
    """The reliability table of probabilities ``prob`` (in [0, 1], no NaN) of segments
    whose labels are ``right`` (0/1), in ``bins`` equal-width bins on [0, 1]."""
    p, r = _inputs(prob, right, "probabilities")
    B = _bins(bins)
    outside = np.flatnonzero((p < 0) | (p > 1))
    if len(outside):
        raise MtannoError(f"probabilities must be in [0, 1], got {p[outside[0]].item()!r} at index "
                          f"{outside[0]}")
    edges = np.arange(B + 1) / B  # k/B exactly rounded, so 0.3 falls in [0.3, 0.4)
    k = np.minimum(np.searchsorted(edges, p, side="right") - 1, B - 1)
    count = np.bincount(k, minlength=B)
    safe = np.maximum(count, 1)
    with np.errstate(invalid="ignore"):
        mean_prob = np.where(count > 0, np.bincount(k, weights=p, minlength=B) / safe, np.nan)
        fraction = np.where(count > 0, np.bincount(k, weights=r, minlength=B) / safe, np.nan)
    return ReliabilityTable(edges[:-1], edges[1:], count.astype(np.int64), mean_prob, fraction)


def expected_calibration_error(prob, right, *, bins: int = DEFAULT_BINS) -> float:
    """The expected calibration error of probabilities ``prob`` (in [0, 1]) of segments
    whose labels are ``right`` (0/1): the count-weighted mean over ``bins`` equal-width
    bins of |mean probability − fraction right| (:class:`ReliabilityTable`; Guo et al.
    2017, §2); NaN without segments."""
    return reliability_table(prob, right, bins=bins).ece
