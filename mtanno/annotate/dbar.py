"""The modified distance Δ̄ of a class over a document ([MBS09] §4, docs/method.md §7
step 2): each match's cost spread over the frames it covers, in the reference
implementation's greedy order (the kernels of :mod:`mtanno.annotate._kernels`) or as the
paper writes it.

Frames are 0-based.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mtanno.annotate._kernels import reference_dbar_kernel
from mtanno.errors import MtannoError
from mtanno.templates.params import ANNOTATION_TAU, check_tau

__all__ = ["modified_delta"]


#: What the reference Δ̄ says of start frames that no matcher gives.
_START_OUTSIDE = "a match with Δ ≤ τ starts before its window or after its end frame"


def _reference_in_spans(delta, start, tau: float, max_hits: int | None, out: np.ndarray,
                        spans) -> tuple[np.ndarray, np.ndarray]:
    """The reference Δ̄ written into ``out`` inside ``spans`` only (``out`` elsewhere left
    as it was): for :func:`label_document` without its matrix. Returns the spans checked
    and with touching ones joined (where the row holds Δ̄, for :func:`_row_spans`)."""
    from mtanno.templates.match import check_spans

    first, last = check_spans(*spans, out.shape[0])
    cap = np.iinfo(np.int64).max if max_hits is None else int(max_hits)
    if reference_dbar_kernel(np.ascontiguousarray(delta, dtype=np.float64),
                             np.ascontiguousarray(start, dtype=np.int64), float(check_tau(tau)),
                             cap, out, first, last, True) < 0:
        raise MtannoError(_START_OUTSIDE)
    if len(first) > 1:
        keep = np.ones(len(first), bool)
        keep[1:] = first[1:] > last[:-1] + 1  # a span that touches the one before joins it
        first, last = first[keep], np.append(last[np.flatnonzero(keep)[1:] - 1], last[-1])
    return first, last


def _row_spans(per_row: Sequence[tuple[np.ndarray, np.ndarray] | None], L: int):
    """(firsts, lasts, offsets) of :func:`segments_from_labels`' ``row_spans``: each row's
    spans, or the whole document for a row given as None."""
    whole = (np.zeros(1, np.int64), np.full(1, L - 1, np.int64))
    parts = [whole if sp is None else sp for sp in per_row]
    offsets = np.zeros(len(parts) + 1, np.int64)
    np.cumsum([len(a) for a, _ in parts], out=offsets[1:])
    return (np.concatenate([a for a, _ in parts]), np.concatenate([b for _, b in parts]),
            offsets)


def modified_delta(delta: np.ndarray, start: np.ndarray, *, tau: float = ANNOTATION_TAU,
                   variant: str = "reference", max_hits: int | None = None,
                   out: np.ndarray | None = None,
                   spans: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Δ̄ from a distance curve Δ and start frames (docs/method.md §7 step 2; [MBS09] §4).

    ``variant="reference"`` (default, what the reference implementation does): repeatedly
    take the smallest remaining Δ(ℓ) ≤ τ (ties: earliest frame), fill the frames of
    [a_ℓ, ℓ] that are still ∞ with Δ(ℓ), and exclude that range from further picks;
    ``max_hits`` caps the picks (the reference used 2000). ``variant="paper"`` ([MBS09] as
    written): for every local minimum ℓ of Δ below τ, Δ̄(k) = min(Δ̄(k), Δ(ℓ)) on [a_ℓ, ℓ].
    Frames are 0-based; Δ = ∞ where no match ends. ``out`` (float64, Δ's length) receives
    Δ̄ instead of a new array (a batch reuses one buffer). ``spans``: (firsts, lasts),
    the sorted disjoint frame ranges (0-based inclusive, :func:`merged_spans`) outside
    which Δ is ∞, such as keyframe windows; the reference variant then reads Δ only
    inside them, so a short window costs little in a long document.
    """
    delta = np.ascontiguousarray(delta, dtype=np.float64)
    start = np.ascontiguousarray(start, dtype=np.int64)
    if delta.shape != start.shape or delta.ndim != 1:
        raise MtannoError("delta and start must be 1-D arrays of the same length")
    tau = check_tau(tau)
    if out is None:
        dbar = np.full(delta.shape[0], np.inf)
    else:
        if out.shape != delta.shape or out.dtype != np.float64:
            raise MtannoError("out must be a float64 array of Δ's length")
        dbar = out
        dbar.fill(np.inf)
    if variant == "reference":
        cap = np.iinfo(np.int64).max if max_hits is None else int(max_hits)
        L = delta.shape[0]
        if spans is None:
            first, last = np.zeros(1, np.int64), np.full(1, L - 1, np.int64)
        else:
            from mtanno.templates.match import check_spans

            first, last = check_spans(*spans, L)
        if reference_dbar_kernel(delta, start, float(tau), cap, dbar, first, last) < 0:
            raise MtannoError(_START_OUTSIDE)
        return dbar
    if variant == "paper":
        d = np.where(np.isfinite(delta), delta, np.inf)
        left = np.concatenate(([np.inf], d[:-1]))
        right = np.concatenate((d[1:], [np.inf]))
        minima = np.flatnonzero((d <= tau) & (d < left) & (d <= right))
        for end in minima:
            s = start[end]
            np.minimum(dbar[s:end + 1], d[end], out=dbar[s:end + 1])
        return dbar
    raise MtannoError(f"unknown Δ̄ variant '{variant}' (reference or paper)")
