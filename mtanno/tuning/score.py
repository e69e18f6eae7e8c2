"""Fast scores of annotations on the held-out documents of cross-validation: the counts of
[MBS09] §7 (docs/method.md §8) that ``mtanno evaluate`` reports, computed on frame arrays.

Segments are (label index, first, last) with 0-based inclusive frames of one array of
``n_frames`` frames (the held-out documents concatenated); labels are indices into one list
of class names shared by truth and output. The counts equal
:func:`mtanno.evaluation.metrics.evaluate_annotations` on the same segments (a test checks it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mtanno.errors import MtannoError
from mtanno.evaluation.metrics import f_measure, ratio

__all__ = ["Counts", "count", "covered_fraction"]


@dataclass
class Counts:
    """Frame-level (correct, predicted, support) and segment-level (correct output
    segments, output segments, found truth segments, truth segments) counts; they add up
    over folds, starting from :meth:`zero`."""

    frame_correct: int
    frame_predicted: int
    frame_support: int
    seg_correct: int
    seg_predicted: int
    seg_found: int
    seg_support: int

    @classmethod
    def zero(cls) -> Counts:
        """No frame and no segment: the start of a sum."""
        return cls(0, 0, 0, 0, 0, 0, 0)

    def __iadd__(self, other: Counts) -> Counts:
        for k, v in vars(other).items():
            setattr(self, k, getattr(self, k) + v)
        return self

    def frame(self) -> tuple[float, float, float]:
        """(P1, R1, F1)."""
        p = ratio(self.frame_correct, self.frame_predicted)
        r = ratio(self.frame_correct, self.frame_support)
        return p, r, f_measure(p, r)

    def segment(self) -> tuple[float, float, float]:
        """(P2, R2, F2)."""
        p = ratio(self.seg_correct, self.seg_predicted)
        r = ratio(self.seg_found, self.seg_support)
        return p, r, f_measure(p, r)


def _check(segs: Sequence[tuple[int, ...]], n_labels: int | None, n_frames: int, what: str,
           ) -> None:
    """Segments (label, first, last), or spans (first, last) without ``n_labels``, inside
    the labels and frames: numpy would take a negative label or frame from the end
    without a word (and count wrong), and a first frame after the last one uncovers
    frames."""
    if not len(segs):
        return
    width = 2 if n_labels is None else 3
    try:
        a = np.asarray(segs, dtype=np.int64)
    except (TypeError, ValueError):  # ragged
        a = np.zeros(0)
    if a.ndim != 2 or a.shape[1] != width:
        raise MtannoError(f"{what} must be ({'' if n_labels is None else 'label, '}first, "
                          f"last) tuples")
    first, last = a[:, -2], a[:, -1]
    if (n_labels is not None and (a[:, 0].min() < 0 or a[:, 0].max() >= n_labels)) \
            or first.min() < 0 or np.any(last < first) or last.max() >= n_frames:
        labels = "" if n_labels is None else f"labels in 0..{n_labels - 1}, "
        raise MtannoError(f"{what} need {labels}0 ≤ first ≤ last < {n_frames}")


def _cover(segs: Sequence[tuple[int, int, int]], n_labels: int, n_frames: int) -> np.ndarray:
    """(labels × frames + 1) cumulative counts of frames covered per label (a frame
    covered twice by one label counts once)."""
    diff = np.zeros((n_labels, n_frames + 1), dtype=np.int64)
    for p, a, b in segs:
        diff[p, a] += 1
        diff[p, b + 1] -= 1
    covered = (np.cumsum(diff[:, :-1], axis=1) > 0).astype(np.int64)
    out = np.zeros((n_labels, n_frames + 1), dtype=np.int64)
    np.cumsum(covered, axis=1, out=out[:, 1:])
    return out


def count(truth: Sequence[tuple[int, int, int]], output: Sequence[tuple[int, int, int]], *,
          n_labels: int, n_frames: int, ignore: np.ndarray | None = None) -> Counts:
    """The evaluation counts of ``output`` against ``truth`` (module docstring).

    ``ignore``: a boolean mask of ``n_frames`` frames that are not scored (no truth segment
    may touch them): output frames there are neither right nor wrong, and an output
    segment lying wholly inside them is not counted. Cross-validation ignores the frames
    of a class that has no template in the fold (:class:`mtanno.tuning.search.Tuner`)."""
    _check(truth, n_labels, n_frames, "truth segments")
    _check(output, n_labels, n_frames, "output segments")
    if ignore is not None:
        ignore = np.asarray(ignore)
        if ignore.dtype != np.bool_ or ignore.shape != (n_frames,):
            raise MtannoError(f"ignore must be a boolean mask of {n_frames} frames")
        kept = np.concatenate([[0], np.cumsum(ignore)])
        if any(kept[b + 1] - kept[a] for _, a, b in truth):
            raise MtannoError("truth segments must not touch ignored frames")
    return _count(truth, output, n_labels, n_frames, ignore)


def _count(truth, output, n_labels: int, n_frames: int, ignore=None,
           truth_cover: np.ndarray | None = None) -> Counts:
    """:func:`count` of segments made by the tuner (not checked again: it scores
    thousands of candidates); ``truth_cover``: ``_cover(truth, …)`` when the caller keeps
    it (the truth of a fold is scored against every candidate)."""
    ct = _cover(truth, n_labels, n_frames) if truth_cover is None else truth_cover
    co = _cover(output, n_labels, n_frames)
    keep = None if ignore is None else ~ignore
    both = predicted = 0
    for p in range(n_labels):
        t = np.diff(ct[p]) > 0
        o = np.diff(co[p]) > 0
        if keep is not None:
            o &= keep
            predicted += int(np.count_nonzero(o))
        both += int(np.count_nonzero(t & o))
    if keep is None:
        predicted = int(co[:, -1].sum())
    else:  # segments wholly inside ignored frames are not counted
        kc = np.concatenate([[0], np.cumsum(keep)])
        output = [(p, a, b) for p, a, b in output if kc[b + 1] - kc[a] > 0]
    return Counts(
        frame_correct=both, frame_predicted=predicted, frame_support=int(ct[:, -1].sum()),
        seg_correct=sum(1 for p, a, b in output if ct[p, b + 1] - ct[p, a] > 0),
        seg_predicted=len(output),
        seg_found=sum(1 for p, a, b in truth if co[p, b + 1] - co[p, a] > 0),
        seg_support=len(truth))


def covered_fraction(frames: Sequence[tuple[int, int]], output: Sequence[tuple[int, int, int]],
                     n_frames: int) -> tuple[int, int]:
    """(frames of the spans ``frames`` that some output segment covers, frames of the
    spans): the numerator and denominator of the unknown-class rate."""
    _check(frames, None, n_frames, "spans")
    _check([seg[1:] for seg in output], None, n_frames, "output segments")
    return _covered_fraction(frames, output, n_frames)


def _covered_fraction(frames, output, n_frames: int) -> tuple[int, int]:
    """:func:`covered_fraction` of segments made by the tuner (not checked again)."""
    mask = np.zeros(n_frames + 1, dtype=np.int64)
    for _, a, b in output:
        mask[a] += 1
        mask[b + 1] -= 1
    cov = np.cumsum(mask[:-1]) > 0
    total = hit = 0
    for a, b in frames:
        total += b - a + 1
        hit += int(np.count_nonzero(cov[a:b + 1]))
    return hit, total
