"""Matching a quantized motion template against documents: the distance function Δ.

Subsequence DTW with a masked local cost ([MR06] §5.2, [MBS09] §4; docs/method.md §3.4).
For a quantized template X (f × K, entries 0, 1 and the wildcard 0.5) and a document Y
(f × L, 0/1, one column per 30 Hz frame), Δ(ℓ) is the cost of the cheapest warping path
that ends at document frame ℓ and covers the whole template, starting at any frame
a_ℓ ≤ ℓ. Small values mark the END of a match; ``start`` holds a_ℓ.

Two variants:

``"reference"`` (default)
    What the reference implementation computes (docs/method/features.md §A, last paragraphs;
    ``../shared/data/reference/retrieval/README.md``): the template is first expanded by its
    weights (column i repeated max(1, round(w_i)) times, round half away from zero, each copy
    of weight w_i / copies); the local cost of expanded column i against a document frame is
    ``m / n * ((w_i + 1) / (2 * max(1, nnz_i)))`` with m the disagreements over the nnz_i
    non-wildcard rows and n the expanded length; D(1, ℓ) = C(1, ℓ); for i ≥ 2 the predecessor
    with the smallest D among the steps is chosen (ties: the first step) and the chosen
    step's weight times C(i, ℓ) is added; Δ(ℓ) = D(n, ℓ).
``"paper"``
    docs/method.md §3.4 as written: c(k, ℓ) = mean disagreement over the non-wildcard rows
    (0 for an all-wildcard column), no expansion, no weight factor; D(k, ℓ) = min over the
    steps of D(predecessor) + weight(step) · c(k, ℓ) (ties: the first step); Δ(ℓ) = D(K, ℓ)/K.

Steps are (template, document) increments; the default is (1,1), (1,2), (2,1) with weights
1, 1, 2 ([MR06] §5.2). A cell no path reaches is +∞ (the reference writes NaN); ``start`` is then
−1. Paths never cross a document boundary.

The kernels stream over the document: they keep only a few columns of D and of the start
pointers (the last max(Δj)+1, or four for the default steps, which are done two document
frames at a time); a_ℓ is propagated forward with the DP, so there is no backtracking matrix
and the working memory is O(K) whatever the document length. With the default steps a
path climbs at most two template rows per frame, so near the start of a range the upper
rows cannot be reached yet and near its end the lower rows cannot reach the last row any
more; those cells are not computed (exact: no path to a match end passes them), which
saves about a sixth of the work in windows a few template lengths long. The outputs are the two
length-L arrays (plus the packed frames, 8 bytes per frame, while matching).

Features are bit-packed (one uint64 per frame for f ≤ 64) and each template column becomes
a (mask of non-wildcard rows, value bits) pair, so the disagreement count is
``popcount((frame ^ value) & mask)``; the cost itself is looked up in a per-column table
indexed by that count, which keeps the floating-point arithmetic exactly that of the
formulas above.
"""

from __future__ import annotations

from collections.abc import Sequence

import numba
import numpy as np

from mtanno.errors import MtannoError
from mtanno.util._bits import popcount64 as _popcount64

__all__ = ["DEFAULT_STEPS", "DEFAULT_STEP_WEIGHTS", "VARIANTS", "PreparedTemplate",
           "check_spans", "column_repeats", "match_documents", "match_lengths", "match_template"]

DEFAULT_STEPS: tuple[tuple[int, int], ...] = ((1, 1), (1, 2), (2, 1))
DEFAULT_STEP_WEIGHTS: tuple[float, ...] = (1.0, 1.0, 2.0)
VARIANTS = ("reference", "paper")


@numba.njit(cache=True)
def _pack_frames(X, out):
    """Bit-pack a (features × frames) 0/1 uint8 matrix: bit i % 64 of ``out[j, i // 64]`` = X[i, j]."""
    f, n = X.shape
    block = 2048  # frames per block: the block's words stay in L1 while the rows pass
    buf = np.empty(block, np.uint64)
    for j0 in range(0, n, block):
        m = min(n, j0 + block) - j0
        for q in range(out.shape[1]):
            buf[:m] = 0
            for i in range(64 * q, min(f, 64 * q + 64)):
                sh = np.uint64(i & 63)
                x = X[i, j0:j0 + m]
                for j in range(m):
                    buf[j] |= np.uint64(x[j]) << sh
            out[j0:j0 + m, q] = buf[:m]


@numba.njit(cache=True, inline="always")
def _cell(c, p0, p1, p2, s0, s1, s2, by_pred, e0, e1, e2, a0, a1, a2):
    """One cell of :func:`_dtw_default_steps` from its predecessors (D, start) by the steps
    (1,1), (1,2), (2,1) and its local cost c: the step ranked first by D + sel·c (ties:
    the first step; ``by_pred``: sel = 0) gives (D + add·c, its start)."""
    if by_pred:
        x0, x1, x2 = p0, p1, p2
    else:
        x0, x1, x2 = p0 + e0 * c, p1 + e1 * c, p2 + e2 * c
    t = x1 < x0  # selects, not branches
    x = x1 if t else x0
    p = p1 if t else p0
    w = a1 if t else a0
    sv = s1 if t else s0
    t = x2 < x
    p = p2 if t else p
    w = a2 if t else w
    sv = s2 if t else sv
    return p + w * c, sv


@numba.njit(cache=True)
def _dtw_default_steps(doc, starts, ends, absolute, masks, vals, table, sel, add, divisor, delta,
                       start):
    """Streaming subsequence DTW, steps (1,1), (1,2), (2,1), f ≤ 64 (one word per frame).

    ``doc`` (L,) packed frames; documents (or spans of one document) are the ranges
    [starts[d], ends[d]) — frames outside every range are left untouched; ``masks``,
    ``vals`` (K,) packed template columns; ``table[k, m]`` the local cost of column k for m
    disagreements. A candidate step s is ranked by D(pred) + sel[s]·c and, when chosen, gives
    D(pred) + add[s]·c (reference: sel = 0, i.e. the smallest predecessor wins; paper:
    sel = add); ties go to the first step. Writes Δ = D(K, ℓ)/divisor and the 0-based start
    frame into ``delta`` and ``start`` (relative to its range, or an index into ``doc`` when
    ``absolute``).

    Two document frames j, j+1 are done per pass over the rows: cell (k, j+1) takes its
    predecessors (k-1, j) and (k-2, j) from registers and shares the load of (k-1, j-1) with
    cell (k, j), which halves the memory traffic. Columns carry two unreachable padding rows
    in front; start pointers are float64 (exact below 2**53) so that all selects stay in one
    register type. An unreachable cell has D = inf and start -1 (its first candidate is
    unreachable too, so the -1 propagates).
    """
    # one kernel: the DTW recurrence with the three default steps unrolled; a generic step
    # loop (the other kernel) is what this specialisation avoids
    K = masks.shape[0]
    inf = np.inf
    u1, u2 = np.uint64(1), np.uint64(2)
    Dc = np.full(K + 2, inf)  # column j
    Dn = np.full(K + 2, inf)  # column j + 1
    D1 = np.full(K + 2, inf)  # column j - 1
    D2 = np.full(K + 2, inf)  # column j - 2
    Sc = np.full(K + 2, -1.0)
    Sn = np.full(K + 2, -1.0)
    S1 = np.full(K + 2, -1.0)
    S2 = np.full(K + 2, -1.0)
    c0 = np.empty(K)
    c1 = np.empty(K)
    e0, e1, e2 = sel[0], sel[1], sel[2]
    a0, a1, a2 = add[0], add[1], add[2]
    by_pred = e0 == 0.0 and e1 == 0.0 and e2 == 0.0
    for d in range(starts.shape[0]):
        b = starts[d]
        n = ends[d] - b
        shift = b if absolute else 0
        Dc[:] = inf  # rows a pass does not compute keep ∞ until computed
        Dn[:] = inf
        D1[:] = inf
        D2[:] = inf
        Sc[:] = -1.0
        Sn[:] = -1.0
        S1[:] = -1.0
        S2[:] = -1.0
        for j in range(0, n, 2):
            y0 = doc[b + j]
            y1 = doc[b + j + 1] if j + 1 < n else y0  # odd length: a dummy last column
            # rows below lo cannot reach the last row by the range's end, rows from hi on
            # cannot be reached yet (a path climbs at most two rows per frame): neither is
            # computed (in a window of a few template lengths, a sixth of the cells)
            lo = max(1, K - 1 - 2 * (n - 1 - j))
            hi = min(K, 2 * j + 3)
            c0[0] = table[0, _popcount64((y0 ^ vals[0]) & masks[0])]
            c1[0] = table[0, _popcount64((y1 ^ vals[0]) & masks[0])]
            Dc[2] = c0[0]
            Sc[2] = j
            Dn[2] = c1[0]
            Sn[2] = j + 1
            dm1, sm1 = (c0[0], np.float64(j)) if lo == 1 else (inf, -1.0)  # (k-1, j)
            dm2, sm2 = inf, -1.0  # (k-2, j)
            q, qs = D1[lo], S1[lo]  # (k-2, j-1)
            # cell (k, j): predecessors (k-1, j-1), (k-1, j-2), (k-2, j-1); cell (k, j+1):
            # (k-1, j), (k-1, j-1), (k-2, j). The same loop twice: over all rows with
            # signed indices, and over rows lo … hi - 1 with unsigned ones (with signed
            # indices and a bound other than K, numba's loop runs 3-4x slower per cell)
            if lo == 1 and hi == K:
                for k in range(1, K):
                    c0[k] = table[k, _popcount64((y0 ^ vals[k]) & masks[k])]
                    c1[k] = table[k, _popcount64((y1 ^ vals[k]) & masks[k])]
                for k in range(1, K):
                    p0, s0 = D1[k + 1], S1[k + 1]
                    d0, sv = _cell(c0[k], p0, D2[k + 1], q, s0, S2[k + 1], qs, by_pred,
                                   e0, e1, e2, a0, a1, a2)
                    dn, rs = _cell(c1[k], dm1, p0, dm2, sm1, s0, sm2, by_pred,
                                   e0, e1, e2, a0, a1, a2)
                    Dc[k + 2] = d0
                    Sc[k + 2] = sv
                    Dn[k + 2] = dn
                    Sn[k + 2] = rs
                    dm2, sm2 = dm1, sm1
                    dm1, sm1 = d0, sv
                    q, qs = p0, s0
            else:
                for kk in range(lo, hi):
                    k = np.uint64(kk)
                    c0[k] = table[k, _popcount64((y0 ^ vals[k]) & masks[k])]
                    c1[k] = table[k, _popcount64((y1 ^ vals[k]) & masks[k])]
                for kk in range(lo, hi):
                    k = np.uint64(kk)
                    p0, s0 = D1[k + u1], S1[k + u1]
                    d0, sv = _cell(c0[k], p0, D2[k + u1], q, s0, S2[k + u1], qs, by_pred,
                                   e0, e1, e2, a0, a1, a2)
                    dn, rs = _cell(c1[k], dm1, p0, dm2, sm1, s0, sm2, by_pred,
                                   e0, e1, e2, a0, a1, a2)
                    Dc[k + u2] = d0
                    Sc[k + u2] = sv
                    Dn[k + u2] = dn
                    Sn[k + u2] = rs
                    dm2, sm2 = dm1, sm1
                    dm1, sm1 = d0, sv
                    q, qs = p0, s0
            delta[b + j] = Dc[K + 1] / divisor
            sj = np.int64(Sc[K + 1])
            start[b + j] = sj + shift if sj >= 0 else sj
            if j + 1 < n:
                delta[b + j + 1] = Dn[K + 1] / divisor
                sj = np.int64(Sn[K + 1])
                start[b + j + 1] = sj + shift if sj >= 0 else sj
            Dc, Dn, D2, D1 = D2, D1, Dc, Dn
            Sc, Sn, S2, S1 = S2, S1, Sc, Sn


@numba.njit(cache=True)
def _dtw_general(doc, starts, ends, absolute, masks, vals, table, di, dj, sel, add, divisor, delta,
                 start):
    """Streaming subsequence DTW for any steps (di[s], dj[s]) and any number of words per frame.

    Same contract as :func:`_dtw_default_steps`, with ``doc`` (L, W) and ``masks``, ``vals``
    (K, W). Keeps a ring of max(dj) + 1 columns; steps with dj = 0 read the current column,
    whose rows above are already done (rows run upwards).
    """
    K, W = masks.shape
    ns = di.shape[0]
    R = 1
    for s in range(ns):
        R = max(R, dj[s] + 1)
    inf = np.inf
    D = np.empty((R, K))
    S = np.empty((R, K), np.int64)
    for d in range(starts.shape[0]):
        b = starts[d]
        n = ends[d] - b
        shift = b if absolute else 0
        D[:] = inf
        S[:] = -1
        for j in range(n):
            slot = j % R
            for k in range(K):
                m = 0
                for q in range(W):
                    m += _popcount64((doc[b + j, q] ^ vals[k, q]) & masks[k, q])
                c = table[k, m]
                if k == 0:
                    D[slot, 0] = c
                    S[slot, 0] = j
                    continue
                best = inf
                val = inf
                bs = -1
                for s in range(ns):
                    pk = k - di[s]
                    if pk < 0 or j < dj[s]:
                        continue
                    ps = (j - dj[s]) % R
                    p = D[ps, pk]
                    x = p + sel[s] * c
                    if x < best:
                        best = x
                        val = p + add[s] * c
                        bs = S[ps, pk]
                D[slot, k] = val
                S[slot, k] = bs if val < inf else -1
            delta[b + j] = D[slot, K - 1] / divisor
            sj = S[slot, K - 1]
            start[b + j] = sj + shift if sj >= 0 else sj


# ---------------------------------------------------------------------------------------------
# input checks and template preparation


#: Most template columns (after the reference variant's expansion by the weights) matching
#: takes: more is no real template and would exhaust memory.
MAX_TEMPLATE_COLUMNS = 1_000_000


def _check_template(values, weights) -> tuple[np.ndarray, np.ndarray]:
    try:
        V = np.asarray(values, dtype=np.float64)
        w = np.asarray(weights, dtype=np.float64)
    except (TypeError, ValueError):
        raise MtannoError("template values and weights must be numeric arrays") from None
    if V.ndim != 2 or V.shape[0] < 1 or V.shape[1] < 1:
        raise MtannoError(f"template values must be a non-empty (features × columns) matrix, "
                          f"got shape {V.shape}")
    if not np.all((V == 0.0) | (V == 1.0) | (V == 0.5)):
        raise MtannoError("template values must be quantized: every entry 0, 1 or 0.5 "
                          "(the wildcard); quantize the template first")
    if w.shape != (V.shape[1],):
        raise MtannoError(f"template weights must have one entry per column ({V.shape[1]}), "
                          f"got shape {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise MtannoError("template weights must be finite and non-negative")
    return V, w


def _check_document(X, f: int, what: str = "document") -> np.ndarray:
    A = np.asarray(X)
    if A.ndim != 2 or A.shape[0] != f:
        raise MtannoError(f"{what} must be a ({f} features × frames) matrix like the template, "
                          f"got shape {A.shape}")
    if A.dtype == np.bool_:
        return A.view(np.uint8)
    if A.dtype == np.uint8:
        if A.size and A.max() > 1:
            raise MtannoError(f"{what} features must be 0 or 1")
        return A
    if not (np.issubdtype(A.dtype, np.integer) or np.issubdtype(A.dtype, np.floating)):
        raise MtannoError(f"{what} features must be 0/1 numbers, got dtype {A.dtype}")
    if A.size and not np.all((A == 0) | (A == 1)):
        raise MtannoError(f"{what} features must be 0 or 1")
    return A.astype(np.uint8)


def _check_steps(steps, step_weights) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    try:
        st = np.asarray(steps, dtype=np.float64)
        sw = np.asarray(step_weights, dtype=np.float64)
    except (TypeError, ValueError):
        raise MtannoError("steps must be (template, document) integer pairs and step_weights "
                          "numbers") from None
    if st.ndim != 2 or st.shape[1] != 2 or st.shape[0] < 1:
        raise MtannoError(f"steps must be a non-empty list of (template, document) pairs, "
                          f"got {steps!r}")
    if not np.all(np.isfinite(st)) or np.any(st != np.round(st)) or np.any(st < 0):
        raise MtannoError(f"steps must be non-negative integers, got {steps!r}")
    if np.any((st[:, 0] == 0) & (st[:, 1] == 0)):
        raise MtannoError("step (0, 0) is not allowed")
    if sw.shape != (st.shape[0],):
        raise MtannoError(f"step_weights must have one weight per step ({st.shape[0]}), "
                          f"got {step_weights!r}")
    if not np.all(np.isfinite(sw)) or np.any(sw < 0):
        raise MtannoError("step weights must be finite and non-negative")
    return st[:, 0].astype(np.int64), st[:, 1].astype(np.int64), sw


def column_repeats(weights: np.ndarray) -> np.ndarray:
    """How often the reference matching repeats each template column
    (docs/method/features.md §A): max(1, round(w_i)), round half away from zero (weights
    are non-negative). Their sum is the number of columns matched, what matching costs per
    document frame. Floats: a template with absurd weights can be told (and refused) before
    counting overflows."""
    w = np.asarray(weights, dtype=np.float64)
    return np.maximum(1.0, np.floor(w + 0.5))


def match_lengths(weights: np.ndarray, *, variant: str = "reference",
                  steps: Sequence[tuple[int, int]] = DEFAULT_STEPS) -> tuple[int, int | None]:
    """The shortest and the longest stretch of document frames (at 30 Hz) that one match of
    a template with these column ``weights`` can cover: its warping path runs from the
    first to the last template column (the reference variant's expanded columns,
    :func:`column_repeats`; the paper variant's K columns) by ``steps`` (template, document)
    increments ([MR06] §5.2). With the default steps (1,1), (1,2), (2,1) a match over n
    columns covers n // 2 + 1 to 2n − 1 frames: a performance much faster or slower than
    the template cannot match at all (``mtanno mt scale`` makes a time-scaled copy). None
    for the longest: a step that advances the document only makes it unbounded."""
    if variant not in VARIANTS:
        raise MtannoError(f"unknown matching variant {variant!r} (choose from "
                          f"{', '.join(VARIANTS)})")
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.size == 0 or not np.all(np.isfinite(w)) or np.any(w < 0):
        raise MtannoError("template weights must be a non-empty 1-D array of finite numbers ≥ 0")
    reps = column_repeats(w).sum() if variant == "reference" else float(w.size)
    if reps > 10_000_000:
        raise MtannoError(f"template weights expand to {reps:g} columns, more than 10⁷")
    n = int(reps)
    di, dj, _ = _check_steps(steps, [1.0] * len(steps))
    big = np.iinfo(np.int64).max // 4
    lo = np.full(n, big, dtype=np.int64)
    hi = np.full(n, -1, dtype=np.int64)
    lo[0] = hi[0] = 0
    for r in range(1, n):  # frames advanced to reach column r (0-based) from column 0
        for a, b in zip(di, dj):
            if 0 < a <= r and hi[r - a] >= 0:
                lo[r] = min(lo[r], lo[r - a] + b)
                hi[r] = max(hi[r], hi[r - a] + b)
    if hi[n - 1] < 0:
        raise MtannoError(f"no warping path by the steps {steps!r} covers {n} template columns")
    unbounded = bool(np.any((di == 0) & (dj > 0)))
    return int(lo[n - 1]) + 1, None if unbounded else int(hi[n - 1]) + 1


class PreparedTemplate:
    """A quantized template in kernel form (packed columns, cost table, steps), to match
    many documents without preparing the template again each time.

    Same parameters and checks as :func:`match_template`; :meth:`match` and
    :meth:`match_documents` behave like the functions of the same names.
    """

    def __init__(self, values: np.ndarray, weights: np.ndarray, *, variant: str = "reference",
                 steps: Sequence[tuple[int, int]] = DEFAULT_STEPS,
                 step_weights: Sequence[float] = DEFAULT_STEP_WEIGHTS):
        if variant not in VARIANTS:
            raise MtannoError(f"unknown matching variant {variant!r} (choose from "
                              f"{', '.join(VARIANTS)})")
        V, w = _check_template(values, weights)
        self.di, self.dj, sw = _check_steps(steps, step_weights)
        self.f = V.shape[0]
        if variant == "reference":
            # expand (docs/method/features.md §A): column i repeated max(1, round(w_i))
            # times, round half away from zero (weights are non-negative), each copy of
            # weight w_i / r_i
            reps = column_repeats(w)
            if reps.sum() > MAX_TEMPLATE_COLUMNS:
                raise MtannoError(f"template weights (largest {w.max():.3g}) expand it to "
                                  f"{reps.sum():.3g} columns, more than the "
                                  f"{MAX_TEMPLATE_COLUMNS} matching takes; weights that large "
                                  "are not meaningful")
            reps = reps.astype(np.int64)
            V = np.repeat(V, reps, axis=1)
            w = np.repeat(w / reps, reps)
        K = V.shape[1]
        mask = V != 0.5
        nnz = mask.sum(axis=0)
        m = np.arange(self.f + 1, dtype=np.float64)[None, :]
        if variant == "reference":
            n = float(K)
            factor = (w + 1.0) / (2.0 * np.maximum(1, nnz))
            self.table = m / n * factor[:, None]
            self.sel = np.zeros_like(sw)
            self.divisor = 1.0
        else:
            self.table = m / np.maximum(1, nnz)[:, None]
            self.sel = sw.copy()
            self.divisor = float(K)
        self.table = np.ascontiguousarray(self.table)
        self.add = sw
        self.K = K
        self.words = (self.f + 63) // 64
        vbits = np.ascontiguousarray((V == 1.0).astype(np.uint8))
        self.masks = np.zeros((K, self.words), dtype=np.uint64)
        self.vals = np.zeros((K, self.words), dtype=np.uint64)
        _pack_frames(np.ascontiguousarray(mask.astype(np.uint8)), self.masks)
        _pack_frames(vbits, self.vals)
        self.fast = (self.words == 1 and len(self.di) == 3
                     and tuple(zip(self.di.tolist(), self.dj.tolist())) == DEFAULT_STEPS)

    def match(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(delta, start) on one document, as :func:`match_template`."""
        return self.match_documents([X])[0]

    def match_documents(self, documents: Sequence[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:
        """One (delta, start) pair per document, as :func:`match_documents`."""
        docs = [_check_document(X, self.f, f"document {i + 1}") for i, X in enumerate(documents)]
        offsets = np.zeros(len(docs) + 1, dtype=np.int64)
        np.cumsum([d.shape[1] for d in docs], out=offsets[1:])
        packed = np.empty((int(offsets[-1]), self.words), dtype=np.uint64)
        for d, b, e in zip(docs, offsets[:-1], offsets[1:]):
            _pack_frames(d, packed[b:e])
        delta, start = self.run(packed, offsets)
        return [(delta[b:e], start[b:e]) for b, e in zip(offsets[:-1], offsets[1:])]

    def match_spans(self, packed: np.ndarray, starts: np.ndarray, ends: np.ndarray, *,
                    out: tuple[np.ndarray, np.ndarray] | None = None, clear: bool = True,
                    ) -> tuple[np.ndarray, np.ndarray]:
        """(delta, start) over a whole packed document (:func:`pack_document`) of which only
        the disjoint spans [starts[i], ends[i]] (0-based inclusive) are matched, each as a
        document of its own; starts are frames of the whole document; Δ = ∞ and start = −1
        elsewhere. One kernel call for all spans, nothing copied ([MBS09] §5: templates
        matched only inside keyframe windows). ``out``: (delta, start) arrays of length L
        to write into instead of new ones; with ``clear=False`` their frames outside the
        spans are left as they are (for a reader that looks inside the spans only)."""
        L = packed.shape[0]
        starts, ends = check_spans(starts, ends, L)
        delta, start = _outputs(out, L)
        if clear:
            delta.fill(np.inf)
            start.fill(-1)
        self._kernel(packed, starts, ends + 1, True, delta, start)
        return delta, start

    def run(self, packed: np.ndarray, offsets: np.ndarray, *,
            out: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Kernel call on packed frames (L, words) with document boundaries ``offsets``
        (into ``out`` = (delta, start) when given)."""
        delta, start = _outputs(out, packed.shape[0])
        self._kernel(packed, offsets[:-1], offsets[1:], False, delta, start)
        return delta, start

    def _kernel(self, packed, starts, ends, absolute, delta, start) -> None:
        if not (isinstance(packed, np.ndarray) and packed.dtype == np.uint64
                and packed.ndim == 2 and packed.shape[1] >= self.words):
            raise MtannoError(f"packed document must be uint64 (frames × at least {self.words} "
                              f"words) for a template of {self.f} features, got "
                              f"{getattr(packed, 'dtype', None)} {np.shape(packed)}")
        if self.fast:
            _dtw_default_steps(packed[:, 0], starts, ends, absolute, self.masks[:, 0],
                               self.vals[:, 0], self.table, self.sel, self.add, self.divisor,
                               delta, start)
        else:
            _dtw_general(packed, starts, ends, absolute, self.masks, self.vals, self.table,
                         self.di, self.dj, self.sel, self.add, self.divisor, delta, start)


def _outputs(out, L: int) -> tuple[np.ndarray, np.ndarray]:
    if out is None:
        return np.empty(L, dtype=np.float64), np.empty(L, dtype=np.int64)
    delta, start = out
    if delta.shape != (L,) or delta.dtype != np.float64 or start.shape != (L,) \
            or start.dtype != np.int64:
        raise MtannoError(f"out must be (float64, int64) arrays of the document's {L} frames")
    return delta, start


def check_spans(firsts, lasts, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Frame ranges [firsts[i], lasts[i]] (0-based inclusive; empty when lasts[i] =
    firsts[i] − 1) checked to be sorted, disjoint and inside ``n_frames`` frames, as int64
    arrays: the windows that :meth:`PreparedTemplate.match_spans` matches and the readers
    of its output look inside (:func:`mtanno.merged_spans` makes them)."""
    a, b = np.ascontiguousarray(firsts, np.int64), np.ascontiguousarray(lasts, np.int64)
    if a.shape != b.shape or a.ndim != 1 or not _spans_ok(a, b, n_frames):
        raise MtannoError(f"spans must be sorted disjoint frame ranges inside the {n_frames} "
                          "frames")
    return a, b


@numba.njit(cache=True)
def _spans_ok(a, b, n):
    """Ranges [a[i], b[i]] sorted, disjoint and inside 0 … n − 1 (empty ones: b = a − 1)
    — one pass instead of several numpy calls (annotation checks them per class)."""
    for i in range(a.shape[0]):
        if b[i] < a[i] - 1 or (i > 0 and a[i] <= b[i - 1]):
            return False
    return a.shape[0] == 0 or (a[0] >= 0 and b[-1] < n)


def pack_document(X: np.ndarray, n_features: int) -> np.ndarray:
    """A (features × frames) 0/1 document checked and bit-packed once (frames × words),
    for :meth:`PreparedTemplate.run` / :meth:`PreparedTemplate.match_spans` of several
    templates with ``n_features`` rows."""
    A = _check_document(X, n_features)
    packed = np.empty((A.shape[1], (n_features + 63) // 64), dtype=np.uint64)
    _pack_frames(A, packed)
    return packed


def match_template(values: np.ndarray, weights: np.ndarray, X: np.ndarray, *,
                   variant: str = "reference",
                   steps: Sequence[tuple[int, int]] = DEFAULT_STEPS,
                   step_weights: Sequence[float] = DEFAULT_STEP_WEIGHTS,
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Distance function Δ and match start frames of a quantized template on one document.

    [MR06] §5.2, [MBS09] §4, docs/method.md §3.4 (the module docstring describes both
    variants).

    Parameters
    ----------
    values:
        Quantized template, (f features × K columns), entries 0, 1 or 0.5 (wildcard).
    weights:
        Template column weights (K,), non-negative; used by the ``"reference"`` variant
        (expansion and cost factor), ignored by ``"paper"``.
    X:
        Document features, (f × L) 0/1 (uint8 or bool), one column per 30 Hz frame.
    variant:
        ``"reference"`` (reproduces the reference implementation) or ``"paper"``.
    steps, step_weights:
        DTW step sizes as (template, document) increments and their multiplicative weights.
        Default (1,1), (1,2), (2,1) with weights 1, 1, 2.

    Returns
    -------
    delta:
        (L,) float64: Δ(ℓ) for every document frame ℓ; ``np.inf`` where no path ends.
    start:
        (L,) int64: 0-based first document frame a_ℓ of the optimal path ending at ℓ
        (frames at 30 Hz), −1 where Δ is infinite. A match spans frames start[ℓ]..ℓ.
    """
    return match_documents(values, weights, [X], variant=variant, steps=steps,
                           step_weights=step_weights)[0]


def match_documents(values: np.ndarray, weights: np.ndarray, documents: Sequence[np.ndarray], *,
                    variant: str = "reference",
                    steps: Sequence[tuple[int, int]] = DEFAULT_STEPS,
                    step_weights: Sequence[float] = DEFAULT_STEP_WEIGHTS,
                    ) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`match_template` for several documents at once (one kernel call).

    Every document is matched on its own (paths never cross documents, as in a database with
    separators); returns one ``(delta, start)`` pair per document, ``start`` relative to that
    document. Documents may be empty (0 frames).
    """
    prep = PreparedTemplate(values, weights, variant=variant, steps=steps,
                            step_weights=step_weights)
    return prep.match_documents(documents)
