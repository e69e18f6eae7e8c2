"""Keyframe search: the frames of documents where a keyframe query has a chain, and the
candidate windows annotation matches templates in ([MBS09] §5; docs/method.md §5).

For each keyframe V_j, the frames whose group vector matches V_j form an interval list
I_j: from an index, the union of the inverted lists of every vector V_j matches with
adjacent segments merged (:meth:`mtanno.index.GroupIndex.intervals`); without an index,
by a direct scan of the feature matrix. A *chain* is t_1 ≤ … ≤ t_n with t_j ∈ I_j and
dmin_j ≤ t_{j+1} − t_j ≤ dmax_j, never crossing a document end. Three linear passes over
the lists find all chains at once:

1. forward: F_1 = I_1, F_{j+1} = I_{j+1} ∩ (F_j ⊕ [dmin_j, dmax_j]) — frames reachable
   from level 1;
2. backward: B_n = F_n, B_j = F_j ∩ (B_{j+1} ⊕ [−dmax_j, −dmin_j]) — the frames that lie on
   a complete chain (on a path of constraints, forward and backward consistency together
   are global consistency);
3. spans: for consecutive levels, each pair of a B_j and a B_{j+1} interval joined by an
   admissible gap contributes the span of its pairs; the union of these spans is exactly
   the union of the spans [t_1, t_n] of all chains (``docs/keyframes.md`` has the proof).

The union's maximal runs are the *hits* (the reference implementation reports, per chain of
segments, [leftmost feasible t_1, rightmost feasible t_n] and merges overlapping windows —
the same frames). Candidate windows widen each hit by the query's extension, clip it to
its document and merge (:meth:`KeyframeHits.windows`). Frames are 0-based in code.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from mtanno.errors import MtannoError
from mtanno.keyframes import _kernels
from mtanno.keyframes.model import (
    UNBOUNDED,
    KeyframeQuery,
    check_features_known,
    tolerant_patterns,
)

__all__ = ["Intervals", "KeyframeHits", "KeyframeSet", "chain_hits", "class_spans",
           "class_windows",
           "document_windows", "search_documents", "search_index"]

Intervals = tuple[np.ndarray, np.ndarray, np.ndarray]
"""An interval list: (doc, start, end) int64 arrays, sorted, disjoint, end inclusive."""


def _empty() -> Intervals:
    z = np.zeros(0, np.int64)
    return z, z.copy(), z.copy()


def _intervals(iv, what: str) -> Intervals:
    """An interval list as three int64 arrays of one length (the kernels read the three
    together, past the shorter ones if they differ)."""
    if len(iv) != 3:
        raise MtannoError(f"{what} must be (doc, start, end) arrays")
    doc, start, end = (np.ascontiguousarray(a, np.int64) for a in iv)
    if doc.ndim != 1 or start.shape != doc.shape or end.shape != doc.shape:
        raise MtannoError(f"{what}: doc, start and end must be 1-D arrays of one length, got "
                          f"shapes {doc.shape}, {start.shape} and {end.shape}")
    return doc, start, end


def _check_gaps(gaps, n: int) -> list[tuple[int, int]]:
    """Gaps (dmin, dmax) between n levels, as integers 0 ≤ dmin ≤ dmax ≤ UNBOUNDED."""
    if n < 1:
        raise MtannoError("a chain needs at least one level")
    if len(gaps) != n - 1:
        raise MtannoError(f"{n} levels need {n - 1} gaps")
    out = [(int(lo), int(hi)) for lo, hi in gaps]
    for lo, hi in out:
        if not 0 <= lo <= hi <= UNBOUNDED:
            raise MtannoError(f"gap ({lo}, {hi}) must satisfy 0 ≤ dmin ≤ dmax ≤ {UNBOUNDED}")
    return out


def _dilate(iv: Intervals, lo: int, hi: int) -> Intervals:
    n = len(iv[0])
    out = tuple(np.empty(n, np.int64) for _ in range(3))
    k = _kernels.dilate(iv[0], iv[1], iv[2], lo, hi, *out)
    return out[0][:k], out[1][:k], out[2][:k]


def _intersect(a: Intervals, b: Intervals) -> Intervals:
    n = len(a[0]) + len(b[0])
    out = tuple(np.empty(n, np.int64) for _ in range(3))
    k = _kernels.intersect(a[0], a[1], a[2], b[0], b[1], b[2], *out)
    return out[0][:k], out[1][:k], out[2][:k]


def _pair_spans(a: Intervals, b: Intervals, dmin: int, dmax: int) -> Intervals:
    cap = len(a[0]) + len(b[0]) + 1
    while True:
        out = tuple(np.empty(cap, np.int64) for _ in range(3))
        k = _kernels.pair_spans(a[0], a[1], a[2], b[0], b[1], b[2], dmin, dmax, *out)
        if k <= cap:
            return out[0][:k], out[1][:k], out[2][:k]
        cap = k


def _union(parts: Sequence[Intervals]) -> Intervals:
    doc = np.concatenate([p[0] for p in parts]) if parts else np.zeros(0, np.int64)
    if not len(doc):
        return _empty()
    start = np.concatenate([p[1] for p in parts])
    end = np.concatenate([p[2] for p in parts])
    order = np.lexsort((start, doc))
    out = tuple(np.empty(len(doc), np.int64) for _ in range(3))
    k = _kernels.merge_sorted(doc[order], start[order], end[order], *out)
    return out[0][:k], out[1][:k], out[2][:k]


def chain_levels(levels: Sequence[Intervals], gaps: Sequence[tuple[int, int]],
                 ) -> list[Intervals]:
    """B_1 … B_n: for each level the frames t_j that lie on a complete chain (passes 1 and
    2 of the module docstring). ``gaps[j] = (dmin, dmax)`` between levels j and j+1."""
    gaps = _check_gaps(gaps, len(levels))
    return _chain_levels([_intervals(lv, f"level {j + 1}") for j, lv in enumerate(levels)], gaps)


def _chain_levels(levels: Sequence[Intervals], gaps: Sequence[tuple[int, int]],
                  ) -> list[Intervals]:
    """:func:`chain_levels` of levels and gaps made by this package (not checked again:
    the keyframe GA chains a few short levels per evaluation, many times)."""
    F = [levels[0]]
    for j, (lo, hi) in enumerate(gaps):
        if not len(F[-1][0]):
            return [_empty() for _ in levels]
        F.append(_intersect(_dilate(F[-1], lo, hi), levels[j + 1]))
    B = [_empty() for _ in levels]
    B[-1] = F[-1]
    for j in range(len(levels) - 2, -1, -1):
        lo, hi = gaps[j]
        B[j] = _intersect(F[j], _dilate(B[j + 1], -hi, -lo))
    return B


def chain_hits(levels: Sequence[Intervals], gaps: Sequence[tuple[int, int]]) -> Intervals:
    """The union of the spans [t_1, t_n] of all chains through ``levels`` (interval lists
    I_1 … I_n) with ``gaps`` (dmin, dmax), as maximal runs: the keyframe hits."""
    gaps = _check_gaps(gaps, len(levels))
    return _chain_hits([_intervals(lv, f"level {j + 1}") for j, lv in enumerate(levels)], gaps)


def _chain_hits(levels: Sequence[Intervals], gaps: Sequence[tuple[int, int]]) -> Intervals:
    """:func:`chain_hits` of levels and gaps made by this package (not checked again)."""
    B = _chain_levels(levels, gaps)
    if len(B) == 1:
        return B[0]
    parts = [_pair_spans(B[j], B[j + 1], lo, hi) for j, (lo, hi) in enumerate(gaps)]
    return _union(parts)


def first_chains(B: Sequence[Intervals], gaps: Sequence[tuple[int, int]], hits: Intervals,
                 ) -> np.ndarray:
    """(hits × n) frames t_1 … t_n of the earliest chain in each hit (greedy: the first
    frame of B_1 in the hit, then the first frame of B_{j+1} at least dmin_j later; every
    frame of B_j continues to a complete chain, so the greedy choice never fails)."""
    n = len(B)
    if n and len(gaps) != n - 1:
        raise MtannoError(f"{n} levels need {n - 1} gaps")
    B = [_intervals(b, f"level {j + 1}") for j, b in enumerate(B)]
    hits = _intervals(hits, "hits")
    out = np.empty((len(hits[0]), n), np.int64)
    keys = [(b[0] << 32) | b[1] for b in B]
    for h in range(len(hits[0])):
        d = int(hits[0][h])
        t = int(hits[1][h])
        for j in range(n):
            lo = t if j == 0 else t + gaps[j - 1][0]
            # first interval of B_j in document d ending at or after lo
            ends = B[j][2]
            i = int(np.searchsorted(keys[j], (d << 32) | lo, side="right")) - 1
            if i < 0 or B[j][0][i] != d or ends[i] < lo:
                i += 1
            if i >= len(ends) or B[j][0][i] != d:
                raise MtannoError(f"hit {h + 1} (document {d}, frame {int(hits[1][h])}) has no "
                                  f"chain through the levels")
            t = max(lo, int(B[j][1][i]))
            out[h, j] = t
    return out


@dataclass
class KeyframeHits:
    """Keyframe hits in a set of documents.

    Attributes
    ----------
    names, lengths:
        Document names and frame counts, by document number.
    doc, start, end:
        One entry per hit (a maximal run of frames covered by chain spans), sorted;
        frames 0-based inclusive.
    query:
        The query searched.
    levels:
        B_1 … B_n, the frames of each level that lie on a complete chain.
    """

    names: tuple[str, ...]
    lengths: np.ndarray
    doc: np.ndarray
    start: np.ndarray
    end: np.ndarray
    query: KeyframeQuery
    levels: list = field(default_factory=list, repr=False)
    _chains: np.ndarray | None = field(default=None, repr=False)

    @property
    def chains(self) -> np.ndarray:
        """(hits × n) frames of the earliest chain in each hit (computed on first use)."""
        if self._chains is None:
            self._chains = first_chains(self.levels, _gaps(self.query),
                                        (self.doc, self.start, self.end))
        return self._chains

    def __len__(self) -> int:
        return len(self.doc)

    def windows(self, *, widths: tuple[int, int] | None = None) -> Intervals:
        """Candidate windows: hits widened by ``widths`` (default: the query's extension,
        :meth:`KeyframeQuery.widths`), clipped to their document and merged where they
        overlap or touch."""
        left, right = self.query.widths() if widths is None else widths
        return widen(self.doc, self.start, self.end, left, right, self.lengths)

    def by_document(self, *, widths: tuple[int, int] | None = None,
                    ) -> dict[str, list[tuple[int, int]]]:
        """Document name → candidate windows [(first, last)] (0-based inclusive), the form
        :func:`mtanno.annotate.annotate_document` takes; documents without a window map
        to an empty list."""
        d, s, e = self.windows(widths=widths)
        out: dict[str, list[tuple[int, int]]] = {n: [] for n in self.names}
        for i, a, b in zip(d.tolist(), s.tolist(), e.tolist()):
            out[self.names[i]].append((a, b))
        return out

    @property
    def frames(self) -> int:
        """Frames covered by the hits."""
        return int((self.end - self.start + 1).sum())

    def as_hits(self, *, windows: bool = False):
        """The hits as :class:`mtanno.index.query.Hits` (document order, no score), so
        they are written, cut and ranked like the index's other query modes: the
        boundaries of a hit are the frames of its earliest chain (group ``keyframes``).
        ``windows``: the candidate windows instead (no boundaries)."""
        from mtanno.index.query import Hits

        if windows:
            d, s, e = self.windows()
            return Hits(d, s, e, np.full(len(d), np.nan))
        bounds = np.concatenate([self.chains, (self.end + 1)[:, None]], axis=1)
        return Hits(self.doc, self.start, self.end, np.full(len(self.doc), np.nan),
                    {"keyframes": bounds})


def widen(doc: np.ndarray, start: np.ndarray, end: np.ndarray, left: int, right: int,
          lengths: np.ndarray) -> Intervals:
    """Intervals widened by ``left``/``right`` frames, clipped to [0, length − 1] of their
    document and merged where they overlap or touch."""
    if left < 0 or right < 0:
        raise MtannoError("window widths must be ≥ 0")
    doc, start, end = _intervals((doc, start, end), "intervals")
    lengths = np.asarray(lengths, np.int64)
    if len(doc) and (doc.min() < 0 or doc.max() >= len(lengths)):
        raise MtannoError(f"interval document numbers must lie in 0..{len(lengths) - 1}")
    return _widen(doc, start, end, left, right, lengths)


def _widen(doc, start, end, left: int, right: int, lengths) -> Intervals:
    """:func:`widen` of intervals made by this package (not checked again)."""
    s = np.maximum(start - left, 0)
    e = np.minimum(end + right, lengths[doc] - 1)
    out = tuple(np.empty(len(doc), np.int64) for _ in range(3))
    k = _kernels.merge_sorted(doc, s, e, *out)
    return out[0][:k], out[1][:k], out[2][:k]


def _gaps(query: KeyframeQuery) -> list[tuple[int, int]]:
    return [(g.dmin, g.upper) for g in query.gaps]


def _run(query: KeyframeQuery, levels: list[Intervals], names, lengths) -> KeyframeHits:
    gaps = _gaps(query)  # checked by Gap
    B = _chain_levels(levels, gaps)  # int64 interval lists of one document set
    if len(B) == 1:
        hits = B[0]
    else:
        hits = _union([_pair_spans(B[j], B[j + 1], lo, hi) for j, (lo, hi) in enumerate(gaps)])
    return KeyframeHits(tuple(names), np.asarray(lengths, np.int64), hits[0], hits[1], hits[2],
                        query, B)


# --------------------------------------------------------------------------- with an index

def _index_pattern(index, query: KeyframeQuery, j: int) -> tuple[str, int, int]:
    """(index group, mask, value) of keyframe j: its fixed features located in the one
    index group that holds them all (mismatches not applied)."""
    kf = query.keyframes[j]
    feats = query.groups[kf.group]
    fixed = [(feats[k], c) for k, c in enumerate(kf.vector) if c != "*"]
    if not fixed:
        g = next(iter(index.groups))
        return g, 0, 0
    for g, gi in index.groups.items():
        pos = {f: b for b, f in enumerate(gi.features)}
        if all(f in pos for f, _ in fixed):
            mask = value = 0
            for f, c in fixed:
                mask |= 1 << pos[f]
                value |= (c == "1") << pos[f]
            return g, mask, value
    raise MtannoError(f"keyframe {j + 1} of class '{query.class_name}' uses features that no "
                      f"single index group holds (index groups: {', '.join(index.groups)})")


def search_index(index, query: KeyframeQuery) -> KeyframeHits:
    """All keyframe hits of ``query`` in an index (:class:`mtanno.index.Index`), through
    its inverted lists ([MBS09] §5, docs/method.md §5). Each keyframe's features must lie in
    one of the index's groups (a keyframe over fewer features than the group, e.g. the
    reference's 13-feature AK-mix against the 14-feature mix group, leaves the others
    free)."""
    check_features_known(query, index.features, feature_set=index.feature_set, what="index")
    if float(query.fps) != float(index.fps):
        raise MtannoError(f"keyframes of class '{query.class_name}' are at {query.fps:g} Hz "
                          f"but the index at {index.fps:g} Hz")
    levels = []
    for j in range(query.n):
        g, mask, value = _index_pattern(index, query, j)
        pats = tolerant_patterns(mask, value, query.keyframes[j].mismatches)
        d, s, e = index.groups[g].intervals(pats)
        levels.append((d.astype(np.int64), s.astype(np.int64), e.astype(np.int64)))
    return _run(query, levels, [d.name for d in index.documents],
                [d.frames for d in index.documents])


# --------------------------------------------------------------------------- direct scan

#: Up to this many keyframes, one pass over the frames each is faster than one pass
#: over the frames for all of them (which tests each distinct frame vector once).
_ONE_BY_ONE = 6


class _Scanner:
    """Matches keyframes against bit-packed feature frames (a direct scan): each keyframe
    is a (mask, value) pair over the packed words of the feature rows; the keyframes of
    one query, or of several queries joined with :meth:`joined`, are matched by
    :meth:`levels`."""

    def __init__(self, query: KeyframeQuery, names: Sequence[str]):
        check_features_known(query, names, feature_set=None, what="feature file")
        pos = {n: i for i, n in enumerate(names)}
        W = (len(names) + 63) // 64
        n = len(query.keyframes)
        self.masks = np.zeros((n, W), np.uint64)
        self.values = np.zeros((n, W), np.uint64)
        self.tol = np.array([int(kf.mismatches) for kf in query.keyframes], np.int64)
        for i, kf in enumerate(query.keyframes):
            feats = query.groups[kf.group]
            for k, c in enumerate(kf.vector):
                if c != "*":
                    r = pos[feats[k]]
                    bit = np.uint64(1) << np.uint64(r % 64)
                    self.masks[i, r // 64] |= bit
                    if c == "1":
                        self.values[i, r // 64] |= bit

    @staticmethod
    def joined(scanners: Sequence[_Scanner]) -> _Scanner:
        """One scanner of all the keyframes of ``scanners``, in order."""
        out = object.__new__(_Scanner)
        out.masks = np.concatenate([s.masks for s in scanners])
        out.values = np.concatenate([s.values for s in scanners])
        out.tol = np.concatenate([s.tol for s in scanners])
        return out

    def runs(self, packed: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The runs of frames that match each keyframe in one packed document, flattened:
        (starts, ends, offsets), keyframe k's runs at [offsets[k], offsets[k + 1]), frames
        0-based inclusive. A pass over the frames per keyframe, or, for more than a few
        keyframes, one pass per 64 of them
        (:func:`mtanno.keyframes._kernels.keyframe_set_changes`, then the runs of each
        keyframe from the changes)."""
        n = self.masks.shape[0]
        L = packed.shape[0]
        offsets = np.zeros(n + 1, np.int64)
        none = np.zeros(0, np.int64)
        if n <= _ONE_BY_ONE:
            s, e = np.empty(L + 1, np.int64), np.empty(L + 1, np.int64)
            starts, ends = [none], [none]
            for k in range(n):
                c = _kernels.keyframe_runs(packed, self.masks[k], self.values[k],
                                           int(self.tol[k]), s, e)
                starts.append(s[:c].copy())
                ends.append(e[:c].copy())
                offsets[k + 1] = offsets[k] + c
            return np.concatenate(starts), np.concatenate(ends), offsets
        pos = np.empty(L + 1, np.int64)
        sets = np.empty(L + 1, np.uint64)
        parts = []
        for a in range(0, n, 64):
            m, v, t = self.masks[a:a + 64], self.values[a:a + 64], self.tol[a:a + 64]
            c = _kernels.keyframe_set_changes(packed, m, v, t, pos, sets)
            counts = _kernels.set_runs(pos, sets, c, len(m), none, none, none)
            off = np.zeros(counts.shape[0] + 1, np.int64)
            np.cumsum(counts, out=off[1:])
            s, e = np.empty(off[-1], np.int64), np.empty(off[-1], np.int64)
            _kernels.set_runs(pos, sets, c, len(m), off[:-1], s, e)
            offsets[a + 1:a + 1 + len(m)] = offsets[a] + off[1:]
            parts.append((s, e))
        if len(parts) == 1:
            return parts[0][0], parts[0][1], offsets
        return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
                offsets)

    def levels(self, packed: np.ndarray, d: int) -> list[Intervals]:
        """Interval lists of every keyframe in one packed document (number ``d``), from
        :meth:`runs`."""
        s, e, off = self.runs(packed)
        lo, hi = off[:-1].tolist(), off[1:].tolist()
        return [(np.full(b - a, d, np.int64), s[a:b], e[a:b]) for a, b in zip(lo, hi)]


def search_documents(documents: Iterable[tuple[str, np.ndarray]], names: Sequence[str],
                     query: KeyframeQuery, *, feature_set: str | None = None) -> KeyframeHits:
    """All keyframe hits of ``query`` in documents given as (name, X) pairs, X a
    (features × frames) 0/1 matrix with rows ``names`` — a direct scan, for documents
    that have no index (same result as :func:`search_index` on an index of them)."""
    if feature_set is not None:
        check_features_known(query, names, feature_set=feature_set, what="feature file")
    scan = _Scanner(query, names)
    doc_names, lengths = [], []
    per_level: list[list[Intervals]] = [[] for _ in range(query.n)]
    from mtanno.templates.match import pack_document

    for d, (name, X) in enumerate(documents):
        X = np.asarray(X)
        if X.ndim != 2 or X.shape[0] != len(names):
            raise MtannoError(f"document '{name}': matrix must be ({len(names)} × frames)")
        doc_names.append(name)
        lengths.append(X.shape[1])
        for j, lv in enumerate(scan.levels(pack_document(X, len(names)), d)):
            per_level[j].append(lv)
    levels = [tuple(np.concatenate([p[k] for p in parts]) if parts else np.zeros(0, np.int64)
                    for k in range(3)) for parts in per_level]
    return _run(query, levels, doc_names, lengths)


def document_windows(X: np.ndarray, names: Sequence[str], query: KeyframeQuery,
                     ) -> list[tuple[int, int]]:
    """Candidate windows [(first, last)] (0-based inclusive) of one class in one document:
    its keyframe hits widened by the query's extension, clipped and merged ([MBS09] §5, the
    input of :func:`mtanno.annotate.class_deltas`)."""
    hits = search_documents([("doc", X)], names, query)
    d, s, e = hits.windows()
    return list(zip(s.tolist(), e.tolist()))


class KeyframeSet:
    """The keyframe queries of several classes prepared once for documents whose feature
    rows are ``names`` (a batch of one layout): their features checked, their keyframes
    joined for one pass over each document's frames. :meth:`windows` gives a document's
    candidate windows per class, as :func:`class_windows` does."""

    def __init__(self, queries: dict[str, KeyframeQuery], names: Sequence[str], *,
                 feature_set: str | None = None):
        for q in queries.values():
            check_features_known(q, names, feature_set=feature_set, what="feature file")
        self.queries = dict(queries)
        self.names = tuple(names)
        self._scanner = _Scanner.joined([_Scanner(q, names) for q in queries.values()]) \
            if queries else None
        self._chains = {cls: (np.array([g[0] for g in _gaps(q)], np.int64),
                              np.array([g[1] for g in _gaps(q)], np.int64), *q.widths())
                        for cls, q in queries.items()}

    def windows(self, packed: np.ndarray) -> dict[str, list[tuple[int, int]]]:
        """Candidate windows [(first, last)] (0-based inclusive) of every class in one
        bit-packed document (:func:`mtanno.templates.match.pack_document`, frames × words):
        its keyframe hits widened by the query's extension, clipped and merged ([MBS09] §5)."""
        return {cls: list(zip(s.tolist(), e.tolist()))
                for cls, (s, e) in self.spans(packed).items()}

    def spans(self, packed: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """:meth:`windows` as arrays: class → (firsts, lasts), int64, sorted, disjoint and
        not touching — the form :func:`mtanno.annotate.annotate_document` takes without
        converting."""
        words = (len(self.names) + 63) // 64
        if not (isinstance(packed, np.ndarray) and packed.dtype == np.uint64
                and packed.ndim == 2 and packed.shape[1] == words):
            raise MtannoError(f"packed document must be uint64 (frames × {words} words) for "
                              f"{len(self.names)} features, got {np.shape(packed)}")
        if self._scanner is None:
            return {}
        starts, ends, offsets = self._scanner.runs(packed)  # all keyframes in one pass
        out = {}
        k = 0
        for cls, q in self.queries.items():  # chains, hits and windows: one kernel call
            lo, hi, left, right = self._chains[cls]
            out[cls] = _kernels.chain_windows(starts, ends, offsets[k:k + q.n + 1], lo, hi,
                                              left, right, packed.shape[0])
            k += q.n
        return out


def class_windows(X: np.ndarray, names: Sequence[str],
                  queries: dict[str, KeyframeQuery] | KeyframeSet, *,
                  feature_set: str | None = None, packed: np.ndarray | None = None,
                  ) -> dict[str, list[tuple[int, int]]]:
    """Candidate windows of every class that has a query, in one document (the
    ``windows`` argument of :func:`mtanno.annotate.annotate_document`); classes without
    a query are absent, i.e. matched everywhere. ``queries``: class → query, or a
    :class:`KeyframeSet` prepared once for a batch of documents. ``packed``: the document
    already bit-packed (:func:`mtanno.templates.match.pack_document`), to reuse it."""
    return {cls: list(zip(s.tolist(), e.tolist())) for cls, (s, e) in
            class_spans(X, names, queries, feature_set=feature_set, packed=packed).items()}


def class_spans(X: np.ndarray, names: Sequence[str],
                queries: dict[str, KeyframeQuery] | KeyframeSet, *,
                feature_set: str | None = None, packed: np.ndarray | None = None,
                ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """:func:`class_windows` as arrays (:meth:`KeyframeSet.spans`): class → (firsts,
    lasts), what ``mtanno annotate`` passes on without converting."""
    from mtanno.templates.match import pack_document

    X = np.asarray(X)
    if X.ndim != 2 or X.shape[0] != len(names):
        raise MtannoError(f"matrix must be ({len(names)} × frames), got shape {X.shape}")
    if packed is None:
        packed = pack_document(X, len(names))
    elif np.shape(packed) != (X.shape[1], (len(names) + 63) // 64) \
            or packed.dtype != np.uint64:
        raise MtannoError(f"packed document must be uint64 ({X.shape[1]} frames × "
                          f"{(len(names) + 63) // 64} words) for {len(names)} features, got "
                          f"{np.shape(packed)}")
    if isinstance(queries, KeyframeSet):
        if queries.names != tuple(names):
            raise MtannoError("keyframe set prepared for other feature rows than the "
                              "document's")
        return queries.spans(packed)
    return KeyframeSet(queries, names, feature_set=feature_set).spans(packed)


def warm_up() -> None:
    """Load the compiled interval kernels (numba's on-disk cache) once, so that timings
    taken afterwards measure searches alone."""
    from mtanno.keyframes.model import Gap, Keyframe

    q = KeyframeQuery("w", "custom", {"g": ("a",)}, [Keyframe("g", "1", 1), Keyframe("g", "0", 2)],
                      [Gap(0, 2)], 2)
    search_documents([("w", np.array([[1, 1, 0, 0]], np.uint8))], ["a"], q)
