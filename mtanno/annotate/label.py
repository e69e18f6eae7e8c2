"""Frame-wise labels of one document ([MBS09] §4–5, docs/method.md §7): every class
template's distance Δ_p over the document (optionally only inside keyframe windows),
its modified distance Δ̄_p (:mod:`mtanno.annotate.dbar`), the label of each frame (the
class of smallest Δ̄) and the maximal runs of one label, extended while Δ̄ keeps falling
towards them — or, with a tuned configuration, the segment decoder of
:mod:`mtanno.annotate.decode`.

Frames are 0-based inside this module.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from mtanno.annotate._kernels import _label_runs
from mtanno.annotate.config import ClassConfig
from mtanno.annotate.dbar import _reference_in_spans, _row_spans, modified_delta
from mtanno.errors import MtannoError
from mtanno.labels.segments import Annotation

__all__ = ["ClassModel", "Windows", "annotate_document", "class_deltas", "evidence_covered",
           "label_document", "label_frames", "merged_spans", "segments_from_labels",
           "single_label_segments", "valid_rows", "valid_windows"]


#: Candidate windows per class (keyframe preselection): a list of (first, last) frames,
#: 0-based inclusive, or a (firsts, lasts) pair of sorted disjoint int64 arrays.
Windows = dict[str, "list[tuple[int, int]] | tuple[np.ndarray, np.ndarray]"]


def label_frames(dbars: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(label index per frame, −1 where every Δ̄ is ∞; Δ_min per frame). Ties → smallest
    class index (docs/method.md §7 step 3)."""
    dmin = dbars.min(axis=0)
    labels = np.argmin(dbars, axis=0).astype(np.int64)
    labels[~np.isfinite(dmin)] = -1
    return labels, dmin


def segments_from_labels(doc: str, names: Sequence[str], dbars: np.ndarray, *,
                         extend: bool | str = True, row_spans=None) -> list[Annotation]:
    """Maximal runs of one label, extended (optional) and merged per label (docs/method.md
    §7 step 4).
    ``extend="unclaimed"`` walks only over frames that no other label has (boundary
    refinement, issue 10). ``row_spans`` (internal, :func:`_row_spans`): (firsts, lasts,
    offsets), the frames where each row holds Δ̄; elsewhere it counts as ∞ and is not read
    (keyframe windows: the rows need not be filled outside them)."""
    dbars = np.ascontiguousarray(dbars, dtype=np.float64)
    L = dbars.shape[1]
    out_p = np.empty(L + 1, np.int64)
    out_s = np.empty(L + 1, np.int64)
    out_t = np.empty(L + 1, np.int64)
    cost = np.empty(L + 1)
    if extend not in (True, False, "unclaimed"):
        raise MtannoError(f"extend must be True, False or 'unclaimed', got {extend!r}")
    rank = np.empty(len(names), np.int64)  # rows sorted by (start, end, label name)
    rank[sorted(range(len(names)), key=lambda i: names[i])] = np.arange(len(names))
    P = dbars.shape[0]
    if row_spans is None:  # every row valid everywhere
        firsts, lasts = np.zeros(P, np.int64), np.full(P, L - 1, np.int64)
        offsets = np.arange(P + 1, dtype=np.int64)
    else:
        firsts, lasts, offsets = row_spans
    m = _label_runs(dbars, firsts, lasts, offsets,
                    2 if extend == "unclaimed" else int(bool(extend)), rank, out_p, out_s,
                    out_t, cost)
    return [Annotation(doc, s, t, names[p], c) for p, s, t, c in
            zip(out_p[:m].tolist(), out_s[:m].tolist(), out_t[:m].tolist(), cost[:m].tolist())]


def single_label_segments(doc: str, names: Sequence[str], dbars: np.ndarray,
                          rows: Sequence[Annotation]) -> list[Annotation]:
    """Resolve overlapping segments into a partition (``annotate --single-label``).

    Every frame covered by one or more of ``rows`` (the segments of one document, possibly
    overlapping after the extension of docs/method.md §7 step 4) keeps the label, among the
    segments covering it, with the smallest Δ̄ there (ties → the smaller label index, as in
    step 3); frames no segment covers stay unlabelled. The result is the maximal runs of
    one label: no two segments share a frame. ``cost`` is the smallest Δ̄ of the label
    inside its run. Frames are 0-based at 30 Hz.
    """
    dbars = np.asarray(dbars, dtype=np.float64)
    P, L = dbars.shape
    index = {n: k for k, n in enumerate(names)}
    cover = np.zeros((P, L), dtype=bool)
    for r in rows:
        cover[index[r.label], r.start:r.end + 1] = True
    # covered frames rank by Δ̄ (∞ after every finite value), uncovered ones never win
    key = np.where(cover, np.nan_to_num(dbars, posinf=np.finfo(np.float64).max), np.inf)
    label = np.argmin(key, axis=0)
    label[~cover.any(axis=0)] = -1
    out: list[Annotation] = []
    change = np.flatnonzero(np.diff(label)) + 1
    for s, e in zip(np.r_[0, change], np.r_[change, L]):
        p = int(label[s])
        if p >= 0:
            out.append(Annotation(doc, int(s), int(e) - 1, names[p],
                                  float(dbars[p, s:e].min())))
    return out


@dataclass
class ClassModel:
    """A class as the annotator needs it: name, quantized template values and weights.

    :meth:`matcher` packs the template for the matching kernel once and keeps it, so a
    batch of documents does not repeat that work per document."""

    name: str
    values: np.ndarray
    weights: np.ndarray
    path: str | None = None
    sha256: str | None = None
    #: a further template of the class (a configuration's ``[templates]``), not the base
    #: template of the template folder
    extra: bool = False
    _prepared: dict = field(default_factory=dict, repr=False, compare=False)

    def record(self) -> dict:
        """The provenance record of the class's template: class, file, SHA-256."""
        return {"class": self.name, "path": self.path, "sha256": self.sha256}

    def matcher(self, variant: str = "reference"):
        from mtanno.templates.match import PreparedTemplate

        if variant not in self._prepared:
            self._prepared[variant] = PreparedTemplate(self.values, self.weights,
                                                       variant=variant)
        return self._prepared[variant]

    def column_keys(self) -> frozenset:
        """The template's distinct columns (as bytes), made once: what
        :func:`evidence_covered` compares."""
        if "columns" not in self._prepared:
            V = np.ascontiguousarray(self.values.T)
            self._prepared["columns"] = frozenset(row.tobytes() for row in V)
        return self._prepared["columns"]

    def evidence_columns(self):
        """The template's :class:`mtanno.annotate.decode.EvidenceColumns` (frame evidence), made
        once."""
        from mtanno.annotate.decode import evidence_columns

        if "evidence" not in self._prepared:
            self._prepared["evidence"] = evidence_columns(self.values)
        return self._prepared["evidence"]


def class_deltas(X: np.ndarray, classes: Sequence[ClassModel], *,
                 windows: Windows | None = None,
                 match_variant: str = "reference") -> list[tuple[np.ndarray, np.ndarray]]:
    """Δ_p and start frames of every class over one document (X: features × frames).

    ``windows`` (from a keyframe stage) restricts a class to candidate windows
    [first, last] (0-based inclusive; clipped to the document, overlapping ones merged; or
    a (firsts, lasts) pair of sorted disjoint arrays, :func:`mtanno.keyframes.class_spans`):
    Δ_p is computed inside each window (windows are matched as separate documents) and is
    ∞ elsewhere ([MBS09] §5). Classes without an entry are matched everywhere. The document
    is bit-packed once for all classes.
    """
    from mtanno.templates.match import pack_document

    L = X.shape[1]
    out = []
    packed = pack_document(X, X.shape[0]) if classes else None
    spans = _class_spans(windows, L)
    for c in classes:
        delta, start = np.empty(L), np.empty(L, np.int64)
        _class_delta(X, packed, c, spans.get(c.name), match_variant, delta, start)
        out.append((delta, start))
    return out


def _class_spans(windows: Windows | None, L: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each class's windows merged once (:func:`merged_spans`), for all its templates; a
    (firsts, lasts) pair of arrays (:func:`mtanno.keyframes.class_spans`) is only checked."""
    from mtanno.templates.match import check_spans

    out = {}
    for name, w in (windows or {}).items():
        if isinstance(w, tuple) and len(w) == 2 and all(isinstance(a, np.ndarray) for a in w):
            out[name] = check_spans(w[0], w[1], L)
        else:
            out[name] = merged_spans(w, L)
    return out


def _class_delta(X, packed, c: ClassModel, spans, match_variant, delta, start, *,
                 clear: bool = True) -> None:
    """Δ and starts of one class into ``delta``/``start`` (inside ``spans``, merged
    windows, if not None; outside them ∞ and −1, or, without ``clear``, as they were)."""
    matcher = c.matcher(match_variant)
    if matcher.f != X.shape[0]:
        raise MtannoError(f"document has {X.shape[0]} features but template '{c.name}' "
                          f"{matcher.f}")
    if spans is not None:
        matcher.match_spans(packed, *spans, out=(delta, start), clear=clear)
    else:
        matcher.run(packed, np.array([0, X.shape[1]], dtype=np.int64), out=(delta, start))


def merged_spans(spans, L: int) -> tuple[np.ndarray, np.ndarray]:
    """Windows (first, last frame; 0-based inclusive) clipped to [0, L − 1], sorted,
    overlapping ones merged: (starts, ends), as the matchers take them."""
    arr = np.array(spans, dtype=np.int64).reshape(-1, 2)
    a, b = np.maximum(arr[:, 0], 0), np.minimum(arr[:, 1], L - 1)
    keep = b >= a
    a, b = a[keep], b[keep]
    if a.size == 0:
        return a, b
    order = np.lexsort((b, a))
    a, b = a[order], b[order]
    reach = np.maximum.accumulate(b)  # furthest end so far
    first = np.ones(a.shape[0], dtype=bool)
    first[1:] = a[1:] > reach[:-1]  # a window that starts after every earlier one ended
    last = np.append(first[1:], True)
    return a[first], reach[last]


def valid_windows(windows: Windows | None, names: Sequence[str], valid: np.ndarray,
                  ) -> Windows | None:
    """``windows`` restricted to the valid frames (``valid``: (frames,) bool, a feature
    file's :attr:`~mtanno.features.store.FeatureFile.valid`), for every class of ``names``: a
    class without windows gets the valid stretches, one with windows their intersection.
    Windows are matched as separate documents (:func:`class_deltas`), so no match, and no
    label, spans or touches an invalid frame. All frames valid: ``windows`` unchanged."""
    valid = np.asarray(valid, dtype=bool)
    if valid.all():
        return windows
    L = valid.shape[0]
    edges = np.flatnonzero(np.diff(np.r_[False, valid, False].astype(np.int8)))
    vf, vl = edges[::2].astype(np.int64), edges[1::2].astype(np.int64) - 1
    spans = _class_spans(windows, L)
    out: Windows = {}
    for name in dict.fromkeys(names):
        if name not in spans:
            out[name] = (vf, vl)
            continue
        wf, wl = spans[name]
        firsts, lasts = [], []
        i = j = 0
        while i < wf.size and j < vf.size:  # two sorted disjoint span lists
            a, b = max(wf[i], vf[j]), min(wl[i], vl[j])
            if a <= b:
                firsts.append(a)
                lasts.append(b)
            if wl[i] < vl[j]:
                i += 1
            else:
                j += 1
        out[name] = (np.array(firsts, np.int64), np.array(lasts, np.int64))
    return out


def valid_rows(rows: Sequence[Annotation], valid: np.ndarray) -> list[Annotation]:
    """``rows`` cut to the valid frames: a row keeps its valid runs (the boundary
    refinement and run extension may reach a few frames past a window). With
    :func:`valid_windows` this makes sure no label covers an invalid frame."""
    valid = np.asarray(valid, dtype=bool)
    if valid.all():
        return list(rows)
    out = []
    for r in rows:
        part = valid[r.start:r.end + 1]
        if part.all():
            out.append(r)
            continue
        edges = np.flatnonzero(np.diff(np.r_[False, part, False].astype(np.int8)))
        out += [r._replace(start=r.start + int(a), end=r.start + int(b) - 1)
                for a, b in zip(edges[::2], edges[1::2])]
    return out


def evidence_covered(classes: Sequence[ClassModel]) -> set[int]:
    """Indices of the templates whose frame evidence another template of the same class
    already gives: every column of theirs is a column of the other one (a time-scaled copy,
    :mod:`mtanno.templates.tempo`, or a duplicate), so their evidence — the best column
    anywhere in the template — is never lower, and the class's minimum stays the other's.
    Of templates with the same columns the first is kept."""
    cols = [c.column_keys() for c in classes]
    out = set()
    for i, a in enumerate(classes):
        for j, b in enumerate(classes):
            if j != i and a.name == b.name and a.values.shape[0] == b.values.shape[0] \
                    and cols[i] <= cols[j] and (cols[i] != cols[j] or j < i):
                out.add(i)
                break
    return out


def annotate_document(doc: str, X: np.ndarray, classes: Sequence[ClassModel], *,
                      config: ClassConfig | None = None,
                      windows: Windows | None = None,
                      dbar_variant: str = "reference", match_variant: str = "reference",
                      max_hits: int | None = None, extend: bool = True,
                      single_label: bool = False, packed: np.ndarray | None = None,
                      matrix: bool = True,
                      ) -> tuple[list[Annotation], list[str], np.ndarray | None]:
    """Annotate one document ([MBS09] §4–5): returns (segments, label names, Δ̄ matrix).

    Labels are the classes, or the superclasses of ``config`` joining them (classes not in
    a superclass keep their name); Δ̄ of a label is the frame-wise minimum of its classes'.
    Segments of different labels may overlap (the reference output); with
    ``single_label`` overlaps are resolved frame by frame to the label with the smallest
    Δ̄ (:func:`single_label_segments`), so the segments form a partition of the labelled
    frames. Several :class:`ClassModel` of one name (a class with several templates) make
    one label, like a superclass. With ``config.resolve`` the segments come from the
    segment decoder (:func:`label_document`; already a partition) and the matrix holds
    Δ/τ per label instead of Δ̄. ``windows``: candidate windows per class, as
    :func:`class_deltas` takes them (:func:`mtanno.keyframes.class_spans`). ``packed``: X
    already bit-packed (:func:`mtanno.templates.match.pack_document`, as for
    :func:`mtanno.keyframes.class_windows`), to pack it once. ``matrix=False``: no matrix
    (None; :func:`label_document`), which saves filling and reading it outside the windows.
    """
    config = config or ClassConfig()
    if not classes:
        raise MtannoError("no class templates to annotate with")
    from mtanno.templates.match import pack_document

    L = X.shape[1]
    if packed is None:
        packed = pack_document(X, X.shape[0])
    elif np.shape(packed) != (L, (X.shape[0] + 63) // 64) or packed.dtype != np.uint64:
        raise MtannoError(f"packed document must be uint64 ({L} frames × "
                          f"{(X.shape[0] + 63) // 64} words), got {np.shape(packed)}")
    # one Δ buffer for all classes: documents can be hours long
    delta, start = np.empty(L), np.empty(L, np.int64)
    evidence = config.resolve and config.frame_weight > 0

    if evidence:
        from mtanno.annotate.decode import EVIDENCE_MARGIN, distinct_frames, row_evidence

        distinct = distinct_frames(packed)  # once for all templates
        covered = evidence_covered(classes)

    spans = _class_spans(windows, L)
    # the reference Δ̄ and the decoder's rows read Δ inside the windows only: the buffer is
    # not cleared outside them
    clear = not config.resolve and dbar_variant != "reference"

    names = [c.name for c in classes]
    rows, own = None, {}
    if config.resolve:  # the only template of a label is matched into the decoder's row
        labels, member_of, count = _label_layout(names, config)
        rows = (np.empty((len(labels), L)), np.empty((len(labels), L), dtype=np.int64))
        for i, n in enumerate(names):
            lab = member_of.get(n, n)
            if count[lab] == 1:
                own[i] = labels.index(lab)

    def matches():
        for i, c in enumerate(classes):
            if i in own:
                k = own[i]
                _class_delta(X, packed, c, spans.get(c.name), match_variant, rows[0][k],
                             rows[1][k], clear=True)
                d, s = None, None
            else:
                _class_delta(X, packed, c, spans.get(c.name), match_variant, delta, start,
                             clear=clear)
                d, s = delta, start
            if not evidence or i in covered:  # covered: its columns are another template's
                yield c.name, d, s, None
                continue
            near = None
            if c.name in spans:  # only where c can be
                first, last = spans[c.name]
                near = merged_spans(np.column_stack((first - EVIDENCE_MARGIN,
                                                     last + EVIDENCE_MARGIN)), L)
            yield c.name, d, s, row_evidence(packed, c.evidence_columns(), spans=near,
                                             distinct=distinct)

    return label_document(doc, names, matches(), L, config=config,
                          dbar_variant=dbar_variant, max_hits=max_hits, extend=extend,
                          single_label=single_label, spans=spans, matrix=matrix, rows=rows)


def _label_layout(names: Sequence[str], config: ClassConfig) -> tuple[list[str], dict, dict]:
    """The labels of templates ``names`` (classes, or the superclasses of ``config``
    joining them) in order of first appearance, the superclass of each member, and the
    number of templates per label."""
    member_of = {m: s for s, ms in config.superclasses.items() for m in ms}
    labels: list[str] = []
    for n in names:
        lab = member_of.get(n, n)
        if lab not in labels:
            labels.append(lab)
    count = {lab: sum(member_of.get(n, n) == lab for n in names) for lab in labels}
    return labels, member_of, count


def label_document(doc: str, names: Sequence[str], matches, n_frames: int, *,
                   config: ClassConfig | None = None, dbar_variant: str = "reference",
                   max_hits: int | None = None, extend: bool = True,
                   single_label: bool = False,
                   spans: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
                   matrix: bool = True,
                   rows: tuple[np.ndarray, np.ndarray] | None = None,
                   ) -> tuple[list[Annotation], list[str], np.ndarray | None]:
    """Segments of one document from its templates' distance functions (docs/method.md
    §7 steps 2–4, or the methods of issue 10 that ``config`` switches on).

    ``names`` is the class of each template, in order; ``matches`` yields, for each
    template in that order, (class, Δ, start frames, frame evidence or None) — Δ and the
    starts as :func:`mtanno.templates.match.match_template` gives them (the arrays may be
    reused buffers: each is read before the next is asked for), the evidence of
    :func:`mtanno.annotate.decode.frame_evidence` where ``config.frame_weight`` is used (an
    array, or a :class:`mtanno.annotate.decode.RowEvidence`, written into the decoder's buffer
    without a temporary; None for a template whose evidence another of its class gives,
    :func:`evidence_covered`; at least one template per class must give it). ``spans``:
    per class, the merged windows outside which its Δ is ∞ (keyframe preselection), so
    that Δ̄ and the decoder's rows read Δ only inside them.

    * Default ([MBS09], the reference implementation): Δ̄ per class with τ (at most the
      class's rejection ceiling ρ), labels, extension (``config.refine``: only over
      frames of no other label).
    * ``config.resolve``: the segment decoder (:func:`mtanno.annotate.decode.decode_segments`) on
      Δ/τ per label (templates with Δ > ρ dropped), with ``config.slack`` when
      ``config.refine``, the relative frame evidence weighted by ``config.frame_weight``
      and ``config.segment_cost`` per segment; a segment's cost is Δ at its end.
    * ``single_label`` (default path only; the decoder's segments are a partition
      already): overlaps resolved frame by frame (:func:`single_label_segments`).

    ``matrix=False``: the matrix is not returned (None), and in the default path the Δ̄
    row of a class with ``spans`` is neither filled nor read outside them (the same
    segments, less work where keyframe windows cover little of the document).

    ``rows`` (segment decoder only): the decoder's (labels × frames) Δ and start arrays,
    allocated by the caller (labels as :func:`_label_layout` orders them), so that the
    only template of a label can be matched straight into its row: ``matches`` then
    yields (class, None, None, evidence) for it, the row holding its raw Δ and starts
    (∞ and anything where no match ends), and the decoder applies its τ and ρ (the same
    segments as folding Δ/τ into the row, one pass over the frames less).

    Returns (segments sorted by start, end and label; label names; Δ̄ or Δ/τ matrix).
    """
    config = config or ClassConfig()
    layout = _label_layout(names, config)
    if not config.resolve:
        return _dbar_segments(doc, matches, int(n_frames), layout, config,
                              dbar_variant=dbar_variant, max_hits=max_hits, extend=extend,
                              single_label=single_label, spans=spans or {}, matrix=matrix)
    return _decoder_segments(doc, names, matches, int(n_frames), layout, config,
                             spans=spans or {}, matrix=matrix, rows=rows)


def _limits(config: ClassConfig, name: str, lab: str) -> tuple[float, float]:
    """(τ, ρ) of template class ``name`` in label ``lab``: its own, else its label's."""
    return (config.tau.get(name, config.tau_for(lab)),
            config.reject.get(name, config.reject_for(lab)))


def _dbar_segments(doc, matches, L: int, layout, config: ClassConfig, *, dbar_variant,
                   max_hits, extend, single_label, spans, matrix):
    """:func:`label_document` without ``config.resolve`` ([MBS09], the reference
    implementation): Δ̄ rows (a label's templates folded by the frame-wise minimum),
    labels and extended runs, and ``single_label`` resolution."""
    labels, member_of, count = layout
    P = len(labels)
    # without the matrix, a row with windows is written and read inside them only
    sparse = (not matrix and not single_label and dbar_variant == "reference"
              and all(n == 1 for n in count.values()))
    row_spans: list[tuple[np.ndarray, np.ndarray] | None] = [None] * P
    mat = np.empty((P, L))  # rows written by modified_delta; folded rows start at ∞
    for k, lab in enumerate(labels):
        if count[lab] > 1:
            mat[k].fill(np.inf)
    tmp = np.empty(L)
    written = set()
    for name, delta, start, _ in matches:
        lab = member_of.get(name, name)
        tau, rho = _limits(config, name, lab)
        k = labels.index(lab)
        sp = spans.get(name)
        if sparse and sp is not None:
            row_spans[k] = _reference_in_spans(delta, start, min(tau, rho), max_hits,
                                               mat[k], sp)
            written.add(k)
            continue
        out = mat[k] if count[lab] == 1 else tmp
        modified_delta(delta, start, tau=min(tau, rho), variant=dbar_variant,
                       max_hits=max_hits, out=out, spans=sp)
        if count[lab] > 1:
            np.minimum(mat[k], tmp, out=mat[k])
        written.add(k)
    for k in set(range(P)) - written:  # a label whose templates gave no Δ
        mat[k].fill(np.inf)
    mode: bool | str = "unclaimed" if (extend and config.refine) else extend
    rows = segments_from_labels(doc, labels, mat, extend=mode,
                                row_spans=_row_spans(row_spans, L) if sparse else None)
    if single_label:
        rows = single_label_segments(doc, labels, mat, rows)
    return rows, labels, (mat if matrix else None)


def _decoder_segments(doc, names, matches, L: int, layout, config: ClassConfig, *, spans,
                      matrix, rows):
    """:func:`label_document` with ``config.resolve``: the matches folded into the
    decoder's rows (:func:`_decoder_rows`), decoded, and each segment's cost as Δ at its
    end."""
    from mtanno.annotate.decode import decode_segments, evidence_sums

    labels = layout[0]
    P = len(labels)
    mat, starts, raw, label_tau, tau_rows, ev = _decoder_rows(names, matches, L, layout,
                                                              config, spans=spans, rows=rows)
    scale, ceiling = np.ones(P), np.full(P, np.inf)
    for k, (tau, rho) in raw.items():
        scale[k], ceiling[k] = tau, rho
    decoded = decode_segments(mat, starts, tau=scale, reject=ceiling,
                              slack=config.slack if config.refine else 0,
                              evidence=None if ev is None else evidence_sums(ev),
                              weight=config.frame_weight, segment_cost=config.segment_cost)
    # cost: Δ at the segment's end, back from Δ/τ where the row holds Δ/τ (to 12 digits:
    # the division's rounding)
    def tau_at(k: int, t: int) -> float:
        if k in raw:
            return 1.0
        return label_tau[k] if k in label_tau else float(tau_rows[k][t])

    out = [Annotation(doc, d.start, d.end, labels[d.label],
                      float(f"{d.cost * tau_at(d.label, d.end):.12g}")) for d in decoded]
    out.sort(key=lambda a: (a.start, a.end, a.label))
    if matrix:  # Δ/τ in every row, as folding gives it
        for k, (tau, rho) in raw.items():
            gone = ~(mat[k] <= rho)
            np.multiply(mat[k], 1.0 / tau, out=mat[k])
            mat[k][gone] = np.inf
    return out, labels, (mat if matrix else None)


def _decoder_rows(names, matches, L: int, layout, config: ClassConfig, *, spans, rows):
    """The segment decoder's inputs from the matches: the (labels × frames) Δ/τ and start
    rows (each label's first template written in full by ``fold_label(first=True)``, so
    the arrays of long documents are not filled twice; a row matched straight into, for
    the only template of a label, keeps raw Δ and its (τ, ρ) in ``raw``), the τ of each
    label for the cost column (``label_tau``; per frame in ``tau_rows`` for a label whose
    members have different τ), and the frame evidence rows (or None)."""
    from mtanno.annotate.decode import RowEvidence, fold_label

    labels, member_of, count = layout
    P = len(labels)
    if rows is not None:
        mat, starts = rows
        if mat.shape != (P, L) or starts.shape != (P, L):
            raise MtannoError(f"decoder rows must be ({P} labels × {L} frames) arrays")
    else:
        mat = np.empty((P, L))
        starts = np.empty((P, L), dtype=np.int64)
    folded: set[int] = set()
    raw: dict[int, tuple[float, float]] = {}  # label → (τ, ρ) of a row holding raw Δ
    # a superclass whose members have different τ keeps, per frame, the τ of the template
    # that gives the minimum
    member_taus: dict[int, set[float]] = {}
    for n in names:
        lab = member_of.get(n, n)
        member_taus.setdefault(labels.index(lab), set()).add(_limits(config, n, lab)[0])
    label_tau = {k: next(iter(t)) for k, t in member_taus.items() if len(t) == 1}
    tau_rows = {k: np.ones(L) for k in member_taus if k not in label_tau}
    # each label's evidence in ev[:, 1:] (its first template's copied, further ones folded
    # by np.minimum), turned into the decoder's running sums in place
    ev = np.empty((P, L + 1)) if config.frame_weight > 0 else None
    has_evidence: set[int] = set()
    for name, delta, start, evidence in matches:
        lab = member_of.get(name, name)
        tau, rho = _limits(config, name, lab)
        if not tau > 0:
            raise MtannoError(f"tau of {name} must be > 0 for the segment decoder, got {tau!r}",
                              path=config.path)
        k = labels.index(lab)
        span = spans.get(name)
        if delta is None:  # matched into its row: the decoder applies τ and ρ
            if rows is None or count[lab] != 1:
                raise MtannoError("a template matched into its row must be the only one "
                                  "of its label, in the decoder rows given")
            raw[k] = (float(tau), float(rho))
        elif k in label_tau:
            fold_label(mat[k], starts[k], delta, start, tau=tau, reject=rho,
                       first=k not in folded, spans=span)
        else:
            before = mat[k].copy() if k in folded else np.full(L, np.inf)
            fold_label(mat[k], starts[k], delta, start, tau=tau, reject=rho,
                       first=k not in folded, spans=span)
            tau_rows[k][mat[k] < before] = tau
        folded.add(k)
        if ev is not None and evidence is not None:
            if k in has_evidence:
                frames = evidence.frames() if isinstance(evidence, RowEvidence) else evidence
                np.minimum(ev[k, 1:], frames, out=ev[k, 1:])
            elif isinstance(evidence, RowEvidence):
                evidence.write(ev[k, 1:])
            else:
                ev[k, 1:] = evidence
            has_evidence.add(k)
    if ev is not None and len(has_evidence) < len(member_taus):
        raise MtannoError("frame_weight > 0 needs the frame evidence of a template of every "
                          "class")
    return mat, starts, raw, label_tau, tau_rows, ev
