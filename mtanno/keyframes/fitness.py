"""Fitness of keyframe queries on training clips ([MBS09] §6, docs/method.md §6).

[MBS09] scores a query on the training clips: it *retrieves* a clip if it has a hit there;
with the positives T⁺ (the class's clips) and negatives T⁻ (every other class's clips),
P = |H ∩ T⁺|/|H|, R = |H ∩ T⁺|/|T⁺| and

    F_β = (1 + β²)·P·R / (β²·P + R),   β = 2 (recall matters more: a motion whose key
                                        poses are missed is lost for good).

Annotation, however, searches long documents where motions follow each other. A query
whose hits stay inside its class's clips while the clips are isolated can still fire on the
transitions between motions. So mtanno scores queries where they will be used
(``docs/keyframes.md``): the training clips are joined, in a seeded random order, into
training *sequences* of :data:`CLIPS_PER_SEQUENCE` clips, and a query is searched there.
A positive clip is *found* if a hit overlaps it (R = found / positives, [MBS09]'s recall);
each hit is attributed to the clip holding its middle frame, and P = the positive clips
among the clips hits are attributed to (a hit on a transition between two other motions
counts against the query). Every clip also appears in :data:`JITTER` copies whose feature
switches are moved by a frame (:func:`jitter_edges`), so a query must not rely on exact
frame coincidences. ``score(..., within=mask)`` counts only the clips of the mask, for
validation on held-out performers.

Keyframes are *genes* ``(position, group number, mask, value)`` over the bits of one group;
their interval lists are cached, so the many queries of a genetic algorithm that share
keyframes cost one chain search each.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mtanno.errors import MtannoError
from mtanno.keyframes import _kernels
from mtanno.keyframes.model import UNBOUNDED, tolerant_patterns

#: A keyframe of the learner: (1-based template column, group number, mask, value).
Gene = tuple[int, int, int, int]
#: Gap bounds (dmin, dmax); dmax None = unbounded.
Bounds = tuple[int, "int | None"]
#: Clips per training sequence.
CLIPS_PER_SEQUENCE = 10
#: Jittered copies of every training clip (:func:`jitter_edges`).
JITTER = 1


def jitter_edges(X: np.ndarray, *, rng: np.random.Generator, p: float = 0.5) -> np.ndarray:
    """A copy of a (features × frames) 0/1 matrix with each switch of each feature moved
    one frame earlier or later, each with probability p/2.

    The same motion recorded again, or sampled at 30 Hz with another phase of the native
    frames (an offset of up to 3 native frames at 120 Hz), switches its features up to a
    frame earlier or later; a keyframe query that only holds on the exact training frames
    (gap bounds of one frame, poses held for one frame) fails there. Training on jittered
    copies keeps the learner from relying on such coincidences.
    """
    X = np.asarray(X, np.uint8)
    Y = X.copy()
    for i in range(X.shape[0]):
        x = X[i]
        edges = np.flatnonzero(x[1:] != x[:-1]) + 1
        if not len(edges):
            continue
        r = rng.random(len(edges))
        earlier = edges[r < p / 2]
        later = edges[(r >= p / 2) & (r < p)]
        Y[i, earlier - 1] = x[earlier]
        Y[i, later] = x[later - 1]
    return Y


def keyframe_tolerance(mask: int, mismatches: int) -> int:
    """Mismatches a learned keyframe with fixed bits ``mask`` tolerates: ``mismatches``
    if it fixes at least 2·mismatches + 2 entries (so most entries still have to agree),
    else 0."""
    return mismatches if bin(mask).count("1") >= 2 * mismatches + 2 else 0


@dataclass(frozen=True)
class Score:
    """Precision, recall and F_β of a query on training clips, with the counts behind
    them: positive clips found and in all, clips hits are attributed to and the positive
    ones among them, and ``support`` = frames of hits inside positive clips (how much room
    the query leaves; larger is more robust)."""

    P: float
    R: float
    F: float
    found: int
    positives: int
    retrieved: int
    relevant: int
    support: int = 0

    def as_dict(self, beta: float) -> dict:
        return {"P": self.P, "R": self.R, "F": self.F, "beta": beta,
                "positive_clips_found": self.found, "positive_clips": self.positives,
                "clips_with_hits": self.retrieved, "positive_clips_with_hits": self.relevant}


def f_beta(P: float, R: float, beta: float) -> float:
    """Weighted F-measure ([MBS09] §6); 0 when P and R are 0."""
    b2 = beta * beta
    den = b2 * P + R
    return 0.0 if den == 0 else (1 + b2) * P * R / den


class TrainingSet:
    """Training clips of all classes, joined into training sequences, for scoring queries.

    Parameters
    ----------
    matrices:
        One (features × frames) 0/1 matrix per clip (rows ``names``).
    labels:
        The class of each clip.
    names:
        Feature (row) names.
    groups:
        Group name → feature names (the feature set's index groups).
    clip_names:
        Optional names of the clips (default ``clip00001`` …), kept in the given order.
    feature_set:
        Name of the feature set (checked against the queries scored).
    performers:
        Optional performer (or recording) of each clip, for validation on held-out
        performers.
    seed:
        Seed of the order in which clips are joined into sequences (and of the jitter).
    jitter:
        Extra copies of every clip with feature switches moved by one frame
        (:func:`jitter_edges`), scored like the originals.
    """

    def __init__(self, matrices: Sequence[np.ndarray], labels: Sequence[str],
                 names: Sequence[str], groups: dict[str, Sequence[str]], *,
                 clip_names: Sequence[str] | None = None, feature_set: str = "custom",
                 performers: Sequence[str | None] | None = None, seed: int = 0,
                 jitter: int = 0):
        from mtanno.index import index_from_matrices

        n = len(matrices)
        if n != len(labels):
            raise MtannoError(f"{n} clips but {len(labels)} labels")
        if not n:
            raise MtannoError("no training clips")
        if jitter:
            rng = np.random.default_rng([seed, 1])
            base = list(clip_names) if clip_names is not None else \
                [f"clip{i + 1:05d}" for i in range(n)]
            perf = list(performers) if performers is not None else [None] * n
            matrices = list(matrices) + [jitter_edges(np.asarray(X, np.uint8), rng=rng)
                                         for _ in range(jitter) for X in matrices]
            labels = list(labels) * (jitter + 1)
            clip_names = base + [f"{c}~{k + 1}" for k in range(jitter) for c in base]
            performers = perf * (jitter + 1)
            n = len(matrices)
        self.n_original = n // (jitter + 1)
        self.names = list(names)
        self.group_names = list(groups)
        self.groups = {g: tuple(f) for g, f in groups.items()}
        self.clip_names = list(clip_names) if clip_names is not None else \
            [f"clip{i + 1:05d}" for i in range(n)]
        if len(set(self.clip_names)) != n:
            raise MtannoError("training clip names must be unique")
        self.labels = np.array([str(x) for x in labels], dtype=object)
        self.performers = list(performers) if performers is not None else [None] * n
        if len(self.performers) != n:
            raise MtannoError(f"{n} clips but {len(self.performers)} performers")
        mats = [np.asarray(X, np.uint8) for X in matrices]
        self.lengths = np.array([X.shape[1] for X in mats], np.int64)
        # clips joined in a seeded random order into sequences (documents of the index)
        order = np.random.default_rng(seed).permutation(n)
        seqs = [order[i:i + CLIPS_PER_SEQUENCE] for i in range(0, n, CLIPS_PER_SEQUENCE)]
        docs = {f"seq{k:05d}": np.concatenate([mats[i] for i in s], axis=1)
                for k, s in enumerate(seqs)}
        self.index = index_from_matrices(docs, self.names, self.groups,
                                         feature_set=feature_set)
        self.doc_lengths = np.array([d.frames for d in self.index.documents], np.int64)
        self.doc_offset = np.r_[0, np.cumsum(self.doc_lengths)].astype(np.int64)
        total = int(self.doc_offset[-1])
        # frame (global over the sequences) → clip; clip → its global frame range
        self.clip_of_frame = np.empty(total, np.int64)
        self.clip_start = np.empty(n, np.int64)
        pos = 0
        for s in seqs:  # documents are named in sequence order, so their order is seqs'
            for i in s:
                self.clip_start[i] = pos
                self.clip_of_frame[pos:pos + self.lengths[i]] = i
                pos += int(self.lengths[i])
        self._gi = [self.index.groups[g] for g in self.group_names]
        self._intervals: dict[tuple[int, int, int], tuple[np.ndarray, ...]] = {}
        self._masks: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        self.evaluations = 0

    @property
    def n_clips(self) -> int:
        return len(self.labels)

    def classes(self) -> list[str]:
        return sorted(set(self.labels.tolist()))

    def positives(self, class_name: str) -> np.ndarray:
        return self.labels == class_name

    def intervals(self, gi: int, mask: int, value: int, mismatches: int = 0,
                  ) -> tuple[np.ndarray, ...]:
        """Interval list of the frames where group ``gi`` matches (mask, value) with at
        most ``mismatches`` fixed bits differing (cached)."""
        key = (gi, mask, value, mismatches)
        iv = self._intervals.get(key)
        if iv is None:
            d, s, e = self._gi[gi].intervals(tolerant_patterns(mask, value, mismatches))
            iv = (d.astype(np.int64), s.astype(np.int64), e.astype(np.int64))
            self._intervals[key] = iv
        return iv

    def _prefixes(self, positives: np.ndarray, within: np.ndarray | None):
        """Prefix sums over global frames of (positive ∧ within) and (within) frames."""
        key = (positives.tobytes(), None if within is None else within.tobytes())
        pre = self._masks.get(key)
        if pre is None:
            inside = np.ones(self.n_clips, bool) if within is None else within
            pf = (positives & inside)[self.clip_of_frame]
            wf = inside[self.clip_of_frame]
            pre = (np.r_[0, np.cumsum(pf)].astype(np.int64),
                   np.r_[0, np.cumsum(wf)].astype(np.int64))
            if len(self._masks) > 64:
                self._masks.clear()
            self._masks[key] = pre
        return pre

    def hits(self, genes: Sequence[Gene], gaps: Sequence[Bounds], mismatches: int = 0):
        """Raw hits (doc, start, end) of the query in the sequences; keyframes with enough
        fixed bits tolerate ``mismatches`` (:func:`keyframe_tolerance`)."""
        from mtanno.keyframes.search import _chain_hits

        levels = [self.intervals(g[1], g[2], g[3], keyframe_tolerance(g[2], mismatches))
                  for g in genes]
        bounds = [(lo, UNBOUNDED if hi is None else hi) for lo, hi in gaps]
        self.evaluations += 1
        return _chain_hits(levels, bounds)  # made here: not checked again

    def score(self, genes: Sequence[Gene], gaps: Sequence[Bounds], positives: np.ndarray,
              beta: float, *, within: np.ndarray | None = None, mismatches: int = 0,
              ) -> Score:
        """P, R and F_β of the query given as genes (module docstring) for the positive
        clips ``positives`` (boolean), over the clips ``within`` (boolean; default all);
        ``mismatches``: tolerance of the keyframes (:func:`keyframe_tolerance`)."""
        return self.score_hits(self.hits(genes, gaps, mismatches), positives, beta,
                               within=within)

    def margins(self, genes: Sequence[Gene], gaps: Sequence[Bounds], positives: np.ndarray, *,
                mismatches: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """For every positive clip with a hit: frames from the clip's first frame to the
        first hit frame in it, and from the last hit frame in it to the clip's last frame
        (how far windows must reach out to hold the whole motion)."""
        d, s, e = self.hits(genes, gaps, mismatches)
        off = self.doc_offset
        a, b = s + off[d], e + off[d]
        end = self.clip_start + self.lengths - 1
        first = np.full(self.n_clips, -1, np.int64)
        last = np.full(self.n_clips, -1, np.int64)
        for x, y in zip(a.tolist(), b.tolist()):
            for c in {int(self.clip_of_frame[x]), int(self.clip_of_frame[y])}:
                lo = max(x, int(self.clip_start[c]))
                hi = min(y, int(end[c]))
                if first[c] < 0 or lo < first[c]:
                    first[c] = lo
                last[c] = max(last[c], hi)
        sel = positives & (first >= 0)
        return first[sel] - self.clip_start[sel], end[sel] - last[sel]

    def score_query(self, query, beta: float, *, within: np.ndarray | None = None) -> Score:
        """P, R and F_β of a :class:`~mtanno.keyframes.model.KeyframeQuery` (any, e.g. a
        hand-made one) for its class."""
        from mtanno.keyframes.search import search_index

        pos = self.positives(query.class_name)
        if not pos.any():
            raise MtannoError(f"class '{query.class_name}' has no training clips")
        h = search_index(self.index, query)
        return self.score_hits((h.doc, h.start, h.end), pos, beta, within=within)

    def score_hits(self, hits, positives: np.ndarray, beta: float, *,
                   within: np.ndarray | None = None) -> Score:
        """Score raw hits (doc, start, end) in the sequences (module docstring)."""
        d, s, e = hits
        off = self.doc_offset
        a, b = s + off[d], e + off[d]
        pos_pre, _ = self._prefixes(positives, within)
        support = int((pos_pre[b + 1] - pos_pre[a]).sum())
        inside = np.ones(self.n_clips, bool) if within is None else within
        owner = self.clip_of_frame[(a + b) // 2]
        owner = np.unique(owner[inside[owner]])
        found = np.zeros(self.n_clips, np.uint8)
        _kernels.mark_clips(a, b, self.clip_of_frame, self.clip_start + self.lengths, found)
        pos = positives & inside
        n_pos = int(pos.sum())
        n_found = int((found.astype(bool) & pos).sum())
        relevant = int(positives[owner].sum())
        P = relevant / len(owner) if len(owner) else 0.0
        R = n_found / n_pos if n_pos else 0.0
        return Score(P, R, f_beta(P, R, beta), n_found, n_pos, len(owner), relevant, support)
