"""Stage 1 of time alignment ([MRC05] §7): a coarse, segment-wise alignment of two motions.

Each motion is cut into its adaptive segments over the chosen features ([MRC05] §4; the
segments of the relational index, :func:`mtanno.index.core.segment`): maximal runs of frames
with the same feature vector. Two motions with the same progression of feature vectors
would be aligned segment by segment; real performances differ — one actor lifts a heel the
other keeps down, so one motion has a short segment the other lacks, or two vectors differ
in a feature.

The two segment sequences are therefore matched by the same DTW recursion as stage 2
(:mod:`mtanno.align.dtw`) run on the segments instead of the frames: the local cost of a
segment pair is the fraction of the chosen features in which their vectors differ, and each
segment weighs its length in frames. A segment matched to two or more consecutive segments
of the other motion is how a *merge* is expressed: a segment one motion lacks (its
neighbours on both sides match one longer segment of the other motion) is merged into the
neighbouring match, at a price of its length times the features in which it differs from
the segment it is matched with, so short deviations are absorbed cheaply and long ones are
matched where their vectors agree best. Equal progressions are matched one to one at no
cost. The segment sequences are a few percent of the frames long ([MRC05]: 3–12 %), so this
costs a small fraction of the frame matrix.

Every matched pair (i, j) spans the rectangle of frames of A's segment i times frames of
B's segment j; their union, widened by ``band`` frames on every side so that segment
boundaries do not force the path ([MRC05] Fig. 11: the gray area), is the :class:`~mtanno.
align.dtw.Area` stage 2 computes. Consecutive pairs' rectangles touch at least at a corner,
so the union is a connected staircase from (0, 0) to (n − 1, m − 1).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from mtanno.align import _kernels as _k
from mtanno.align.dtw import Area, WarpingPath, warp_codes
from mtanno.errors import MtannoError
from mtanno.index.core import MAX_GROUP_FEATURES, segment

__all__ = ["ALL", "CoarseAlignment", "Segments", "coarse_alignment", "pair_area",
           "select_features"]

#: Group name meaning every feature of the set.
ALL = "all"
#: Group name meaning the features that measure no velocity (:func:`pose_features`).
POSE = "pose"
#: Feature measures that compare velocities (mtanno.features.table): they depend on how
#: fast a motion is performed, which is what alignment evens out.
VELOCITY_MEASURES = frozenset({"move_plane", "move_dir", "move_diff", "fast", "heading_rate"})


def pose_features(names: Sequence[str]) -> tuple[str, ...]:
    """The features among ``names`` that describe a pose alone (no velocity measure), as
    defined by the built-in feature sets' tables."""
    from mtanno.features import FEATURE_SETS

    measure = {f.name: f.measure for fs in FEATURE_SETS.values() for f in fs.features}
    return tuple(n for n in names if n in measure and measure[n] not in VELOCITY_MEASURES)


@dataclass(frozen=True)
class Segments:
    """Adaptive segments of one motion ([MRC05] §4): 0-based start frames, lengths in
    frames and feature codes (bit k = k-th chosen feature)."""

    start: np.ndarray
    length: np.ndarray
    code: np.ndarray

    @classmethod
    def of(cls, codes: np.ndarray) -> Segments:
        """The segments of per-frame codes."""
        s, n, c = segment(np.asarray(codes, dtype=np.int64))
        return cls(s.astype(np.int64), n.astype(np.int64), c.astype(np.int64))

    @property
    def end(self) -> np.ndarray:
        """Last frame of each segment (0-based, inclusive)."""
        return self.start + self.length - 1

    def __len__(self) -> int:
        return int(self.start.shape[0])

    def phases(self) -> np.ndarray:
        """Relative position of every frame in its segment: (t − start + ½) / length, in
        (0, 1)."""
        idx = np.repeat(np.arange(len(self)), self.length)
        t = np.arange(idx.shape[0])
        return (t - self.start[idx] + 0.5) / self.length[idx]


@dataclass(frozen=True)
class CoarseAlignment:
    """The result of stage 1.

    Attributes
    ----------
    segments_a, segments_b:
        The two motions' segments.
    pairs:
        The segment warping path: matched segment pairs, ``pairs.a[k]`` of A with
        ``pairs.b[k]`` of B; its ``mean`` is the length-weighted mean fraction of differing
        features.
    area:
        The union of the pairs' rectangles widened by ``band`` frames.
    band:
        The widening in frames.
    """

    segments_a: Segments
    segments_b: Segments
    pairs: WarpingPath
    area: Area
    band: int


def select_features(names: Sequence[str], groups: Mapping[str, Sequence[str]], *,
                    features: Sequence[str] | None = None, group: str | None = None,
                    ) -> tuple[str, ...]:
    """The features alignment uses: ``features`` by name, or the features of ``group`` (a
    group of the feature set, or ``"all"``); default all. At most 62 (codes are int64)."""
    if features is not None and group is not None:
        raise MtannoError("give features or a group, not both")
    if features is not None:
        chosen = tuple(features)
        if not chosen:
            raise MtannoError("no features given")
        for f in chosen:
            if f not in names:
                raise MtannoError(f"unknown feature '{f}' (features of this set: "
                                  f"{', '.join(names[:4])}, …)")
        if len(set(chosen)) != len(chosen):
            raise MtannoError("a feature is named twice")
    elif group is None or group == ALL:
        chosen = tuple(names)
    elif group == POSE:
        chosen = pose_features(names)
        if not chosen:
            raise MtannoError("no pose features (features of a built-in feature set that "
                              "measure no velocity) among these features")
    elif group in groups:
        chosen = tuple(groups[group])
    else:
        raise MtannoError(f"unknown group '{group}' (groups of this feature set: "
                          f"{', '.join([*groups, ALL, POSE])})")
    if len(chosen) > MAX_GROUP_FEATURES:
        raise MtannoError(f"{len(chosen)} features chosen; alignment takes at most "
                          f"{MAX_GROUP_FEATURES}")
    return chosen


def _check_band(band) -> int:
    if isinstance(band, bool) or not isinstance(band, (int, np.integer)) or band < 0:
        raise MtannoError(f"band must be a non-negative whole number of frames, got {band!r}")
    return int(band)


def pair_area(segments_a: Segments, segments_b: Segments, pairs: WarpingPath, *,
              band: int) -> Area:
    """The union of the rectangles of the matched segment pairs, each widened by ``band``
    frames on all four sides and clipped to the matrix (module docstring)."""
    band = _check_band(band)
    start_a, end_a = _segment_frames(segments_a, "A")
    start_b, end_b = _segment_frames(segments_b, "B")
    pa = np.ascontiguousarray(pairs.a, np.int64)
    pb = np.ascontiguousarray(pairs.b, np.int64)
    # the kernel reads the segments by these numbers, unchecked
    if pa.ndim != 1 or pa.shape != pb.shape or not len(pa) or pa.min() < 0 \
            or pa.max() >= len(start_a) or pb.min() < 0 or pb.max() >= len(start_b):
        raise MtannoError(f"segment pairs must number segments of A (0..{len(start_a) - 1}) "
                          f"and of B (0..{len(start_b) - 1}), one of each per pair")
    n = int(end_a[-1] + 1)
    lo = np.empty(n, dtype=np.int64)
    hi = np.empty(n, dtype=np.int64)
    _k.pair_area(pa, pb, start_a, end_a, start_b, end_b, band, lo, hi)
    return Area(lo, hi, int(end_b[-1] + 1)).check()


def _segment_frames(segments: Segments, what: str) -> tuple[np.ndarray, np.ndarray]:
    """(first, last frames) of a motion's segments, int64, at least one segment."""
    start = np.ascontiguousarray(segments.start, np.int64)
    length = np.ascontiguousarray(segments.length, np.int64)
    if start.ndim != 1 or start.shape != length.shape or not len(start):
        raise MtannoError(f"segments of {what} need one start frame per length (at least "
                          f"one segment), got shapes {start.shape} and {length.shape}")
    return start, start + length - 1


def coarse_alignment(codes_a: np.ndarray, codes_b: np.ndarray, *, n_features: int,
                     band: int) -> CoarseAlignment:
    """Stage 1 on per-frame feature codes (module docstring).

    Parameters
    ----------
    codes_a, codes_b:
        (n,) and (m,) int64 codes of the chosen features per analysis frame
        (:func:`mtanno.index.core.frame_codes`); both non-empty.
    n_features:
        Number of chosen features (1 … 62).
    band:
        Frames by which each matched rectangle is widened on every side.
    """
    band = _check_band(band)
    if len(codes_a) == 0 or len(codes_b) == 0:
        raise MtannoError(f"cannot align an empty motion ({len(codes_a)} and {len(codes_b)} "
                          "frames)")
    sa, sb = Segments.of(codes_a), Segments.of(codes_b)
    pairs = warp_codes(sa.code, sb.code, n_features=n_features,
                       weights_a=sa.length.astype(np.float64),
                       weights_b=sb.length.astype(np.float64))
    return CoarseAlignment(sa, sb, pairs, pair_area(sa, sb, pairs, band=band), band)
