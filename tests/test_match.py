"""The streaming bit-packed matching kernels against the full-matrix oracle (tests/naive_match.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from naive_match import match_naive

from mtanno.errors import MtannoError
from mtanno.templates.match import PreparedTemplate, _pack_frames, match_documents, match_template

STEP_SETTINGS = [
    (((1, 1), (1, 2), (2, 1)), (1.0, 1.0, 2.0)),   # default (fast kernel)
    (((1, 1), (1, 2), (2, 1)), (2.0, 0.5, 1.0)),   # default steps, other weights (fast kernel)
    (((1, 1), (0, 1), (1, 0)), (1.0, 1.0, 1.0)),   # the reference's built-in defaults
    (((2, 1), (1, 1), (1, 2)), (2.0, 1.0, 1.0)),   # same steps, other order: other ties
    (((1, 1), (1, 3), (3, 1), (1, 2)), (1.0, 1.5, 3.0, 1.0)),
    (((1, 0), (0, 2)), (1.0, 0.25)),
]


def random_case(rng, f, K, L, p_wild):
    V = rng.integers(0, 2, size=(f, K)).astype(float)
    V[rng.random((f, K)) < p_wild] = 0.5
    if K > 1 and rng.random() < 0.3:
        V[:, rng.integers(K)] = 0.5  # an all-wildcard column
    w = rng.uniform(0.0, 3.0, size=K)  # rounds to 0..3 copies: expansion is exercised
    X = (rng.random((f, L)) < rng.uniform(0.1, 0.9)).astype(np.uint8)
    return V, w, X


def assert_same(got, want):
    d, s = got
    dn, sn = want
    assert d.dtype == np.float64 and s.dtype == np.int64
    np.testing.assert_array_equal(d, dn)
    np.testing.assert_array_equal(s, sn)


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), f=st.sampled_from([1, 3, 40, 64, 65, 130]),
       K=st.integers(1, 9), L=st.integers(0, 25), p_wild=st.sampled_from([0.0, 0.2, 0.6, 1.0]),
       variant=st.sampled_from(["reference", "paper"]),
       steps=st.sampled_from(range(len(STEP_SETTINGS))))
def test_streaming_equals_naive(seed, f, K, L, p_wild, variant, steps):
    rng = np.random.default_rng(seed)
    V, w, X = random_case(rng, f, K, L, p_wild)
    st_, sw = STEP_SETTINGS[steps]
    got = match_template(V, w, X, variant=variant, steps=st_, step_weights=sw)
    assert_same(got, match_naive(V, w, X, variant=variant, steps=st_, step_weights=sw))


@pytest.mark.parametrize("variant", ["reference", "paper"])
def test_longer_documents_and_k_greater_than_l(variant):
    rng = np.random.default_rng(7)
    for f, K, L in [(40, 30, 200), (40, 60, 20), (12, 5, 400), (70, 8, 60), (40, 1, 30)]:
        V, w, X = random_case(rng, f, K, L, 0.2)
        for st_, sw in STEP_SETTINGS[:3]:
            got = match_template(V, w, X, variant=variant, steps=st_, step_weights=sw)
            assert_same(got, match_naive(V, w, X, variant=variant, steps=st_, step_weights=sw))


def test_templates_close_to_the_document_give_ties_and_zero_costs():
    # a template cut from the document itself: many exact zeros and equal costs, the hard case
    # for tie-breaking
    rng = np.random.default_rng(3)
    X = (rng.random((10, 80)) < 0.5).astype(np.uint8)
    V = X[:, 20:32].astype(float)
    V[rng.random(V.shape) < 0.5] = 0.5
    for variant in ("reference", "paper"):
        got = match_template(V, np.ones(12), X, variant=variant)
        assert_same(got, match_naive(V, np.ones(12), X, variant=variant))
        assert np.min(got[0]) == 0.0


def test_no_path_ends_before_the_slope_allows_it():
    # steps (1,1),(1,2),(2,1): a template of K columns needs at least ceil(K/2) frames
    V = np.zeros((2, 7))
    d, s = match_template(V, np.ones(7), np.zeros((2, 10), np.uint8))
    assert np.all(np.isinf(d[:3])) and np.all(s[:3] == -1)
    assert np.all(np.isfinite(d[3:])) and np.all(d[3:] == 0.0)
    assert s[3] == 0


def test_batch_documents_are_independent():
    rng = np.random.default_rng(11)
    V, w, _ = random_case(rng, 40, 6, 0, 0.3)
    docs = [(rng.random((40, n)) < 0.4).astype(np.uint8) for n in (0, 1, 5, 30, 17)]
    res = match_documents(V, w, docs)
    assert len(res) == len(docs)
    for X, got in zip(docs, res):
        assert_same(got, match_naive(V, w, X))
    # the same documents concatenated are not the same thing: paths may cross boundaries
    joined = match_template(V, w, np.concatenate(docs, axis=1))
    split = np.concatenate([d for d, _ in res])
    assert joined[0].shape == split.shape


def test_bool_and_float_documents_are_accepted():
    rng = np.random.default_rng(2)
    V, w, X = random_case(rng, 40, 5, 20, 0.2)
    ref = match_template(V, w, X)
    assert_same(match_template(V, w, X.astype(bool)), ref)
    assert_same(match_template(V, w, X.astype(float)), ref)
    assert_same(match_template(V, w, np.asfortranarray(X)), ref)


def test_memory_layout_of_packing():
    X = np.zeros((70, 3), np.uint8)
    X[0, 0] = X[63, 1] = X[64, 2] = X[69, 2] = 1
    out = np.empty((3, 2), np.uint64)
    _pack_frames(X, out)
    assert out.tolist() == [[1, 0], [1 << 63, 0], [0, 1 | (1 << 5)]]


@pytest.mark.parametrize("kwargs, message", [
    (dict(values=np.full((3, 2), 0.3)), "quantized"),
    (dict(values=np.zeros((3, 0))), "non-empty"),
    (dict(values=np.zeros(3)), "non-empty"),
    (dict(weights=np.ones(3)), "one entry per column"),
    (dict(weights=np.array([1.0, -1.0])), "non-negative"),
    (dict(weights=np.array([1.0, np.nan])), "finite"),
    (dict(X=np.zeros((4, 5), np.uint8)), "3 features"),
    (dict(X=np.full((3, 5), 2, np.uint8)), "0 or 1"),
    (dict(X=np.full((3, 5), 0.5)), "0 or 1"),
    (dict(variant="fast"), "unknown matching variant"),
    (dict(steps=((0, 0), (1, 1)), step_weights=(1, 1)), "(0, 0)"),
    (dict(steps=((1, -1),), step_weights=(1,)), "non-negative integers"),
    (dict(steps=((1, 1.5),), step_weights=(1,)), "non-negative integers"),
    (dict(steps=((1, 1),), step_weights=(1, 2)), "one weight per step"),
    (dict(steps=(), step_weights=()), "non-empty"),
    (dict(steps=((1, 1),), step_weights=(-1,)), "non-negative"),
])
def test_bad_input_raises_mtanno_error(kwargs, message):
    args = dict(values=np.zeros((3, 2)), weights=np.ones(2), X=np.zeros((3, 5), np.uint8))
    options = {k: kwargs.pop(k) for k in ("variant", "steps", "step_weights") if k in kwargs}
    args.update(kwargs)
    with pytest.raises(MtannoError, match=message.replace("(", r"\(").replace(")", r"\)")):
        match_template(args["values"], args["weights"], args["X"], **options)


def test_prepared_template_is_reusable():
    rng = np.random.default_rng(9)
    V, w, _ = random_case(rng, 40, 7, 0, 0.3)
    prep = PreparedTemplate(V, w, variant="paper")
    for n in (3, 50, 0, 21):
        X = (rng.random((40, n)) < 0.5).astype(np.uint8)
        assert_same(prep.match(X), match_naive(V, w, X, variant="paper"))
    with pytest.raises(MtannoError, match="document 2 must be"):
        prep.match_documents([np.zeros((40, 2), np.uint8), np.zeros((39, 2), np.uint8)])


@pytest.mark.parametrize("variant", ["reference", "paper"])
def test_windows_of_a_few_template_lengths_equal_naive(variant):
    """Spans of one to three template lengths (keyframe windows): the kernel skips the
    cells of a span's first frames that no path reaches yet and of its last frames that
    cannot reach the template's end any more; every span still equals the oracle."""
    from mtanno.templates.match import pack_document

    rng = np.random.default_rng(5)
    for K in (7, 24, 41):
        V, w, _ = random_case(rng, 40, K, 0, 0.2)
        prep = PreparedTemplate(V, w, variant=variant)
        n = prep.K
        X = (rng.random((40, 12 * n)) < 0.4).astype(np.uint8)
        lengths = rng.integers(max(1, n // 2 - 2), 3 * n + 3, size=6)
        gaps = rng.integers(1, 5, size=6)
        firsts = np.cumsum(gaps + np.concatenate(([0], lengths[:-1]))) - 1
        keep = firsts + lengths - 1 < X.shape[1]
        firsts, lasts = firsts[keep], (firsts + lengths - 1)[keep]
        delta, start = prep.match_spans(pack_document(X, 40), firsts, lasts)
        for a, b in zip(firsts, lasts):
            dn, sn = match_naive(V, w, X[:, a:b + 1], variant=variant)
            np.testing.assert_array_equal(delta[a:b + 1], dn)
            np.testing.assert_array_equal(start[a:b + 1], np.where(sn >= 0, sn + a, sn))


def _lengths_by_paths(n, steps):
    """Every number of document frames a path from column 0 to column n − 1 can cover
    (exhaustive, small n; steps advancing the document only are not allowed here)."""
    seen, todo, out = set(), [(0, 0)], set()
    while todo:
        r, d = todo.pop()
        if (r, d) in seen:
            continue
        seen.add((r, d))
        if r == n - 1:
            out.add(d + 1)
        for a, b in steps:
            if r + a <= n - 1:
                todo.append((r + a, d + b))
    return out


@pytest.mark.parametrize("steps", [s for s, _ in STEP_SETTINGS if all(a > 0 for a, _ in s)])
@pytest.mark.parametrize("n", [1, 2, 3, 4, 7, 12])
def test_match_lengths_against_all_paths(n, steps):
    from mtanno.templates.match import match_lengths

    got = _lengths_by_paths(n, steps)
    assert match_lengths(np.ones(n), variant="paper", steps=steps) == (min(got), max(got))


def test_match_lengths_default_steps_and_the_kernel():
    """A zero-cost match of a template whose first and last columns ask for a feature that
    is on at two frames only exists exactly when their distance is in the range."""
    from mtanno.templates.match import column_repeats, match_lengths

    w = np.array([1.0, 2.4, 0.2, 1.6, 1.0])  # expands to 1 + 2 + 1 + 2 + 1 = 7 columns
    assert column_repeats(w).sum() == 7
    lo, hi = match_lengths(w)
    assert (lo, hi) == (7 // 2 + 1, 2 * 7 - 1)
    V = np.full((1, 5), 0.5)
    V[0, 0] = V[0, -1] = 1.0
    for span in range(1, 20):
        X = np.zeros((1, 30), dtype=np.uint8)
        X[0, 5] = X[0, 5 + span - 1] = 1
        delta, start = match_template(V, w, X)
        zero = delta[5 + span - 1] == 0 and start[5 + span - 1] == 5
        assert zero == (lo <= span <= hi), span
    assert match_lengths(np.ones(4), steps=((1, 1), (0, 1))) == (4, None)
    assert match_lengths(np.ones(3), variant="paper") == (2, 5)
    for bad in ([], [np.nan], [-1.0], [[1.0]]):
        with pytest.raises(MtannoError):
            match_lengths(np.array(bad))
    with pytest.raises(MtannoError, match="no warping path"):
        match_lengths(np.ones(4), variant="paper", steps=((2, 1),))
    with pytest.raises(MtannoError, match="variant"):
        match_lengths(np.ones(4), variant="fast")
