"""The numba kernels of the reference modified distance Δ̄ ([MBS09] §4, docs/method.md §7
step 2; private, wrapped by :func:`mtanno.annotate.dbar.modified_delta`, which validates its
input, and tested against a slow reference in ``tests/naive*.py``).

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

The kernels here call only each other (numba's on-disk cache keys a kernel on its own
file: a family of kernels that call each other stays in one file).
"""

from __future__ import annotations

import numba
import numpy as np


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
