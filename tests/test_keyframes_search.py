"""Keyframe search (docs/method.md §5) against the brute-force oracle of naive_keyframes.py:
random documents and random queries, through an index and by a direct scan."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from naive_keyframes import hits_naive, random_query, windows_naive

from mtanno.errors import MtannoError
from mtanno.index import index_from_matrices
from mtanno.keyframes import (
    Gap,
    Keyframe,
    KeyframeQuery,
    KeyframeSet,
    class_windows,
    search_documents,
    search_index,
)
from mtanno.keyframes.search import chain_hits

NAMES = ["a", "b", "c", "d", "e", "f", "g"]
GROUPS = {"g": ("a", "b", "c", "d", "e"), "h": ("f", "g")}
SMALL = {"g": ("a", "b", "c"), "h": ("d", "e")}


def _docs(rng, n_docs, p=0.25):
    out = {}
    for i in range(n_docs):
        L = int(rng.integers(1, 40))
        out[f"d{i}"] = (np.cumsum(rng.random((len(NAMES), L)) < p, axis=1) % 2).astype(np.uint8)
    return out


def _as_runs(hits, d):
    sel = hits.doc == d
    return list(zip(hits.start[sel].tolist(), hits.end[sel].tolist()))


def check_against_oracle(seed):
    rng = np.random.default_rng(seed)
    docs = _docs(rng, int(rng.integers(1, 4)))
    q = random_query(rng, GROUPS)
    idx = index_from_matrices(docs, NAMES, GROUPS)
    by_index = search_index(idx, q)
    by_scan = search_documents(list(docs.items()), NAMES, q)
    left, right = int(rng.integers(0, 5)), int(rng.integers(0, 5))
    for name, X in docs.items():
        want = hits_naive(X, NAMES, q)
        di = by_index.names.index(name)
        ds = by_scan.names.index(name)
        assert _as_runs(by_index, di) == want
        assert _as_runs(by_scan, ds) == want
        wd, ws, we = by_index.windows(widths=(left, right))
        got = list(zip(ws[wd == di].tolist(), we[wd == di].tolist()))
        assert got == windows_naive(X, NAMES, q, left, right)
    for h in range(len(by_scan)):  # the earliest chain lies in its hit and is a chain
        ch = by_scan.chains[h]
        X = docs[by_scan.names[by_scan.doc[h]]]
        assert by_scan.start[h] == ch[0] and ch[-1] <= by_scan.end[h]
        from naive_keyframes import matches
        for j, t in enumerate(ch):
            assert matches(X, NAMES, q, j, int(t))
            if j:
                g = q.gaps[j - 1]
                assert g.dmin <= t - ch[j - 1] <= (g.dmax if g.dmax is not None else 10**9)


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_search_equals_brute_force(seed):
    check_against_oracle(seed)


def test_dense_documents_and_wide_gaps():
    """Long runs and unbounded gaps: many interval pairs per level."""
    for seed in range(40):
        rng = np.random.default_rng(1000 + seed)
        docs = _docs(rng, 2, p=0.05)
        q = random_query(rng, GROUPS, n_max=5)
        hits = search_documents(list(docs.items()), NAMES, q)
        for d, X in enumerate(docs.values()):
            assert _as_runs(hits, d) == hits_naive(X, NAMES, q)


def test_worked_example():
    """F15 on at frames 2–4; keyframe 2 (F15 off) 1–3 frames later: chains (2,5), (3,5),
    (3,6), (4,5), (4,6), (4,7) → one hit 2–7; widened 0 left, 2·(5−3) = 4 right."""
    X = np.zeros((7, 20), np.uint8)
    X[0, 2:5] = 1
    q = KeyframeQuery("c", "custom", SMALL, [Keyframe("g", "1**", 1), Keyframe("g", "0**", 3)],
                      [Gap(1, 3)], 5)
    h = search_documents([("x", X)], NAMES, q)
    assert (h.start.tolist(), h.end.tolist(), h.chains.tolist()) == ([2], [7], [[2, 5]])
    d, s, e = h.windows()
    assert (s.tolist(), e.tolist()) == ([2], [11])


def test_same_frame_across_groups():
    """Gap (0, 0) joins conditions on two groups at one frame."""
    X = np.zeros((7, 10), np.uint8)
    X[0, [1, 2, 6]] = 1
    X[3, [2, 3, 7]] = 1
    q = KeyframeQuery("c", "custom", SMALL, [Keyframe("g", "1**", 4), Keyframe("h", "1*", 4)],
                      [Gap(0, 0)], 8)
    h = search_documents([("x", X)], NAMES, q)
    assert list(zip(h.start.tolist(), h.end.tolist())) == [(2, 2)]


def test_chain_hits_array_api():
    lv = [(np.array([0, 0]), np.array([0, 10]), np.array([1, 12])),
          (np.array([0]), np.array([5]), np.array([5]))]
    d, s, e = chain_hits(lv, [(3, 5)])
    assert (d.tolist(), s.tolist(), e.tolist()) == ([0], [0], [5])
    with pytest.raises(MtannoError):
        chain_hits(lv, [])


def test_index_needs_one_group_per_keyframe():
    docs = {"x": np.zeros((7, 4), np.uint8)}
    idx = index_from_matrices(docs, NAMES, {"g": ("a", "b"), "h": ("c", "d", "e", "f", "g")})
    q = KeyframeQuery("c", "custom", SMALL, [Keyframe("g", "11*", 1)], [], 2)
    assert len(search_index(idx, q)) == 0
    q = KeyframeQuery("c", "custom", SMALL, [Keyframe("g", "1*1", 1)], [], 2)
    with pytest.raises(MtannoError, match="no single index group"):
        search_index(idx, q)


def test_wrong_feature_set_or_missing_feature():
    docs = {"x": np.zeros((7, 4), np.uint8)}
    idx = index_from_matrices(docs, NAMES, GROUPS, feature_set="other")
    q = KeyframeQuery("c", "custom", SMALL, [Keyframe("g", "1**", 1)], [], 2)
    with pytest.raises(MtannoError, match="feature set 'custom' but the index holds 'other'"):
        search_index(idx, q)
    q2 = KeyframeQuery("c", "custom", {"g": ("a", "zz")}, [Keyframe("g", "1*", 1)], [], 2)
    with pytest.raises(MtannoError, match="'zz', which the feature file lacks"):
        search_documents([("x", docs["x"])], NAMES, q2)


def test_search_without_jit():
    """The interval kernels as plain Python give the oracle's answers too."""
    from nojit import run_without_jit

    run_without_jit("test_keyframes_search", "check_against_oracle", *[(s,) for s in range(60)])


def test_mismatch_tolerance():
    """A keyframe with one mismatch allowed matches frames differing in one fixed entry."""
    X = np.zeros((7, 6), np.uint8)
    X[:4, 1] = [1, 1, 1, 1]      # exact
    X[:4, 3] = [1, 0, 1, 1]      # one off
    X[:4, 5] = [0, 0, 1, 1]      # two off
    q = KeyframeQuery("c", "custom", GROUPS, [Keyframe("g", "1111*", 1, 1)], [], 2)
    h = search_documents([("x", X)], NAMES, q)
    assert list(zip(h.start.tolist(), h.end.tolist())) == [(1, 1), (3, 3)]
    idx = index_from_matrices({"x": X}, NAMES, GROUPS)
    hi = search_index(idx, q)
    assert list(zip(hi.start.tolist(), hi.end.tolist())) == [(1, 1), (3, 3)]
    with pytest.raises(MtannoError, match="mismatch"):
        KeyframeQuery("c", "custom", GROUPS, [Keyframe("g", "11***", 1, 1)], [], 2)


def _naive_runs(X, rows, values, tol):
    """Runs of frames of X (features × frames) with at most ``tol`` of ``rows`` differing
    from ``values``."""
    from naive_keyframes import runs

    bad = (X[rows, :] != np.asarray(values, np.uint8)[:, None]).sum(axis=0)
    return runs(bad <= tol)


def check_keyframe_sets(seed):
    """Many keyframes matched in one pass (the cached kernel behind ``class_windows``)
    equal a naive scan per keyframe: more than 64 features (two words a frame), more
    than 64 keyframes (two passes), and documents with more distinct frame vectors than
    the cache keeps."""
    from mtanno.keyframes.search import _Scanner
    from mtanno.templates.match import pack_document

    rng = np.random.default_rng(seed)
    f = int(rng.choice([7, 70]))
    names = [f"x{i}" for i in range(f)]
    L = int(rng.choice([1, 50, 7000]))  # 7000 random frames overflow the cache
    p = 0.5 if L == 7000 else 0.1
    X = (np.cumsum(rng.random((f, L)) < p, axis=1) % 2).astype(np.uint8)
    n = int(rng.choice([7, 70]))
    want, queries = [], {}
    for k in range(n):
        rows = rng.choice(f, size=int(rng.integers(1, min(f, 6) + 1)), replace=False)
        vals = rng.integers(0, 2, size=rows.size)
        tol = int(rng.integers(0, 2)) if rows.size >= 4 else 0
        want.append(_naive_runs(X, rows, vals, tol))
        group = tuple(names[r] for r in rows)
        queries[k] = KeyframeQuery(f"c{k}", "custom", {"g": group},
                                   [Keyframe("g", "".join(map(str, vals)), 1, tol)], [], 2)
    scan = _Scanner.joined([_Scanner(q, names) for q in queries.values()])
    got = scan.levels(pack_document(X, f), 3)
    for (d, s, e), w in zip(got, want):
        assert list(zip(s.tolist(), e.tolist())) == w
        assert np.all(d == 3)


@pytest.mark.parametrize("seed", range(12))
def test_keyframe_sets_in_one_pass(seed):
    check_keyframe_sets(seed)


def test_keyframe_sets_without_jit():
    from nojit import run_without_jit

    run_without_jit("test_keyframes_search", "check_keyframe_sets", *[(s,) for s in range(4)])


@given(st.integers(0, 10_000))
@settings(max_examples=30, deadline=None)
def test_class_windows_equal_each_querys_windows(seed):
    check_class_windows(seed)


def test_class_windows_without_jit():
    """The fused kernel behind class_windows (chains, hits and windows in one call) run as
    plain Python."""
    from nojit import run_without_jit

    run_without_jit("test_keyframes_search", "check_class_windows", *[(s,) for s in range(3)])


def check_class_windows(seed):
    """Windows of several classes found together equal each query's own windows."""
    from mtanno.keyframes import class_spans, class_windows, document_windows

    rng = np.random.default_rng(seed)
    X = _docs(rng, 1, p=0.15)["d0"]
    queries = {f"c{i}": random_query(rng, GROUPS) for i in range(int(rng.integers(1, 6)))}
    got = class_windows(X, NAMES, queries)
    assert got == {c: document_windows(X, NAMES, q) for c, q in queries.items()}
    assert class_windows(X, NAMES, KeyframeSet(queries, NAMES)) == got  # prepared once
    spans = class_spans(X, NAMES, KeyframeSet(queries, NAMES))  # as arrays
    assert {c: list(zip(s.tolist(), e.tolist())) for c, (s, e) in spans.items()} == got
    assert all(s.dtype == np.int64 and e.dtype == np.int64 for s, e in spans.values())


def test_keyframe_set_checks_its_documents():
    q = KeyframeQuery("c", "custom", SMALL, [Keyframe("g", "1**", 1)], [], 2)
    ks = KeyframeSet({"c": q}, NAMES)
    X = np.zeros((7, 5), np.uint8)
    with pytest.raises(MtannoError, match="prepared for other feature rows"):
        class_windows(X[:6], NAMES[:6], ks)
    with pytest.raises(MtannoError, match="packed document must be uint64"):
        ks.windows(np.zeros((5, 2), np.uint64))
    with pytest.raises(MtannoError, match="which the feature file lacks"):
        KeyframeSet({"c": q}, ["a", "b"])
    assert KeyframeSet({}, NAMES).windows(np.zeros((5, 1), np.uint64)) == {}


def test_annotate_files_takes_a_keyframe_set(tmp_path):
    """A batch annotated with a prepared KeyframeSet equals one with the queries' dict."""
    from mtanno.annotate import ClassModel, annotate_files
    from mtanno.features.store import FeatureLayout, write_features

    rng = np.random.default_rng(1)
    X = (rng.random((7, 60)) < 0.4).astype(np.uint8)
    path = tmp_path / "d.parquet"
    write_features(path, X, NAMES, np.arange(1, 61), {"document": "d", "feature_set": "custom",
                                                   "analysis_fps": 30.0})
    models = [ClassModel("c", X[:, 5:12].astype(float), np.ones(7))]
    q = KeyframeQuery("c", "custom", SMALL, [Keyframe("g", "1**", 1)], [], 7)
    layout = FeatureLayout("custom", tuple(NAMES), 30.0)
    with_dict = annotate_files([path], models, layout=layout, keyframes={"c": q})
    with_set = annotate_files([path], models, layout=layout,
                              keyframes=KeyframeSet({"c": q}, NAMES))
    assert with_set.failed == with_dict.failed == [] and with_set.rows == with_dict.rows


def test_interval_lists_that_would_read_past_their_arrays_are_refused():
    """Interval lists whose doc, start and end arrays differ in length (the kernels read
    them together), gaps out of order, document numbers outside the lengths and packed
    documents of another shape raise instead of reading past the arrays."""
    from mtanno.keyframes.search import chain_levels, first_chains, widen

    lv = [(np.array([0, 0]), np.array([0, 10]), np.array([1, 12])),
          (np.array([0]), np.array([5]), np.array([5]))]
    ragged = (np.zeros(1000, np.int64), np.array([0]), np.array([3]))
    with pytest.raises(MtannoError, match="level 1: doc, start and end must be 1-D arrays of one"):
        chain_hits([ragged, lv[1]], [(3, 5)])
    with pytest.raises(MtannoError, match="level 2: doc, start and end"):
        chain_levels([lv[0], ragged], [(3, 5)])
    with pytest.raises(MtannoError, match="must satisfy 0 ≤ dmin ≤ dmax"):
        chain_hits(lv, [(5, 3)])
    with pytest.raises(MtannoError, match="must satisfy 0 ≤ dmin ≤ dmax"):
        chain_hits(lv, [(0, 2**64)])
    with pytest.raises(MtannoError, match="at least one level"):
        chain_hits([], [])
    B = chain_levels(lv, [(3, 5)])
    hits = chain_hits(lv, [(3, 5)])
    assert first_chains(B, [(3, 5)], hits).tolist() == [[0, 5]]
    with pytest.raises(MtannoError, match="hits: doc, start and end"):
        first_chains(B, [(3, 5)], (np.array([0, 0]), np.array([0]), np.array([5])))
    with pytest.raises(MtannoError, match="has no chain through the levels"):
        first_chains(B, [(3, 5)], (np.array([1]), np.array([0]), np.array([5])))
    with pytest.raises(MtannoError, match="2 levels need 1 gaps"):
        first_chains(B, [], hits)
    lengths = np.array([15, 5])
    with pytest.raises(MtannoError, match="intervals: doc, start and end"):
        widen(np.zeros(1000, np.int64), np.array([2]), np.full(1000, 3), 1, 1, lengths)
    for doc in (2, -1):
        with pytest.raises(MtannoError, match=r"document numbers must lie in 0\.\.1"):
            widen(np.array([doc]), np.array([2]), np.array([3]), 1, 1, lengths)
    from mtanno.keyframes import class_windows
    from mtanno.templates.match import pack_document

    X = np.zeros((len(NAMES), 20), np.uint8)
    q = KeyframeQuery("c", "custom", GROUPS, [Keyframe("g", "0****", 1)], [], 2)
    assert class_windows(X, NAMES, {"c": q}, packed=pack_document(X, len(NAMES))) == {
        "c": [(0, 19)]}
    for packed in (np.zeros((20, 3), np.uint64), np.zeros((10, 1), np.uint64),
                   np.zeros(20, np.uint64), np.zeros((20, 1), np.int64)):
        with pytest.raises(MtannoError, match="packed document must be uint64"):
            class_windows(X, NAMES, {"c": q}, packed=packed)
    with pytest.raises(MtannoError, match=r"matrix must be \(7 × frames\)"):
        class_windows(X[0], NAMES, {"c": q}, packed=pack_document(X, len(NAMES)))
