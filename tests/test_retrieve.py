"""Hit extraction (docs/method.md §3.5) against the literal oracle, hand-made Δ curves,
ranking."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from naive_match import hits_naive, match_naive

from mtanno.errors import MtannoError
from mtanno.retrieve import Hit, HitList, extract_hits, retrieve


def random_curve(rng, n):
    # few distinct values: many exact ties; some frames without a path
    delta = rng.integers(0, 12, size=n) / 40.0
    delta[rng.random(n) < 0.15] = np.inf
    start = np.array([rng.integers(max(0, e - 25), e + 1) for e in range(n)], dtype=np.int64)
    start[np.isinf(delta)] = -1
    return delta, start


@settings(max_examples=300, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 120),
       mode=st.sampled_from(["retrieval", "classification"]),
       tau=st.sampled_from([0.0, 0.05, 0.1, 0.175, 0.3]), max_hits=st.integers(1, 12),
       eb=st.sampled_from([0.0, 0.5, 1.0]), ef=st.sampled_from([0.0, 0.1, 0.33]),
       sb=st.sampled_from([0.0, 0.1]), sf=st.sampled_from([0.0, 0.5, 1.2]))
def test_extract_hits_equals_naive(seed, n, mode, tau, max_hits, eb, ef, sb, sf):
    delta, start = random_curve(np.random.default_rng(seed), n)
    got = extract_hits(delta, start, tau=tau, mode=mode, max_hits=max_hits, end_excl=(eb, ef),
                       start_excl=(sb, sf), doc="d", doc_index=3)
    want, truncated = hits_naive(delta, start, tau=tau, mode=mode, max_hits=max_hits,
                                 end_excl=(eb, ef), start_excl=(sb, sf))
    assert [(h.start, h.end, h.cost) for h in got] == want
    assert got.truncated == truncated and got.cap == max_hits
    assert all(h.doc == "d" and h.doc_index == 3 for h in got)
    costs = [h.cost for h in got]
    assert costs == sorted(costs)


def test_retrieval_rules_on_a_hand_made_curve():
    inf = math.inf
    #        0    1    2    3    4    5    6    7    8    9   10   11   12   13   14   15
    delta = [inf, inf, inf, .05, .04, .04, .09, inf, inf, inf, .02, .03, .01, inf, .08, .5]
    start = [-1, -1, -1, 0, 0, 1, 2, -1, -1, -1, 8, 8, 9, -1, 12, 13]
    hits = extract_hits(np.array(delta), np.array(start), tau=0.1)
    # 12 (start 9, len 4) first: blanks ends [10, 13], start zone [8, 11]; 10, 11 are gone.
    # 4 (.04, before 5 on the tie; start 0, len 5): blanks [1, 5], start zone [0, 3].
    # 14 (start 12, free) is recorded. 6 (start 2, inside [0, 3]) is dropped. 15 is above τ.
    assert [(h.start, h.end, h.cost) for h in hits] == [(9, 12, .01), (0, 4, .04), (12, 14, .08)]
    assert not hits.truncated
    assert [h.length for h in hits] == [4, 5, 3]


def test_ties_go_to_the_lowest_frame_and_classification_blanks_the_hit_only():
    delta = np.array([0.1, 0.0, 0.0, 0.0, 0.2])
    start = np.array([0, 0, 1, 1, 3])
    hits = extract_hits(delta, start, tau=0.15, mode="classification", max_hits=10)
    # 1 (start 0) blanks [0, 1]; then 2 (start 1) blanks [1, 2]; then 3 (start 1); 0 is gone
    assert [(h.start, h.end) for h in hits] == [(0, 1), (1, 2), (1, 3)]


def test_cap_flag_only_when_something_was_cut_off():
    delta = np.array([0.0, 0.01, 0.02])
    start = np.array([0, 1, 2])
    full = extract_hits(delta, start, tau=1, mode="classification", max_hits=3)
    assert len(full) == 3 and not full.truncated
    capped = extract_hits(delta, start, tau=1, mode="classification", max_hits=2)
    assert len(capped) == 2 and capped.truncated
    # retrieval: the third candidate would be dropped (its start is covered), so the cap cuts
    # nothing off
    start_r = np.array([0, 0, 0])
    r = extract_hits(delta, start_r, tau=1, end_excl=(0, 0), start_excl=(0, 0), max_hits=1)
    assert len(r) == 1 and not r.truncated


def test_nan_counts_as_no_match():
    hits = extract_hits(np.array([np.nan, 0.01, np.nan]), np.array([-1, 0, -1]), tau=0.1)
    assert [(h.start, h.end) for h in hits] == [(0, 1)]


@pytest.mark.parametrize("kwargs, message", [
    (dict(mode="best"), "unknown hit mode"),
    (dict(max_hits=0), "positive integer"),
    (dict(max_hits=2.5), "positive integer"),
    (dict(tau="x"), "tau must be a number"),
    (dict(tau=float("nan")), "NaN"),
    (dict(end_excl=(0.5,)), "pair of numbers"),
    (dict(start_excl=(-0.1, 0.5)), "non-negative"),
    (dict(start=np.array([0, 0])), "equal length"),
    (dict(start=np.array([0, 2, 0])), "0..end"),
    (dict(start=np.array([0.0, 0.0, 0.0])), "integer"),
])
def test_bad_input_raises_mtanno_error(kwargs, message):
    args = dict(delta=np.array([0.0, 0.0, 0.0]), start=np.array([0, 0, 0]), tau=0.1)
    args.update(kwargs)
    with pytest.raises(MtannoError, match=message):
        extract_hits(args.pop("delta"), args.pop("start"), **args)


def test_retrieve_ranks_across_documents_like_one_greedy_pass():
    rng = np.random.default_rng(5)
    V = rng.integers(0, 2, size=(8, 6)).astype(float)
    V[rng.random(V.shape) < 0.3] = 0.5
    w = np.ones(6)
    docs = [(f"doc{i}", (rng.random((8, n)) < 0.5).astype(np.uint8))
            for i, n in enumerate([40, 0, 25, 60])]
    docs.append(("copy", docs[0][1].copy()))  # equal costs in two documents: earlier doc first
    hits = retrieve(V, w, docs, tau=0.3, max_hits=1000)
    want = []
    for i, (name, X) in enumerate(docs):
        d, s = match_naive(V, w, X)
        for rank, (a, e, c) in enumerate(hits_naive(d, s, tau=0.3, mode="retrieval",
                                                    max_hits=1000)[0]):
            want.append((c, i, rank, name, a, e))
    want.sort(key=lambda t: t[:3])
    assert [(h.cost, h.doc_index, h.doc, h.start, h.end) for h in hits] == \
        [(c, i, name, a, e) for c, i, _, name, a, e in want]
    assert len(hits) > 5 and not hits.truncated
    assert len({h.doc_index for h in hits}) >= 3
    capped = retrieve(V, w, docs, tau=0.3, max_hits=3)
    assert list(capped) == list(hits)[:3] and capped.truncated


def test_retrieve_rejects_bad_documents():
    with pytest.raises(MtannoError, match="pairs"):
        retrieve(np.zeros((2, 2)), np.ones(2), [np.zeros((2, 4))], tau=0.1)
    with pytest.raises(MtannoError, match="2 features"):
        retrieve(np.zeros((2, 2)), np.ones(2), [("a", np.zeros((3, 4)))], tau=0.1)


def test_hitlist_is_a_list_of_hits():
    hl = HitList([Hit("a", 0, 4, 0.1)], truncated=True, cap=1)
    assert hl == [Hit("a", 0, 4, 0.1)] and hl.truncated and hl.cap == 1
