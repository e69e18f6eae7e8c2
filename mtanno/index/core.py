"""The relational index in memory: adaptive segmentation, inverted lists, documents, groups.

[MRC05] §4 and §5.3 (docs/method.md §4): for a feature group F (a named subset of the feature
set's features, e.g. lower/upper/mix), the F-segments of a document are the maximal runs of
frames with equal F-feature vectors. A segment's vector is stored as an integer *code*,
``Σ_k bit_k · 2^k`` over the group's features in group order (the reference
implementation's ``index_segments`` code). For every code v the inverted list L(v) holds the
segments with that vector, as ascending *segment rows*: rows number the segments of all
documents one after another, documents in index order (sorted by name), so a document's
segments are one contiguous range of rows. Each segment is in exactly one list; with each
segment its start frame and length are stored, so hits and keyframe intervals convert
back to frames (0-based in code, 1-based in files).

:class:`Index` is what :func:`mtanno.index.open_index` returns and what the query and
keyframe code use; :mod:`mtanno.index.storage` reads and writes it.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.features.inputs import feature_files
from mtanno.features.store import FeatureLayout, check_layout, common_layout, read_features

#: Most features a group may have (codes are int64).
MAX_GROUP_FEATURES = 62
_GROUP_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


@dataclass(frozen=True)
class Document:
    """One indexed document: name (feature file stem), SHA-256 of the feature file's bytes,
    number of frames at the analysis rate, and the feature file path it was read from."""

    name: str
    sha256: str
    frames: int
    path: str


class GroupIndex:
    """Segments and inverted lists of one feature group ([MRC05] §5.3).

    Attributes (arrays over segment rows unless said otherwise)
    ----------------------------------------------------------
    name, features:
        Group name and its feature names; bit k of a code is ``features[k]``.
    doc:
        0-based document number of each row (int32).
    start, length:
        0-based first frame and length in frames (int32).
    code:
        The segment's feature vector as a code (int64).
    doc_offsets:
        (documents + 1) first row of each document, then the number of rows (int64).
    list_codes:
        (lists) the codes that occur, ascending (int64); list v is L(list_codes[v]).
    list_offsets, postings:
        CSR form of the inverted lists: list v = ``postings[list_offsets[v]:list_offsets[v+1]]``,
        ascending segment rows (int64 offsets, int32 rows).
    seg_list:
        Number of the list each row is in (int32; derived).
    """

    def __init__(self, name: str, features: Sequence[str], doc: np.ndarray, start: np.ndarray,
                 length: np.ndarray, code: np.ndarray, doc_offsets: np.ndarray,
                 list_codes: np.ndarray | None = None, list_offsets: np.ndarray | None = None,
                 postings: np.ndarray | None = None):
        self.name = name
        self.features = tuple(features)
        self.doc = np.ascontiguousarray(doc, dtype=np.int32)
        self.start = np.ascontiguousarray(start, dtype=np.int32)
        self.length = np.ascontiguousarray(length, dtype=np.int32)
        self.code = np.ascontiguousarray(code, dtype=np.int64)
        self.doc_offsets = np.ascontiguousarray(doc_offsets, dtype=np.int64)
        if list_codes is None:
            list_codes, list_offsets, postings = inverted_lists(self.code)
        self.list_codes = np.ascontiguousarray(list_codes, dtype=np.int64)
        self.list_offsets = np.ascontiguousarray(list_offsets, dtype=np.int64)
        self.postings = np.ascontiguousarray(postings, dtype=np.int32)
        self.seg_list = np.empty(len(self.code), dtype=np.int32)
        self.seg_list[self.postings] = np.repeat(
            np.arange(len(self.list_codes), dtype=np.int32), np.diff(self.list_offsets))

    @property
    def n_segments(self) -> int:
        return len(self.code)

    @property
    def n_lists(self) -> int:
        """Number of non-empty inverted lists (distinct vectors that occur)."""
        return len(self.list_codes)

    @property
    def list_sizes(self) -> np.ndarray:
        return np.diff(self.list_offsets)

    def rows(self, d: int) -> range:
        """Segment rows of document number ``d``."""
        n = len(self.doc_offsets) - 1
        if not 0 <= d < n:  # −1 would read the row count as a first row
            raise MtannoError(f"document number {d} outside 0..{n - 1}")
        return range(int(self.doc_offsets[d]), int(self.doc_offsets[d + 1]))

    def segments(self, d: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(start frames, lengths, codes) of document ``d``'s segments (frames 0-based)."""
        r = self.rows(d)
        return self.start[r.start:r.stop], self.length[r.start:r.stop], self.code[r.start:r.stop]

    def list_of(self, code: int) -> np.ndarray:
        """The inverted list L(code): ascending segment rows (empty if the code never occurs)."""
        v = int(np.searchsorted(self.list_codes, code))
        if v < len(self.list_codes) and self.list_codes[v] == code:
            return self.postings[self.list_offsets[v]:self.list_offsets[v + 1]]
        return self.postings[:0]

    def lists_matching(self, patterns: Iterable[tuple[int, int]]) -> np.ndarray:
        """Boolean mask over lists: codes v with ``v & mask == value`` for some pattern."""
        out = np.zeros(len(self.list_codes), dtype=bool)
        by_mask: dict[int, list[int]] = {}
        for m, val in patterns:
            by_mask.setdefault(int(m), []).append(int(val))
        for m, vals in by_mask.items():
            keys = self.list_codes & np.int64(m)
            out |= (np.isin(keys, np.array(vals, dtype=np.int64)) if len(vals) > 1
                    else keys == vals[0])
        return out

    def intervals(self, patterns: Iterable[tuple[int, int]]):
        """Frame intervals where the group's vector matches a pattern (``(mask, value)``
        pairs, see :meth:`lists_matching`): the union of the matching inverted lists with
        adjacent segments merged (docs/method.md §5, keyframe search). Returns (doc, start,
        end) arrays, 0-based, ``end`` inclusive, sorted by document and frame."""
        from mtanno.index import _kernels

        member = self.lists_matching(patterns)
        sel = np.flatnonzero(member)
        total = int(self.list_sizes[sel].sum())
        if total * 8 < self.n_segments:  # few postings: gather and sort them
            parts = [self.postings[self.list_offsets[v]:self.list_offsets[v + 1]] for v in sel]
            rows = np.sort(np.concatenate(parts)) if parts else np.zeros(0, np.int32)
        else:  # many: one pass over the segments, already in row order
            rows = np.flatnonzero(member[self.seg_list])
        n = len(rows)
        doc, start, end = (np.empty(n, np.int64) for _ in range(3))
        k = _kernels.merge_rows(rows.astype(np.int64), self.doc, self.start, self.length,
                                doc, start, end)
        return doc[:k], start[:k], end[:k]


def inverted_lists(code: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(list codes, CSR offsets, postings) of the inverted lists over segment codes: list v
    holds the rows with code ``list_codes[v]``, ascending ([MRC05] §5.1, eq. 6)."""
    order = np.argsort(code, kind="stable")
    sorted_codes = code[order]
    if len(code):
        first = np.flatnonzero(np.r_[True, sorted_codes[1:] != sorted_codes[:-1]])
    else:
        first = np.zeros(0, dtype=np.int64)
    offsets = np.r_[first, len(code)].astype(np.int64)
    return sorted_codes[first], offsets, order.astype(np.int32)


def frame_codes(X: np.ndarray, rows: Sequence[int]) -> np.ndarray:
    """Per-frame code ``Σ_k X[rows[k], t] · 2^k`` (int64) of a (features × frames) 0/1
    matrix over the given rows (a group's features in group order)."""
    codes = np.zeros(X.shape[1], dtype=np.int64)
    for k, r in enumerate(rows):
        codes |= X[r].astype(np.int64) << k
    return codes


def segment(codes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Adaptive segmentation ([MRC05] §4): (start frames, lengths, codes) of the maximal runs
    of equal per-frame codes, frames 0-based."""
    n = len(codes)
    if n == 0:
        z = np.zeros(0, dtype=np.int64)
        return z, z, z
    starts = np.flatnonzero(np.r_[True, codes[1:] != codes[:-1]])
    lengths = np.diff(np.r_[starts, n])
    return starts, lengths, codes[starts]


@dataclass
class FeatureDoc:
    """A feature file read for indexing: document name, hash, matrix, names, metadata."""

    name: str
    sha256: str
    X: np.ndarray
    names: list[str]
    meta: dict
    path: str


def read_feature_doc(path: str | os.PathLike) -> FeatureDoc:
    """Read a feature file (``mtanno features`` output) and hash its bytes in one pass."""
    ff = read_features(path, sha256=True)
    return FeatureDoc(ff.document, ff.sha256, ff.X, ff.names, ff.meta, ff.path)


def read_feature_docs(paths: Sequence[str | os.PathLike], *,
                      failures: list[str] | None = None,
                      progress: Callable[[int, int], None] | None = None) -> list[FeatureDoc]:
    """Read many feature files, one after another. With ``failures``, a file that cannot
    be read is left out and its message appended there; without, it is raised.
    ``progress(done, total)`` is called after each file.

    Not in threads: a feature file is small (Bandai set 2: 2 148 files of 130 frames) and
    most of its reading is Python (metadata, checks), so a pool of 2 threads on 2 cores
    took longer (1.88 s against 1.71 s for the 2 148 files, and 2.62 s CPU against 1.71 s;
    the 232 HDM05 files: 0.19 s against 0.16 s; issue 25, docs/benchmarks.md)."""
    def one(p):
        try:
            return read_feature_doc(p)
        except MtannoError as exc:
            if failures is None:
                raise
            return str(exc)

    def collect(results) -> list:
        out = []
        for result in results:  # in the order of paths, as they are read
            out.append(result)
            if progress is not None:
                progress(len(out), len(paths))
        return out

    got = collect(map(one, paths))
    if failures is not None:
        failures.extend(g for g in got if isinstance(g, str))
    return [g for g in got if not isinstance(g, str)]


def collect_feature_files(inputs: Iterable[str | os.PathLike], *,
                          failures: list[str] | None = None) -> list[Path]:
    """Feature files named by ``inputs`` (see :func:`mtanno.features.inputs.feature_files`; with
    ``failures``, an input naming no feature file is reported there and the rest go on)."""
    return feature_files(inputs, failures=failures)


@dataclass
class Index:
    """A relational index (in memory): documents, groups and their inverted lists.

    Attributes
    ----------
    feature_set, feature_set_version:
        The feature set of every indexed feature file (e.g. ``mrc05``).
    features:
        All feature names of that set, in column order.
    fps:
        Frame rate of the indexed frames (the analysis rate, 30).
    documents:
        Indexed documents, sorted by name; their position is the document number.
    groups:
        Group name → :class:`GroupIndex`, in the order the groups were given.
    root, generation:
        Directory and generation it was read from (None/0 for an index built in memory).
    """

    feature_set: str
    feature_set_version: int
    features: tuple[str, ...]
    fps: float
    documents: list[Document]
    groups: dict[str, GroupIndex]
    root: Path | None = None
    generation: int = 0
    _doc_numbers: dict[str, int] = field(default_factory=dict, repr=False)

    def __post_init__(self):
        self._doc_numbers = {d.name: i for i, d in enumerate(self.documents)}

    @property
    def frames(self) -> int:
        return sum(d.frames for d in self.documents)

    def doc_number(self, name: str) -> int:
        """Document number of the document called ``name``."""
        try:
            return self._doc_numbers[name]
        except KeyError:
            raise MtannoError(f"document '{name}' is not in the index") from None

    def locate(self, feature: str) -> tuple[str, int]:
        """(group, bit) of a feature name; the first group containing it."""
        for g in self.groups.values():
            if feature in g.features:
                return g.name, g.features.index(feature)
        if feature in self.features:
            raise MtannoError(f"feature '{feature}' is in no index group (groups: "
                              f"{', '.join(self.groups)})")
        raise MtannoError(f"unknown feature '{feature}' (feature set {self.feature_set}; "
                          f"known: {', '.join(self.features)})")

    def feature_matrix(self, doc: str | int, features: Sequence[str] | None = None,
                       ) -> np.ndarray:
        """(features × frames) uint8 matrix of an indexed document, rebuilt from the group
        segments (default: every feature of the set that some group covers, in set order)."""
        d = doc if isinstance(doc, (int, np.integer)) else self.doc_number(doc)
        if not 0 <= d < len(self.documents):
            raise MtannoError(f"document number {d} outside 0..{len(self.documents) - 1}")
        if features is None:
            covered = {f for g in self.groups.values() for f in g.features}
            features = [f for f in self.features if f in covered]
        X = np.zeros((len(features), self.documents[d].frames), dtype=np.uint8)
        for i, name in enumerate(features):
            gname, bit = self.locate(name)
            start, length, code = self.groups[gname].segments(d)
            X[i] = np.repeat(((code >> bit) & 1).astype(np.uint8), length)
        return X


def resolve_groups(feature_names: Sequence[str], default: Mapping[str, Sequence[str]],
                   groups: Mapping[str, Sequence[str]] | Sequence[str] | None,
                   ) -> dict[str, tuple[str, ...]]:
    """Group name → feature names, validated. ``groups``: None (the feature set's groups),
    a list of group names (a subset of them) or a mapping name → feature names (custom
    groups, e.g. AK mix without F40)."""
    if groups is None:
        out = {g: tuple(f) for g, f in default.items()}
    elif isinstance(groups, Mapping):
        out = {str(g): tuple(f) for g, f in groups.items()}
    else:
        out = {}
        for g in groups:
            if g not in default:
                raise MtannoError(f"unknown group '{g}' (groups of this feature set: "
                                  f"{', '.join(default)})")
            out[g] = tuple(default[g])
    if not out:
        raise MtannoError("no index groups given")
    for g, feats in out.items():
        if not _GROUP_NAME.match(g):
            raise MtannoError(f"invalid group name '{g}' (letters, digits, _ . - only)")
        if not feats:
            raise MtannoError(f"group '{g}' has no features")
        if len(feats) > MAX_GROUP_FEATURES:
            raise MtannoError(f"group '{g}' has {len(feats)} features; at most "
                              f"{MAX_GROUP_FEATURES} are supported (index groups, not all bits)")
        if len(set(feats)) != len(feats):
            raise MtannoError(f"group '{g}' names a feature twice")
        for f in feats:
            if f not in feature_names:
                raise MtannoError(f"group '{g}': unknown feature '{f}'")
    return out


def doc_layout(d: FeatureDoc) -> FeatureLayout:
    """The feature layout (set, names, rate) of a feature file read for indexing."""
    return FeatureLayout(str(d.meta["feature_set"]), tuple(d.names),
                         float(d.meta["analysis_fps"]), f"feature file {d.path}")


def check_compatible(docs: Sequence[FeatureDoc], *, layout: FeatureLayout | None = None,
                     failures: list[str] | None = None) -> list[FeatureDoc]:
    """The documents that can go into one index: all with the same feature layout (that of
    ``layout``, e.g. an existing index's, or else the layout most of them share, see
    :func:`mtanno.features.store.common_layout`, so an odd file is the one named) and unique names.
    With ``failures``, a document that does not fit is left out and its message appended;
    without, the first one is raised. Returns the documents kept."""
    if not docs:
        return []
    want = layout or common_layout([doc_layout(d) for d in docs])
    seen: dict[str, str] = {}
    kept = []
    for d in docs:
        try:
            check_layout(doc_layout(d), want, path=d.path)
            if d.name in seen:
                raise MtannoError(f"document name '{d.name}' appears twice: {seen[d.name]} "
                                  f"and {d.path}", path=d.path)
        except MtannoError as exc:
            if failures is None:
                raise
            failures.append(str(exc))
            continue
        seen[d.name] = d.path
        kept.append(d)
    return kept


def doc_segments(X: np.ndarray, names: Sequence[str], groups: Mapping[str, Sequence[str]],
                 ) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Group → (starts, lengths, codes) of one document's F-segments ([MRC05] §4)."""
    pos = {n: i for i, n in enumerate(names)}
    return {g: segment(frame_codes(X, [pos[f] for f in feats])) for g, feats in groups.items()}


def segment_documents(matrices: Sequence[np.ndarray], names: Sequence[str],
                      groups: Mapping[str, Sequence[str]],
                      ) -> list[dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """:func:`doc_segments` of many documents (same rows ``names``) at once: the matrices
    are concatenated, runs are cut at every document start, and the segments split back."""
    if len(matrices) < 2:
        return [doc_segments(X, names, groups) for X in matrices]
    lens = np.array([X.shape[1] for X in matrices], dtype=np.int64)
    offsets = np.r_[0, np.cumsum(lens)]
    total = int(offsets[-1])
    X = np.concatenate(matrices, axis=1)
    first = np.zeros(total, dtype=bool)
    first[offsets[:-1][lens > 0]] = True
    pos = {n: i for i, n in enumerate(names)}
    out: list[dict] = [{} for _ in matrices]
    for g, feats in groups.items():
        codes = frame_codes(X, [pos[f] for f in feats])
        change = first.copy()
        if total > 1:
            change[1:] |= codes[1:] != codes[:-1]
        starts = np.flatnonzero(change)
        lengths = np.diff(np.r_[starts, total])
        seg_codes = codes[starts]
        doc = np.searchsorted(offsets, starts, side="right") - 1
        local = starts - offsets[doc]
        cut = np.r_[0, np.cumsum(np.bincount(doc, minlength=len(matrices)))]
        for d in range(len(matrices)):
            a, b = cut[d], cut[d + 1]
            out[d][g] = (local[a:b], lengths[a:b], seg_codes[a:b])
    return out


def assemble(feature_set: str, version: int, features: Sequence[str], fps: float,
             groups: Mapping[str, Sequence[str]],
             docs: Mapping[str, tuple[Document, dict]]) -> Index:
    """Build an :class:`Index` from per-document segments ``docs``: name → (document,
    group → (starts, lengths, codes)). Documents are ordered by name, so the result does
    not depend on the order they were given in (incremental updates equal a rebuild)."""
    names = sorted(docs)
    documents = [docs[n][0] for n in names]
    out: dict[str, GroupIndex] = {}
    for g, feats in groups.items():
        parts = [docs[n][1][g] for n in names]
        counts = np.array([len(p[0]) for p in parts], dtype=np.int64)
        offsets = np.r_[0, np.cumsum(counts)].astype(np.int64)
        cols = [np.concatenate([p[k] for p in parts]) if parts else np.zeros(0, np.int64)
                for k in range(3)]
        out[g] = GroupIndex(g, feats, np.repeat(np.arange(len(names), dtype=np.int32), counts),
                            cols[0].astype(np.int32), cols[1].astype(np.int32),
                            cols[2].astype(np.int64), offsets)
    return Index(feature_set, int(version), tuple(features), float(fps), documents, out)


def index_from_matrices(matrices: Mapping[str, np.ndarray], names: Sequence[str],
                        groups: Mapping[str, Sequence[str]], *, feature_set: str = "custom",
                        fps: float = 30.0) -> Index:
    """An in-memory index over (features × frames) 0/1 matrices keyed by document name
    (for tests and for callers that hold features already)."""
    gs = resolve_groups(names, groups, None)
    mats = {}
    for name, X in matrices.items():
        X = np.asarray(X, dtype=np.uint8)
        if X.ndim != 2 or X.shape[0] != len(names):
            raise MtannoError(f"document '{name}': matrix must be ({len(names)} × frames)")
        mats[name] = X
    segs = segment_documents(list(mats.values()), names, gs)
    docs = {name: (Document(name, "", int(X.shape[1]), ""), sg)
            for (name, X), sg in zip(mats.items(), segs)}
    return assemble(feature_set, 1, names, fps, gs, docs)
