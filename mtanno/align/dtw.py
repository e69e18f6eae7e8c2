"""Stage 2 of time alignment ([MRC05] §7): dynamic time warping inside an area of the cost matrix.

The cost matrix of motions A (n frames, rows) and B (m frames, columns) is computed only
inside an *area* (:class:`Area`): per row a the columns ``lo[a] .. hi[a]``. The area that
stage 1 (:mod:`mtanno.align.coarse`) derives from the matched segment pairs is a staircase
band along the coarse alignment; :func:`Area.full` is the whole matrix (classical DTW).

The recursion is classical DTW (docs/method.md §3.1): steps (1, 1), (1, 0), (0, 1), each
adding the local cost of the cell it enters, D(a, b) = c(a, b) + min(D(a−1, b−1),
D(a−1, b), D(a, b−1)); ties go to the diagonal, then to the step that advances A. The total
cost is the sum of the local costs along the path, the *mean cost* that sum divided by the
path's length. With weights per row and column (stage 1, where a row or column is a
segment and its weight its length in frames) a step adds the local cost times the weight of
what it enters: the row's weight for (1, 0), the column's for (0, 1), the larger of the two
for (1, 1) (a diagonal run through a block of equal costs visits max(rows, columns) cells);
the mean cost is then the total divided by the summed weights of the path's steps.

Local costs (docs/method.md §3.1 for DTW; [MRC05] §7 and Kovar and Gleicher's point-cloud
distance for the poses):

* ``positions`` — the mean over the joints of the Euclidean distance between two poses
  normalised for root translation, heading and body size (:func:`mtanno.align.poses.
  normalize_poses`), in leg lengths;
* ``features`` — the fraction of the chosen features in which two frames differ (Hamming
  distance / number of features), plus a tie-break that is at most half of one feature:
  :data:`FEATURE_TIE` / number of features times the difference of the two frames' relative
  positions in their segments (0 at a segment's first frame … 1 at its last). Features are
  constant inside a segment, so without it every path through a pair of segments would
  cost the same and DTW would take the diagonal-first one; with it the path crosses the
  pair from corner to corner, i.e. assumes an even pace inside each segment.

Only two rows of the accumulated cost are kept; the step chosen in each computed cell (one
byte) is kept for backtracking, so memory is one byte per computed cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mtanno.align import _kernels as _k
from mtanno.errors import MtannoError

__all__ = ["FEATURE_TIE", "MAX_CELLS", "Area", "WarpingPath", "local_costs", "path_agreement", "warp_codes",
           "warp_poses"]

#: Most cells one DTW computes (one byte of memory each for the backtracking).
MAX_CELLS = 600_000_000
#: Weight of the within-segment tie-break of the feature cost, times 1 / number of features.
FEATURE_TIE = 0.5


@dataclass(frozen=True)
class Area:
    """Cells of an n × m cost matrix that DTW computes: row a holds columns
    ``lo[a] .. hi[a]`` (0-based, inclusive). Valid areas (:meth:`check`) start in the
    corner (0, 0), end in (n − 1, m − 1), have ``lo`` and ``hi`` non-decreasing and
    consecutive rows touching or overlapping (``lo[a + 1] ≤ hi[a] + 1``), so a warping path
    runs through them."""

    lo: np.ndarray
    hi: np.ndarray
    m: int

    @property
    def n(self) -> int:
        return int(self.lo.shape[0])

    @property
    def cells(self) -> int:
        """Number of cells in the area."""
        return int(np.sum(self.hi - self.lo + 1))

    @property
    def fraction(self) -> float:
        """Cells in the area / cells of the whole matrix."""
        return self.cells / (self.n * self.m)

    @classmethod
    def full(cls, n: int, m: int) -> Area:
        """The whole n × m matrix."""
        return cls(np.zeros(n, dtype=np.int64), np.full(n, m - 1, dtype=np.int64), int(m))

    def contains(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Which cells (a[k], b[k]) lie in the area."""
        a = np.asarray(a, dtype=np.int64)
        b = np.asarray(b, dtype=np.int64)
        return (self.lo[a] <= b) & (b <= self.hi[a])

    def check(self) -> Area:
        """The area itself if valid (class docstring), else :class:`MtannoError`."""
        lo, hi, m = self.lo, self.hi, self.m
        if lo.ndim != 1 or lo.shape != hi.shape or lo.shape[0] < 1 or m < 1:
            raise MtannoError(f"an area needs lo and hi of one entry per row (≥ 1 row) and "
                              f"m ≥ 1 columns, got shapes {lo.shape}, {hi.shape} and m = {m}")
        if np.any(lo < 0) or np.any(hi >= m) or np.any(lo > hi):
            raise MtannoError(f"area rows must satisfy 0 ≤ lo ≤ hi < m = {m}")
        if lo[0] != 0 or hi[-1] != m - 1:
            raise MtannoError("the area must contain the first cell (0, 0) and the last "
                              "cell (n − 1, m − 1)")
        if np.any(np.diff(lo) < 0) or np.any(np.diff(hi) < 0) or np.any(lo[1:] > hi[:-1] + 1):
            raise MtannoError("the area must be a connected staircase: lo and hi "
                              "non-decreasing, lo[a + 1] ≤ hi[a] + 1")
        return self


@dataclass(frozen=True)
class WarpingPath:
    """A warping path from (0, 0) to (n − 1, m − 1) and what computing it took.

    Attributes
    ----------
    a, b:
        (k,) int64: the path's cells, 0-based frames of A and of B, in order.
    total:
        Accumulated cost D(n − 1, m − 1) (module docstring).
    weight:
        Summed step weights of the path (its length for frames).
    cells:
        Cells of the cost matrix computed (the area's size).
    n, m:
        Frames (or segments) of A and B.
    """

    a: np.ndarray
    b: np.ndarray
    total: float
    weight: float
    cells: int
    n: int
    m: int

    @property
    def mean(self) -> float:
        """Total cost / weight: the mean local cost along the path."""
        return self.total / self.weight

    @property
    def fraction(self) -> float:
        """Computed cells / cells of the whole n × m matrix."""
        return self.cells / (self.n * self.m)


def _weights(w, n: int, what: str) -> np.ndarray:
    if w is None:
        return np.ones(n, dtype=np.float64)
    w = np.ascontiguousarray(w, dtype=np.float64)
    if w.shape != (n,) or not np.all(np.isfinite(w)) or np.any(w < 0):
        raise MtannoError(f"{what} must be {n} finite non-negative numbers")
    return w


def _run(kind: int, PA, PB, CA, CB, nfeat: float, tie: float, n: int, m: int,
         area: Area | None, wa, wb) -> WarpingPath:
    if n < 1 or m < 1:
        raise MtannoError(f"cannot align an empty motion ({n} and {m} frames)")
    area = (Area.full(n, m) if area is None else area).check()
    if area.n != n or area.m != m:
        raise MtannoError(f"the area is {area.n} × {area.m} but the motions have {n} and "
                          f"{m} frames")
    lo = np.ascontiguousarray(area.lo, dtype=np.int64)
    hi = np.ascontiguousarray(area.hi, dtype=np.int64)
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(hi - lo + 1, out=offsets[1:])
    cells = int(offsets[-1])
    if cells > MAX_CELLS:
        raise MtannoError(f"the area has {cells} cells, more than the {MAX_CELLS} one DTW "
                          "computes (one byte each); restrict it (a smaller {band}, or not "
                          "{full})", options=("band", "full"))
    wa = _weights(wa, n, "weights_a")
    wb = _weights(wb, m, "weights_b")
    steps = np.empty(cells, dtype=np.uint8)
    total = float(_k.dtw_area(lo, hi, offsets, wa, wb, kind, PA, PB, CA, CB, nfeat, tie,
                              steps))
    if not np.isfinite(total):  # a valid area always has a path; costs were not finite
        raise MtannoError("the local costs are not finite (NaN or infinite positions?)")
    out_a = np.empty(n + m - 1, dtype=np.int64)
    out_b = np.empty(n + m - 1, dtype=np.int64)
    first = _k.backtrack(lo, offsets, steps, m - 1, out_a, out_b)
    a, b = out_a[first:].copy(), out_b[first:].copy()
    # step weights: the row's for (1, 0), the column's for (0, 1), the larger for (1, 1)
    w = np.maximum(wa[a], wb[b])
    w[1:] = np.where(a[1:] == a[:-1], wb[b[1:]], np.where(b[1:] == b[:-1], wa[a[1:]], w[1:]))
    return WarpingPath(a, b, total, float(w.sum()), cells, n, m)


def _poses(P, what: str) -> np.ndarray:
    P = np.asarray(P, dtype=np.float64)
    if P.ndim != 3 or P.shape[2] != 3 or P.shape[1] < 1:
        raise MtannoError(f"{what} must be (frames × joints × 3) positions, got shape "
                          f"{P.shape}")
    if not np.all(np.isfinite(P)):
        raise MtannoError(f"{what} contain NaN or infinite values")
    return np.ascontiguousarray(P.reshape(P.shape[0], -1))


def warp_poses(PA: np.ndarray, PB: np.ndarray, *, area: Area | None = None) -> WarpingPath:
    """DTW of two pose sequences with the pose distance (module docstring).

    Parameters
    ----------
    PA, PB:
        (n × J × 3) and (m × J × 3) joint positions, normalised as by
        :func:`mtanno.align.poses.normalize_poses` (the unit of the cost is theirs), one
        pose per frame at the analysis rate; the same J joints in the same order.
    area:
        The cells to compute (default: the whole matrix, classical DTW).
    """
    A = _poses(PA, "positions of A")
    B = _poses(PB, "positions of B")
    if A.shape[1] != B.shape[1]:
        raise MtannoError(f"the motions have {A.shape[1] // 3} and {B.shape[1] // 3} joints; "
                          "poses can only be compared joint by joint")
    z = np.zeros(1, dtype=np.int64)
    return _run(_k.POSE, A, B, z, z, 1.0, 0.0, A.shape[0], B.shape[0], area, None, None)


def warp_codes(CA: np.ndarray, CB: np.ndarray, *, n_features: int, area: Area | None = None,
               weights_a: np.ndarray | None = None, weights_b: np.ndarray | None = None,
               phases: tuple[np.ndarray, np.ndarray] | None = None, tie: float = 0.0,
               ) -> WarpingPath:
    """DTW of two feature-code sequences with the Hamming distance / ``n_features``.

    Parameters
    ----------
    CA, CB:
        (n,) and (m,) int64 codes, bit k = feature k of the chosen features
        (:func:`mtanno.index.core.frame_codes`), one per frame or per segment.
    n_features:
        Number of features in the codes (1 … 62).
    area:
        The cells to compute (default: the whole matrix).
    weights_a, weights_b:
        Weight of each row and column (default 1: frames; segment lengths in stage 1).
    phases, tie:
        Relative positions (0 … 1) of the frames of A and B in their segments
        (:meth:`mtanno.align.coarse.Segments.phases`) and the weight of their difference
        in the local cost (default none): it breaks ties inside runs of equal features, so
        that the path crosses a pair of segments from corner to corner (module docstring).
    """
    if not 1 <= n_features <= 62:
        raise MtannoError(f"feature codes need 1 to 62 features, got {n_features}")
    A = np.ascontiguousarray(CA, dtype=np.int64)
    B = np.ascontiguousarray(CB, dtype=np.int64)
    if A.ndim != 1 or B.ndim != 1:
        raise MtannoError("feature codes must be one-dimensional")
    for C in (A, B):
        if C.size and (C.min() < 0 or C.max() >> n_features):
            raise MtannoError(f"feature codes must lie in [0, 2**{n_features})")
    if phases is None:
        PA, PB, tie = np.zeros((A.shape[0], 1)), np.zeros((B.shape[0], 1)), 0.0
    else:
        PA, PB = (np.ascontiguousarray(np.asarray(p, dtype=np.float64).reshape(-1, 1))
                  for p in phases)
        if PA.shape[0] != A.shape[0] or PB.shape[0] != B.shape[0]:
            raise MtannoError("phases must have one value per code")
        if not (np.isfinite(tie) and tie >= 0):
            raise MtannoError(f"tie must be a finite non-negative weight, got {tie!r}")
    return _run(_k.CODES, PA, PB, A, B, float(n_features), float(tie), A.shape[0], B.shape[0],
                area, weights_a, weights_b)


def _popcount(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=np.int64)
    out = np.zeros(x.shape, dtype=np.int64)
    for k in range(63):
        out += (x >> k) & 1
    return out


def local_costs(path: WarpingPath, *, poses: tuple[np.ndarray, np.ndarray] | None = None,
                codes: tuple[np.ndarray, np.ndarray] | None = None,
                n_features: int | None = None,
                phases: tuple[np.ndarray, np.ndarray] | None = None,
                tie: float = 0.0) -> np.ndarray:
    """Local cost of every cell of ``path``: give the two pose sequences (``poses``) or the
    two code sequences, the number of features and the phases and tie weight
    (``codes``, ``n_features``, ``phases``, ``tie``) it was computed from."""
    if poses is not None:
        A, B = (np.asarray(P, dtype=np.float64) for P in poses)
        _check_path(path, len(A), len(B))
        return np.linalg.norm(A[path.a] - B[path.b], axis=2).mean(axis=1)
    if codes is None or n_features is None:
        raise MtannoError("local_costs needs poses, or codes and n_features")
    CA, CB = (np.asarray(C, dtype=np.int64) for C in codes)
    _check_path(path, len(CA), len(CB))
    out = _popcount(CA[path.a] ^ CB[path.b]) / n_features
    if phases is not None:
        out = out + tie * np.abs(np.asarray(phases[0])[path.a] - np.asarray(phases[1])[path.b])
    return out


def _check_path(path: WarpingPath, n: int, m: int) -> None:
    """The cells of ``path`` lie in an n × m matrix (numpy takes a negative frame from the
    end without a word)."""
    a, b = np.asarray(path.a), np.asarray(path.b)
    if a.ndim != 1 or a.shape != b.shape or not len(a) or a.min() < 0 or a.max() >= n \
            or b.min() < 0 or b.max() >= m:
        raise MtannoError(f"the warping path's cells must lie in the {n} × {m} matrix of "
                          "its motions")


def _intervals(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """(n × 2): first and last b matched with each a (paths are monotone)."""
    out = np.empty((n, 2), dtype=np.int64)
    first = np.r_[True, a[1:] != a[:-1]]
    last = np.r_[a[1:] != a[:-1], True]
    out[a[first], 0] = b[first]
    out[a[last], 1] = b[last]
    return out


def path_agreement(p: WarpingPath, q: WarpingPath, *, tolerance: int = 0) -> float:
    """Fraction of the frames (of A and of B together) that two warping paths of the same
    matrix match alike: a frame of A agrees when the first and the last frame of B matched
    with it differ by at most ``tolerance`` frames between the paths (0: the same frames),
    and likewise for a frame of B."""
    if (p.n, p.m) != (q.n, q.m):
        raise MtannoError(f"paths of different matrices ({p.n} × {p.m}, {q.n} × {q.m})")
    _check_path(p, p.n, p.m)
    _check_path(q, q.n, q.m)
    same_a = np.all(np.abs(_intervals(p.a, p.b, p.n) - _intervals(q.a, q.b, q.n))
                    <= tolerance, axis=1)
    same_b = np.all(np.abs(_intervals(p.b, p.a, p.m) - _intervals(q.b, q.a, q.m))
                    <= tolerance, axis=1)
    return float((same_a.sum() + same_b.sum()) / (p.n + p.m))
