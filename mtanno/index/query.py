"""Queries on the relational index: exact, fuzzy, adaptive fuzzy and m-mismatch hits.

[MRC05] §5.1–5.2 and §6.2 (docs/method.md §4). A query over one feature group is a sequence
of *fuzzy sets* V_1 … V_L of that group's feature vectors. A fuzzy set is written as patterns
``(mask, value)`` over the group's bits: vector v is in the set iff ``v & mask == value`` for
some pattern (features outside ``mask`` are free, "*"); an exact query has one full-mask
pattern per position. Adjacent sets that intersect are merged (their union) until neighbours
are disjoint, as [MRC05] §5.2 prescribes; this coarsens the query.

Hits on a document with F-feature sequence w_1 … w_M (its F-segments, [MRC05] §4):

* ``exact`` / ``fuzzy``: segment k with w_{k+i−1} ∈ V_i for i = 1 … L (eq. 4 and 9); computed
  as the intersection of the inverted lists L(V_i) shifted by i − 1 (eq. 7 and 11): the
  candidates are the rows of the smallest L(V_j), and a candidate survives the intersection
  with L(V_i) iff its segment i − j further on lies in one of V_i's lists (each segment is
  in exactly one list, so this membership test *is* the intersection).
* ``mismatches = m``: up to m positions may disagree (optionally only positions marked
  allowed); candidates are the union of the m + 1 smallest shifted lists (one of them must
  match), or the smallest list of a position that may not mismatch.
* ``adaptive``: the document's segmentation is coarsened into maximal runs of V_1-segments,
  V_2-segments, …; a hit is the first segment of a maximal V_1 run followed directly by
  runs of V_2 … V_L; the hit reports the coarsened boundaries ([MRC05] §5.2, the example
  after eq. 11). With ``min_segment = N > 1`` the runs need not be adjacent: between two
  consecutive runs the document may pass through other vectors for at most N − 1 frames
  (a *transition*: one knee bending a frame before the other).
* query by example (``Query.smooth``, adaptive mode): the example's runs over the chosen
  features shorter than N frames were given to their neighbours
  (:func:`mtanno.index.example.drop_short_segments`), and each candidate document's runs
  over the same features go through the same rule; a hit is L consecutive smoothed runs
  with the example's values. The example is smoothed whole before ``--frames`` cuts it,
  so its source document has exactly the cut's runs there.

Hits of queries with segment lengths (query by example) are *trimmed*: the first and last
query segments are the poses before and after the motion, and a hit keeps at most as many
frames of them as the example has, so idle time around a motion does not inflate the hit;
the untrimmed span stays in :attr:`Hits.span_start` / :attr:`Hits.span_end`, and the
ranking score is computed on the untrimmed runs.

Queries over several groups are answered per group and intersected on frames: a hit is a
combination of one hit per group in the same document whose frame ranges overlap, reported
as the common frames. Hits are ranked by the segment-length heuristic of [MRC05] §6.2 (sum over
positions of |query segment length − hit segment length| in frames) when the query has
segment lengths (query by example), else listed in document order. An example cut by
``--frames`` usually starts and ends inside runs; its first and last positions are scored
against the whole runs the cut fell in (``GroupQuery.context``), so the example's own
source scores 0 and ranks first whatever the cut.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from mtanno.errors import MtannoError
from mtanno.index import _kernels
from mtanno.index.core import GroupIndex, Index

QUERY_MODES = ("exact", "fuzzy", "adaptive")


@dataclass(frozen=True)
class FuzzySet:
    """A set of feature vectors of one group, as patterns ``(mask, value)`` (value ⊆ mask):
    v is in the set iff ``v & mask == value`` for some pattern. ``mask == 0`` is every
    vector."""

    patterns: tuple[tuple[int, int], ...]

    def __post_init__(self):
        if not self.patterns:
            raise MtannoError("empty fuzzy set (no allowed feature vector)")
        for m, v in self.patterns:
            if m < 0 or v & ~m:
                raise ValueError(f"pattern value {v:b} has bits outside its mask {m:b}")

    @classmethod
    def exact(cls, code: int, n_bits: int) -> FuzzySet:
        """The set holding one vector (all ``n_bits`` features fixed)."""
        return cls((((1 << n_bits) - 1, int(code)),))

    @property
    def universal(self) -> bool:
        """True if the set allows every vector."""
        return any(m == 0 for m, _ in self.patterns)

    def contains(self, code: int) -> bool:
        return any(code & m == v for m, v in self.patterns)

    def intersects(self, other: FuzzySet) -> bool:
        return any((v1 ^ v2) & m1 & m2 == 0
                   for m1, v1 in self.patterns for m2, v2 in other.patterns)

    def union(self, other: FuzzySet) -> FuzzySet:
        pats = list(self.patterns)
        pats += [p for p in other.patterns if p not in pats]
        return FuzzySet(tuple(pats))

    def size(self, n_bits: int) -> int:
        """Number of vectors in the set (exact count, by enumeration for small groups)."""
        if len(self.patterns) == 1:
            return 1 << (n_bits - bin(self.patterns[0][0]).count("1"))
        return sum(self.contains(v) for v in range(1 << n_bits))


@dataclass(frozen=True)
class GroupQuery:
    """A query over one group: fuzzy sets, optional segment lengths in frames (for ranking)
    and optional per-position flags saying where a mismatch is allowed. ``context`` (query
    by example): the whole lengths in the example, frames, of the runs its first and last
    segment were cut from by ``--frames``, which the ranking compares hits with."""

    group: str
    sets: tuple[FuzzySet, ...]
    lengths: tuple[int, ...] | None = None
    allowed: tuple[bool, ...] | None = None
    context: tuple[int, int] | None = None

    def __post_init__(self):
        if not self.sets:
            raise MtannoError(f"query for group '{self.group}' has no fuzzy sets")
        for name in ("lengths", "allowed"):
            v = getattr(self, name)
            if v is not None and len(v) != len(self.sets):
                raise MtannoError(f"query for group '{self.group}': {len(v)} {name} for "
                                  f"{len(self.sets)} fuzzy sets")

    def normalized(self) -> GroupQuery:
        """Adjacent intersecting sets merged into their union, repeatedly, until neighbours
        are disjoint ([MRC05] §5.2); lengths add up, a merged position may mismatch if any of
        its parts may."""
        sets = list(self.sets)
        lengths = list(self.lengths) if self.lengths is not None else None
        allowed = list(self.allowed) if self.allowed is not None else None
        i = 0
        while i + 1 < len(sets):
            if sets[i].intersects(sets[i + 1]):
                sets[i] = sets[i].union(sets.pop(i + 1))
                if lengths is not None:
                    lengths[i] += lengths.pop(i + 1)
                if allowed is not None:
                    other = allowed.pop(i + 1)
                    allowed[i] = allowed[i] or other
                i = max(i - 1, 0)
            else:
                i += 1
        context = self.context if len(sets) == len(self.sets) else None
        return GroupQuery(self.group, tuple(sets), None if lengths is None else tuple(lengths),
                          None if allowed is None else tuple(allowed), context)

    @property
    def projection(self) -> tuple[int, tuple[int, ...]] | None:
        """(mask, values) when every set is one pattern over the same mask (a query by
        example: the chosen features fixed, the group's others free), else None."""
        masks = {s.patterns[0][0] for s in self.sets if len(s.patterns) == 1}
        if len(masks) != 1 or any(len(s.patterns) != 1 for s in self.sets):
            return None
        return masks.pop(), tuple(s.patterns[0][1] for s in self.sets)

    @property
    def trivial(self) -> bool:
        """A single set allowing every vector: constrains nothing."""
        return len(self.sets) == 1 and self.sets[0].universal


@dataclass(frozen=True)
class Query:
    """A query: one :class:`GroupQuery` per group, the mode, the number of mismatches and,
    for the adaptive mode, the shortest run in frames that counts as a phase of the motion
    (``min_segment``; shorter runs between two phases are transitions, module docstring;
    1 is [MRC05]'s rule). ``smooth`` (query by example, adaptive mode): the documents'
    runs over the chosen features are smoothed as the example's were (runs shorter than
    ``min_segment`` given to their neighbour) and matched run for run, instead of passing
    through transitions (module docstring)."""

    parts: tuple[GroupQuery, ...]
    mode: str = "adaptive"
    mismatches: int = 0
    min_segment: int = 1
    smooth: bool = False

    def __post_init__(self):
        if self.mode not in QUERY_MODES:
            raise MtannoError(f"unknown query mode '{self.mode}' (one of "
                              f"{', '.join(QUERY_MODES)})")
        if self.mismatches < 0:
            raise MtannoError("mismatches must be ≥ 0")
        if not isinstance(self.min_segment, int) or self.min_segment < 1:
            raise MtannoError(f"min_segment must be a whole number of frames ≥ 1, got "
                              f"{self.min_segment!r}")
        if self.mismatches and self.mode == "adaptive":
            raise MtannoError("mismatches work with the exact and fuzzy modes, not adaptive")
        if self.smooth and self.mode != "adaptive":
            raise MtannoError("smoothed documents (query by example) need the adaptive mode")
        if self.smooth and any(p.projection is None for p in self.parts):
            raise MtannoError("a smoothed query needs one pattern over the same features at "
                              "every position of a group (a query by example)")
        if not self.parts:
            raise MtannoError("query has no groups")
        if len({p.group for p in self.parts}) != len(self.parts):
            raise MtannoError("query names a group twice")


@dataclass
class GroupHits:
    """Hits of one group query, sorted by (document, start).

    ``rows`` is (hits × (L+1)): the first segment row matched to each query position, then
    one past the last row; ``doc``, ``start``, ``end`` are the document number and the
    frame range (0-based, end inclusive); ``bounds`` (hits × (L+1)) are the start frame of
    each matched (coarsened) segment and, last, end + 1."""

    group: str
    rows: np.ndarray
    doc: np.ndarray
    start: np.ndarray
    end: np.ndarray
    bounds: np.ndarray

    def __len__(self) -> int:
        return len(self.doc)


@dataclass
class Hits:
    """Ranked hits of a query (arrays in rank order).

    ``doc`` document numbers, ``start``/``end`` frames (0-based, end inclusive), ``score``
    the segment-length score (NaN without query lengths; lower is better), ``bounds``
    group → (hits × (L_g+1)) frame boundaries of the matched segments of that group (start
    frame of each, then end + 1), ``cost`` template costs when ranked by an MT (∞ where the
    template cannot fit the hit), ``span_start``/``span_end`` the untrimmed frames of hits
    that were trimmed (module docstring; None when the query has no segment lengths)."""

    doc: np.ndarray
    start: np.ndarray
    end: np.ndarray
    score: np.ndarray
    bounds: dict[str, np.ndarray] = field(default_factory=dict)
    cost: np.ndarray | None = None
    span_start: np.ndarray | None = None
    span_end: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.doc)

    def take(self, order: np.ndarray) -> Hits:
        def pick(a):
            return None if a is None else a[order]

        return Hits(self.doc[order], self.start[order], self.end[order], self.score[order],
                    {g: b[order] for g, b in self.bounds.items()}, pick(self.cost),
                    pick(self.span_start), pick(self.span_end))

    @property
    def unfit(self) -> int:
        """Number of hits a ranking template could not fit (cost ∞); 0 when not ranked."""
        return 0 if self.cost is None else int(np.isinf(self.cost).sum())

    def rows(self, index: Index) -> list[dict]:
        """One dict per hit for output files: doc name, 1-based inclusive frames, rank,
        score, mt_cost (when ranked; None where the template cannot fit), span_start and
        span_end (untrimmed frames, when hits are trimmed), boundaries (``group=b1 b2 … end``
        with 1-based frames; the last number is the group's last matched frame)."""
        out = []
        for i in range(len(self)):
            parts = []
            for g, b in self.bounds.items():
                nums = [int(x) + 1 for x in b[i, :-1]] + [int(b[i, -1])]
                parts.append(f"{g}=" + " ".join(map(str, nums)))
            row = {"doc": index.documents[int(self.doc[i])].name, "start": int(self.start[i]) + 1,
                   "end": int(self.end[i]) + 1, "rank": i + 1,
                   "score": None if np.isnan(self.score[i]) else float(self.score[i])}
            if self.cost is not None:
                row["mt_cost"] = float(self.cost[i]) if np.isfinite(self.cost[i]) else None
            if self.span_start is not None:
                row["span_start"] = int(self.span_start[i]) + 1
                row["span_end"] = int(self.span_end[i]) + 1
            row["boundaries"] = "; ".join(parts)
            out.append(row)
        return out


def _membership(g: GroupIndex, sets: Sequence[FuzzySet]) -> np.ndarray:
    """(positions × lists) uint8: list v belongs to V_i."""
    member = np.zeros((len(sets), g.n_lists), dtype=np.uint8)
    for i, s in enumerate(sets):
        member[i] = g.lists_matching(s.patterns)
    return member


def _csr(member: np.ndarray, positions: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    ids = [np.flatnonzero(member[p]) for p in positions]
    off = np.zeros(len(ids) + 1, dtype=np.int64)
    off[1:] = np.cumsum([len(x) for x in ids])
    return (np.concatenate(ids).astype(np.int64) if ids else np.zeros(0, np.int64)), off


def run_group(index: Index, gq: GroupQuery, *, mode: str = "adaptive", mismatches: int = 0,
              min_segment: int = 1, smooth: bool = False) -> GroupHits:
    """All hits of one (normalized) group query; see the module docstring (``min_segment``
    in frames at the index's rate: transitions of up to ``min_segment − 1`` frames between
    the runs of an adaptive hit; with ``smooth``, the documents' runs shorter than that are
    given to their neighbours instead, as in the example, :attr:`Query.smooth`)."""
    if gq.group not in index.groups:
        raise MtannoError(f"unknown group '{gq.group}' (index groups: {', '.join(index.groups)})")
    if mode not in QUERY_MODES:
        raise MtannoError(f"unknown query mode '{mode}' (one of {', '.join(QUERY_MODES)})")
    g = index.groups[gq.group]
    n_bits = len(g.features)
    for s in gq.sets:
        for m, _ in s.patterns:
            if m >> n_bits:
                raise MtannoError(f"pattern uses bits beyond the {n_bits} features of group "
                                  f"'{g.name}'")
    if mode == "exact":
        full = (1 << n_bits) - 1
        if any(len(s.patterns) != 1 or s.patterns[0][0] != full for s in gq.sets):
            raise MtannoError(f"exact mode needs every feature of group '{g.name}' fixed at "
                              "every position (use {mode} fuzzy or adaptive)", options=("mode",))
    L = len(gq.sets)
    if mode == "adaptive" and any(a.intersects(b) for a, b in zip(gq.sets, gq.sets[1:])):
        # the runs of intersecting neighbours overlap: a run may end past its document
        raise MtannoError(f"adaptive query of group '{g.name}': neighbouring fuzzy sets must "
                          "be disjoint (GroupQuery.normalized merges them)")
    if mismatches and mismatches >= L:
        raise MtannoError(f"{mismatches} mismatches allowed in a query of {L} segments "
                          f"(group '{g.name}'); must be fewer")
    member = _membership(g, gq.sets)
    sizes = member.astype(np.int64) @ g.list_sizes
    if smooth:
        return _smoothed_group(g, gq, member, sizes, min_segment)
    if mode == "adaptive":
        j = int(np.argmin(sizes))
        lists = np.flatnonzero(member[j]).astype(np.int64)
        out = np.empty(int(sizes[j]), dtype=np.int64)
        n = _kernels.adaptive_hits(j, lists, g.list_offsets, g.postings, member, g.seg_list,
                                   g.doc, g.length, g.doc_offsets, int(min_segment) - 1, out)
        firsts = np.sort(out[:n])
        rows = np.empty((n, L + 1), dtype=np.int64)
        _kernels.adaptive_bounds(firsts, member, g.seg_list, g.doc, g.doc_offsets, rows)
    else:
        allowed = np.ones(L, np.uint8) if gq.allowed is None else np.array(gq.allowed, np.uint8)
        if allowed.shape != (L,):  # the kernel reads one flag per position
            raise MtannoError(f"query for group '{g.name}': {allowed.size} allowed flags for "
                              f"{L} fuzzy sets")
        if mismatches == 0:
            src = [int(np.argmin(sizes))]
        else:
            forced = np.flatnonzero(allowed == 0)
            if len(forced):
                src = [int(forced[np.argmin(sizes[forced])])]
            else:
                src = sorted(np.argsort(sizes, kind="stable")[:mismatches + 1].tolist())
        src_lists, src_off = _csr(member, src)
        out = np.empty(int(sizes[src].sum()), dtype=np.int64)
        n = _kernels.fixed_hits(np.array(src, np.int64), src_lists, src_off, g.list_offsets,
                                g.postings, member, g.seg_list, g.doc, int(mismatches),
                                allowed, out)
        firsts = np.sort(out[:n])
        rows = firsts[:, None] + np.arange(L + 1, dtype=np.int64)[None, :]
    last = rows[:, -1] - 1
    start = g.start[rows[:, 0]].astype(np.int64)
    end = (g.start[last] + g.length[last] - 1).astype(np.int64)
    bounds = np.empty_like(rows)
    bounds[:, :-1] = g.start[rows[:, :-1]]
    bounds[:, -1] = end + 1
    return GroupHits(g.name, rows, g.doc[rows[:, 0]].astype(np.int64), start, end, bounds)


def _smoothed_group(g: GroupIndex, gq: GroupQuery, member: np.ndarray, sizes: np.ndarray,
                    min_segment: int) -> GroupHits:
    """Hits of a query by example on the smoothed documents (:attr:`Query.smooth`): the
    candidates are the documents holding a segment of every query value (a smoothed run
    keeps the value of one of its segments), then ``_kernels.smoothed_hits`` walks them."""
    mask, values = gq.projection
    L = len(values)
    docs = None
    for j in np.argsort(sizes, kind="stable"):  # rarest value first: fewest documents
        lists = np.flatnonzero(member[j])
        rows = np.concatenate([g.postings[g.list_offsets[v]:g.list_offsets[v + 1]]
                               for v in lists]) if len(lists) else np.zeros(0, np.int32)
        have = np.unique(g.doc[rows])
        docs = have if docs is None else np.intersect1d(docs, have, assume_unique=True)
        if not len(docs):
            break
    docs = docs.astype(np.int64)
    cap = int((g.doc_offsets[docs + 1] - g.doc_offsets[docs]).sum()) if len(docs) else 0
    doc = np.empty(cap, np.int64)
    rows = np.empty((cap, L + 1), np.int64)
    bounds = np.empty((cap, L + 1), np.int64)
    n = _kernels.smoothed_hits(docs, g.doc_offsets, g.code, g.start, g.length, np.int64(mask),
                               np.array(values, np.int64), int(min_segment), doc, rows, bounds)
    doc, rows, bounds = doc[:n], rows[:n], bounds[:n]
    return GroupHits(g.name, rows, doc, bounds[:, 0].copy(), bounds[:, -1] - 1, bounds)


def _length_score(bounds: np.ndarray, lengths: Sequence[int] | None,
                  context: tuple[int, int] | None = None) -> np.ndarray:
    """[MRC05] §6.2's segment-length score of hits (lower is better): Σ over positions of
    |query length − hit run length|, frames. With ``context`` (an example cut by
    ``--frames``, :attr:`GroupQuery.context`) the first and last positions are compared
    with the whole runs of the example the cut fell in, not with the cut's partial ones,
    which the document's runs never share (so the example's source scores 0)."""
    if lengths is None:
        return np.full(len(bounds), np.nan)
    hit_len = np.diff(bounds, axis=1)
    q = np.array(lengths, dtype=np.int64)
    if context is not None:
        q[0], q[-1] = context
    return np.abs(hit_len - q[None, :]).sum(axis=1).astype(float)


def _trim(gh: GroupHits, lengths: Sequence[int] | None):
    """(start, end, bounds) of a group's hits with the first and last matched run cut to at
    most the query's first and last segment length (module docstring); unchanged without
    lengths or with one segment."""
    if lengths is None or len(lengths) < 2:
        return gh.start, gh.end, gh.bounds
    start = np.maximum(gh.start, gh.bounds[:, 1] - int(lengths[0]))
    end = np.minimum(gh.end, gh.bounds[:, -2] + int(lengths[-1]) - 1)
    bounds = gh.bounds.copy()
    bounds[:, 0] = start
    bounds[:, -1] = end + 1
    return start, end, bounds


def _intersect(a_doc, a_start, a_end, gh: GroupHits):
    """Pairs of overlapping hits (combined so far × next group), with the common frames."""
    cap = max(16, 2 * (len(a_doc) + len(gh)))
    while True:
        ia = np.empty(cap, np.int64)
        ib = np.empty(cap, np.int64)
        n = _kernels.overlap_pairs(a_doc, a_start, a_end, gh.doc, gh.start, gh.end, ia, ib)
        if n <= cap:
            return ia[:n], ib[:n]
        cap = n


def search(index: Index, query: Query) -> Hits:
    """Answer ``query`` on ``index``: per group, then intersected on frames, then ranked by
    the segment-length heuristic ([MRC05] §6.2) or, without query lengths, in document order.
    Hits of queries with segment lengths are trimmed (module docstring); their untrimmed
    frames are the hits' ``span_start``/``span_end``."""
    parts = [p.normalized() for p in query.parts]
    parts = [p for p in parts if not p.trivial] or parts[:1]
    if len(parts) == 1 and parts[0].trivial:
        raise MtannoError("query constrains no feature (every set allows every vector)")
    ghits = [run_group(index, p, mode=query.mode, mismatches=query.mismatches,
                       min_segment=query.min_segment, smooth=query.smooth) for p in parts]
    trimmed = [_trim(gh, p.lengths) for p, gh in zip(parts, ghits)]
    first = ghits[0]
    doc, (start, end, _) = first.doc, trimmed[0]
    span_s, span_e = first.start, first.end
    picks = [np.arange(len(first))]
    for gh, (g_start, g_end, _) in zip(ghits[1:], trimmed[1:]):
        ia, ib = _intersect(doc, start, end, replace(gh, start=g_start, end=g_end))
        doc = doc[ia]
        start = np.maximum(start[ia], g_start[ib])
        end = np.minimum(end[ia], g_end[ib])
        span_s = np.maximum(span_s[ia], gh.start[ib])
        span_e = np.minimum(span_e[ia], gh.end[ib])
        picks = [p[ia] for p in picks] + [ib]
        order = np.lexsort((end, start, doc))
        doc, start, end, span_s, span_e = (a[order] for a in (doc, start, end, span_s, span_e))
        picks = [p[order] for p in picks]
    score = np.zeros(len(doc))
    for p, gh, pick in zip(parts, ghits, picks):  # [MRC05]'s score: the runs as matched
        score += _length_score(gh.bounds[pick], p.lengths, p.context)
    with_span = any(p.lengths is not None and len(p.sets) > 1 for p in parts)
    hits = Hits(doc, start, end, score,
                {gh.group: b[pick] for gh, (_, _, b), pick in zip(ghits, trimmed, picks)},
                span_start=span_s if with_span else None, span_end=span_e if with_span else None)
    if len(ghits) > 1:  # identical frame ranges from different combinations: keep the best
        order = np.lexsort((np.nan_to_num(score, nan=np.inf), end, start, doc))
        hits = hits.take(order)
        keep = np.r_[True, (np.diff(hits.doc) != 0) | (np.diff(hits.start) != 0)
                     | (np.diff(hits.end) != 0)]
        hits = hits.take(np.flatnonzero(keep))
    order = np.lexsort((hits.start, hits.doc, np.nan_to_num(hits.score, nan=np.inf)))
    return hits.take(order)


def warm_up() -> None:
    """Load the compiled query kernels (numba's on-disk cache, a few hundred ms once per
    process), so that timings taken afterwards measure the queries alone."""
    from mtanno.index.core import index_from_matrices

    idx = index_from_matrices({"w": np.array([[0, 1, 0], [1, 1, 0]], np.uint8)}, ["a", "b"],
                              {"g": ["a"], "h": ["b"]})
    parts = (GroupQuery("g", (FuzzySet.exact(0, 1), FuzzySet.exact(1, 1))),
             GroupQuery("h", (FuzzySet.exact(1, 1),)))
    search(idx, Query(parts, "adaptive"))
    search(idx, Query(parts[:1], "exact"))
    search(idx, Query(parts, "adaptive", smooth=True))  # a query by example's kernel
