"""The numba kernels of the annotate stage (private; each is wrapped by a public function
that validates its input, and tested against a slow reference in ``tests/naive*.py``):

* the reference modified distance Δ̄ ([MBS09] §4, docs/method.md §7 step 2;
  :func:`mtanno.annotate.dbar.modified_delta`);
* labels and extended runs of a Δ̄ matrix (docs/method.md §7 steps 3–4;
  :func:`mtanno.annotate.label.segments_from_labels`);
* the segment decoder and its frame evidence (issue 10; :mod:`mtanno.annotate.decode`).

The reference Δ̄ takes the ends ℓ with Δ(ℓ) ≤ τ in increasing order of Δ (ties: earliest
frame); a pick fills the frames of its match [a_ℓ, ℓ] that are still empty with Δ(ℓ) and
blocks every end inside it. :func:`_greedy_dbar` does exactly that (a radix sort of the
candidates, then path-compressed skips over filled frames). :func:`_split_dbar` gets the
same result without sorting, by divide and conquer: the first pick of a stretch of empty
frames is its smallest candidate (a range-minimum query on a segment tree); the pick splits
the stretch into the empty frames left of its start and right of its end, which are solved
in turn, in any order. That is exact as long as no pick reaches left into empty frames
outside its stretch (a match that crosses the path of another; the (1,2) and (2,1) steps
allow it). :func:`reference_dbar_kernel` cuts each span into pieces that no match crosses
and solves each piece by :func:`_split_dbar`, or by :func:`_greedy_dbar` where a pick
reaches out of its stretch (and everything by :func:`_greedy_dbar` when a hit cap bites).
Frames are 0-based.
"""

from __future__ import annotations

import numba
import numpy as np

from mtanno.util._bits import popcount64 as _popcount

# ----------------------------------------------------------- reference Δ̄ ([MBS09] §4)


@numba.njit(cache=True)
def _stable_order(delta, bits, cand):
    """Indices ``cand`` (increasing) stably sorted by ``delta`` (not NaN; ``bits`` is its
    uint64 view): an LSD radix sort, 11 bits per pass, of keys that order like the floats
    (sign bit flipped for x ≥ 0, all bits for x < 0; ±0 as +0), so ties keep the earlier
    frame first; passes where every key has the same digit are skipped."""
    n = cand.shape[0]
    keys = np.empty(n, np.uint64)
    sign = np.uint64(1) << np.uint64(63)
    for i in range(n):
        x = delta[cand[i]]
        b = bits[cand[i]]
        keys[i] = sign if x == 0.0 else (b | sign if x > 0.0 else ~b)
    idx = cand.copy()
    tmp = np.empty(n, np.int64)
    kt = np.empty(n, np.uint64)
    count = np.empty(2049, np.int64)
    mask = np.uint64(2047)
    for sh in range(0, 64, 11):
        shift = np.uint64(sh)
        count[:] = 0
        for i in range(n):
            count[np.int64((keys[i] >> shift) & mask) + 1] += 1
        if count.max() == n:
            continue
        for b in range(2048):
            count[b + 1] += count[b]
        for i in range(n):
            k = np.int64((keys[i] >> shift) & mask)
            tmp[count[k]] = idx[i]
            kt[count[k]] = keys[i]
            count[k] += 1
        idx, tmp = tmp, idx
        keys, kt = kt, keys
    return idx


@numba.njit(cache=True, inline="always")
def _next_empty(nxt, k):
    """The first frame ≥ k with nxt[f] == f, compressing the path walked."""
    r = k
    while nxt[r] != r:
        r = nxt[r]
    while nxt[k] != r:
        following = nxt[k]
        nxt[k] = r
        k = following
    return r


@numba.njit(cache=True)
def _greedy_dbar(delta, bits, start, tau, max_hits, dbar, span_first, span_last):
    """Reference Δ̄ into ``dbar`` (∞ inside the spans on entry) as the reference computes
    it: the candidates radix-sorted (:func:`_stable_order`), then each one in turn is
    picked unless an earlier pick filled its frame; at most ``max_hits`` picks. Work
    arrays cover the spans' range only. Returns the picks, or −1 if a pick's start lies
    before its span or after its end."""
    if span_first.shape[0] == 0:
        return 0
    n = 0
    for w in range(span_first.shape[0]):
        for i in range(span_first[w], span_last[w] + 1):
            if delta[i] <= tau:
                n += 1
    cand = np.empty(n, np.int64)
    n = 0
    for w in range(span_first.shape[0]):
        for i in range(span_first[w], span_last[w] + 1):
            if delta[i] <= tau:
                cand[n] = i
                n += 1
    order = _stable_order(delta, bits, cand)
    # a frame is blocked exactly when a pick has filled it; filled runs are skipped through
    # path-compressed pointers to the next empty frame (nxt[f - o] for frame f), so each
    # frame is written once (pointers set inside the spans and one frame past each: a fill
    # stops there)
    o = span_first[0]
    nxt = np.empty(span_last[-1] - o + 2, np.int64)
    low = np.empty(span_last[-1] - o + 1, np.int64)  # first frame of each frame's span
    for w in range(span_first.shape[0]):
        for i in range(span_first[w] - o, span_last[w] - o + 1):
            nxt[i] = i
            low[i] = span_first[w]
        nxt[span_last[w] - o + 1] = span_last[w] - o + 1
    hits = 0
    for i in range(order.shape[0]):
        if hits >= max_hits:
            break
        end = order[i]
        if nxt[end - o] != end - o:
            continue
        d = delta[end]
        a = start[end]
        if a < low[end - o] or a > end:
            return -1
        k = _next_empty(nxt, a - o)
        while k <= end - o:
            dbar[k + o] = d
            nxt[k] = k + 1
            k = _next_empty(nxt, k + 1)
        hits += 1
    return hits


@numba.njit(cache=True, inline="always")
def _first(delta, a, b):
    """Of two candidates (frames, −1 for none), the one that comes first in the reference
    order: smaller Δ, then the earlier frame (±0 tie)."""
    if b < 0:
        return a
    if a < 0:
        return b
    if delta[a] < delta[b] or (delta[a] == delta[b] and a < b):
        return a
    return b


@numba.njit(cache=True, inline="always")
def _bisect(cand, lo, hi, frame):
    """The first index in [lo, hi) with cand[index] ≥ frame (cand increasing), else hi."""
    while lo < hi:
        mid = (lo + hi) >> 1
        if cand[mid] < frame:
            lo = mid + 1
        else:
            hi = mid
    return lo


@numba.njit(cache=True)
def _split_dbar(delta, start, dbar, cand, n, tree, stack, x0):
    """Δ̄ of one piece of a span, starting at frame ``x0``, by divide and conquer (module
    docstring). ``cand[:n]``: the piece's candidate ends (Δ ≤ τ, increasing); ``tree`` (≥ 2·size, size
    the power of two ≥ n) and ``stack`` (≥ (n + 1) × 4) are work space. Writes the picks'
    costs into ``dbar`` (∞ in the span on entry) and returns the number of picks, or −1
    when a pick starts left of the filled frames before its stretch, or after its end
    (the caller then recomputes the piece with :func:`_greedy_dbar`)."""
    size = 1
    while size < n:
        size *= 2
    for p in range(n):
        tree[size + p] = cand[p]
    for p in range(n, size):
        tree[size + p] = -1
    for p in range(size - 1, 0, -1):
        tree[p] = _first(delta, tree[2 * p], tree[2 * p + 1])
    # a stretch: its candidates [i, j), its empty frames from x, filled ones from lo to x − 1
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = 0, n, x0, x0
    top = 1
    hits = 0
    while top > 0:
        top -= 1
        i, j, x, lo = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        if i >= j:
            continue
        best = -1  # range minimum over leaves [i, j)
        left, right = i + size, j + size
        while left < right:
            if left & 1:
                best = _first(delta, tree[left], best)
                left += 1
            if right & 1:
                right -= 1
                best = _first(delta, tree[right], best)
            left >>= 1
            right >>= 1
        a = start[best]
        if a < lo or a > best:
            return -1
        d = delta[best]
        for k in range(max(a, x), best + 1):
            dbar[k] = d
        hits += 1
        cut = _bisect(cand, i, j, a)  # candidates left of the match
        after = _bisect(cand, cut, j, best + 1)  # and right of it
        stack[top, 0], stack[top, 1], stack[top, 2] = after, j, best + 1
        stack[top, 3] = lo if a <= x else a
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = i, cut, x, lo
        top += 2
    return hits


#: Fewest candidates of a piece (pieces that no match crosses are joined up to it): a
#: piece costs a call, a failed one the sorted greedy over it.
_PIECE = 256


@numba.njit(cache=True)
def _pieces(start, cand, n, begins):
    """Mark in ``begins`` the candidates of cand[:n] (one span) where a piece that no
    candidate's match crosses begins: no match of a later candidate reaches back to the
    frame of the one before (begins[0] is set)."""
    reach = start[cand[n - 1]] if n else 0
    for p in range(n - 1, 0, -1):
        reach = min(reach, start[cand[p]])
        begins[p] = reach > cand[p - 1]
    begins[0] = True


@numba.njit(cache=True)
def reference_dbar_kernel(delta, start, tau, max_hits, dbar, span_first, span_last,
                          fill=False):
    """Reference Δ̄ into ``dbar`` over the sorted disjoint spans [span_first[i], span_last[i]]
    (Δ is read only inside them; matches never leave them), at most ``max_hits`` picks;
    the spans of ``dbar`` must be ∞ on entry (the caller fills them, or ``fill``: this
    kernel, leaving ``dbar`` outside the spans as it was). A span is cut into pieces
    that no candidate's match crosses (a piece's picks neither fill nor block frames of
    another; pieces of fewer than ``_PIECE`` candidates are joined), each solved on its
    own by :func:`_split_dbar`, or by :func:`_greedy_dbar` where that is not exact; all
    spans by :func:`_greedy_dbar` if the cap bites. Returns the picks, or −1 if a pick's
    start lies before its span or after its end."""
    bits = delta.view(np.uint64)
    if fill:
        for w in range(span_first.shape[0]):
            dbar[span_first[w]:span_last[w] + 1] = np.inf
    m = 0
    for w in range(span_first.shape[0]):
        c = 0
        for i in range(span_first[w], span_last[w] + 1):
            if delta[i] <= tau:
                c += 1
        m = max(m, c)
    size = 1
    while size < m:
        size *= 2
    cand = np.empty(m, np.int64)
    begins = np.empty(m + 1, np.bool_)
    tree = np.empty(2 * size, np.int64)
    stack = np.empty((m + 1, 4), np.int64)
    first = np.empty(1, np.int64)
    last = np.empty(1, np.int64)
    hits = 0
    for w in range(span_first.shape[0]):
        n = 0
        for i in range(span_first[w], span_last[w] + 1):
            if delta[i] <= tau:
                cand[n] = i
                n += 1
        _pieces(start, cand, n, begins)
        begins[n] = True
        q = 0
        for p in range(1, n + 1):
            if not begins[p] or (p - q < _PIECE and p < n):
                continue
            x = span_first[w] if q == 0 else cand[q - 1] + 1
            got = _split_dbar(delta, start, dbar, cand[q:p], p - q, tree, stack, x)
            if got < 0:  # crossing matches: this piece in the sorted order
                dbar[x:cand[p - 1] + 1] = np.inf
                first[0], last[0] = x, cand[p - 1]
                got = _greedy_dbar(delta, bits, start, tau, max_hits, dbar, first, last)
                if got < 0:
                    return -1
            hits += got
            q = p
    if hits > max_hits:  # the cap bites: the picks in the global order
        for w in range(span_first.shape[0]):
            dbar[span_first[w]:span_last[w] + 1] = np.inf
        return _greedy_dbar(delta, bits, start, tau, max_hits, dbar, span_first, span_last)
    return hits


# ---------------------------------- labels and runs (docs/method.md §7 steps 3–4)


@numba.njit(cache=True)
def _extend(dbar, s, t, lo, hi):
    """Walk outward from [s, t] while Δ̄ does not rise (docs/method.md §7 step 4), inside
    frames lo … hi (where the row holds Δ̄: outside, it would be ∞ and stop the walk)."""
    r = s
    while r > lo and dbar[r - 1] <= dbar[r]:
        r -= 1
    u = t
    while u < hi and dbar[u + 1] <= dbar[u]:
        u += 1
    return r, u


@numba.njit(cache=True)
def _extend_unclaimed(dbar, labels, p, s, t, lo, hi):
    """:func:`_extend` that walks only over frames whose label is none or ``p`` (boundary
    refinement, issue 10: the extension never runs into another class's frames)."""
    r = s
    while r > lo and dbar[r - 1] <= dbar[r] and (labels[r - 1] < 0 or labels[r - 1] == p):
        r -= 1
    u = t
    while u < hi and dbar[u + 1] <= dbar[u] and (labels[u + 1] < 0 or labels[u + 1] == p):
        u += 1
    return r, u


@numba.njit(cache=True)
def _frame_labels(dbars, firsts, lasts, offsets, labels):
    """Each frame's label: the row with the smallest Δ̄ (ties → smaller row), −1 where
    every Δ̄ is ∞. Row p holds Δ̄ only in its spans [firsts[i], lasts[i]], i in
    offsets[p] … offsets[p + 1] − 1 (sorted, disjoint; elsewhere it counts as ∞ and is not
    read). Rows are read in order, a block of frames at a time (contiguous loads instead of
    one load per row and frame)."""
    P, L = dbars.shape
    block = 1024
    best = np.empty(block)
    at = offsets[:-1].copy()  # each row's first span not yet behind the block
    for j0 in range(0, L, block):
        j1 = min(L, j0 + block)
        best[:j1 - j0] = np.inf
        lab = labels[j0:j1]
        lab[:] = -1
        for p in range(P):
            i = at[p]
            while i < offsets[p + 1] and lasts[i] < j0:
                i += 1
            at[p] = i
            while i < offsets[p + 1] and firsts[i] < j1:
                a = max(firsts[i], j0) - j0
                row = dbars[p, j0:j1]
                for j in range(a, min(lasts[i] + 1, j1) - j0):  # selects: it vectorizes
                    v = row[j]
                    b = best[j]
                    t = v < b
                    best[j] = v if t else b
                    lab[j] = p if t else lab[j]
                i += 1


@numba.njit(cache=True, inline="always")
def _span_of(firsts, lo, hi, frame):
    """The index in lo … hi − 1 of the last span starting at or before ``frame``."""
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if firsts[mid] <= frame:
            lo = mid
        else:
            hi = mid
    return lo


@numba.njit(cache=True)
def _label_runs(dbars, firsts, lasts, offsets, extend, rank, out_p, out_s, out_t, out_cost):
    """Segments of a Δ̄ matrix (labels × frames; row p valid in its spans only, as for
    :func:`_frame_labels`): each frame's label is the smallest Δ̄ (ties → smaller label,
    none where all are ∞); maximal runs of one label, extended while Δ̄ of the label does
    not rise (``extend`` 1; 2: only over frames of no other label; 0: not extended),
    merged per label where they overlap, with the smallest Δ̄ inside. Writes (label,
    start, end, cost) sorted by start, end and ``rank`` of the label (the order of the
    label names); returns their number."""
    P, L = dbars.shape
    labels = np.empty(L, np.int64)
    _frame_labels(dbars, firsts, lasts, offsets, labels)
    n = 0
    prev = -2
    s0 = 0
    for j in range(L + 1):
        lab = labels[j] if j < L else -1
        if j == L or lab != prev:
            if j > 0 and prev >= 0:
                s, t = s0, j - 1
                if extend:  # the walk stays inside the row's spans around the run
                    lo = firsts[_span_of(firsts, offsets[prev], offsets[prev + 1], s)]
                    hi = lasts[_span_of(firsts, offsets[prev], offsets[prev + 1], t)]
                    if extend == 2:
                        s, t = _extend_unclaimed(dbars[prev], labels, prev, s, t, lo, hi)
                    else:
                        s, t = _extend(dbars[prev], s, t, lo, hi)
                out_p[n] = prev
                out_s[n] = s
                out_t[n] = t
                n += 1
            prev = lab
            s0 = j
    order = np.argsort(out_p[:n] * (L + 1) + out_s[:n])
    sp = out_p[:n][order]
    ss = out_s[:n][order]
    st = out_t[:n][order]
    m = 0
    # numba twin of keyframes/_kernels.py dilate (and merge_sorted): here runs merge per
    # label and only where they overlap (touching runs stay two), and a kernel calls
    # kernels of its own file only (numba's cache does not see changes to another file;
    # util/_bits.py)
    for i in range(n):
        if m > 0 and out_p[m - 1] == sp[i] and ss[i] <= out_t[m - 1]:  # overlapping: merge
            if st[i] > out_t[m - 1]:
                out_t[m - 1] = st[i]
        else:
            out_p[m] = sp[i]
            out_s[m] = ss[i]
            out_t[m] = st[i]
            m += 1
    by_rank = np.argsort(rank[out_p[:m]], kind="mergesort")
    key = out_s[:m] * (L + 1) + out_t[:m]
    order = by_rank[np.argsort(key[by_rank], kind="mergesort")]
    sp = out_p[:m][order]
    ss = out_s[:m][order]
    st = out_t[:m][order]
    for i in range(m):
        out_p[i] = sp[i]
        out_s[i] = ss[i]
        out_t[i] = st[i]
        c = np.inf
        for j in range(ss[i], st[i] + 1):
            if dbars[sp[i], j] < c:
                c = dbars[sp[i], j]
        out_cost[i] = c
    return m


# ------------------------------------------------------- segment decoder (issue 10)


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
