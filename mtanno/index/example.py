"""Queries made from an example or read from a file ([MRC05] §5.2–5.3, ``docs/index.md``):
query by example (:func:`example_query`: the example's F-segments as a sequence of fuzzy
sets, with their lengths for ranking; short segments turned into transitions), and the
JSON query file (:func:`parse_query`, :func:`load_query`).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.index.core import Index, segment
from mtanno.index.query import FuzzySet, GroupQuery, Query

__all__ = ["DEFAULT_MIN_SEGMENT", "cut_segments", "drop_short_segments", "example_matrix",
           "example_file_query", "example_query", "load_query", "parse_query", "resolve_features"]


def example_matrix(index: Index, example: str | os.PathLike
                   ) -> tuple[np.ndarray, list[str], str]:
    """(features × frames matrix, feature names, label) of a query-by-example source
    (``query --example``): a feature file (checked against the index's feature set, names
    and rate), or the name of an indexed document (its features that some group holds)."""
    from mtanno.features.store import FeatureLayout, check_layout
    from mtanno.index.core import doc_layout, read_feature_doc

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


def drop_short_segments(lengths: np.ndarray, values: np.ndarray, min_segment: int, *,
                        keep_ends: bool = False) -> tuple[list[int], list[int]]:
    """An example's segmentation without its transients: segments shorter than
    ``min_segment`` frames are dropped and their frames given to the segment before them
    (the one after, at the start), then neighbours with equal vectors are joined. When no
    segment is long enough the longest one (the first of equal ones) stays. With
    ``keep_ends`` the first and last segments stay whatever their length (a recording's
    ends cut a pose short; they are not transients). Returns (lengths, values)."""
    keep = [int(n) >= min_segment for n in lengths]
    if keep_ends and keep:
        keep[0] = keep[-1] = True
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
    """Query by example ([MRC05] §6.2, docs/method.md §4): the example's segmentation over the
    chosen features, per group, becomes a sequence of fuzzy sets that fix the chosen bits
    and leave the group's other features free; segment lengths (frames) go along for the
    ranking. ``X`` is the example's (features × frames) matrix with row ``names`` (the
    index's feature set), ``frames`` an optional 0-based inclusive range.

    ``min_segment`` (frames; :data:`DEFAULT_MIN_SEGMENT` on the command line): example
    segments shorter than it are transients, not query segments
    (:func:`drop_short_segments`, applied to the whole example before ``frames`` cuts it:
    :func:`cut_segments`). In the adaptive mode the query is *smoothed*
    (:attr:`Query.smooth`): each document's runs over the chosen features go through the
    same rule, so the example's own source is found with the same segments, and ranks
    first with score 0 whatever the cut."""
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
        codes = np.zeros(n, dtype=np.int64)
        for i, bit in chosen:
            codes |= X[pos[features[i]]].astype(np.int64) << bit
        lengths, vals, context = cut_segments(codes, a, b, min_segment)
        sets = tuple(FuzzySet(((mask, int(v)),)) for v in vals)
        parts.append(GroupQuery(g, sets, tuple(lengths), context=context))
    return Query(tuple(parts), mode, mismatches, min_segment, smooth=mode == "adaptive")


def cut_segments(codes: np.ndarray, a: int, b: int, min_segment: int
                 ) -> tuple[list[int], list[int], tuple[int, int]]:
    """The segments of frames ``a..b`` (0-based, inclusive) of an example whose per-frame
    codes are ``codes``: the whole example is segmented and smoothed
    (:func:`drop_short_segments`, its first and last runs kept), as every document of the
    index is when queried
    (:attr:`Query.smooth`), then cut to the range, so the cut's segments are those its
    source document has there. The first and last are usually partial (the cut falls
    inside a run); one shorter than ``min_segment`` frames is left out (the frames before
    the motion chosen), unless it is all there is. Returns (lengths, values, the whole
    lengths of the runs the first and last segments were cut from), frames."""
    _, lengths, vals = segment(codes)
    lengths, vals = drop_short_segments(lengths, vals, min_segment, keep_ends=True)
    ends = np.cumsum(lengths)
    starts = ends - np.asarray(lengths)
    first = int(np.searchsorted(ends, a, side="right"))
    last = int(np.searchsorted(ends, b, side="right"))
    cut = [int(min(e, b + 1) - max(s, a)) for s, e in zip(starts[first:last + 1],
                                                          ends[first:last + 1])]
    idx = list(range(first, last + 1))
    if len(cut) > 1 and cut[-1] < min_segment:
        cut, idx = cut[:-1], idx[:-1]
    if len(cut) > 1 and cut[0] < min_segment:
        cut, idx = cut[1:], idx[1:]
    return cut, [int(vals[i]) for i in idx], (int(lengths[idx[0]]), int(lengths[idx[-1]]))


def _feature_pos(index: Index, name: str) -> int:
    """Position of a feature in the index's feature set, by name or, for a built-in set,
    by id, reference name or [MRC05] Table 1 name (``F07``, ``kneeRightAngle``, ``Fl7``)."""
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


def example_file_query(index: Index, example: str | os.PathLike, features: Sequence[str], *,
                       frames: str | None = None, mode: str = "adaptive", mismatches: int = 0,
                       min_segment: int = DEFAULT_MIN_SEGMENT) -> Query:
    """:func:`example_query` of an example file (a feature file at the index's rate, or an
    indexed document's name: :func:`example_matrix`): ``features`` are names, ids or
    aliases of the index's feature set (:func:`resolve_features`), ``frames`` the range
    ``'A:B'`` of the example (1-based inclusive, either side may be empty; None: all of
    it) — ``mtanno query --example FILE --frames A:B --features ...``."""
    from mtanno.util.clips import parse_frame_range

    X, names, _ = example_matrix(index, example)
    return example_query(index, X, names, resolve_features(index, features),
                         frames=parse_frame_range(frames, X.shape[1]), mode=mode,
                         mismatches=mismatches, min_segment=min_segment)
