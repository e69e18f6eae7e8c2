"""Numba kernels of the relational index ([MRC05] §5): candidate scans over inverted lists.

Private and small; :mod:`mtanno.index.query` validates everything and calls them. Common
arguments: ``member`` is the (query positions × lists) 0/1 matrix saying which inverted lists
make up the fuzzy set V_i of each query position (so a segment row r lies in L(V_i) iff
``member[i, seg_list[r]]``: every segment is in exactly one list, [MRC05] §5.3); ``offsets`` /
``postings`` are the inverted lists in CSR form (list v = rows ``postings[offsets[v]:
offsets[v+1]]``, ascending); ``seg_list`` and ``seg_doc`` give each segment row's list and
0-based document; ``doc_offsets`` the first row of each document (plus the total).
Segment rows are numbered over the concatenation of all documents in index order, so a
document's segments are one contiguous range and a hit never crosses a document end.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def fixed_hits(src, src_lists, src_lists_off, offsets, postings, member, seg_list, seg_doc,
               mismatches, allowed, out):
    """Fixed-length hits (exact, fuzzy and m-mismatch; [MRC05] §5.1–5.2, eq. 7 and 11).

    A hit is a first row k such that rows k … k+L−1 lie in one document and at most
    ``mismatches`` positions i have row k+i outside L(V_i), each of them with
    ``allowed[i]``. Candidates come from the lists of the source positions ``src`` (list
    ids of ``src[p]`` are ``src_lists[src_lists_off[p]:src_lists_off[p+1]]``): a candidate
    from source position p is dropped if an earlier source position also matches there, so
    each hit is written once (unsorted) into ``out``; returns their number. With m
    mismatches the caller passes m+1 source positions, or one position that must match.
    """
    n_pos = member.shape[0]
    n_rows = seg_list.shape[0]
    cnt = 0
    # numba twin of the candidate loop of adaptive_hits: both walk the postings of some
    # lists, but a shared walk would have to collect the candidates into an array first
    # (numba has no cheap callbacks), an extra pass and allocation per query: measured
    # (one inlined gather kernel, 300 fuzzy and 300 adaptive example queries on the index of
    # the HDM05 clips, numba 0.68) 5 % slower here, as fast in adaptive_hits
    for p in range(src.shape[0]):
        j = src[p]
        for li in range(src_lists_off[p], src_lists_off[p + 1]):
            v = src_lists[li]
            for idx in range(offsets[v], offsets[v + 1]):
                k = postings[idx] - j
                if k < 0 or k + n_pos > n_rows or seg_doc[k] != seg_doc[k + n_pos - 1]:
                    continue
                dup = False
                for q in range(p):
                    if member[src[q], seg_list[k + src[q]]]:
                        dup = True
                        break
                if dup:
                    continue
                bad = 0
                ok = True
                for i in range(n_pos):
                    if not member[i, seg_list[k + i]]:
                        bad += 1
                        if not allowed[i] or bad > mismatches:
                            ok = False
                            break
                if ok:
                    out[cnt] = k
                    cnt += 1
    return cnt


@numba.njit(cache=True)
def adaptive_hits(j, lists, offsets, postings, member, seg_list, seg_doc, seg_len, doc_offsets,
                  max_gap, out):
    """Adaptive fuzzy hits ([MRC05] §5.2): first rows k1 of maximal runs of V_1-segments
    followed by a maximal run of V_2-segments, …, V_L-segments, in one document.

    Between the run of V_i and the run of V_{i+1} the document may pass through segments in
    neither set for at most ``max_gap`` frames in all (a transition; ``seg_len`` gives each
    row's length in frames); ``max_gap = 0`` is [MRC05]'s rule, runs directly adjacent.
    Candidates are the rows of L(V_j) (``lists`` = list ids of position j) that start a
    maximal V_j run; from each the chain is walked backwards to V_1 and forwards to V_L.
    Adjacent sets are disjoint (the caller merges intersecting neighbours) and a transition
    holds no segment of its two sets, so the walk is the same in both directions and each
    hit is found exactly once, from its own V_j run. Writes first rows into ``out``
    (unsorted) and returns their number.
    """
    n_pos = member.shape[0]
    cnt = 0
    # numba twin of the candidate loop of fixed_hits (the figures are there): written out
    for li in range(lists.shape[0]):
        v = lists[li]
        for idx in range(offsets[v], offsets[v + 1]):
            p = postings[idx]
            d = seg_doc[p]
            lo = doc_offsets[d]
            hi = doc_offsets[d + 1]
            if p > lo and member[j, seg_list[p - 1]]:
                continue  # not the first segment of its V_j run
            ok = True
            b = p
            for i in range(j - 1, -1, -1):
                gap = 0
                while (b - 1 >= lo and gap <= max_gap and not member[i, seg_list[b - 1]]
                       and not member[i + 1, seg_list[b - 1]]):
                    gap += seg_len[b - 1]
                    b -= 1
                if gap > max_gap or b - 1 < lo or not member[i, seg_list[b - 1]]:
                    ok = False
                    break
                b -= 1
                while b - 1 >= lo and member[i, seg_list[b - 1]]:
                    b -= 1
            if not ok:
                continue
            e = p
            while e < hi and member[j, seg_list[e]]:
                e += 1
            for i in range(j + 1, n_pos):
                gap = 0
                while (e < hi and gap <= max_gap and not member[i - 1, seg_list[e]]
                       and not member[i, seg_list[e]]):
                    gap += seg_len[e]
                    e += 1
                if gap > max_gap or e >= hi or not member[i, seg_list[e]]:
                    ok = False
                    break
                while e < hi and member[i, seg_list[e]]:
                    e += 1
            if ok:
                out[cnt] = b
                cnt += 1
    return cnt


@numba.njit(cache=True)
def adaptive_bounds(firsts, member, seg_list, seg_doc, doc_offsets, out):
    """Coarsened segment boundaries of adaptive hits: ``out[h, i]`` = first row of the run
    matched to V_i, ``out[h, L]`` = one past the last row of the V_L run (maximal). A
    transition between two runs (:func:`adaptive_hits`) is skipped: its rows count with
    the run before it."""
    n_pos = member.shape[0]
    for h in range(firsts.shape[0]):
        e = firsts[h]
        hi = doc_offsets[seg_doc[e] + 1]
        for i in range(n_pos):
            while i > 0 and e < hi and not member[i, seg_list[e]]:
                e += 1
            out[h, i] = e
            while e < hi and member[i, seg_list[e]]:
                e += 1
        out[h, n_pos] = e


@numba.njit(cache=True)
def overlap_pairs(doc_a, start_a, end_a, doc_b, start_b, end_b, out_a, out_b):
    """Pairs (i, j) of hits of two groups in the same document whose frame ranges
    [start, end] (inclusive) overlap. Both inputs are sorted by (doc, start). Writes into
    ``out_a``/``out_b`` while room is left and returns the total number of pairs (call
    again with larger outputs if it exceeds their size)."""
    cnt = 0
    j0 = 0
    nb = doc_b.shape[0]
    # numba twin of keyframes/_kernels.py pair_spans (the same two-pointer walk): it writes
    # spans, this the pairs' indices, and a kernel calls kernels of its own file only
    # (numba's cache does not see changes to another file; util/_bits.py)
    for i in range(doc_a.shape[0]):
        while j0 < nb and doc_b[j0] < doc_a[i]:
            j0 += 1
        j = j0
        while j < nb and doc_b[j] == doc_a[i] and start_b[j] <= end_a[i]:
            if end_b[j] >= start_a[i]:
                if cnt < out_a.shape[0]:
                    out_a[cnt] = i
                    out_b[cnt] = j
                cnt += 1
            j += 1
    return cnt


@numba.njit(cache=True)
def merge_rows(rows, seg_doc, seg_start, seg_len, out_doc, out_start, out_end):
    """Frame intervals of a sorted set of segment rows, adjacent segments of one document
    merged (for keyframe search, docs/method.md §5). Returns the number of intervals;
    ``out_end`` is inclusive."""
    cnt = 0
    for i in range(rows.shape[0]):
        r = rows[i]
        if cnt > 0 and r == rows[i - 1] + 1 and seg_doc[r] == out_doc[cnt - 1]:
            out_end[cnt - 1] = seg_start[r] + seg_len[r] - 1
        else:
            out_doc[cnt] = seg_doc[r]
            out_start[cnt] = seg_start[r]
            out_end[cnt] = seg_start[r] + seg_len[r] - 1
            cnt += 1
    return cnt


@numba.njit(cache=True)
def smoothed_hits(docs, doc_offsets, code, seg_start, seg_len, mask, values, min_len,
                  out_doc, out_rows, out_bounds):
    """Hits of a query by example on the documents' *smoothed* segmentation
    ([MRC05] §5.2 adaptive hits, with the example's own smoothing applied to the documents).

    For each document number in ``docs``: its segments are projected onto the query's
    chosen bits (``code & mask``) and equal neighbours joined (the runs of [MRC05]'s
    coarsening); runs shorter than ``min_len`` frames but the first and last (the
    recording's ends cut a pose short) are then given to the run before them and equal
    neighbours joined again — the rule of :func:`mtanno.index.example.drop_short_segments`
    with ``keep_ends``, which the example's segmentation went through — and a hit is
    ``L = len(values)`` consecutive smoothed runs with exactly those projected values.
    Writes per hit its document, the segment row where each of its runs starts plus one
    past its last row (``out_rows``, hits × (L+1)) and the runs' start frames plus end + 1
    (``out_bounds``); returns the number of hits (outputs must hold one row per segment of
    the candidate documents)."""
    L = values.shape[0]
    cnt = 0
    for di in range(docs.shape[0]):
        d = docs[di]
        lo = doc_offsets[d]
        hi = doc_offsets[d + 1]
        n = hi - lo
        if n == 0:
            continue
        # projected runs: value, first row, frames
        r_val = np.empty(n, np.int64)
        r_row = np.empty(n, np.int64)
        r_len = np.empty(n, np.int64)
        nr = 0
        for r in range(lo, hi):
            v = code[r] & mask
            if nr > 0 and r_val[nr - 1] == v:
                r_len[nr - 1] += seg_len[r]
            else:
                r_val[nr] = v
                r_row[nr] = r
                r_len[nr] = seg_len[r]
                nr += 1
        # drop the short runs but the first and last (drop_short_segments, keep_ends)
        c_val = np.empty(nr, np.int64)
        c_row = np.empty(nr, np.int64)
        c_start = np.empty(nr, np.int64)
        c_len = np.empty(nr, np.int64)
        nc = 0
        frame = seg_start[lo]
        for k in range(nr):
            if nc > 0 and (c_val[nc - 1] == r_val[k]
                           or (r_len[k] < min_len and k < nr - 1)):
                c_len[nc - 1] += r_len[k]  # a transient, or the same value again
            else:
                c_val[nc] = r_val[k]
                c_row[nc] = r_row[k]
                c_start[nc] = frame
                c_len[nc] = r_len[k]
                nc += 1
            frame += r_len[k]
        for k in range(nc - L + 1):
            ok = True
            for i in range(L):
                if c_val[k + i] != values[i]:
                    ok = False
                    break
            if not ok:
                continue
            out_doc[cnt] = d
            for i in range(L):
                out_rows[cnt, i] = c_row[k + i]
                out_bounds[cnt, i] = c_start[k + i]
            last = k + L - 1
            out_rows[cnt, L] = c_row[last + 1] if last + 1 < nc else hi
            out_bounds[cnt, L] = c_start[last] + c_len[last]
            cnt += 1
    return cnt
