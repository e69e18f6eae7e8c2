"""The fold data of ``mtanno tune``'s search (issue 10; issue 34 for its size): per fold and
class the templates learned from the fold's training examples and matched against its
held-out documents (worker tasks: :func:`learn_fold_class`, :func:`match_fold_class`), and
what :class:`mtanno.tuning.search.Tuner` keeps of them (:func:`fold_data`): the match cache
of every fold and, for the runs with a class left out, views of the documents that hold
the class (:func:`_subset`: arrays sliced when they are read, never copied).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from mtanno.templates.tempo import time_scaled
from mtanno.tuning.cv import Fold

__all__ = ["fold_data", "learn_fold_class", "match_fold_class", "prepare_fold_class"]


def prepare_fold_class(cls: str, train, held_X: np.ndarray, offsets: np.ndarray, *,
                       deltas: Sequence[float], groups: Sequence[int], learn: dict,
                       spans: tuple[np.ndarray, np.ndarray] | None, evidence: bool,
                       evidence_spans: tuple[np.ndarray, np.ndarray] | None = None,
                       scales: Sequence[float] = ()) -> dict:
    """One class of one fold: its templates learned from ``train`` (:func:`learn_fold_class`)
    and matched against the held-out documents with each δ (:func:`match_fold_class`).
    Returns ``{"groups": {k: k'}, "match": {(δ, k', i): (Δ, absolute starts, evidence or
    None)}}``. (``tune`` runs the two halves apart: the search's first step needs only
    template (1, 0), the others only at the δ it chose.)"""
    templates, made = learn_fold_class(cls, train, groups=groups, learn=learn, scales=scales)
    return {"groups": made,
            "match": match_fold_class(templates, held_X, offsets, deltas=deltas, spans=spans,
                                      evidence=evidence, evidence_spans=evidence_spans)}


def learn_fold_class(cls: str, train, *, groups: Sequence[int], learn: dict,
                     scales: Sequence[float] = ()) -> tuple[dict, dict]:
    """The templates of one class of one fold, learned from ``train`` (all examples, and
    per group for each group count of ``groups``): ``({key: template}, {k: k'})``. k' groups
    were made for k asked (fewer when a group would be too small); template (1, 0) is the
    one learned from all examples, (k', i) group i of a split into k', and (0, f) for each
    f of ``scales`` template (1, 0) time-scaled by f (:func:`mtanno.templates.tempo.
    time_scaled`)."""
    from mtanno.templates.learn import learn_template
    from mtanno.tuning.cluster import example_distances, group_examples

    templates = {(1, 0): learn_template(train, class_name=cls, **learn)}
    for f in scales:
        templates[(0, float(f))] = time_scaled(templates[(1, 0)], float(f))
    made = {1: 1}
    if groups:
        D = example_distances(train)
        for k in groups:
            lab = group_examples(D, k)
            n = made[k] = int(lab.max()) + 1
            if n < 2 or (n, 0) in templates:
                continue  # no split, or the split of a smaller k again (k-medoids falls back)
            for i in range(n):
                templates[(n, i)] = learn_template([e for e, g in zip(train, lab) if g == i],
                                                   class_name=cls, **learn)
    return templates, made


def match_fold_class(templates: dict, held_X: np.ndarray, offsets: np.ndarray, *,
                     deltas: Sequence[float], spans: tuple[np.ndarray, np.ndarray] | None,
                     evidence: bool,
                     evidence_spans: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """The templates of :func:`learn_fold_class` quantized with each δ and matched against
    the held-out documents (``offsets``; only inside ``spans`` — absolute first and last
    frames — when keyframe windows are given; the frame evidence then only inside
    ``evidence_spans``, the windows widened as annotate widens them):
    ``{(δ, k, i): (Δ, absolute starts, evidence or None)}`` (evidence None without
    ``evidence``, and for a time-scaled copy: it equals the template's)."""
    from mtanno.annotate.decode import distinct_frames, frame_evidence
    from mtanno.templates.match import PreparedTemplate, pack_document
    from mtanno.templates.model import quantize

    packed = pack_document(held_X, held_X.shape[0])
    distinct = distinct_frames(packed) if evidence else None
    out = {}
    for delta in deltas:
        for key, mt in templates.items():
            q = quantize(mt, delta)
            prep = PreparedTemplate(q.values, q.weights)
            if spans is None:
                d, s = prep.run(packed, offsets)
                # run gives starts relative to each document: make them absolute
                for a, b in zip(offsets[:-1], offsets[1:]):
                    seg = s[a:b]
                    seg[seg >= 0] += a
            else:
                d, s = prep.match_spans(packed, spans[0], spans[1])
            ev = frame_evidence(packed, q.values, spans=evidence_spans,
                                distinct=distinct) if evidence and key[0] else None
            out[(float(delta), *key)] = (d, s, ev)
    return out


@dataclass
class _FoldData:
    name: str
    n_frames: int
    offsets: np.ndarray
    classes: list[str]                      # classes with templates in this fold
    truth: list[tuple[int, int, int]]       # (label id, first, last)
    truth_by_class: dict[str, list[tuple[int, int]]]
    match: dict                             # (δ, class, k, i) -> (Δ, starts, evidence)
                                            # (k = 0: time-scaled by i, evidence None)
    groups: dict                            # (class, k) -> groups made
    hidden: dict = field(default_factory=dict)  # class -> _FoldData of its documents only
    absent: dict = field(default_factory=dict)  # class without a template here -> spans
    ignore: np.ndarray | None = None        # their frames and the background documents'
                                            # (not scored in F1, F2 by the search)
    known_ignore: np.ndarray | None = None  # the absent classes' frames only
    n_background: int = 0                   # background documents (the last ones)
    spans: list | None = None               # a subset's documents: (first, end, first
                                            # here) frames in its fold (:func:`_subset`)
    truth_cover: np.ndarray | None = None   # score._cover of the truth, once


def _gather(spans: Sequence[tuple[int, int, int]], arr: np.ndarray) -> np.ndarray:
    """The frames ``a..b−1`` of every span (a, b, new first frame) of ``arr`` (last axis),
    concatenated: a fold's array restricted to some of its documents."""
    return np.concatenate([arr[..., a:b] for a, b, _ in spans], axis=-1)


def _gather_starts(spans: Sequence[tuple[int, int, int]], st: np.ndarray) -> np.ndarray:
    """:func:`_gather` of start frames, moved along with their documents (−1 stays)."""
    out = _gather(spans, st)
    for a, b, n in spans:
        part = out[..., n:n + b - a]
        np.add(part, n - a, out=part, where=part >= 0)
    return out


class _SubsetMatch(Mapping):
    """The match cache of a fold seen through some of its documents (:func:`_subset`):
    each entry sliced when it is read, so a subset holds no copy of the fold's arrays
    (issue 34: the copies of every class's subset were most of ``tune``'s memory)."""

    def __init__(self, match: dict, spans: list[tuple[int, int, int]]):
        self._match = match
        self._spans = spans

    def __getitem__(self, key):
        d, st, ev = self._match[key]
        return (_gather(self._spans, d), _gather_starts(self._spans, st),
                None if ev is None else _gather(self._spans, ev))

    def __iter__(self):
        return iter(self._match)

    def __len__(self) -> int:
        return len(self._match)


def _subset(fd: _FoldData, docs: Sequence[int]) -> _FoldData:
    """The fold restricted to some of its documents (the unknown-class runs of a class
    need only the documents that hold it): arrays sliced as they are read
    (:class:`_SubsetMatch`), start frames moved along."""
    if len(docs) == len(fd.offsets) - 1:
        return fd
    lengths = [int(fd.offsets[d + 1] - fd.offsets[d]) for d in docs]
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    spans = [(int(fd.offsets[d]), int(fd.offsets[d + 1]), int(offsets[j]))
             for j, d in enumerate(docs)]
    new_of = {int(d): j for j, d in enumerate(docs)}

    def frame(a: int) -> int:
        d = int(np.searchsorted(fd.offsets, a, side="right")) - 1
        return int(a - fd.offsets[d] + offsets[new_of[d]])

    keep = [(c, a, b) for c, a, b in fd.truth
            if int(np.searchsorted(fd.offsets, a, side="right")) - 1 in new_of]
    truth = [(c, frame(a), frame(b)) for c, a, b in keep]
    by_class: dict[str, list[tuple[int, int]]] = {}
    for c, lst in fd.truth_by_class.items():
        for a, b in lst:
            if int(np.searchsorted(fd.offsets, a, side="right")) - 1 in new_of:
                by_class.setdefault(c, []).append((frame(a), frame(b)))
    return _FoldData(fd.name, int(offsets[-1]), offsets, fd.classes, truth, by_class,
                     _SubsetMatch(fd.match, spans), fd.groups, spans=spans)


def _sub_arrays(sub: _FoldData, arrays):
    """:meth:`Tuner.decoder_arrays` of a subset from those of its fold (the same numbers: every
    entry is a minimum over the templates of one frame, so slicing before or after is
    alike)."""
    mat, st, ev = arrays
    return (_gather(sub.spans, mat), _gather_starts(sub.spans, st),
            None if ev is None else _gather(sub.spans, ev))



def fold_data(f: Fold, prepared: dict[tuple[str, str], dict], classes: Sequence[str],
              ids: dict[str, int]) -> _FoldData:
    """What the search keeps of fold ``f``: the matches of its classes' templates
    (``prepared``, as :func:`prepare_fold_class` gives them; ``ids``: label of every class
    name), its truth, the classes absent from it and the frames not scored, and per class
    the subset of its documents that hold the class (:func:`_subset`)."""
    match, groups, present = {}, {}, []
    for c in classes:
        got = prepared.get((f.name, c))
        if got is None:
            continue
        present.append(c)
        for (delta, k, i), v in got["match"].items():
            match[(delta, c, k, i)] = v
        for k, n in got["groups"].items():
            groups[(c, k)] = n
    by_class: dict[str, list[tuple[int, int]]] = {}
    for c, a, b in f.held_out.truth:
        by_class.setdefault(c, []).append((a, b))
    # A class without a template in this fold (its examples all held out, or no
    # template at all) is an unknown motion here: its frames count in U, not in
    # F1 and F2, which score the classes the fold can know.
    absent = {c: spans for c, spans in by_class.items() if c not in present}
    ignore = None
    if absent:
        ignore = np.zeros(f.held_out.n_frames, dtype=bool)
        for spans in absent.values():
            for a, b in spans:
                ignore[a:b + 1] = True
    # background documents (the last ones) shape the confidence, not the search
    n_bg = len(f.background)
    known_ignore = ignore
    if n_bg:
        ignore = np.zeros(f.held_out.n_frames, dtype=bool) if ignore is None \
            else ignore.copy()
        ignore[int(f.held_out.offsets[-1 - n_bg]):] = True
    fd = _FoldData(f.name, f.held_out.n_frames, f.held_out.offsets, present,
                   [(ids[c], a, b) for c, a, b in f.held_out.truth
                    if c in present], by_class, match, groups, absent=absent,
                   ignore=ignore, known_ignore=known_ignore, n_background=n_bg)
    for c in present:
        docs = sorted({int(np.searchsorted(fd.offsets, a, side="right")) - 1
                       for a, _ in by_class.get(c, [])})
        if docs:
            fd.hidden[c] = _subset(fd, docs)
    return fd
