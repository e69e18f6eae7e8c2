"""The methods of tuned annotation (issue 10) on hand-made Δ curves: the segment decoder
(overlap resolution, boundary refinement, rejection, frame-wise tie-breaking, document
boundaries), the refined extension of the reference decoder, the frame evidence — and the
decoder against its naive twin and an exhaustive search (hypothesis, JIT on and off)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from naive_decode import best_column_naive, decode_naive, least_cost_exhaustive

from mtanno.annotate import ClassConfig, label_document, segments_from_labels
from mtanno.annotate.decode import decode_segments, frame_evidence, relative_evidence
from mtanno.errors import MtannoError
from mtanno.templates.match import pack_document

INF = math.inf


def _curve(L, matches):
    """Δ and starts of one label from {end: (start, Δ)}."""
    d = np.full(L, INF)
    s = np.full(L, -1, dtype=np.int64)
    for end, (a, v) in matches.items():
        d[end], s[end] = v, a
    return d, s


def _decode(curves, **kw):
    D = np.vstack([c[0] for c in curves])
    S = np.vstack([c[1] for c in curves])
    kw.setdefault("tau", [0.13] * len(curves))
    kw.setdefault("slack", 0)
    return [(d.label, d.start, d.end) for d in decode_segments(D, S, **kw)]


def test_overlapping_matches_are_resolved_into_a_partition():
    # a matches 0..9 (cost 0.02), b matches 6..15 (0.03) and 10..15 (0.06): the reference
    # annotation would output both whole spans, overlapping on 6..9; the decoder keeps a
    # whole and b's later-starting match
    a = _curve(16, {9: (0, 0.02)})
    b = _curve(16, {15: (6, 0.03), 14: (10, 0.06)})
    assert _decode([a, b]) == [(0, 0, 9), (1, 10, 14)]
    # with boundary refinement b's better match may start 4 frames later: the neighbours
    # meet, and b covers its frames to 15
    assert _decode([a, b], slack=4) == [(0, 0, 9), (1, 10, 15)]
    # the cheapest partition wins: b2 (0.01 over 6..15) beats a (0.02 over 0..9) when
    # matches must start where they start (6 unlabelled frames + 10·0.01/0.13 < 10·0.02/0.13
    # + 6); with the slack both fit side by side
    b2 = _curve(16, {15: (6, 0.01)})
    assert _decode([a, b2]) == [(1, 6, 15)]
    assert _decode([a, b2], slack=4) == [(0, 0, 9), (1, 10, 15)]


def test_rejection_ceiling_leaves_an_unknown_motion_unlabelled():
    a = _curve(12, {11: (2, 0.09)})  # below τ = 0.13: labelled
    assert _decode([a]) == [(0, 2, 11)]
    assert _decode([a], reject=[0.08]) == []  # above the ceiling: left unlabelled
    assert _decode([a], reject=[0.09]) == [(0, 2, 11)]  # inclusive
    assert _decode([a], tau=[0.085]) == []  # Δ/τ > 1: dearer than unlabelled frames
    assert _decode([a], tau=[0.095]) == [(0, 2, 11)]


def test_frame_evidence_breaks_near_ties():
    a = _curve(10, {9: (0, 0.050)})
    b = _curve(10, {9: (0, 0.051)})
    assert _decode([a, b]) == [(0, 0, 9)]
    ev = np.array([[0.2] * 10, [0.0] * 10])  # the frames look like b
    assert _decode([a, b], evidence=ev, weight=0.1) == [(1, 0, 9)]
    assert _decode([a, b], evidence=ev, weight=0.0) == [(0, 0, 9)]


def test_segment_cost_keeps_a_long_motion_whole_and_drops_short_matches():
    # a long motion of a (0..19, Δ 0.06) against b's two short matches inside it (0..9 and
    # 10..19, Δ 0.05 each): without a segment cost the two cheaper b pieces win; a cost of
    # 2 frames per match makes the one a match cheaper (20·0.06/0.13 + 2 < 20·0.05/0.13 + 4)
    a = _curve(20, {19: (0, 0.06)})
    b = _curve(20, {9: (0, 0.05), 19: (10, 0.05)})
    assert _decode([a, b]) == [(1, 0, 19)]  # b's touching pieces merged
    assert _decode([a, b], segment_cost=2.0) == [(0, 0, 19)]
    # a short match worth less than its cost stays unlabelled: 3·(1 − 0.1/0.13) < 1
    c = _curve(10, {6: (4, 0.10)})
    assert _decode([c]) == [(0, 4, 6)]
    assert _decode([c], segment_cost=1.0) == []
    with pytest.raises(MtannoError, match="segment cost"):
        _decode([c], segment_cost=-1.0)
    with pytest.raises(MtannoError, match="segment cost"):
        _decode([c], segment_cost=float("inf"))


def test_touching_segments_of_a_label_merge_but_not_across_documents():
    a = _curve(12, {5: (0, 0.02), 11: (6, 0.03)})
    got = decode_segments(np.vstack([a[0]]), np.vstack([a[1]]), tau=[0.13], slack=0)
    assert [(d.start, d.end, d.cost) for d in got] == [(0, 11, 0.02)]
    got = decode_segments(np.vstack([a[0]]), np.vstack([a[1]]), tau=[0.13], slack=0,
                          boundaries=[6])
    assert [(d.start, d.end) for d in got] == [(0, 5), (6, 11)]
    # a slack never moves a start into the previous document
    b = _curve(12, {11: (7, 0.01)})
    assert _decode([b], slack=3, boundaries=[6]) == [(0, 6, 11)]
    assert _decode([b], slack=3) == [(0, 4, 11)]


def test_decoder_input_checks():
    d, s = _curve(5, {4: (0, 0.1)})
    with pytest.raises(MtannoError, match="tau must give one number > 0"):
        decode_segments(d[None], s[None], tau=[0.0])
    with pytest.raises(MtannoError, match="slack"):
        decode_segments(d[None], s[None], tau=[0.1], slack=-1)
    with pytest.raises(MtannoError, match="needs evidence"):
        decode_segments(d[None], s[None], tau=[0.1], weight=0.5)
    with pytest.raises(MtannoError, match="evidence must be ≥ 0"):
        decode_segments(d[None], s[None], tau=[0.1], weight=0.5, evidence=-np.ones((1, 5)))
    with pytest.raises(MtannoError, match="boundaries"):
        decode_segments(d[None], s[None], tau=[0.1], boundaries=[5])
    with pytest.raises(MtannoError, match="one shape"):
        decode_segments(d[None], s[None, :4], tau=[0.1])


@st.composite
def problems(draw):
    P = draw(st.integers(1, 3))
    L = draw(st.integers(1, 9))
    deltas, starts = [], []
    for _ in range(P):
        row_d, row_s = [], []
        for ell in range(L):
            if draw(st.booleans()):
                row_d.append(draw(st.sampled_from([0.01, 0.02, 0.05, 0.1, 0.12, 0.2])))
                row_s.append(draw(st.integers(0, ell)))
            else:
                row_d.append(INF)
                row_s.append(-1)
        deltas.append(row_d)
        starts.append(row_s)
    tau = [draw(st.sampled_from([0.05, 0.1, 0.13])) for _ in range(P)]
    reject = [draw(st.sampled_from([INF, 0.05, 0.1])) for _ in range(P)]
    slack = draw(st.integers(0, 3))
    weight = draw(st.sampled_from([0.0, 0.25, 1.0]))
    evidence = [[draw(st.sampled_from([0.0, 0.1, 0.5])) for _ in range(L)] for _ in range(P)]
    boundaries = sorted(set(draw(st.lists(st.integers(1, max(1, L - 1)), max_size=2)))) \
        if L > 1 else []
    segment_cost = draw(st.sampled_from([0.0, 0.0, 0.5, 2.0]))
    return deltas, starts, tau, reject, slack, evidence, weight, boundaries, segment_cost


def check_against_oracles(problem):
    deltas, starts, tau, reject, slack, evidence, weight, boundaries, seg = problem
    got = decode_segments(np.array(deltas), np.array(starts), tau=tau, reject=reject,
                          slack=slack, evidence=np.array(evidence), weight=weight,
                          boundaries=boundaries, segment_cost=seg)
    want, cost = decode_naive(deltas, starts, tau, reject, slack, evidence, weight, boundaries,
                              seg)
    assert [tuple(d) for d in got] == want
    assert cost == pytest.approx(least_cost_exhaustive(deltas, starts, tau, reject, slack,
                                                       evidence, weight, boundaries, seg))


@settings(max_examples=300, deadline=None)
@given(problems())
def test_decoder_equals_naive_twin_and_is_optimal(problem):
    check_against_oracles(problem)


def check_seeded(seed):
    """A seeded random problem (for the run without JIT)."""
    rng = np.random.default_rng(seed)
    P, L = int(rng.integers(1, 4)), int(rng.integers(1, 9))
    deltas = np.where(rng.random((P, L)) < 0.5, rng.choice([0.01, 0.05, 0.1, 0.2], (P, L)), INF)
    starts = np.where(np.isfinite(deltas), [[int(rng.integers(0, j + 1)) for j in range(L)]
                                            for _ in range(P)], -1)
    problem = (deltas.tolist(), starts.tolist(), [0.13] * P, [INF] * P, int(seed % 3),
               rng.choice([0.0, 0.2], (P, L)).tolist(), 0.5 if seed % 2 else 0.0,
               [L // 2] if L > 2 else [], 1.5 if seed % 4 >= 2 else 0.0)
    check_against_oracles(problem)
    # relative evidence against its definition (∞ entries: no part in the minimum, 0)
    E = np.where(rng.random((P, L)) < 0.3, INF, rng.random((P, L)))
    low = [min([E[p, t] for p in range(P) if np.isfinite(E[p, t])], default=0.0)
           for t in range(L)]
    want = [[E[p, t] - low[t] if np.isfinite(E[p, t]) else 0.0 for t in range(L)]
            for p in range(P)]
    assert relative_evidence(E).tolist() == want
    # running sums in place: the same numbers as relative evidence + the decoder's sums
    from mtanno.annotate.decode import EvidenceSums, evidence_sums

    buf = np.empty((P, L + 1))
    buf[:, 1:] = E
    sums = evidence_sums(buf)
    assert isinstance(sums, EvidenceSums) and sums.cum is buf
    want_cum = np.zeros((P, L + 1))
    for t in range(L):
        want_cum[:, t + 1] = want_cum[:, t] + np.array(want)[:, t]
    assert np.array_equal(buf, want_cum)
    D = np.where(rng.random((P, L)) < 0.6, rng.choice([0.01, 0.05, 0.1], (P, L)), INF)
    S = np.where(np.isfinite(D), 0, -1)
    kw = dict(tau=[0.13] * P, slack=1, weight=0.5)
    assert decode_segments(D, S, evidence=sums, **kw) == \
        decode_segments(D, S, evidence=relative_evidence(E), **kw)
    # folding a label's first template into rows that hold anything
    from mtanno.annotate.decode import fold_label

    row, row_start = np.full(L, INF), np.full(L, -1, np.int64)
    fold_label(row, row_start, D[0], S[0], tau=0.1, reject=0.05)
    junk, junk_start = rng.random(L) - 5, rng.integers(-9, 9, L)
    fold_label(junk, junk_start, D[0], S[0], tau=0.1, reject=0.05, first=True)
    assert np.array_equal(junk, row) and np.array_equal(junk_start, row_start)
    # with spans (keyframe windows): Δ outside them is not read
    cut = int(rng.integers(0, L + 1))
    firsts, lasts = np.array([0, cut + 1]), np.array([cut - 1, L - 1])
    keep = lasts >= firsts
    firsts, lasts = firsts[keep], lasts[keep]
    inside = np.zeros(L, bool)
    for a, b in zip(firsts, lasts):
        inside[a:b + 1] = True
    row, row_start = np.full(L, INF), np.full(L, -1, np.int64)
    fold_label(row, row_start, np.where(inside, D[-1], INF), S[-1], tau=0.1)
    junk, junk_start = rng.random(L) - 5, rng.integers(-9, 9, L)
    fold_label(junk, junk_start, np.where(inside, D[-1], -1.0), S[-1], tau=0.1, first=True,
               spans=(firsts, lasts))
    assert np.array_equal(junk, row) and np.array_equal(junk_start, row_start)
    # distinct frames (the hash table over run values)
    from mtanno.annotate.decode import distinct_frames

    X = rng.choice(np.array([0, 3, 1 << 40, 2 ** 64 - 1], np.uint64),
                   size=(int(rng.integers(1, 30)), 1))
    rows, inv = distinct_frames(X)
    assert np.array_equal(rows[inv], X) and len(rows) == len(np.unique(X))


def test_decoder_without_jit():
    from nojit import run_without_jit

    run_without_jit("test_decode", "check_seeded", *[(s,) for s in range(12)])


def test_distinct_frames_rebuild_the_document():
    from mtanno.annotate.decode import distinct_frames

    rng = np.random.default_rng(3)
    for words in (1, 2):
        P = rng.integers(0, 4, size=(50, words)).astype(np.uint64)
        P = np.repeat(P, rng.integers(1, 5, size=50), axis=0)  # runs, as poses hold
        rows, inv = distinct_frames(P)
        assert np.array_equal(rows[inv], P)
        assert len({tuple(r) for r in rows.tolist()}) == len(rows)
    rows, inv = distinct_frames(np.zeros((0, 1), np.uint64))
    assert rows.shape == (0, 1) and inv.shape == (0,)
    # values that collide in the hash table (equal after folding the shifts) and many runs
    base = np.array([0, 1, 1 << 17, 1 << 31, 1 << 47, (1 << 17) ^ 1, (1 << 63) | 5,
                     2 ** 64 - 1], dtype=np.uint64)
    vals = np.concatenate([base, rng.integers(0, 2 ** 63, 3000, dtype=np.uint64) << np.uint64(1)])
    P = rng.choice(vals, size=20000).reshape(-1, 1)
    rows, inv = distinct_frames(P)
    assert np.array_equal(rows[inv], P) and len(rows) == len(np.unique(P))


def test_frame_evidence_equals_its_definition():
    rng = np.random.default_rng(5)
    for f in (7, 40, 70):  # one and two words per frame
        X = (rng.random((f, 30)) < 0.5).astype(np.uint8)
        V = rng.choice([0.0, 0.5, 1.0], size=(f, 6), p=[0.3, 0.4, 0.3])
        V[:, 2] = 0.5  # a wildcard-only column is skipped
        got = frame_evidence(pack_document(X, f), V)
        assert got.tolist() == pytest.approx(best_column_naive(X.tolist(), V.tolist()))
    assert frame_evidence(pack_document(X, 70), np.full((70, 3), 0.5)).tolist() == [0.0] * 30
    rel = relative_evidence(np.array([[0.1, 0.5], [0.3, 0.2]]))
    assert np.allclose(rel, [[0.0, 0.3], [0.2, 0.0]])
    # only inside spans (a class's keyframe windows): ∞ elsewhere, and ∞ takes no part in
    # the minimum of the relative evidence
    full = frame_evidence(pack_document(X, 70), V)
    part = frame_evidence(pack_document(X, 70), V, spans=(np.array([2, 20]), np.array([5, 40])))
    inside = np.zeros(30, bool)
    inside[2:6] = inside[20:] = True
    assert np.array_equal(part[inside], full[inside]) and np.isinf(part[~inside]).all()
    rel = relative_evidence(np.array([[0.1, np.inf, np.inf], [0.3, 0.2, np.inf]]))
    assert np.allclose(rel, [[0.0, 0.0, 0.0], [0.2, 0.0, 0.0]])
    E = np.array([[0.1, np.inf, np.inf], [0.3, 0.2, np.inf]])
    assert relative_evidence(E, out=E) is E and np.allclose(E, rel)  # in place
    with pytest.raises(MtannoError, match="out must be"):
        relative_evidence(E, out=np.empty((3, 2)))
    # kept per distinct frame, with the template's columns made once: the same numbers,
    # written into a buffer (junk before) without a temporary
    from mtanno.annotate.decode import RowEvidence, evidence_columns, row_evidence

    packed, cols = pack_document(X, 70), evidence_columns(V)
    for spans in (None, (np.array([2, 20, 9]), np.array([5, 40, 3]))):
        want = frame_evidence(packed, V, spans=spans)
        got = row_evidence(packed, cols, spans=spans)
        buf = np.full(30, -7.0)
        got.write(buf)
        assert isinstance(got, RowEvidence) and np.array_equal(buf, want)
        assert np.array_equal(got.frames(), want)
    with pytest.raises(MtannoError, match="the document 64 bits"):
        row_evidence(pack_document(X[:40], 40), cols)


def test_label_document_applies_tau_reject_and_several_templates():
    # two templates of class a (a short and a long variant) and one of b
    L = 20
    a1 = _curve(L, {9: (0, 0.05)})
    a2 = _curve(L, {9: (2, 0.02)})
    b = _curve(L, {19: (10, 0.04)})
    matches = [("a", *a1, None), ("a", *a2, None), ("b", *b, None)]
    cfg = ClassConfig(resolve=True, default_tau=0.13)
    rows, labels, mat = label_document("d", ["a", "a", "b"], iter(matches), L, config=cfg)
    assert labels == ["a", "b"]
    assert [(r.label, r.start, r.end, r.cost) for r in rows] == [("a", 2, 9, 0.02),
                                                                ("b", 10, 19, 0.04)]
    assert mat[0, 9] == pytest.approx(0.02 / 0.13)
    cfg = ClassConfig(resolve=True, default_tau=0.13, reject={"a": 0.03}, tau={"b": 0.03})
    rows, _, _ = label_document("d", ["a", "a", "b"], iter(matches), L, config=cfg)
    assert [(r.label, r.start, r.end) for r in rows] == [("a", 2, 9)]  # b above its τ
    cfg = ClassConfig(resolve=True, refine=True, slack=2, default_tau=0.13)
    rows, _, _ = label_document("d", ["a", "a", "b"], iter(matches), L, config=cfg)
    assert [(r.label, r.start) for r in rows] == [("a", 0), ("b", 10)]  # start moved to 0


def test_refined_extension_stops_at_frames_of_another_class():
    # a wins frames 3..4 and would extend right over 5..6 (Δ̄ keeps falling), which b wins
    a = np.array([INF, INF, 0.10, 0.04, 0.03, 0.02, 0.02, INF])
    b = np.array([0.05, 0.05, 0.05, 0.08, 0.08, 0.01, 0.01, 0.01])
    free = segments_from_labels("d", ["a", "b"], np.vstack([a, b]))
    assert ("a", 3, 6) in {(s.label, s.start, s.end) for s in free}
    refined = segments_from_labels("d", ["a", "b"], np.vstack([a, b]), extend="unclaimed")
    assert {(s.label, s.start, s.end) for s in refined} == {("b", 0, 2), ("a", 3, 4),
                                                            ("b", 5, 7)}
    with pytest.raises(MtannoError, match="extend must be"):
        segments_from_labels("d", ["a", "b"], np.vstack([a, b]), extend="sometimes")


def test_evidence_sums_bad_input():
    from mtanno.annotate.decode import evidence_sums

    with pytest.raises(MtannoError, match="C-contiguous float64"):
        evidence_sums(np.zeros((2, 3), np.float32))
    with pytest.raises(MtannoError, match="C-contiguous float64"):
        evidence_sums(np.zeros((3, 2)).T)
    buf = np.array([[0.0, 0.2, 0.1, 0.3], [0.0, 0.5, np.nan, 0.1]])  # NaN: not computed
    assert np.allclose(evidence_sums(buf).cum, [[0.0, 0.0, 0.0, 0.2], [0.0, 0.3, 0.3, 0.3]])
    with pytest.raises(MtannoError, match="evidence sums of another shape"):
        decode_segments(np.zeros((2, 4)), np.zeros((2, 4), np.int64), tau=[0.1, 0.1],
                        weight=0.5, evidence=evidence_sums(np.zeros((2, 3))))


def test_frame_evidence_refuses_what_would_read_past_its_arrays():
    """Spans, distinct frames, buffers and template columns that do not fit the document
    raise instead of reading or writing past the arrays in the kernels."""
    from mtanno.annotate.decode import (
        EvidenceColumns,
        RowEvidence,
        distinct_frames,
        evidence_columns,
        row_evidence,
    )

    rng = np.random.default_rng(5)
    X = rng.integers(0, 2, (100, 50)).astype(np.uint8)
    packed = pack_document(X, 100)
    V = rng.integers(0, 2, (10, 4)).astype(float)
    # a template of fewer words than the document is compared with its first rows
    want = frame_evidence(pack_document(X[:10], 10), V)
    assert np.array_equal(frame_evidence(packed, V), want)
    assert np.array_equal(frame_evidence(packed, np.vstack([V, np.full((90, 4), 0.5)])), want)
    with pytest.raises(MtannoError, match="one last frame per first frame"):
        row_evidence(packed, V, spans=(np.arange(0, 40, 2), np.array([5])))
    rows, inverse = distinct_frames(packed)
    whole = (np.array([0]), np.array([49]))
    with pytest.raises(MtannoError, match="not one of the .* distinct rows"):
        row_evidence(packed, V, spans=whole, distinct=(rows, inverse + len(rows))).frames()
    with pytest.raises(MtannoError, match="not one of the .* distinct rows"):
        row_evidence(packed, V, distinct=(rows, inverse - len(rows) - 1)).frames()
    with pytest.raises(MtannoError, match="distinct frames of another document"):
        row_evidence(packed, V, distinct=(rows[:, 0], inverse))
    ev = row_evidence(packed, V, spans=whole)
    with pytest.raises(MtannoError, match="one entry per frame"):
        ev.write(np.empty(10))
    with pytest.raises(MtannoError, match="inside the 50 frames"):
        RowEvidence(ev.per_row, ev.inverse, (np.array([0]), np.array([10**6]))).write(
            np.empty(50))
    cols = evidence_columns(V)
    with pytest.raises(MtannoError, match="evidence columns need"):
        EvidenceColumns(np.vstack([cols.masks, cols.masks]), cols.vals, cols.inv_nnz, 10)
    with pytest.raises(MtannoError, match="frames × words"):
        distinct_frames(packed[:, 0])
    with pytest.raises(MtannoError, match="labels × frames"):
        relative_evidence(np.zeros(5))
