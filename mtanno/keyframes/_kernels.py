"""Numba kernels of keyframe search (docs/method.md §5): operations on interval lists.

An *interval list* is three int64 arrays ``doc, start, end`` (frames 0-based, ``end``
inclusive), sorted by (doc, start), with intervals of one document disjoint and not
touching (``start > previous end + 1``). Keyframe search propagates such lists level by
level; every kernel here is one linear pass (two-pointer merges), so a query costs time
linear in the total length of the lists involved, and memory bounded by them.

Private: :mod:`mtanno.keyframes.search` validates inputs and calls these. A kernel calls
kernels of this file only (numba's cache does not see changes across files).
"""

from __future__ import annotations

import numba
import numpy as np

from mtanno.util._bits import popcount64 as _popcount


@numba.njit(cache=True)
def dilate(doc, start, end, lo, hi, out_doc, out_start, out_end):
    """Minkowski sum of an interval list with [lo, hi] (``lo ≤ hi``): every interval
    [s, e] becomes [s + lo, e + hi]; overlapping or touching results of one document are
    merged. Returns the number of intervals written. The input may overlap or touch too
    (sorted by (doc, start)): with lo = hi = 0 this is :func:`merge_sorted`."""
    cnt = 0
    # numba twin of the run merge in annotate/_kernels.py _label_runs, which merges per
    # label and only where runs overlap: each kernel file calls its own kernels only
    # (numba's cache does not see changes to another file; util/_bits.py)
    for i in range(doc.shape[0]):
        s = start[i] + lo
        e = end[i] + hi
        if cnt > 0 and out_doc[cnt - 1] == doc[i] and s <= out_end[cnt - 1] + 1:
            if e > out_end[cnt - 1]:
                out_end[cnt - 1] = e
        else:
            out_doc[cnt] = doc[i]
            out_start[cnt] = s
            out_end[cnt] = e
            cnt += 1
    return cnt


@numba.njit(cache=True)
def intersect(a_doc, a_start, a_end, b_doc, b_start, b_end, out_doc, out_start, out_end):
    """Intersection of two interval lists (two pointers). The output needs room for
    ``len(a) + len(b)`` intervals; returns the number written."""
    i = 0
    j = 0
    cnt = 0
    na = a_doc.shape[0]
    nb = b_doc.shape[0]
    while i < na and j < nb:
        if a_doc[i] < b_doc[j]:
            i += 1
            continue
        if b_doc[j] < a_doc[i]:
            j += 1
            continue
        s = max(a_start[i], b_start[j])
        e = min(a_end[i], b_end[j])
        if s <= e:
            out_doc[cnt] = a_doc[i]
            out_start[cnt] = s
            out_end[cnt] = e
            cnt += 1
        if a_end[i] < b_end[j]:
            i += 1
        else:
            j += 1
    return cnt


@numba.njit(cache=True)
def pair_spans(a_doc, a_start, a_end, b_doc, b_start, b_end, dmin, dmax,
               out_doc, out_start, out_end):
    """For every pair of an interval [p, q] of ``a`` and [r, s] of ``b`` in one document
    that holds frames a ∈ [p, q], b ∈ [r, s] with dmin ≤ b − a ≤ dmax, the span
    [min a, max b] of those pairs = [max(p, r − dmax), min(s, q + dmax)] (every frame in it
    lies between such a pair, see ``docs/keyframes.md``). Writes while room is left and
    returns the total number (call again with a larger output if it exceeds the room)."""
    cnt = 0
    room = out_doc.shape[0]
    nb = b_doc.shape[0]
    k0 = 0
    # numba twin of index/_kernels.py overlap_pairs (the same two-pointer walk over pairs
    # of one document, writing while room is left): it writes the pairs' indices, this
    # their spans, and a kernel calls kernels of its own file only (util/_bits.py)
    for i in range(a_doc.shape[0]):
        d = a_doc[i]
        p = a_start[i]
        q = a_end[i]
        while k0 < nb and (b_doc[k0] < d or (b_doc[k0] == d and b_end[k0] < p + dmin)):
            k0 += 1
        k = k0
        while k < nb and b_doc[k] == d and b_start[k] <= q + dmax:
            r = b_start[k]
            s = b_end[k]
            lo = max(p, r - dmax)
            hi = min(s, q + dmax)
            if lo <= min(q, s - dmin) and hi >= max(r, p + dmin):
                if cnt < room:
                    out_doc[cnt] = d
                    out_start[cnt] = lo
                    out_end[cnt] = hi
                cnt += 1
            k += 1
    return cnt


@numba.njit(cache=True)
def merge_sorted(doc, start, end, out_doc, out_start, out_end):
    """Union of intervals sorted by (doc, start) (they may overlap or touch): the maximal
    runs of covered frames. Returns the number written."""
    return dilate(doc, start, end, 0, 0, out_doc, out_start, out_end)


@numba.njit(cache=True)
def mark_clips(start, end, clip_of_frame, clip_end, out):
    """Set ``out[c] = 1`` for every clip c that a frame range [start[i], end[i]] (global
    frames over joined clips) overlaps; ``clip_end[c]`` is one past the clip's last
    frame. Visits one frame per clip touched, not every frame."""
    for i in range(start.shape[0]):
        t = start[i]
        while t <= end[i]:
            c = clip_of_frame[t]
            out[c] = 1
            t = clip_end[c]


@numba.njit(cache=True)
def keyframe_runs(words, mask, value, tolerance, out_start, out_end):
    """Maximal runs of frames matching a keyframe, from bit-packed frames (frames × words,
    bit i % 64 of word i // 64 = feature row i): a frame matches if at most ``tolerance``
    of the bits in ``mask`` differ from ``value``. Writes (start, end) pairs, end
    inclusive; returns their number. One pass over the frames."""
    L, W = words.shape
    cnt = 0
    inside = False
    for j in range(L + 1):
        ok = False
        if j < L:
            bad = 0
            for q in range(W):
                d = (words[j, q] ^ value[q]) & mask[q]
                if d:
                    bad += _popcount(d) if tolerance else 1
                    if bad > tolerance:
                        break
            ok = bad <= tolerance
        if ok and not inside:
            out_start[cnt] = j
            inside = True
        elif not ok and inside:
            out_end[cnt] = j - 1
            cnt += 1
            inside = False
    return cnt


_SLOT_BITS = 13  # cache size limit: a document has ~1000–2000 distinct frame vectors
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


@numba.njit(cache=True, inline="always")
def _matches(words, j, mask, value, tolerance, k):
    """Frame ``j`` matches keyframe ``k``: at most ``tolerance[k]`` of the bits in
    ``mask[k]`` differ from ``value[k]``."""
    bad = 0
    for q in range(words.shape[1]):
        d = (words[j, q] ^ value[k, q]) & mask[k, q]
        if d:
            bad += _popcount(d) if tolerance[k] else 1
            if bad > tolerance[k]:
                return False
    return True


@numba.njit(cache=True)
def keyframe_set_changes(words, mask, value, tolerance, pos, sets):
    """The frames where the set of matching keyframes changes, for up to 64 keyframes
    (rows of ``mask``, ``value``; their tolerances) in one pass over the frames: from frame
    ``pos[i]`` on the set is ``sets[i]`` (bit k: keyframe k matches), up to the next entry;
    the last entry is frame L with the empty set. ``pos`` and ``sets`` need L + 1 entries;
    returns how many were written. The keyframes are tested once per distinct frame vector,
    looked up where the vector changes (at 30 Hz about every second frame) in an
    open-addressing hash cache of the set of keyframes each matches (when it is three
    quarters full, further vectors are tested without caching). Twenty keyframes cost about
    what two do one by one."""
    L, W = words.shape
    nk = mask.shape[0]
    bits = 1  # 2**bits slots, at least twice the frames of short documents
    while bits < _SLOT_BITS and (1 << bits) < 2 * L:
        bits += 1
    S = 1 << bits
    shift = np.uint64(64 - bits)
    keys = np.zeros((S, W), np.uint64)
    sets_of = np.zeros(S, np.uint64)
    used = np.zeros(S, np.bool_)
    n_used = 0
    one = np.uint64(1)
    prev = np.uint64(0)
    m = 0
    for j in range(L + 1):
        cur = np.uint64(0)
        if j < L:
            if j > 0:
                same = True
                for q in range(W):
                    if words[j, q] != words[j - 1, q]:
                        same = False
                        break
                if same:
                    continue
            h = np.uint64(0)
            for q in range(W):
                h = (h ^ words[j, q]) * _GOLDEN
            slot = np.int64(h >> shift)
            found = False
            while used[slot]:
                found = True
                for q in range(W):
                    if keys[slot, q] != words[j, q]:
                        found = False
                        break
                if found:
                    break
                slot = (slot + 1) & (S - 1)
            if found:
                cur = sets_of[slot]
            else:
                for k in range(nk):
                    if _matches(words, j, mask, value, tolerance, k):
                        cur |= one << np.uint64(k)
                if 4 * n_used < 3 * S:
                    for q in range(W):
                        keys[slot, q] = words[j, q]
                    sets_of[slot] = cur
                    used[slot] = True
                    n_used += 1
        if cur != prev or j == L:
            pos[m] = j
            sets[m] = cur
            m += 1
        prev = cur
    return m


@numba.njit(cache=True)
def set_runs(pos, sets, m, nk, offsets, out_start, out_end):
    """The runs of each of ``nk`` keyframes from the change points of
    :func:`keyframe_set_changes` (``pos[:m]``, ``sets[:m]``). With ``offsets`` empty,
    counts the runs of each keyframe and returns the counts; else writes the runs of
    keyframe k as (start, end) pairs, end inclusive, into ``out_start``/``out_end`` from
    ``offsets[k]`` on (the counts' prefix sums) and returns the counts again."""
    write = offsets.shape[0] > 0
    first = np.zeros(nk, np.int64)
    count = np.zeros(nk, np.int64)
    one = np.uint64(1)
    prev = np.uint64(0)
    for i in range(m):
        cur = sets[i]
        j = pos[i]
        x = cur ^ prev
        while x:
            low = x & (~x + one)  # lowest set bit: keyframe k enters or leaves
            k = _popcount(low - one)
            x ^= low
            if cur & low:
                first[k] = j
            else:
                if write:
                    out_start[offsets[k] + count[k]] = first[k]
                    out_end[offsets[k] + count[k]] = j - 1
                count[k] += 1
        prev = cur
    return count


@numba.njit(cache=True)
def _level(starts, ends, offsets, j):
    """Level j of one document's flattened runs, as an interval list (document 0)."""
    a, b = offsets[j], offsets[j + 1]
    return np.zeros(b - a, np.int64), starts[a:b], ends[a:b]


@numba.njit(cache=True)
def _dilated_meet(a, b, lo, hi):
    """Intersection of interval list ``a`` dilated by [lo, hi] with interval list ``b``."""
    m = a[0].shape[0]
    dd, ds, de = np.empty(m, np.int64), np.empty(m, np.int64), np.empty(m, np.int64)
    k = dilate(a[0], a[1], a[2], lo, hi, dd, ds, de)
    cap = k + b[0].shape[0]
    od, os_, oe = np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap, np.int64)
    k = intersect(dd[:k], ds[:k], de[:k], b[0], b[1], b[2], od, os_, oe)
    return od[:k], os_[:k], oe[:k]


@numba.njit(cache=True)
def chain_windows(starts, ends, offsets, gap_lo, gap_hi, left, right, length):
    """Candidate windows of one query in one document of ``length`` frames, in one call
    (what :mod:`mtanno.keyframes.search` does with the kernels above, list by list): the
    runs of keyframe j are ``starts``/``ends`` [offsets[j], offsets[j + 1]); chains with
    gaps [gap_lo[j], gap_hi[j]] (forward and backward passes), the union of their spans,
    widened by ``left``/``right`` frames, clipped and merged. Returns (first, last)
    arrays, 0-based inclusive."""
    n = offsets.shape[0] - 1
    none = np.zeros(0, np.int64)
    F = [_level(starts, ends, offsets, 0)]
    for j in range(n - 1):
        if F[j][0].shape[0] == 0:
            return none, none
        F.append(_dilated_meet(F[j], _level(starts, ends, offsets, j + 1), gap_lo[j],
                               gap_hi[j]))
    if F[n - 1][0].shape[0] == 0:
        return none, none
    B = [F[n - 1]]  # B_n … B_1
    for j in range(n - 2, -1, -1):
        B.append(_dilated_meet(B[-1], F[j], -gap_hi[j], -gap_lo[j]))
    if n == 1:
        hs, he = B[0][1], B[0][2]
    else:
        total = 0
        parts = []
        for j in range(n - 1):
            a, b = B[n - 1 - j], B[n - 2 - j]
            cap = a[0].shape[0] + b[0].shape[0] + 1
            while True:
                od = np.empty(cap, np.int64)
                os_ = np.empty(cap, np.int64)
                oe = np.empty(cap, np.int64)
                k = pair_spans(a[0], a[1], a[2], b[0], b[1], b[2], gap_lo[j], gap_hi[j],
                               od, os_, oe)
                if k <= cap:
                    break
                cap = k
            parts.append((os_[:k], oe[:k]))
            total += k
        ps, pe = np.empty(total, np.int64), np.empty(total, np.int64)
        i = 0
        for s, e in parts:
            ps[i:i + s.shape[0]] = s
            pe[i:i + s.shape[0]] = e
            i += s.shape[0]
        order = np.argsort(ps, kind="mergesort")
        zero = np.zeros(total, np.int64)
        hd, hs, he = np.empty(total, np.int64), np.empty(total, np.int64), np.empty(total,
                                                                                    np.int64)
        k = merge_sorted(zero, ps[order], pe[order], hd, hs, he)
        hs, he = hs[:k], he[:k]
    m = hs.shape[0]
    ws, we = np.empty(m, np.int64), np.empty(m, np.int64)
    for i in range(m):
        ws[i] = max(hs[i] - left, 0)
        we[i] = min(he[i] + right, length - 1)
    od, os_, oe = np.empty(m, np.int64), np.empty(m, np.int64), np.empty(m, np.int64)
    k = merge_sorted(np.zeros(m, np.int64), ws, we, od, os_, oe)
    return os_[:k], oe[:k]
