"""The segment decoder of tuned annotation: overlap resolution, boundary refinement,
rejection and frame-wise tie-breaking (issue 10; ``docs/annotation.md``).

[MBS09]'s annotation (§4, docs/method.md §7) labels every frame with the class of smallest
modified distance Δ̄ and then extends the runs outward, so segments of different classes
overlap and extended segments run past the true boundaries. The segment decoder instead
chooses, per document, the cheapest *partition* into matches and unlabelled frames, by
dynamic programming over the frames:

* a match of label p ends at a frame ℓ whose distance Δ_p(ℓ) (docs/method.md §3.4) is at
  most the label's rejection ceiling ρ_p (∞ unless tuned); it starts at the start frame
  a_ℓ of that match, or — boundary refinement — anywhere within ``slack`` frames of it, so
  that neighbouring matches meet instead of overlapping or leaving a sliver between them;
* a match covering frames k…ℓ costs (ℓ − k + 1)·Δ_p(ℓ)/τ_p, plus ``weight`` times the sum of
  the frame-wise evidence E_p over k…ℓ (tie-breaking; :func:`frame_evidence`), plus a fixed
  ``segment_cost`` λ per match; an unlabelled frame costs 1 — so a match of n frames is
  worth taking only where Δ_p/τ_p < 1 − λ/n, τ_p both thresholds the class and calibrates
  its costs against the other classes', and λ (in frames) keeps a long motion from being
  cut into short matches of other classes, and short spurious matches out;
* the partition of least total cost wins (ties: an unlabelled frame before a match, a
  smaller label index, an earlier start); touching segments of one label are merged.

Every frame gets at most one label, every segment is one whole match (or several touching
ones), and frames where no class matches well enough stay unlabelled — which is what
rejects motions of classes without a template. The work is O(L · P · (2·slack + 1)) for L
frames and P labels, with O(L) memory besides the P × L distance and start arrays.

Frames are 0-based inside this module.
"""

from __future__ import annotations

__all__ = [
    "DEFAULT_SLACK", "EVIDENCE_MARGIN", "Decoded", "EvidenceColumns", "EvidenceSums", "RowEvidence",
    "decode_segments", "distinct_frames", "evidence_columns", "evidence_sums", "fold_label",
    "frame_evidence", "relative_evidence", "row_evidence",
]

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from mtanno.annotate._kernels import (
    _best_column,
    _decode,
    _distinct_words,
    _fold,
    _prefix,
    _relative,
    _relative_sums,
    _segments,
    _take_spans,
)
from mtanno.errors import MtannoError
from mtanno.templates.match import check_spans

#: Frames a segment start may move from its match's start (boundary refinement).
DEFAULT_SLACK = 3


#: Frames around a class's candidate windows (keyframes) where its evidence is computed:
#: at least the largest slack a segment start may move out of a window.
EVIDENCE_MARGIN = 8


class Decoded(NamedTuple):
    """One decoded segment: label index, 0-based inclusive frames, Δ at its end (the
    smallest over merged touching matches)."""

    label: int
    start: int
    end: int
    cost: float


def _check_labels(deltas, starts, tau, reject):
    deltas = np.ascontiguousarray(deltas, dtype=np.float64)
    starts = np.ascontiguousarray(starts, dtype=np.int64)
    if deltas.ndim != 2 or deltas.shape != starts.shape:
        raise MtannoError("deltas and starts must be (labels × frames) arrays of one shape")
    P = deltas.shape[0]
    tau = np.asarray(tau, dtype=np.float64).reshape(-1)
    if tau.shape != (P,) or not np.all(tau > 0):
        raise MtannoError(f"tau must give one number > 0 per label ({P} labels)")
    if reject is None:
        reject = np.full(P, np.inf)
    reject = np.asarray(reject, dtype=np.float64).reshape(-1)
    if reject.shape != (P,) or np.isnan(reject).any():
        raise MtannoError(f"reject must give one number per label ({P} labels)")
    return deltas, starts, tau, reject


def decode_segments(deltas: np.ndarray, starts: np.ndarray, *, tau: Sequence[float] | np.ndarray,
                    reject: Sequence[float] | np.ndarray | None = None,
                    slack: int = DEFAULT_SLACK, evidence: np.ndarray | None = None,
                    weight: float = 0.0, segment_cost: float = 0.0,
                    boundaries: Sequence[int] = ()) -> list[Decoded]:
    """The least-cost partition of a document into label segments and unlabelled frames
    (module docstring; issue 10, built on [MBS09] §4's distance functions).

    Parameters
    ----------
    deltas, starts:
        (labels × frames) Δ_p(ℓ) (∞ where no match ends) and the 0-based start frame a_ℓ
        of each match (−1 where none), as :func:`mtanno.templates.match.match_template`
        gives them per class (a label with several templates: their frame-wise minimum).
    tau:
        τ_p per label (> 0): a match covering n frames costs n·Δ/τ_p, an unlabelled frame 1.
    reject:
        Rejection ceiling ρ_p per label: matches with Δ_p(ℓ) > ρ_p are never taken
        (default ∞).
    slack:
        Boundary refinement: a segment may start up to ``slack`` frames (30 Hz) before or
        after its match's start a_ℓ (0: exactly at a_ℓ).
    evidence, weight:
        Frame-wise evidence (labels × frames, ≥ 0, small where the frame looks like the
        label; :func:`relative_evidence`), or its running sums (:class:`EvidenceSums`, one
        array less for long documents), and its weight per frame; 0 ignores it.
    segment_cost:
        λ ≥ 0, added once per match (in units of an unlabelled frame's cost): a match of n
        frames pays off only where its mean Δ/τ is below 1 − λ/n; 0 (default) is the
        plain decoder.
    boundaries:
        Frames where a further document begins, when several documents are decoded as
        one array (their matches must not cross documents): no segment starts before its
        document, and segments of neighbouring documents are not merged.

    Returns
    -------
    The segments in frame order, touching segments of one label merged.
    """
    deltas, starts, tau, reject = _check_labels(deltas, starts, tau, reject)
    if not isinstance(slack, (int, np.integer)) or isinstance(slack, bool) or slack < 0:
        raise MtannoError(f"slack must be an integer ≥ 0, got {slack!r}")
    weight = float(weight)
    if not weight >= 0 or not np.isfinite(weight):
        raise MtannoError(f"frame-evidence weight must be a finite number ≥ 0, got {weight!r}")
    segment_cost = float(segment_cost)
    if not segment_cost >= 0 or not np.isfinite(segment_cost):
        raise MtannoError(f"segment cost must be a finite number ≥ 0, got {segment_cost!r}")
    P, L = deltas.shape
    if weight > 0 and isinstance(evidence, EvidenceSums):
        if evidence.cum.shape != (P, L + 1):
            raise MtannoError("evidence sums of another shape than (labels × frames + 1)")
        cum = evidence.cum
    elif weight > 0:
        if evidence is None or np.shape(evidence) != (P, L):
            raise MtannoError("a frame-evidence weight needs evidence of shape (labels × frames)")
        cum = np.empty((P, L + 1))
        if not _prefix(np.ascontiguousarray(evidence, dtype=np.float64), cum):
            raise MtannoError("frame evidence must be ≥ 0 (relative_evidence gives that)")
    else:
        cum = np.zeros((P, 1))
    cuts = np.unique(np.asarray(boundaries, dtype=np.int64))
    if cuts.size and (cuts[0] <= 0 or cuts[-1] >= L):
        raise MtannoError(f"document boundaries must lie inside 1..{L - 1}")
    first = np.zeros(L, dtype=np.int64)
    first[cuts] = cuts
    np.maximum.accumulate(first, out=first)
    best = np.empty(L + 1)
    back_k = np.zeros(L + 1, dtype=np.int64)
    back_p = np.full(L + 1, -1, dtype=np.int64)
    _decode(deltas, starts, 1.0 / tau, reject, cum, weight, segment_cost, int(slack), first,
            best, back_k, back_p)
    lab = np.empty(L, np.int64)
    seg_start = np.empty(L, np.int64)
    seg_end = np.empty(L, np.int64)
    cost = np.empty(L)
    m = _segments(back_k, back_p, deltas, first, lab, seg_start, seg_end, cost)
    return [Decoded(*row) for row in zip(lab[:m].tolist(), seg_start[:m].tolist(),
                                         seg_end[:m].tolist(), cost[:m].tolist())]


def fold_label(row: np.ndarray, row_start: np.ndarray, delta: np.ndarray, start: np.ndarray, *,
               tau: float, reject: float = np.inf, first: bool = False,
               spans: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """Fold one template's match into its label's row of the decoder's input, in place:
    ``row`` = min(``row``, Δ/τ) over the frames where Δ ≤ ``reject`` (Δ·(1/τ), the decoder's
    rounding), ``row_start`` the start frames of the minima (several templates of a class,
    or the classes of a superclass, make one label). ``first``: the label's first template,
    written as if the rows held ∞ and −1 (they may then be uninitialised, ``np.empty``).
    ``spans``: (firsts, lasts), the sorted disjoint frame ranges (0-based inclusive) outside
    which Δ is ∞ (keyframe windows), read only inside them."""
    if not tau > 0:
        raise MtannoError(f"tau must be > 0 for the segment decoder, got {tau!r}")
    if spans is None:
        first_, last = np.zeros(1, np.int64), np.full(1, len(delta) - 1, np.int64)
    else:
        first_, last = check_spans(*spans, len(delta))
    if not (len(row) == len(row_start) == len(delta) == len(start)):
        raise MtannoError("row, row_start, delta and start must have one entry per frame")
    _fold(np.ascontiguousarray(delta, dtype=np.float64), np.ascontiguousarray(start, np.int64),
          float(reject), 1.0 / float(tau), row, row_start, bool(first), first_, last)


def distinct_frames(packed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of a bit-packed document (:func:`mtanno.templates.match.
    pack_document`) and, per frame, the index of its row: feature vectors repeat for many
    frames in a row, so the evidence of every template is computed once per distinct
    vector. Computed once per document: runs of equal rows first (poses hold for many
    frames), then, for one word per frame (up to 64 features), a hash table over the
    runs' values (rows in order of first appearance); wider rows go through a sort."""
    P = np.ascontiguousarray(packed)
    if P.ndim != 2:
        raise MtannoError(f"a packed document is (frames × words), got shape {P.shape}")
    L = P.shape[0]
    if L == 0:
        return P[:0], np.zeros(0, np.int64)
    new = np.ones(L, dtype=bool)
    new[1:] = (P[1:] != P[:-1]).any(axis=1)
    heads = np.flatnonzero(new)
    lengths = np.diff(np.append(heads, L))
    if P.shape[1] == 1:
        inv = np.empty(heads.shape[0], np.int64)
        u = _distinct_words(np.ascontiguousarray(P[heads, 0]), inv).reshape(-1, 1)
    else:
        u, inv = np.unique(P[heads], axis=0, return_inverse=True)
    return np.ascontiguousarray(u), np.repeat(inv.reshape(-1), lengths)


@dataclass(frozen=True)
class EvidenceColumns:
    """A quantized template's distinct columns with a fixed entry, in kernel form (bit
    masks of the fixed rows, bit values, 1 / number of fixed rows): what
    :func:`frame_evidence` compares every frame with. Made once per template
    (:func:`evidence_columns`; :class:`mtanno.annotate.ClassModel` keeps it)."""

    masks: np.ndarray
    vals: np.ndarray
    inv_nnz: np.ndarray
    n_features: int

    def __post_init__(self):
        # the kernel reads vals and inv_nnz by the rows of masks
        m, v, w = (np.asarray(a) for a in (self.masks, self.vals, self.inv_nnz))
        if m.ndim != 2 or v.shape != m.shape or w.shape != (m.shape[0],):
            raise MtannoError(f"evidence columns need masks and vals of one (columns × words) "
                              f"shape and one 1/nnz per column, got {m.shape}, {v.shape} and "
                              f"{w.shape}")


def evidence_columns(values: np.ndarray) -> EvidenceColumns:
    """:class:`EvidenceColumns` of a (features × K) quantized template (0, 1, 0.5 =
    wildcard); wildcard-only columns are left out (none left: every frame gets 0)."""
    from mtanno.templates.match import pack_document

    V = np.asarray(values)
    fixed = V != 0.5
    keep = fixed.any(axis=0)
    fixed = fixed[:, keep]
    ones = (V[:, keep] == 1.0) & fixed
    words = (V.shape[0] + 63) // 64
    # the columns packed as document frames are: bit i of word i // 64 for feature i
    masks = pack_document(fixed.astype(np.uint8), V.shape[0])
    vals = pack_document(ones.astype(np.uint8), V.shape[0])
    if masks.shape[0]:
        pairs = np.unique(np.concatenate([masks, vals], axis=1), axis=0)  # distinct columns
        masks = np.ascontiguousarray(pairs[:, :words])
        vals = np.ascontiguousarray(pairs[:, words:])
    nnz = np.array([sum(bin(int(x)).count("1") for x in row) for row in masks], dtype=np.float64)
    return EvidenceColumns(masks, vals, 1.0 / nnz, int(V.shape[0]))


@dataclass(frozen=True)
class RowEvidence:
    """A template's frame evidence kept per distinct frame (:func:`distinct_frames`):
    ``per_row[r]`` for the frames whose row is r (``inverse``), inside ``spans`` (first and
    last frames, 0-based inclusive; None: everywhere) and ∞ outside. :meth:`frames` gives
    the array :func:`frame_evidence` returns; :meth:`write` writes it into a buffer
    without temporaries (the decoder's evidence rows of long documents)."""

    per_row: np.ndarray
    inverse: np.ndarray
    spans: tuple[np.ndarray, np.ndarray] | None

    def write(self, out: np.ndarray) -> None:
        """out[t] = the evidence of frame t (float64, one entry per frame)."""
        L = self.inverse.shape[0]
        if out.shape != (L,):
            raise MtannoError(f"out must have one entry per frame ({L}), got shape {out.shape}")
        if self.spans is None:
            firsts, lasts = np.zeros(1, np.int64), np.full(1, L - 1, np.int64)
        else:
            firsts, lasts = _span_arrays(self.spans)
        err = _take_spans(self.per_row, self.inverse, firsts, lasts, out)
        if err == 1:
            raise MtannoError(f"frame evidence spans must lie inside the {L} frames")
        if err == 2:
            raise MtannoError(f"frame evidence: a frame's row is not one of the "
                              f"{self.per_row.shape[0]} distinct rows (distinct frames of "
                              "another document?)")

    def frames(self) -> np.ndarray:
        out = np.empty(self.inverse.shape[0])
        self.write(out)
        return out


def _span_arrays(spans) -> tuple[np.ndarray, np.ndarray]:
    """(firsts, lasts) as int64 arrays of one length."""
    if len(spans) != 2:
        raise MtannoError("spans must be a pair (first frames, last frames)")
    a, b = np.ascontiguousarray(spans[0], np.int64), np.ascontiguousarray(spans[1], np.int64)
    if a.ndim != 1 or a.shape != b.shape:
        raise MtannoError(f"spans need one last frame per first frame, got shapes {a.shape} "
                          f"and {b.shape}")
    return a, b


def row_evidence(packed: np.ndarray, values: np.ndarray | EvidenceColumns, *,
                 spans: tuple[np.ndarray, np.ndarray] | None = None,
                 distinct: tuple[np.ndarray, np.ndarray] | None = None) -> RowEvidence:
    """:func:`frame_evidence` as a :class:`RowEvidence` (computed per distinct frame,
    spread over the frames only when written); ``values`` may be the template's
    :class:`EvidenceColumns` already made."""
    cols = values if isinstance(values, EvidenceColumns) else evidence_columns(values)
    if np.ndim(packed) != 2:
        raise MtannoError(f"a packed document is (frames × words), got shape {np.shape(packed)}")
    L = packed.shape[0]
    words = packed.shape[1]
    if cols.n_features > 64 * words or cols.masks.shape[1] > words:
        raise MtannoError(f"template has {cols.n_features} features, the document "
                          f"{64 * words} bits")
    if spans is not None:
        first, last = _span_arrays(spans)
        spans = (np.clip(first, 0, L), np.clip(last, -1, L - 1))
    rows, inverse = distinct if distinct is not None else distinct_frames(packed)
    if np.ndim(rows) != 2 or np.ndim(inverse) != 1 or rows.shape[1] != words \
            or inverse.shape[0] != L:
        raise MtannoError("distinct frames of another document")
    got = np.zeros(rows.shape[0])
    if cols.masks.shape[0] and rows.shape[0]:
        n = np.array([rows.shape[0] - 1], np.int64)
        _best_column(rows, cols.masks, cols.vals, cols.inv_nnz, np.zeros(1, np.int64), n, got)
    return RowEvidence(got, inverse, spans)


def frame_evidence(packed: np.ndarray, values: np.ndarray | EvidenceColumns, *,
                   spans: tuple[np.ndarray, np.ndarray] | None = None,
                   distinct: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Frame-wise evidence of one quantized template: for every frame of a bit-packed
    document (:func:`mtanno.templates.match.pack_document`), the smallest fraction of
    disagreeing fixed entries over the template's columns — 0 where the frame's pose is
    one the template holds anywhere, whatever the order (a "bag of columns"; wildcard-only
    columns are skipped, a template of only those gives 0). ``values`` is the (features ×
    K) quantized template (0, 1, 0.5 = wildcard), or its :class:`EvidenceColumns`. With
    ``spans`` (first and last frames, 0-based inclusive, e.g. a class's candidate windows
    widened by :data:`EVIDENCE_MARGIN`) only those frames are computed, the others are ∞.
    ``distinct``: :func:`distinct_frames` of ``packed``, when the caller has it (one
    document, many templates)."""
    return row_evidence(packed, values, spans=spans, distinct=distinct).frames()


@dataclass(frozen=True)
class EvidenceSums:
    """Running sums of the relative evidence per label, ``cum[p, t]`` = the sum over frames
    0…t−1 (labels × frames + 1), as :func:`decode_segments` uses them; made by
    :func:`evidence_sums`, which checks them."""

    cum: np.ndarray


def evidence_sums(buffer: np.ndarray) -> EvidenceSums:
    """In place: ``buffer`` (labels × frames + 1) holds each label's frame evidence in
    ``buffer[:, 1:]`` (∞ where not computed; column 0 is free); it becomes the relative
    evidence's (:func:`relative_evidence`) running sums per label — the same numbers as
    :func:`relative_evidence` followed by :func:`decode_segments`' own sums, without a
    second labels × frames array. Entries that are not finite (∞: not computed, e.g.
    outside a class's keyframe windows) take no part in a frame's minimum and add 0."""
    if not (isinstance(buffer, np.ndarray) and buffer.ndim == 2 and buffer.dtype == np.float64
            and buffer.flags.c_contiguous and buffer.shape[1] >= 1):
        raise MtannoError("evidence buffer must be a C-contiguous float64 (labels × frames + 1) "
                          "array")
    _relative_sums(buffer)
    return EvidenceSums(buffer)


def relative_evidence(evidence: np.ndarray, *, out: np.ndarray | None = None) -> np.ndarray:
    """Per-label evidence (labels × frames) minus the smallest of each frame: 0 for the
    label whose template fits the frame best, the margin behind it for the others. ∞
    entries (frames a label was not computed for: outside its candidate windows, where it
    cannot claim frames) take no part in the minimum and become 0. ``out`` (float64, the
    evidence's shape; may be the evidence array itself) receives the result."""
    E = np.ascontiguousarray(evidence, dtype=np.float64)
    if E.ndim != 2:
        raise MtannoError(f"evidence must be (labels × frames), got shape {E.shape}")
    if out is None:
        out = np.empty_like(E)
    elif out.shape != E.shape or out.dtype != np.float64 or not out.flags.c_contiguous:
        raise MtannoError("out must be a C-contiguous float64 array of the evidence's shape")
    if E.shape[0]:
        _relative(E, out)
    return out
