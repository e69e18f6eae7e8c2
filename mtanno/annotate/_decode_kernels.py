"""The numba kernels of the segment decoder and its frame evidence (issue 10; private,
wrapped by :mod:`mtanno.annotate.decode`, which validates their input, and tested against a
slow reference in ``tests/naive*.py``). Frames are 0-based.

The kernels here call only each other and :func:`mtanno.util._bits.popcount64` (numba's
on-disk cache keys a kernel on its own file: a family of kernels that call each other stays
in one file).
"""

from __future__ import annotations

import numba
import numpy as np

from mtanno.util._bits import popcount64 as _popcount


@numba.njit(cache=True)
def _decode(delta, start, scale, ceiling, cum_ev, weight, seg_cost, slack, first, best,
            back_k, back_p):
    """Least-cost partition of frames 0…L−1 into matches and unlabelled frames.

    ``best[j]`` is the least cost of frames 0…j−1; a match of label p ending at ℓ starts
    at k ∈ [a − slack, a + slack] ∩ [first[ℓ], ℓ] (a = start[p, ℓ]; ``first`` holds the
    first frame of ℓ's document when several are decoded at once) and costs
    (ℓ − k + 1)·delta[p, ℓ]·scale[p] + weight·(cum_ev[p, ℓ + 1] − cum_ev[p, k]) + seg_cost;
    an unlabelled frame costs 1. Only strictly cheaper choices replace earlier ones.
    Matches too short to pay their segment cost are skipped without trying their starts
    (exact: best[ℓ] ≤ best[k] + ℓ − k, as the unlabelled frames show)."""
    P, L = delta.shape
    best[0] = 0.0
    for ell in range(L):
        b = best[ell] + 1.0
        bk = ell
        bp = -1
        for p in range(P):
            d = delta[p, ell]
            if not d <= ceiling[p]:  # ∞ (no match ends here), NaN, or rejected
                continue
            per = d * scale[p]
            if per >= 1.0:  # never cheaper than unlabelled frames (weights are ≥ 0)
                continue
            a = start[p, ell]  # read only now: most matches cost more than τ
            if a < 0:
                continue
            lo = max(first[ell], a - slack)
            hi = min(ell, a + slack)
            # a match of n ≤ ell − lo + 1 frames costs at least n·per + seg_cost more than
            # best[k], and leaving its frames unlabelled costs n: it cannot win where
            # n·(1 − per) < seg_cost (less a bound on the rounding of both sums)
            n = ell - lo + 1
            if n * (1.0 - per) < seg_cost - 2.3e-16 * (1.01 * (ell + 1) + n + seg_cost + 1.0) \
                    * (n + 6):
                continue
            for k in range(lo, hi + 1):
                c = best[k] + (ell - k + 1) * per + seg_cost
                if weight != 0.0:
                    c += weight * (cum_ev[p, ell + 1] - cum_ev[p, k])
                if c < b:
                    b = c
                    bk = k
                    bp = p
        best[ell + 1] = b
        back_k[ell + 1] = bk
        back_p[ell + 1] = bp


@numba.njit(cache=True)
def _segments(back_k, back_p, deltas, first, lab, seg_start, seg_end, cost):
    """The decoded segments from the back pointers, in frame order, touching segments of
    one label in one document merged (cost: the smallest Δ at their ends); returns their
    number."""
    n = 0
    j = back_k.shape[0] - 1
    while j > 0:
        k, p = back_k[j], back_p[j]
        if p >= 0:
            lab[n], seg_start[n], seg_end[n], cost[n] = p, k, j - 1, deltas[p, j - 1]
            n += 1
        j = k
    for i in range(n // 2):  # the walk went backwards
        r = n - 1 - i
        lab[i], lab[r] = lab[r], lab[i]
        seg_start[i], seg_start[r] = seg_start[r], seg_start[i]
        seg_end[i], seg_end[r] = seg_end[r], seg_end[i]
        cost[i], cost[r] = cost[r], cost[i]
    m = 0
    for i in range(n):  # in place: m ≤ i
        p, a, b, c = lab[i], seg_start[i], seg_end[i], cost[i]
        if m > 0 and lab[m - 1] == p and seg_end[m - 1] + 1 == a \
                and first[a] == first[seg_end[m - 1]]:
            seg_end[m - 1] = b
            cost[m - 1] = min(cost[m - 1], c)
        else:
            lab[m], seg_start[m], seg_end[m], cost[m] = p, a, b, c
            m += 1
    return m


@numba.njit(cache=True)
def _best_column(packed, masks, vals, inv_nnz, starts, ends, out):
    """out[t] = min over columns k of (disagreements of frame t on k's fixed rows) / nnz_k,
    for the frames t of the spans [starts[i], ends[i]]; the template's words only (a
    document may have more)."""
    words = masks.shape[1]
    K = masks.shape[0]
    for i in range(starts.shape[0]):
        for t in range(starts[i], ends[i] + 1):
            b = np.inf
            for k in range(K):
                m = 0
                for w in range(words):
                    m += _popcount((packed[t, w] ^ vals[k, w]) & masks[k, w])
                c = m * inv_nnz[k]
                if c < b:
                    b = c
            out[t] = b


@numba.njit(cache=True)
def _fold(delta, start, ceiling, inv_tau, row, row_start, first, span_first, span_last):
    """row = min(row, Δ·(1/τ) where Δ ≤ ceiling), with the start frames of the minima,
    over the frames of the spans [span_first[i], span_last[i]] (Δ is ∞ elsewhere and not
    read); ``first``: as if row were ∞ and row_start −1 before (they are written
    everywhere)."""
    if first:
        row[:] = np.inf
        row_start[:] = -1
    for i in range(span_first.shape[0]):
        for t in range(span_first[i], span_last[i] + 1):
            d = delta[t]
            if d <= ceiling:
                v = d * inv_tau
                if v < row[t]:
                    row[t] = v
                    row_start[t] = start[t]


@numba.njit(cache=True)
def _distinct_words(x, inverse):
    """Distinct values of ``x`` (uint64) in order of first appearance; ``inverse[i]`` the
    index of x[i] among them. Open addressing with linear probing on a table of at least
    twice as many slots as values (the key folded by shifts, so no multiply wraps)."""
    n = x.shape[0]
    size = 2
    while size < 2 * n:
        size *= 2
    mask = np.uint64(size - 1)
    keys = np.empty(size, np.uint64)
    ids = np.full(size, -1, np.int64)
    uniq = np.empty(n, np.uint64)
    m = 0
    for i in range(n):
        v = x[i]
        h = (v ^ (v >> np.uint64(17)) ^ (v >> np.uint64(31)) ^ (v >> np.uint64(47))) & mask
        j = np.int64(h)
        while ids[j] >= 0 and keys[j] != v:
            j = (j + 1) & (size - 1)
        if ids[j] < 0:
            keys[j] = v
            ids[j] = m
            uniq[m] = v
            m += 1
        inverse[i] = ids[j]
    return uniq[:m]


@numba.njit(cache=True)
def _take_spans(per_row, inverse, firsts, lasts, out):
    """out = ∞, and out[t] = per_row[inverse[t]] for the frames t of the spans. Returns 0,
    or (out partly written) 1 where a non-empty span leaves the frames of ``out``, 2 where a
    frame's row is not one of ``per_row`` (checked here, in the pass that reads them)."""
    L = out.shape[0]
    n = per_row.shape[0]
    out[:] = np.inf
    for i in range(firsts.shape[0]):
        a = firsts[i]
        b = lasts[i]
        if b >= a and (a < 0 or b >= L):
            return 1
        for t in range(a, b + 1):
            r = inverse[t]
            if r < 0 or r >= n:
                return 2
            out[t] = per_row[r]
    return 0


@numba.njit(cache=True)
def _prefix(E, cum):
    """cum[p, t] = E[p, 0] + … + E[p, t − 1], added in frame order; False if an entry is
    negative or NaN (the decoder's pruning needs evidence ≥ 0)."""
    P, L = E.shape
    ok = True
    for p in range(P):
        acc = 0.0
        cum[p, 0] = 0.0
        for t in range(L):
            e = E[p, t]
            if not e >= 0.0:
                ok = False
            acc += e
            cum[p, t + 1] = acc
    return ok


@numba.njit(cache=True)
def _relative_sums(buf):
    """buf[:, 1:] evidence → buf[p, t] = Σ_{s < t} (buf[p, s + 1] − least finite entry of
    frame s; 0 where not finite), added in frame order (every term is ≥ 0)."""
    P, L1 = buf.shape
    for p in range(P):
        buf[p, 0] = 0.0
    for t in range(1, L1):
        low = np.inf
        for p in range(P):
            if buf[p, t] < low:  # False for ∞ and NaN
                low = buf[p, t]
        for p in range(P):
            e = buf[p, t]
            buf[p, t] = buf[p, t - 1] + (e - low if np.isfinite(e) else 0.0)


@numba.njit(cache=True)
def _relative(E, out):
    """out = E − (per column, the least finite entry); non-finite entries give 0."""
    P, L = E.shape
    low = np.full(L, np.inf)
    for p in range(P):
        for t in range(L):
            e = E[p, t]
            if e < low[t]:  # False for ∞ and NaN
                low[t] = e
    for p in range(P):
        for t in range(L):
            e = E[p, t]
            out[p, t] = e - low[t] if np.isfinite(e) else 0.0
