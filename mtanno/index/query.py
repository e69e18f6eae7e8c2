"""Queries on the relational index: exact, fuzzy, adaptive fuzzy and m-mismatch hits.

MRC05 §5.1–5.2 and §6.2 (algorithms.md §4). A query over one feature group is a sequence of
*fuzzy sets* V_1 … V_L of that group's feature vectors. A fuzzy set is written as patterns
``(mask, value)`` over the group's bits: vector v is in the set iff ``v & mask == value`` for
some pattern (features outside ``mask`` are free, "*"); an exact query has one full-mask
pattern per position. Adjacent sets that intersect are merged (their union) until neighbours
are disjoint, as MRC05 §5.2 prescribes; this coarsens the query.

Hits on a document with F-feature sequence w_1 … w_M (its F-segments, MRC05 §4):

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
  runs of V_2 … V_L; the hit reports the coarsened boundaries (MRC05 §5.2, the example
  after eq. 11). With ``min_segment = N > 1`` the runs need not be adjacent: between two
  consecutive runs the document may pass through other vectors for at most N − 1 frames
  (a *transition*: one knee bending a frame before the other), and query by example turns
  example segments shorter than N frames into such transitions too (:func:`example_query`).

Hits of queries with segment lengths (query by example) are *trimmed*: the first and last
query segments are the poses before and after the motion, and a hit keeps at most as many
frames of them as the example has, so idle time around a motion does not inflate the hit;
the untrimmed span stays in :attr:`Hits.span_start` / :attr:`Hits.span_end`, and the
ranking score is computed on the untrimmed runs.

Queries over several groups are answered per group and intersected on frames: a hit is a
combination of one hit per group in the same document whose frame ranges overlap, reported
as the common frames. Hits are ranked by the segment-length heuristic of MRC05 §6.2 (sum over
positions of |query segment length − hit segment length| in frames) when the query has
segment lengths (query by example), else listed in document order.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.index import _kernels
from mtanno.index.core import GroupIndex, Index, segment

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
    and optional per-position flags saying where a mismatch is allowed."""

    group: str
    sets: tuple[FuzzySet, ...]
    lengths: tuple[int, ...] | None = None
    allowed: tuple[bool, ...] | None = None

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
        are disjoint (MRC05 §5.2); lengths add up, a merged position may mismatch if any of
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
        return GroupQuery(self.group, tuple(sets), None if lengths is None else tuple(lengths),
                          None if allowed is None else tuple(allowed))

    @property
    def trivial(self) -> bool:
        """A single set allowing every vector: constrains nothing."""
        return len(self.sets) == 1 and self.sets[0].universal


@dataclass(frozen=True)
class Query:
    """A query: one :class:`GroupQuery` per group, the mode, the number of mismatches and,
    for the adaptive mode, the shortest run in frames that counts as a phase of the motion
    (``min_segment``; shorter runs between two phases are transitions, module docstring;
    1 is MRC05's rule)."""

    parts: tuple[GroupQuery, ...]
    mode: str = "adaptive"
    mismatches: int = 0
    min_segment: int = 1

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


# --- running one group ----------------------------------------------------------------------

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
              min_segment: int = 1) -> GroupHits:
    """All hits of one (normalized) group query; see the module docstring (``min_segment``
    in frames at the index's rate: transitions of up to ``min_segment − 1`` frames between
    the runs of an adaptive hit)."""
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
                              "every position (use --mode fuzzy or adaptive)")
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


# --- several groups, ranking ---------------------------------------------------------------

def _length_score(bounds: np.ndarray, lengths: Sequence[int] | None) -> np.ndarray:
    if lengths is None:
        return np.full(len(bounds), np.nan)
    hit_len = np.diff(bounds, axis=1)
    return np.abs(hit_len - np.asarray(lengths, dtype=np.int64)[None, :]).sum(axis=1).astype(float)


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
    the segment-length heuristic (MRC05 §6.2) or, without query lengths, in document order.
    Hits of queries with segment lengths are trimmed (module docstring); their untrimmed
    frames are the hits' ``span_start``/``span_end``."""
    parts = [p.normalized() for p in query.parts]
    parts = [p for p in parts if not p.trivial] or parts[:1]
    if len(parts) == 1 and parts[0].trivial:
        raise MtannoError("query constrains no feature (every set allows every vector)")
    ghits = [run_group(index, p, mode=query.mode, mismatches=query.mismatches,
                       min_segment=query.min_segment) for p in parts]
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
    for p, gh, pick in zip(parts, ghits, picks):  # MRC05's score: the runs as matched
        score += _length_score(gh.bounds[pick], p.lengths)
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


def rank_by_template(index: Index, hits: Hits, values: np.ndarray, weights: np.ndarray,
                     features: Sequence[str]) -> Hits:
    """Re-rank hits by the cost of a quantized motion template on each hit's frames only
    (MRC05 §6.2, "finer ranking … on the few hits"; algorithms.md §3.4): cost = min Δ over
    the hit, with Δ computed on the hit's frames; ∞ where the hit is too short for the
    template (such hits are ranked last; :attr:`Hits.unfit` counts them). ``values``
    (f × K, 0/1/0.5), ``weights`` (K,), ``features`` the template's feature names (rebuilt
    from the index's groups)."""
    from mtanno.templates.match import match_documents

    _check_hits(index, hits)
    names = list(features)
    cache: dict[int, np.ndarray] = {}
    docs = []
    for d, s, e in zip(hits.doc, hits.start, hits.end):
        d = int(d)
        if d not in cache:
            cache[d] = index.feature_matrix(d, names)
        docs.append(cache[d][:, int(s):int(e) + 1])
    costs = np.full(len(hits), np.inf)
    if docs:
        for i, (delta, _) in enumerate(match_documents(values, weights, docs)):
            if len(delta) and np.isfinite(delta).any():
                costs[i] = float(np.min(delta))
    hits = replace(hits, cost=costs)
    order = np.lexsort((hits.start, hits.doc, costs))
    return hits.take(order)


def _check_hits(index: Index, hits: Hits) -> None:
    """Hits of ``index``: one document number and frame range per hit, inside it."""
    doc, start, end = (np.asarray(a) for a in (hits.doc, hits.start, hits.end))
    if doc.ndim != 1 or start.shape != doc.shape or end.shape != doc.shape:
        raise MtannoError("hits need one document number, start and end per hit")
    if not len(doc):
        return
    if doc.min() < 0 or doc.max() >= len(index.documents):
        raise MtannoError(f"hit document numbers must lie in 0..{len(index.documents) - 1}")
    frames = np.array([d.frames for d in index.documents], np.int64)[doc]
    if np.any(start < 0) or np.any(end < start) or np.any(end >= frames):
        raise MtannoError("hit frames must lie inside their document (0 ≤ start ≤ end < "
                          "frames)")


def rank_by_template_file(index: Index, hits: Hits, path: str | os.PathLike
                          ) -> tuple[Hits, int]:
    """:func:`rank_by_template` with a motion-template JSON file (``query --rank-mt``):
    read with :func:`mtanno.templates.model.load_template`, checked against the index's
    feature set, quantized with the retrieval δ (:data:`mtanno.retrieve.DEFAULT_DELTA`,
    MR06 §5.2) unless it already is. Returns (ranked hits, the template's columns)."""
    from mtanno.retrieve import DEFAULT_DELTA
    from mtanno.templates.model import load_template, quantize

    mt = load_template(path)
    if mt.feature_set != index.feature_set:
        raise MtannoError(f"template is for feature set '{mt.feature_set}' but the index holds "
                          f"'{index.feature_set}'", path=str(path))
    missing = [n for n in mt.feature_names if n not in index.features]
    if missing:
        raise MtannoError(f"template feature '{missing[0]}' is not in the index's feature set",
                          path=str(path))
    if not mt.quantized:
        mt = quantize(mt, DEFAULT_DELTA)
    ranked = rank_by_template(index, hits, mt.values, mt.weights, list(mt.feature_names))
    return ranked, int(mt.values.shape[1])


def write_query_hits(path: str | os.PathLike, index: Index, hits: Hits, *,
                     top: int | None = None, inputs: Sequence[str | os.PathLike] = (),
                     ranked_by: str | os.PathLike | None = None, **record) -> None:
    """Write the hit table of ``hits`` (:meth:`Hits.rows`, the best ``top`` only) atomically
    in the format of ``path``'s suffix (``-``: CSV on standard output), with its provenance:
    the query's ``inputs`` and the index generation, the ranking template ``ranked_by``
    (its cost column is written when the hits were ranked), ``top`` and ``record``."""
    from mtanno.util.tables import file_record, provenance, write_table

    rows = hits.rows(index)
    if top is not None:
        rows = rows[:top]
    write_table(path, hit_table(rows, with_mt=hits.cost is not None,
                                with_span=hits.span_start is not None), provenance=provenance(
        inputs=[file_record(i) for i in inputs] + [{"path": str(index.root / "manifest.json"),
                                                    "generation": index.generation}],
        templates=[file_record(ranked_by)] if ranked_by else (), top=top,
        feature_set=index.feature_set, **record))


def example_matrix(index: Index, example: str | os.PathLike
                   ) -> tuple[np.ndarray, list[str], str]:
    """(features × frames matrix, feature names, label) of a query-by-example source
    (``query --example``): a feature file (checked against the index's feature set, names
    and rate), or the name of an indexed document (its features that some group holds)."""
    from mtanno.index.core import doc_layout, read_feature_doc
    from mtanno.util.store import FeatureLayout, check_layout

    p = Path(example)
    if p.is_file():
        doc = read_feature_doc(p)
        check_layout(doc_layout(doc), FeatureLayout(index.feature_set, tuple(index.features),
                                                    float(index.fps), f"the index {index.root}"),
                     path=str(p))
        return doc.X, doc.names, str(p)
    if str(example) in {d.name for d in index.documents}:
        covered = {f for g in index.groups.values() for f in g.features}
        names = [f for f in index.features if f in covered]
        return index.feature_matrix(str(example), names), names, str(example)
    raise MtannoError("example is neither a feature file nor an indexed document",
                      path=str(example))


# --- building queries ----------------------------------------------------------------------

def _projection(index: Index, features: Sequence[str]) -> dict[str, list[tuple[int, int]]]:
    """Group → [(position in ``features``, bit in group)] of the chosen features."""
    if not features:
        raise MtannoError("no features chosen")
    if len(set(features)) != len(features):
        raise MtannoError("a feature is chosen twice")
    out: dict[str, list[tuple[int, int]]] = {}
    for i, f in enumerate(features):
        g, bit = index.locate(f)
        out.setdefault(g, []).append((i, bit))
    return {g: out[g] for g in index.groups if g in out}


#: Default shortest phase of a query by example, in frames at 30 Hz (100 ms): runs of one
#: or two frames — one knee bending a frame before the other — are transitions.
DEFAULT_MIN_SEGMENT = 3


def drop_short_segments(lengths: np.ndarray, values: np.ndarray, min_segment: int
                        ) -> tuple[list[int], list[int]]:
    """An example's segmentation without its transients: segments shorter than
    ``min_segment`` frames are dropped and their frames given to the segment before them
    (the one after, at the start), then neighbours with equal vectors are joined. When no
    segment is long enough the longest one (the first of equal ones) stays. Returns
    (lengths, values)."""
    keep = [int(n) >= min_segment for n in lengths]
    if not any(keep):
        keep[int(np.argmax(lengths))] = True
    out_len: list[int] = []
    out_val: list[int] = []
    carry = 0
    for n, v, k in zip(lengths.tolist(), values.tolist(), keep):
        if not k:
            if out_len:
                out_len[-1] += n
            else:
                carry += n
            continue
        if out_val and out_val[-1] == v:
            out_len[-1] += n
        else:
            out_len.append(n + carry)
            out_val.append(v)
        carry = 0
    return out_len, out_val


def example_query(index: Index, X: np.ndarray, names: Sequence[str], features: Sequence[str], *,
                  frames: tuple[int, int] | None = None, mode: str = "adaptive",
                  mismatches: int = 0, min_segment: int = 1) -> Query:
    """Query by example (MRC05 §6.2, algorithms.md §4): the example's segmentation over the
    chosen features, per group, becomes a sequence of fuzzy sets that fix the chosen bits
    and leave the group's other features free; segment lengths (frames) go along for the
    ranking. ``X`` is the example's (features × frames) matrix with row ``names`` (the
    index's feature set), ``frames`` an optional 0-based inclusive range.

    ``min_segment`` (frames; :data:`DEFAULT_MIN_SEGMENT` on the command line): example
    segments shorter than it are transitions, not query segments
    (:func:`drop_short_segments`), and the query lets documents pass through transitions
    of up to ``min_segment − 1`` frames between its segments (adaptive mode)."""
    features = [index.features[_feature_pos(index, f)] for f in features]
    pos = {n: i for i, n in enumerate(names)}
    missing = [f for f in features if f not in pos]
    if missing:
        raise MtannoError(f"example lacks feature '{missing[0]}'")
    n = X.shape[1]
    a, b = (0, n - 1) if frames is None else frames
    if not (0 <= a <= b < n):
        raise MtannoError(f"frames {a + 1}:{b + 1} outside the example's 1:{n}")
    parts = []
    for g, chosen in _projection(index, features).items():
        mask = sum(1 << bit for _, bit in chosen)
        codes = np.zeros(b - a + 1, dtype=np.int64)
        for i, bit in chosen:
            codes |= X[pos[features[i]], a:b + 1].astype(np.int64) << bit
        _, lengths, vals = segment(codes)
        lengths, vals = drop_short_segments(lengths, vals, min_segment)
        sets = tuple(FuzzySet(((mask, int(v)),)) for v in vals)
        parts.append(GroupQuery(g, sets, tuple(int(x) for x in lengths)))
    return Query(tuple(parts), mode, mismatches, min_segment)


def _feature_pos(index: Index, name: str) -> int:
    """Position of a feature in the index's feature set, by name or, for a built-in set,
    by id, reference name or MRC05 Table 1 name (``F07``, ``kneeRightAngle``, ``Fl7``)."""
    if name in index.features:
        return index.features.index(name)
    from mtanno.features import FEATURE_SETS

    fs = FEATURE_SETS.get(index.feature_set)
    if fs is not None and list(fs.names) == list(index.features):
        try:
            return fs.index(name)
        except MtannoError:
            pass
    raise MtannoError(f"unknown feature '{name}' (feature set {index.feature_set}; known: "
                      f"{', '.join(index.features)})")


def resolve_features(index: Index, names: Iterable[str]) -> list[str]:
    """Feature names (or ids/aliases of a built-in set) → the index's feature names."""
    return [index.features[_feature_pos(index, n.strip())] for n in names if n.strip()]


_JSON_KEYS = {"feature_set", "features", "steps", "lengths", "mode", "mismatches",
              "allowed_mismatches", "min_segment", "comment"}


def _pattern(text: str, n: int, where: str) -> list[str | None]:
    s = "".join(text.split())
    if len(s) != n or any(c not in "01*" for c in s):
        raise MtannoError(f"{where}: pattern '{text}' must have one of 0, 1, * per chosen "
                          f"feature ({n})")
    return [None if c == "*" else c for c in s]


def parse_query(spec: dict, index: Index, *, path: str | None = None) -> Query:
    """A :class:`Query` from a JSON query object (``docs/index.md``)::

        {"features": ["rknee_bent", "lknee_bent"],
         "steps": ["00", "11", ["01", "10"], "00"],
         "lengths": [10, 20, 5, 10],            (optional, frames, for ranking)
         "mode": "adaptive",                     (optional: exact | fuzzy | adaptive)
         "mismatches": 0, "allowed_mismatches": [3],   (optional, 1-based steps)
         "min_segment": 3,                       (optional, frames; default 1: transitions
                                                  between the steps' runs, adaptive mode)
         "feature_set": "mrc05"}                 (optional, checked against the index)

    A step is a pattern (one 0/1/* per chosen feature) or a list of patterns (their union).
    Each group gets the projection of the steps onto its chosen features (then adjacent
    intersecting sets are merged)."""
    def err(msg):
        return MtannoError(msg, path=path)

    if not isinstance(spec, dict):
        raise err("query must be a JSON object")
    unknown = sorted(set(spec) - _JSON_KEYS)
    if unknown:
        raise err(f"unknown key '{unknown[0]}' in query (known: {', '.join(sorted(_JSON_KEYS))})")
    fs = spec.get("feature_set")
    if fs is not None and fs != index.feature_set:
        raise err(f"query is for feature set '{fs}' but the index holds '{index.feature_set}'")
    feats = spec.get("features")
    if not isinstance(feats, list) or not feats or not all(isinstance(f, str) for f in feats):
        raise err("'features' must be a non-empty list of feature names")
    try:
        feats = resolve_features(index, feats)
        proj = _projection(index, feats)
    except MtannoError as exc:
        raise err(exc.message) from None
    steps = spec.get("steps")
    if not isinstance(steps, list) or not steps:
        raise err("'steps' must be a non-empty list of patterns")
    parsed: list[list[list[str | None]]] = []
    for i, st in enumerate(steps, 1):
        alts = st if isinstance(st, list) else [st]
        if not alts:
            raise err(f"step {i}: empty fuzzy set (no allowed pattern)")
        if not all(isinstance(a, str) for a in alts):
            raise err(f"step {i}: a pattern must be a string of 0, 1 and *")
        parsed.append([_pattern(a, len(feats), f"step {i}") for a in alts])
    lengths = spec.get("lengths")
    if lengths is not None and (not isinstance(lengths, list) or len(lengths) != len(steps)
                                or not all(isinstance(x, int) and x > 0 for x in lengths)):
        raise err("'lengths' must list one positive frame count per step")
    mism = spec.get("mismatches", 0)
    if not isinstance(mism, int) or mism < 0:
        raise err("'mismatches' must be a non-negative integer")
    allowed_pos = spec.get("allowed_mismatches")
    allowed = None
    if allowed_pos is not None:
        if not isinstance(allowed_pos, list) or not all(
                isinstance(x, int) and 1 <= x <= len(steps) for x in allowed_pos):
            raise err(f"'allowed_mismatches' must list step numbers 1..{len(steps)}")
        allowed = tuple(i + 1 in allowed_pos for i in range(len(steps)))
    mode = spec.get("mode", "adaptive")
    min_segment = spec.get("min_segment", 1)
    if not isinstance(min_segment, int) or isinstance(min_segment, bool) or min_segment < 1:
        raise err("'min_segment' must be a whole number of frames ≥ 1")
    parts = []
    for g, chosen in proj.items():
        sets = []
        for alts in parsed:
            pats = []
            for a in alts:
                m = v = 0
                for i, bit in chosen:
                    if a[i] is not None:
                        m |= 1 << bit
                        v |= (a[i] == "1") << bit
                if (m, v) not in pats:
                    pats.append((m, v))
            sets.append(FuzzySet(tuple(pats)))
        parts.append(GroupQuery(g, tuple(sets), None if lengths is None else tuple(lengths),
                                allowed))
    try:
        return Query(tuple(parts), mode, mism, min_segment)
    except MtannoError as exc:
        raise err(exc.message) from None


def load_query(path: str | os.PathLike, index: Index) -> Query:
    """Read a JSON query file (see :func:`parse_query`)."""
    from mtanno.errors import read_json

    p = Path(path)
    spec, _ = read_json(p, what="query file")
    return parse_query(spec, index, path=str(p))


QUERY_HIT_COLUMNS = ("doc", "start", "end", "rank", "score", "mt_cost", "span_start",
                     "span_end", "boundaries")


def hit_table(rows: Sequence[dict], *, with_mt: bool = False, with_span: bool = False):
    """The query hit table (``docs/index.md``) of :meth:`Hits.rows` as a
    :class:`pyarrow.Table`: doc, start, end, rank, score (an integer column when every
    score is whole), mt_cost (only ``with_mt``; null where the template cannot fit),
    span_start, span_end (only ``with_span``: untrimmed frames), boundaries."""
    import pyarrow as pa

    from mtanno.util.tables import arrow_table

    optional = {"mt_cost": with_mt, "span_start": with_span, "span_end": with_span}
    cols = [c for c in QUERY_HIT_COLUMNS if optional.get(c, True)]
    scores = [r.get("score") for r in rows]
    whole = all(s is None or float(s).is_integer() for s in scores)
    types = {"doc": pa.string(), "boundaries": pa.string(), "mt_cost": pa.float64(),
             "score": pa.int64() if whole else pa.float64()}
    data = {}
    for c in cols:
        values = [r.get(c) for r in rows]
        if c == "score" and whole:
            values = [None if v is None else int(v) for v in values]
        data[c] = values
    return arrow_table(data, types)  # (names of non-UTF-8 files written as text)


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
