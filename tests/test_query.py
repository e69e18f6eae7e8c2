"""Queries against a brute-force scan of the segment sequences (MRC05 §5.1–5.2), the eq. 8
worked example, query normalisation, multi-group intersection, ranking, query by example,
JSON query files."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mtanno.errors import MtannoError
from mtanno.index import (
    FuzzySet,
    GroupQuery,
    Query,
    example_query,
    index_from_matrices,
    parse_query,
    run_group,
    search,
)

# --- brute force -----------------------------------------------------------------------


def _members(fs: FuzzySet, n_bits: int) -> set[int]:
    return {v for v in range(1 << n_bits) if any(v & m == val for m, val in fs.patterns)}


def brute_fixed(seqs, sets, mismatches=0, allowed=None):
    """(doc, first segment) of every fixed-length hit: eq. 4/9 with up to m mismatches."""
    L = len(sets)
    allowed = [True] * L if allowed is None else allowed
    hits = []
    for d, w in enumerate(seqs):
        for k in range(len(w) - L + 1):
            bad = [i for i in range(L) if w[k + i] not in sets[i]]
            if len(bad) <= mismatches and all(allowed[i] for i in bad):
                hits.append((d, k))
    return hits


def brute_adaptive(seqs, sets, lengths=None, max_gap=0):
    """(doc, boundaries) of every adaptive fuzzy hit, written from MRC05 §5.2 directly;
    with ``max_gap`` > 0, the runs of consecutive sets may be separated by a transition:
    segments in neither set, at most ``max_gap`` frames in all (``lengths``: segment
    lengths per document)."""
    hits = []
    for d, w in enumerate(seqs):
        M = len(w)
        for k1 in range(M):
            if w[k1] not in sets[0] or (k1 > 0 and w[k1 - 1] in sets[0]):
                continue
            e, bounds, ok = k1, [], True
            for i, V in enumerate(sets):
                gap = 0
                while (i > 0 and max_gap > 0 and e < M and w[e] not in V
                       and w[e] not in sets[i - 1] and gap + lengths[d][e] <= max_gap):
                    gap += lengths[d][e]
                    e += 1
                if e >= M or w[e] not in V:
                    ok = False
                    break
                bounds.append(e)
                while e < M and w[e] in V:
                    e += 1
            if ok:
                hits.append((d, tuple(bounds + [e])))
    return hits


# --- strategies --------------------------------------------------------------------------

N_BITS = 3


@st.composite
def documents(draw, n_features=N_BITS):
    """1–4 documents as feature matrices built from runs of random vectors."""
    docs = {}
    for d in range(draw(st.integers(1, 4))):
        runs = draw(st.lists(st.tuples(st.integers(0, (1 << n_features) - 1), st.integers(1, 4)),
                             min_size=0, max_size=25))
        cols = [[(v >> b) & 1 for b in range(n_features)] for v, n in runs for _ in range(n)]
        docs[f"d{d}"] = np.array(cols, dtype=np.uint8).T.reshape(n_features, -1)
    return docs


@st.composite
def fuzzy_sets(draw, n_bits=N_BITS):
    pats = []
    for _ in range(draw(st.integers(1, 2))):
        m = draw(st.integers(0, (1 << n_bits) - 1))
        if draw(st.booleans()):
            m = (1 << n_bits) - 1  # often exact vectors, so that hits exist
        pats.append((m, draw(st.integers(0, (1 << n_bits) - 1)) & m))
    return FuzzySet(tuple(dict.fromkeys(pats)))


NAMES = [f"f{i}" for i in range(N_BITS)]


def _index(docs):
    return index_from_matrices(docs, NAMES, {"g": NAMES})


def _seqs(idx):
    g = idx.groups["g"]
    return [g.segments(d)[2].tolist() for d in range(len(idx.documents))]


def _query_from_doc(draw, seqs, L):
    """Sets that contain a document's own segment vectors (so a hit exists), loosened."""
    d = draw(st.integers(0, len(seqs) - 1))
    w = seqs[d]
    if len(w) < L:
        return None
    k = draw(st.integers(0, len(w) - L))
    sets = []
    for i in range(L):
        free = draw(st.integers(0, (1 << N_BITS) - 1)) if draw(st.booleans()) else 0
        m = ((1 << N_BITS) - 1) & ~free
        sets.append(FuzzySet(((m, w[k + i] & m),)))
    return sets


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_fixed_modes_equal_brute_force(data):
    docs = data.draw(documents())
    idx = _index(docs)
    seqs = _seqs(idx)
    L = data.draw(st.integers(1, 5))
    sets = (_query_from_doc(data.draw, seqs, L) if data.draw(st.booleans()) else None) \
        or data.draw(st.lists(fuzzy_sets(), min_size=L, max_size=L))
    m = data.draw(st.integers(0, max(0, len(sets) - 1)))
    allowed = tuple(data.draw(st.lists(st.booleans(), min_size=len(sets), max_size=len(sets))))
    gq = GroupQuery("g", tuple(sets), allowed=allowed if data.draw(st.booleans()) else None)
    norm = gq.normalized()
    if norm.trivial or m >= len(norm.sets):
        m = 0
    mem = [_members(s, N_BITS) for s in norm.sets]
    hits = run_group(idx, norm, mode="fuzzy", mismatches=m)
    got = [(int(d), int(r) - int(idx.groups["g"].doc_offsets[d]))
           for d, r in zip(hits.doc, hits.rows[:, 0])]
    assert got == brute_fixed(seqs, mem, m, norm.allowed)
    # frames: the matched segments' start frames, then one past the last frame
    g = idx.groups["g"]
    for row, b in zip(hits.rows[:, 0], hits.bounds):
        starts = g.start[row:row + len(norm.sets)].tolist()
        last = row + len(norm.sets) - 1
        assert b.tolist() == starts + [int(g.start[last] + g.length[last])]
    # exact mode = fuzzy mode when every set is one vector
    if all(len(s.patterns) == 1 and s.patterns[0][0] == (1 << N_BITS) - 1 for s in norm.sets):
        exact = run_group(idx, norm, mode="exact", mismatches=m)
        assert np.array_equal(exact.rows, hits.rows)


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_adaptive_equals_brute_force(data):
    docs = data.draw(documents())
    idx = _index(docs)
    seqs = _seqs(idx)
    L = data.draw(st.integers(1, 5))
    sets = (_query_from_doc(data.draw, seqs, L) if data.draw(st.booleans()) else None) \
        or data.draw(st.lists(fuzzy_sets(), min_size=L, max_size=L))
    norm = GroupQuery("g", tuple(sets)).normalized()
    mem = [_members(s, N_BITS) for s in norm.sets]
    for a, b in zip(mem, mem[1:]):
        assert not a & b  # neighbours disjoint after normalisation
    hits = run_group(idx, norm, mode="adaptive")
    off = idx.groups["g"].doc_offsets
    got = [(int(d), tuple(int(x) - int(off[d]) for x in r)) for d, r in zip(hits.doc, hits.rows)]
    assert got == brute_adaptive(seqs, mem)


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_adaptive_with_transitions_equals_brute_force(data):
    """min_segment N: runs of consecutive query sets may be N − 1 frames apart, the frames
    between them in neither set (a transition); found once each, from any position."""
    docs = data.draw(documents())
    idx = _index(docs)
    seqs = _seqs(idx)
    g = idx.groups["g"]
    lengths = [g.segments(d)[1].tolist() for d in range(len(idx.documents))]
    L = data.draw(st.integers(1, 5))
    sets = (_query_from_doc(data.draw, seqs, L) if data.draw(st.booleans()) else None) \
        or data.draw(st.lists(fuzzy_sets(), min_size=L, max_size=L))
    min_segment = data.draw(st.integers(1, 6))
    norm = GroupQuery("g", tuple(sets)).normalized()
    mem = [_members(s, N_BITS) for s in norm.sets]
    hits = run_group(idx, norm, mode="adaptive", min_segment=min_segment)
    off = g.doc_offsets
    got = [(int(d), tuple(int(x) - int(off[d]) for x in r)) for d, r in zip(hits.doc, hits.rows)]
    assert got == brute_adaptive(seqs, mem, lengths, min_segment - 1)


def test_transitions_in_documents_and_example():
    """One knee bends a frame before the other: with min_segment 1 (MRC05) the example's
    one-frame transient is a query segment of its own and a document without it is missed;
    with min_segment 3 both documents are found."""
    def doc(cols):
        return np.array(cols, np.uint8).T

    r = [0, 0]
    ex = doc([r] * 5 + [[1, 0]] + [[1, 1]] * 10 + [r] * 5)           # transient 10
    other = doc([r] * 6 + [[0, 1]] * 2 + [[1, 1]] * 9 + [[1, 0]] + [r] * 4)  # 01 ×2, 10
    far = doc([r] * 6 + [[0, 1]] * 3 + [[1, 1]] * 9 + [r] * 4)        # 3-frame transition
    idx = index_from_matrices({"ex": ex, "other": other, "far": far}, ["rk", "lk"],
                              {"g": ["rk", "lk"]})
    strict = example_query(idx, ex, ["rk", "lk"], ["rk", "lk"])
    assert len(strict.parts[0].sets) == 4
    assert [idx.documents[d].name for d in search(idx, strict).doc] == ["ex"]
    q = example_query(idx, ex, ["rk", "lk"], ["rk", "lk"], min_segment=3)
    assert q.min_segment == 3 and q.parts[0].lengths == (6, 10, 5)  # transient joins the 00
    hits = search(idx, q)
    assert sorted(idx.documents[d].name for d in hits.doc) == ["ex", "other"]
    assert "far" in [idx.documents[d].name for d in
                     search(idx, replace(q, min_segment=4)).doc]


def test_drop_short_segments():
    from mtanno.index.example import drop_short_segments

    def drop(lengths, values, n):
        return drop_short_segments(np.array(lengths), np.array(values), n)

    assert drop([7, 1, 23, 4], [0, 2, 3, 0], 3) == ([8, 23, 4], [0, 3, 0])
    # a leading transient goes to the segment after it; equal neighbours are joined
    assert drop([1, 5, 2, 5], [1, 0, 1, 0], 3) == ([13], [0])
    assert drop([2, 1, 2], [0, 1, 2], 3) == ([5], [0])  # none long enough: the longest stays
    assert drop([2, 1, 2], [0, 1, 2], 1) == ([2, 1, 2], [0, 1, 2])


def test_hits_are_trimmed_to_the_example_context():
    """A kick at frames 53–68 inside a long idle document: the adaptive runs reach from
    frame 1 to the end, the hit keeps as many idle frames as the example has around it."""
    ex = np.array([[0] * 4 + [1] * 16 + [0] * 3], np.uint8)
    long = np.zeros((1, 185), np.uint8)
    long[0, 52:68] = 1
    idx = index_from_matrices({"ex": ex, "long": long}, ["k"], {"g": ["k"]})
    q = example_query(idx, ex, ["k"], ["k"])
    hits = search(idx, q)
    row = next(r for r in hits.rows(idx) if r["doc"] == "long")
    assert (row["span_start"], row["span_end"]) == (1, 185)
    assert (row["start"], row["end"]) == (53 - 4, 68 + 3)
    assert row["boundaries"] == "g=49 53 69 71"


@settings(max_examples=200, deadline=None)
@given(st.lists(fuzzy_sets(), min_size=1, max_size=6))
def test_normalisation_merges_intersecting_neighbours(sets):
    gq = GroupQuery("g", tuple(sets), lengths=tuple(range(1, len(sets) + 1)))
    norm = gq.normalized()
    mem = [_members(s, N_BITS) for s in norm.sets]
    assert all(not (a & b) for a, b in zip(mem, mem[1:]))
    # every merged set is the union of a run of consecutive original sets, in order
    orig = [_members(s, N_BITS) for s in sets]
    i = 0
    for merged, length in zip(mem, norm.lengths):
        j, acc, total = i, set(), 0
        while acc != merged or (j < len(orig) and total < length):
            acc |= orig[j]
            total += j + 1
            j += 1
        assert acc == merged and total == length
        i = j
    assert i == len(orig)


def test_eq8_worked_example():
    # MRC05 §5.1 eq. 8 and §5.2: F² = (F_r, F_l) on the walk of Fig. 3
    seq = ["11", "01", "11", "10", "11", "01", "11", "10", "11", "01"]
    lens = [3, 2, 4, 1, 5, 2, 3, 2, 2, 4]
    cols = [[int(v[0]), int(v[1])] for v, n in zip(seq, lens) for _ in range(n)]
    idx = index_from_matrices({"walk": np.array(cols, np.uint8).T}, ["Fr", "Fl"],
                              {"F2": ["Fr", "Fl"]})
    g = idx.groups["F2"]

    def code(v):
        return int(v[0]) | int(v[1]) << 1

    # L((11)) = {1,3,5,7,9}, L((01)) = {2,6,10}, L((10)) = {4,8} (1-based segment numbers)
    assert (g.list_of(code("11")) + 1).tolist() == [1, 3, 5, 7, 9]
    assert (g.list_of(code("01")) + 1).tolist() == [2, 6, 10]
    assert (g.list_of(code("10")) + 1).tolist() == [4, 8]
    assert g.list_of(code("00")).size == 0
    q = GroupQuery("F2", tuple(FuzzySet.exact(code(v), 2) for v in ("10", "11", "01")))
    assert (run_group(idx, q, mode="exact").rows[:, 0] + 1).tolist() == [4, 8]
    V13 = FuzzySet.exact(code("00"), 2).union(FuzzySet.exact(code("01"), 2))
    V2 = FuzzySet.exact(code("10"), 2).union(FuzzySet.exact(code("11"), 2))
    q = GroupQuery("F2", (V13, V2, V13))
    ad = run_group(idx, q, mode="adaptive")
    # hits {2, 6}: k1, k2, k3 = 2, 3, 6 and 6, 7, 10 (then one past the V3 run)
    assert (ad.rows + 1).tolist() == [[2, 3, 6, 7], [6, 7, 10, 11]]
    assert len(run_group(idx, q, mode="fuzzy")) == 0  # H_D(F[Q]_fuz) = ∅
    # the adaptive hits equal the exact hits of F_r alone (MRC05 §5.2)
    fr = index_from_matrices({"walk": np.array(cols, np.uint8).T[:1]}, ["Fr"], {"r": ["Fr"]})
    qr = GroupQuery("r", (FuzzySet.exact(0, 1), FuzzySet.exact(1, 1), FuzzySet.exact(0, 1)))
    hr = run_group(fr, qr, mode="exact")
    assert np.array_equal(hr.start, ad.start) and np.array_equal(hr.end, ad.end)
    # frames: hit 1 covers segments 2–6 = frames 4–17 (1-based)
    assert (ad.start + 1).tolist() == [4, 16] and (ad.end + 1).tolist() == [17, 28]


def test_two_groups_intersect_on_frames():
    rng = np.random.default_rng(5)
    names = ["a", "b", "c", "d"]
    docs = {f"x{i}": (np.cumsum(rng.random((4, 80)) < 0.12, axis=1) % 2).astype(np.uint8)
            for i in range(4)}
    idx = index_from_matrices(docs, names, {"g1": ["a", "b"], "g2": ["c", "d"]})
    q1 = GroupQuery("g1", (FuzzySet(((1, 0),)), FuzzySet(((1, 1),)), FuzzySet(((1, 0),))))
    q2 = GroupQuery("g2", (FuzzySet(((3, 0),)), FuzzySet(((3, 3), (3, 1)))))
    h1 = run_group(idx, q1.normalized())
    h2 = run_group(idx, q2.normalized())
    want = set()
    for i in range(len(h1)):
        for j in range(len(h2)):
            if h1.doc[i] == h2.doc[j]:
                s, e = max(h1.start[i], h2.start[j]), min(h1.end[i], h2.end[j])
                if s <= e:
                    want.add((int(h1.doc[i]), int(s), int(e)))
    hits = search(idx, Query((q1, q2), "adaptive"))
    got = set(zip(hits.doc.tolist(), hits.start.tolist(), hits.end.tolist()))
    assert got == want and len(hits) == len(want) and want
    assert set(hits.bounds) == {"g1", "g2"}


def test_ranking_by_segment_lengths():
    # two documents hold the same constellation sequence, one with the query's timing
    def doc(lens):
        return np.array([[0] * lens[0] + [1] * lens[1] + [0] * lens[2]], np.uint8)

    idx = index_from_matrices({"a": doc([5, 20, 5]), "b": doc([5, 9, 5]), "c": doc([1, 10, 1])},
                              ["k"], {"g": ["k"]})
    q = GroupQuery("g", (FuzzySet.exact(0, 1), FuzzySet.exact(1, 1), FuzzySet.exact(0, 1)),
                   lengths=(4, 10, 4))
    hits = search(idx, Query((q,), "exact"))
    assert [idx.documents[d].name for d in hits.doc] == ["b", "c", "a"]
    assert hits.score.tolist() == [1 + 1 + 1, 3 + 0 + 3, 1 + 10 + 1]
    rows = hits.rows(idx)
    # the hit keeps at most 4 frames of the first and last run (the query's lengths); the
    # score and span_start/span_end are those of the untrimmed runs
    assert rows[0] == {"doc": "b", "start": 2, "end": 18, "rank": 1, "score": 3.0,
                       "span_start": 1, "span_end": 19, "boundaries": "g=2 6 15 18"}


def test_example_query_fixes_chosen_bits():
    X = np.array([[0, 0, 1, 1, 1, 0],     # a
                  [1, 0, 1, 0, 1, 0],     # b (not chosen)
                  [0, 0, 0, 1, 1, 1]], np.uint8)  # c
    idx = index_from_matrices({"e": X}, ["a", "b", "c"], {"g": ["a", "b"], "h": ["c"]})
    q = example_query(idx, X, ["a", "b", "c"], ["a", "c"], frames=(1, 5))
    (pg, ph) = q.parts
    assert pg.group == "g" and [s.patterns for s in pg.sets] == [((1, 0),), ((1, 1),), ((1, 0),)]
    assert pg.lengths == (1, 3, 1)
    assert ph.group == "h" and [s.patterns for s in ph.sets] == [((1, 0),), ((1, 1),)]
    assert ph.lengths == (2, 3)
    hits = search(idx, q)
    # adaptive runs are maximal: the a = 0 and c = 0 runs reach back to frame 0 (the span);
    # the hit keeps as many frames of them as the example has (1 of g's, 2 of h's)
    assert len(hits) == 1 and hits.start[0] == 1 and hits.end[0] == 5
    assert hits.span_start[0] == 0 and hits.span_end[0] == 5
    assert hits.bounds["g"].tolist() == [[1, 2, 5, 6]] and hits.bounds["h"].tolist() == [[1, 3, 6]]
    with pytest.raises(MtannoError, match="unknown feature 'zz'"):
        example_query(idx, X, ["a", "b", "c"], ["zz"])
    with pytest.raises(MtannoError, match="outside"):
        example_query(idx, X, ["a", "b", "c"], ["a"], frames=(3, 9))
    with pytest.raises(MtannoError, match="exact mode needs every feature"):
        search(idx, example_query(idx, X, ["a", "b", "c"], ["a"], mode="exact"))


def test_mismatch_options_are_checked():
    # one segment per frame, codes 0 1 2 3 0 1 over features (a, b)
    X = np.array([[0, 1, 0, 1, 0, 1], [0, 0, 1, 1, 0, 0]], np.uint8)
    idx = index_from_matrices({"e": X}, ["a", "b"], {"g": ["a", "b"]})
    q = GroupQuery("g", (FuzzySet.exact(0, 2), FuzzySet.exact(3, 2)))
    with pytest.raises(MtannoError, match="mismatches work with the exact and fuzzy"):
        Query((q,), "adaptive", 1)
    with pytest.raises(MtannoError, match="must be fewer"):
        search(idx, Query((q,), "exact", 2))
    with pytest.raises(MtannoError, match="empty fuzzy set"):
        FuzzySet(())
    assert len(search(idx, Query((q,), "exact"))) == 0
    assert search(idx, Query((q,), "exact", 1)).start.tolist() == [0, 2, 4]
    only_second = GroupQuery("g", q.sets, allowed=(False, True))
    assert search(idx, Query((only_second,), "exact", 1)).start.tolist() == [0, 4]


# --- JSON queries ------------------------------------------------------------------------

def _json_index():
    X = np.array([[0, 0, 1, 1, 0, 0, 1, 1, 0],
                  [0, 1, 1, 0, 0, 1, 1, 0, 0],
                  [1, 1, 1, 1, 0, 0, 0, 0, 0]], np.uint8)
    return index_from_matrices({"e": X}, ["a", "b", "c"], {"g": ["a", "b"], "h": ["c"]},
                               feature_set="mrc05")


def test_parse_query_projects_steps_per_group():
    idx = _json_index()
    q = parse_query({"features": ["a", "c"], "steps": ["0*", ["11", "1*"], "01"],
                     "lengths": [2, 3, 4], "mode": "fuzzy", "mismatches": 1,
                     "allowed_mismatches": [2]}, idx)
    assert q.mode == "fuzzy" and q.mismatches == 1
    g, h = q.parts
    assert [s.patterns for s in g.sets] == [((1, 0),), ((1, 1),), ((1, 0),)]
    assert [s.patterns for s in h.sets] == [((0, 0),), ((1, 1), (0, 0)), ((1, 1),)]
    assert g.allowed == (False, True, False) and g.lengths == (2, 3, 4)
    # group h: "*", {"1", "*"}, "1" all intersect → one universal set → unconstrained
    assert h.normalized().trivial
    assert not g.normalized().trivial


@pytest.mark.parametrize("spec, message", [
    ({"features": ["a"], "steps": [[]]}, "step 1: empty fuzzy set"),
    ({"features": ["zz"], "steps": ["0"]}, "unknown feature 'zz'"),
    ({"features": ["a"], "steps": ["01"]}, "must have one of 0, 1, \\* per chosen feature"),
    ({"features": ["a"], "steps": ["2"]}, "must have one of 0, 1"),
    ({"features": ["a"], "steps": []}, "'steps' must be a non-empty list"),
    ({"features": [], "steps": ["0"]}, "'features' must be a non-empty list"),
    ({"features": ["a"], "steps": ["0"], "feature_set": "mr06-ak40"},
     "query is for feature set 'mr06-ak40' but the index holds 'mrc05'"),
    ({"features": ["a"], "steps": ["0"], "mode": "loose"}, "unknown query mode 'loose'"),
    ({"features": ["a"], "steps": ["0"], "lenghts": [1]}, "unknown key 'lenghts'"),
    ({"features": ["a"], "steps": ["0", "1"], "lengths": [1]}, "'lengths' must list"),
    ({"features": ["a"], "steps": ["0"], "allowed_mismatches": [2]}, "'allowed_mismatches'"),
    ([1, 2], "query must be a JSON object"),
])
def test_parse_query_rejects_bad_input(spec, message):
    with pytest.raises(MtannoError, match=message):
        parse_query(spec, _json_index(), path="q.json")


def test_json_query_end_to_end(tmp_path):
    from mtanno.index import load_query

    idx = _json_index()
    p = tmp_path / "q.json"
    p.write_text(json.dumps({"features": ["a", "b"], "steps": ["00", "11", "00"]}))
    hits = search(idx, load_query(p, idx))
    # a,b = 00 01 11 10 00 01 11 10 00: adaptive runs of 00, then 11 (incl. 01/10? no: only
    # 11 is allowed), so no hit; fuzzy with * for b finds the two "1" blocks of a
    assert len(hits) == 0
    p.write_text(json.dumps({"features": ["a"], "steps": ["0", "1", "0"]}))
    hits = search(idx, load_query(p, idx))
    assert hits.start.tolist() == [0, 4] and hits.end.tolist() == [5, 8]
    p.write_text("{bad")
    with pytest.raises(MtannoError, match="malformed JSON"):
        load_query(p, idx)


def test_rank_by_template_orders_hits_by_cost():
    from mtanno.index import rank_by_template
    from mtanno.templates.match import match_template

    def doc(lens):
        return np.array([[0] * lens[0] + [1] * lens[1] + [0] * lens[2]], np.uint8)

    idx = index_from_matrices({"a": doc([3, 12, 3]), "b": doc([3, 4, 3]), "c": doc([1, 1, 1])},
                              ["k"], {"g": ["k"]})
    q = GroupQuery("g", (FuzzySet.exact(0, 1), FuzzySet.exact(1, 1), FuzzySet.exact(0, 1)))
    hits = search(idx, Query((q,), "exact"))
    values = np.array([[0.0, 1.0, 1.0, 1.0, 1.0, 0.0]])
    weights = np.ones(6)
    ranked = rank_by_template(idx, hits, values, weights, ["k"])
    names = [idx.documents[d].name for d in ranked.doc]
    # each cost is min Δ of the template on the hit's own frames
    for d, s, e, cost in zip(ranked.doc, ranked.start, ranked.end, ranked.cost):
        X = idx.feature_matrix(int(d))[:, s:e + 1]
        delta, _ = match_template(values, weights, X)
        assert cost == (np.min(delta) if np.isfinite(delta).any() else np.inf)
    assert names[0] == "b" and names[-1] == "c" and np.isinf(ranked.cost[-1])
    assert ranked.unfit == 1 and hits.unfit == 0
    assert [r.get("mt_cost") for r in ranked.rows(idx)][-1] is None


def test_queries_refuse_documents_modes_and_sets_outside_the_index():
    """Hits outside their documents, document numbers past the index, unknown modes,
    intersecting neighbours in adaptive mode and ragged mismatch flags raise (the kernels
    and the boundaries after them assume they fit)."""
    from mtanno.index import rank_by_template
    from mtanno.index.query import Hits

    X = np.array([[0, 1, 0, 1, 0, 1], [0, 0, 1, 1, 0, 0]], np.uint8)
    idx = index_from_matrices({"d": X, "e": X}, ["a", "b"], {"g": ["a", "b"]})
    values, weights = np.array([[0.0, 1.0], [0.5, 0.5]]), np.ones(2)

    def hits(doc, start, end):
        return Hits(np.array(doc), np.array(start), np.array(end), np.full(len(doc), np.nan))

    assert len(rank_by_template(idx, hits([1], [0], [5]), values, weights, ["a", "b"])) == 1
    for h, msg in [(hits([2], [0], [3]), "document numbers must lie in 0..1"),
                   (hits([-1], [0], [3]), "document numbers must lie in 0..1"),
                   (hits([0], [4], [2]), "inside their document"),
                   (hits([0], [-1], [2]), "inside their document"),
                   (hits([0], [0], [6]), "inside their document"),
                   (hits([0, 1], [0], [2]), "one document number, start and end per hit")]:
        with pytest.raises(MtannoError, match=msg):
            rank_by_template(idx, h, values, weights, ["a", "b"])
    for d in (2, -1):
        with pytest.raises(MtannoError, match=rf"document number {d} outside 0\.\.1"):
            idx.feature_matrix(d)
    q = GroupQuery("g", (FuzzySet.exact(0, 2), FuzzySet.exact(3, 2)))
    with pytest.raises(MtannoError, match="unknown query mode 'exakt'"):
        run_group(idx, q, mode="exakt")
    loose = GroupQuery("g", (FuzzySet(((0, 0),)), FuzzySet.exact(3, 2)))
    with pytest.raises(MtannoError, match="neighbouring fuzzy sets must be disjoint"):
        run_group(idx, loose, mode="adaptive", min_segment=3)
    assert len(run_group(idx, loose.normalized(), mode="adaptive", min_segment=3)) == 2
    ragged = GroupQuery("g", q.sets)
    object.__setattr__(ragged, "allowed", (True,))  # past GroupQuery's own check
    with pytest.raises(MtannoError, match="1 allowed flags for 2 fuzzy sets"):
        run_group(idx, ragged, mode="fuzzy", mismatches=1)


def test_group_sizes_and_example_matrix_in_memory():
    """index info's rows and query --example's source on an index without files."""
    from mtanno.index import example_matrix, group_sizes

    X = np.array([[0, 0, 1, 1, 1, 0], [1, 1, 1, 0, 0, 0]], np.uint8)
    idx = index_from_matrices({"d": X, "e": X[:, ::-1].copy()}, ["a", "b"], {"g": ["a", "b"]})
    (row,) = group_sizes(idx)
    # d has the codes (b), (b), (a b), (a), (a), () -> 4 segments; e the mirror -> 4
    assert (row["group"], row["features"], row["frames"], row["segments"]) == ("g", 2, 12, 8)
    assert row["possible_lists"] == 4 and row["bytes"] == 0 and row["segments_per_frame"] == 8 / 12
    M, names, label = example_matrix(idx, "e")
    assert names == ["a", "b"] and label == "e" and np.array_equal(M, X[:, ::-1])
    with pytest.raises(MtannoError, match="neither a feature file nor an indexed document"):
        example_matrix(idx, "nope")
