"""Annotation (docs/method.md §7) on hand-made Δ curves: Δ̄, labels, ties, extension."""

from __future__ import annotations

import numpy as np
import pytest
from nojit import run_without_jit

from mtanno.annotate import (
    Annotation,
    ClassConfig,
    label_frames,
    load_class_config,
    merged_spans,
    modified_delta,
    read_annotations,
    segments_from_labels,
    single_label_segments,
    write_annotations,
)
from mtanno.errors import MtannoError

INF = np.inf


def naive_dbar(delta, start, tau, max_hits=None):
    """Literal reading of docs/method.md §7 step 2 (reference variant)."""
    d = [x if np.isfinite(x) else INF for x in delta]
    dbar = [INF] * len(d)
    blocked = [False] * len(d)
    hits = 0
    while True:
        cand = [(d[i], i) for i in range(len(d)) if not blocked[i] and d[i] <= tau]
        if not cand or (max_hits is not None and hits >= max_hits):
            break
        v, end = min(cand)  # ties: earliest frame
        for k in range(start[end], end + 1):
            if dbar[k] == INF:
                dbar[k] = v
            blocked[k] = True
        hits += 1
    return np.array(dbar)


def naive_segments(doc, names, dbars, extend=True):
    """Literal reading of docs/method.md §7 steps 3–4: per-frame argmin label, maximal
    runs, extension while Δ̄ does not rise, merge of overlapping runs of a label, smallest Δ̄
    inside."""
    P, L = dbars.shape
    labels = []
    for j in range(L):
        col = [dbars[p, j] for p in range(P)]
        m = min(col)
        labels.append(col.index(m) if np.isfinite(m) else -1)
    runs = {}
    j = 0
    while j < L:
        k = j
        while k + 1 < L and labels[k + 1] == labels[j]:
            k += 1
        p = labels[j]
        if p >= 0:
            s, t = j, k
            if extend:
                while s > 0 and dbars[p, s - 1] <= dbars[p, s]:
                    s -= 1
                while t + 1 < L and dbars[p, t + 1] <= dbars[p, t]:
                    t += 1
            runs.setdefault(p, []).append([s, t])
        j = k + 1
    out = []
    for p, segs in runs.items():
        segs.sort()
        merged = [segs[0]]
        for s, t in segs[1:]:
            if s <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], t)
            else:
                merged.append([s, t])
        out += [Annotation(doc, s, t, names[p], float(min(dbars[p, s:t + 1])))
                for s, t in merged]
    return sorted(out, key=lambda a: (a.start, a.end, a.label))


@pytest.mark.parametrize("seed", range(40))
def test_segments_match_naive(seed):
    rng = np.random.default_rng(seed)
    P, L = int(rng.integers(1, 5)), int(rng.integers(0, 80))
    dbars = np.round(rng.random((P, L)) * 0.2, 2)  # rounding makes ties and plateaus
    dbars[rng.random((P, L)) < 0.4] = INF
    names = [f"c{i}" for i in range(P)]
    for extend in (True, False):
        assert segments_from_labels("d", names, dbars, extend=extend) == \
            naive_segments("d", names, dbars, extend)


@pytest.mark.parametrize("seed", range(30))
def test_single_label_is_a_partition_by_smallest_dbar(seed):
    """--single-label: no frame in two segments, the frames labelled are exactly those of
    the overlapping output, and each frame's label has the smallest Δ̄ among the labels
    whose overlapping segments cover it."""
    rng = np.random.default_rng(seed)
    P, L = int(rng.integers(1, 5)), int(rng.integers(1, 80))
    dbars = np.round(rng.random((P, L)) * 0.2, 2)
    dbars[rng.random((P, L)) < 0.4] = INF
    names = [f"c{i}" for i in range(P)]
    rows = segments_from_labels("d", names, dbars)
    single = single_label_segments("d", names, dbars, rows)
    owner = np.full(L, -1)
    for a in single:
        assert (owner[a.start:a.end + 1] == -1).all()  # a partition: no shared frame
        owner[a.start:a.end + 1] = names.index(a.label)
        assert a.cost == dbars[names.index(a.label), a.start:a.end + 1].min()
    covered = np.zeros((P, L), bool)
    for a in rows:
        covered[names.index(a.label), a.start:a.end + 1] = True
    assert np.array_equal(owner >= 0, covered.any(axis=0))
    for j in np.flatnonzero(owner >= 0):
        cands = [p for p in range(P) if covered[p, j]]
        best = min(cands, key=lambda p: (dbars[p, j], p))
        assert owner[j] == best
    for a, b in zip(single, single[1:]):  # maximal runs
        assert a.end < b.start and (a.end + 1 < b.start or a.label != b.label)


def test_single_label_resolves_hand_made_overlap():
    a = np.array([0.05, 0.04, 0.03, 0.02, 0.03, 0.04, 0.05])
    b = np.array([INF, INF, INF, INF, 0.01, 0.01, INF])
    rows = segments_from_labels("d", ["a", "b"], np.vstack([a, b]))
    assert [(r.label, r.start, r.end) for r in rows] == [("a", 0, 6), ("b", 4, 5)]
    single = single_label_segments("d", ["a", "b"], np.vstack([a, b]), rows)
    assert [(r.label, r.start, r.end, r.cost) for r in single] == [
        ("a", 0, 3, 0.02), ("b", 4, 5, 0.01), ("a", 6, 6, 0.05)]


def test_reference_dbar_hand_made():
    delta = np.array([INF, INF, 0.10, 0.05, 0.08, 0.20, 0.04, 0.12])
    start = np.array([-1, -1, 0, 1, 2, 3, 5, 6])
    got = modified_delta(delta, start, tau=0.13)
    # picks: 0.04 at 6 (span 5..6), 0.05 at 3 (span 1..3), 0.10 at 2 blocked, 0.08 at 4
    # (span 2..4: fills 4), 0.12 at 7 (span 6..7: fills 7)
    assert got.tolist() == [INF, 0.05, 0.05, 0.05, 0.08, 0.04, 0.04, 0.12]
    assert modified_delta(delta, start, tau=0.13, max_hits=1).tolist() == [INF] * 5 + [0.04] * 2 + [INF]
    assert np.isinf(modified_delta(delta, start, tau=0.13, max_hits=0)).all()


@pytest.mark.parametrize("seed", range(20))
def test_reference_dbar_matches_naive(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 60))
    delta = rng.random(n) * 0.2
    delta[rng.random(n) < 0.2] = INF
    delta[rng.random(n) < 0.2] = 0.05  # ties
    start = np.array([max(0, i - int(rng.integers(0, 8))) for i in range(n)])
    cap = None if seed % 3 else 3
    assert np.array_equal(modified_delta(delta, start, tau=0.13, max_hits=cap),
                          naive_dbar(delta, start, 0.13, cap))


def check_reference_dbar(seed: int) -> None:
    """The radix-sorted picks of the reference Δ̄ against the naive reading, on values that
    exercise every key digit: ties, ±0, negatives, tiny and huge magnitudes, ∞ and NaN."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    pool = np.array([0.0, -0.0, 0.05, 0.05, 1e-300, 5e-324, -0.01, -1e10, 0.1299, 0.13,
                     0.130001, INF, np.nan, 2.0**-40])
    delta = np.where(rng.random(n) < 0.5, rng.random(n) * 0.2, rng.choice(pool, n))
    start = np.array([max(0, i - int(rng.integers(0, 12))) for i in range(n)])
    cap = None if seed % 4 else int(rng.integers(0, 20))  # 0: no picks at all
    got = modified_delta(delta, start, tau=0.13, max_hits=cap)
    want = naive_dbar(np.where(np.isnan(delta), INF, delta), start, 0.13, cap)
    assert np.array_equal(got, want), seed
    # with spans (keyframe windows): Δ is ∞ outside them and not read there
    cuts = np.sort(rng.choice(n + 1, size=min(n + 1, 6), replace=False))
    firsts, lasts = cuts[:-1:2], cuts[1::2] - 1
    keep = lasts >= firsts
    firsts, lasts = firsts[keep], lasts[keep]
    inside = np.zeros(n, bool)
    for a, b in zip(firsts, lasts):
        inside[a:b + 1] = True
    d2 = np.where(inside, delta, INF)
    s2 = np.maximum(start, np.repeat(firsts, lasts - firsts + 1)[np.cumsum(inside) - 1]
                    if inside.any() else start)  # matches stay inside their span
    want = naive_dbar(np.where(np.isnan(d2), INF, d2), s2, 0.13, cap)
    junk = np.where(inside, d2, -1.0)  # outside the spans: values that must not be read
    got = modified_delta(junk, s2, tau=0.13, max_hits=cap, spans=(firsts, lasts))
    assert np.array_equal(got, want), seed


def check_dbar_strategies(seed: int) -> tuple[int, int]:
    """Δ̄ of real matcher outputs (starts mostly increasing, sometimes crossing) against the
    naive reading, and each strategy of :mod:`mtanno.annotate._kernels` on its own: the divide and
    conquer either agrees with the naive Δ̄ or declines (−1), the sorted greedy always
    agrees. Returns (spans it solved, spans it declined)."""
    from mtanno.annotate._kernels import _greedy_dbar, _split_dbar
    from mtanno.templates.match import PreparedTemplate

    rng = np.random.default_rng(seed)
    f, K, L = 6, int(rng.integers(2, 9)), int(rng.integers(20, 300))
    values = rng.choice([0.0, 1.0, 0.5], size=(f, K), p=[0.4, 0.4, 0.2])
    prep = PreparedTemplate(values, rng.integers(1, 4, K).astype(float))
    X = (rng.random((f, L)) < 0.5).astype(np.uint8)
    cuts = np.sort(rng.choice(np.arange(1, L), size=4, replace=False))
    firsts, lasts = np.array([0, cuts[1]]), np.array([cuts[0], cuts[2]])
    from mtanno.templates.match import pack_document

    delta, start = prep.match_spans(pack_document(X, f), firsts, lasts)
    finite = delta[np.isfinite(delta)]
    tau = float(np.quantile(finite, 0.6)) if finite.size else 0.1
    want = naive_dbar(delta, start, tau)
    assert np.array_equal(modified_delta(delta, start, tau=tau, spans=(firsts, lasts)), want)
    greedy = np.full(L, INF)
    assert _greedy_dbar(delta, delta.view(np.uint64), start, tau, 10**9, greedy, firsts,
                        lasts) >= 0
    assert np.array_equal(greedy, want)
    solved = declined = 0
    for x, y in zip(firsts, lasts):
        cand = x + np.flatnonzero(delta[x:y + 1] <= tau)
        got = np.full(L, INF)
        size = 1 << max(0, int(len(cand) - 1).bit_length())
        if _split_dbar(delta, start, got, cand, len(cand), np.empty(2 * size, np.int64),
                       np.empty((len(cand) + 1, 4), np.int64), x) < 0:
            declined += 1
        else:
            assert np.array_equal(got[x:y + 1], want[x:y + 1])
            solved += 1
    return solved, declined


def test_dbar_strategies_agree_with_the_naive_reading():
    """Both strategies are exercised: most spans of real Δ are solved by divide and
    conquer, and crossing matches make it decline on some."""
    solved = declined = 0
    for seed in range(60):
        s, d = check_dbar_strategies(seed)
        solved, declined = solved + s, declined + d
    assert solved > 20 and declined > 0, (solved, declined)


def test_dbar_strategies_without_jit():
    run_without_jit("test_annotate", "check_dbar_strategies", (0,), (5,))


def test_modified_delta_refuses_starts_outside_their_span():
    """Start frames that no matcher gives (after the end, before the window) and windows
    outside the document are refused instead of being followed out of the arrays."""
    from mtanno.annotate.decode import fold_label
    from mtanno.templates.match import PreparedTemplate

    delta = np.array([INF, 0.05, 0.02, INF, 0.01])
    with pytest.raises(MtannoError, match="starts before its window or after its end"):
        modified_delta(delta, np.array([0, 0, 9, 0, 3]), tau=0.13)
    with pytest.raises(MtannoError, match="starts before its window"):
        modified_delta(delta, np.array([0, 0, -1, 0, 3]), tau=0.13)
    with pytest.raises(MtannoError, match="starts before its window"):
        modified_delta(delta, np.array([0, 0, 1, 0, 2]), tau=0.13,
                       spans=(np.array([0, 3]), np.array([2, 4])))
    got = modified_delta(delta, np.array([0, 0, 1, 0, 3]), tau=0.13,
                         spans=(np.array([0, 3]), np.array([2, 4])))
    assert got.tolist() == [INF, 0.02, 0.02, 0.01, 0.01]
    for bad in ((np.array([1, 0]), np.array([2, 4])), (np.array([0]), np.array([5])),
                (np.array([-1]), np.array([2])), (np.array([0, 2]), np.array([2, 4]))):
        with pytest.raises(MtannoError, match="spans must be sorted disjoint"):
            modified_delta(delta, np.zeros(5, np.int64), tau=0.13, spans=bad)
        with pytest.raises(MtannoError, match="spans must be sorted disjoint"):
            fold_label(np.empty(5), np.empty(5, np.int64), delta, np.zeros(5, np.int64),
                       tau=0.1, spans=bad)
        with pytest.raises(MtannoError, match="spans must be sorted disjoint"):
            PreparedTemplate(np.ones((40, 2)), np.ones(2)).match_spans(
                np.zeros((5, 1), np.uint64), *bad)


def test_packed_documents_of_another_width_are_refused():
    """A bit-packed document narrower than the template (or of another dtype) would be
    read past its rows by the matcher."""
    from mtanno.annotate import ClassModel, annotate_document
    from mtanno.templates.match import PreparedTemplate

    prep = PreparedTemplate(np.ones((70, 3)), np.ones(3))
    for packed in (np.zeros((9, 1), np.uint64), np.zeros((9, 2), np.int64), np.zeros(9)):
        with pytest.raises(MtannoError, match="packed document must be uint64"):
            prep.run(packed, np.array([0, 9]))
        with pytest.raises(MtannoError, match="packed document must be uint64"):
            prep.match_spans(packed, [0], [8])
    X = np.zeros((70, 9), np.uint8)
    with pytest.raises(MtannoError, match="packed document must be uint64"):
        annotate_document("d", X, [ClassModel("a", np.ones((70, 3)), np.ones(3))],
                          packed=np.zeros((9, 1), np.uint64))


@pytest.mark.parametrize("seed", range(30))
def test_reference_dbar_radix_order(seed):
    check_reference_dbar(seed)


def test_reference_dbar_without_jit():
    run_without_jit("test_annotate", "check_reference_dbar", (0,), (3,), (4,))


def naive_merged(spans, L):
    merged = []
    for a, b in sorted((max(0, a), min(L - 1, b)) for a, b in spans):
        if b < a:
            continue
        if merged and a <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    return merged


@pytest.mark.parametrize("seed", range(20))
def test_merged_spans_matches_naive(seed):
    rng = np.random.default_rng(seed)
    L = int(rng.integers(1, 80))
    spans = [(int(a), int(a + rng.integers(-3, 15))) for a in rng.integers(-10, L + 5,
                                                                           rng.integers(0, 12))]
    starts, ends = merged_spans(spans, L)
    assert [[a, b] for a, b in zip(starts.tolist(), ends.tolist())] == naive_merged(spans, L)
    assert starts.dtype == ends.dtype == np.int64


def test_paper_dbar_local_minima():
    delta = np.array([0.3, 0.1, 0.2, 0.05, 0.06, 0.3])
    start = np.array([0, 0, 1, 1, 3, 4])
    got = modified_delta(delta, start, tau=0.13, variant="paper")
    # local minima below τ: 1 (0.1, span 0..1) and 3 (0.05, span 1..3)
    assert got.tolist() == [0.1, 0.05, 0.05, 0.05, INF, INF]
    with pytest.raises(MtannoError, match="unknown Δ̄ variant"):
        modified_delta(delta, start, variant="nope")


def test_labels_ties_go_to_smallest_index():
    dbars = np.array([[0.1, 0.2, INF, 0.05], [0.1, 0.1, INF, 0.06]])
    labels, dmin = label_frames(dbars)
    assert labels.tolist() == [0, 1, -1, 0]
    assert dmin[2] == INF


def test_segment_extension_and_merge():
    # class a wins frames 3..4; b wins 0..2 and 5..7
    a = np.array([0.12, 0.11, 0.10, 0.02, 0.03, 0.03, 0.09, INF])
    b = np.array([0.05, 0.05, 0.06, 0.07, 0.07, 0.01, 0.01, 0.01])
    segs = segments_from_labels("d", ["a", "b"], np.vstack([a, b]))
    # MBS09 §4: extend left while Δ̄ is increasing-or-constant on [r, s], right while it is
    # decreasing-or-constant on [t, u]: a's 3..4 → 3..5 (0.03 = 0.03), not left (0.10 > 0.02)
    assert {(s.label, s.start, s.end) for s in segs} == {("a", 3, 5), ("b", 0, 2), ("b", 5, 7)}
    unext = segments_from_labels("d", ["a", "b"], np.vstack([a, b]), extend=False)
    assert {(s.label, s.start, s.end) for s in unext} == {("b", 0, 2), ("a", 3, 4), ("b", 5, 7)}


def test_extension_merges_overlapping_runs_of_one_label():
    a = np.array([0.05, 0.04, 0.05, 0.06, 0.05, 0.04, 0.05])
    b = np.array([0.09, 0.09, 0.09, 0.01, 0.09, 0.09, 0.09])
    segs = segments_from_labels("d", ["a", "b"], np.vstack([a, b]))
    a_segs = [(s.start, s.end) for s in segs if s.label == "a"]
    # runs 0..2 and 4..6 extend into 0..3? (0.05 → 0.06 rises: no) — stay disjoint
    assert a_segs == [(0, 2), (4, 6)]
    a2 = np.array([0.05, 0.04, 0.03, 0.02, 0.03, 0.04, 0.05])
    segs = segments_from_labels("d", ["a", "b"], np.vstack([a2, b]))
    assert [(s.start, s.end) for s in segs if s.label == "a"] == [(0, 6)]


def test_class_config(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text('[tau]\ndefault = 0.1\nsit = 0.06\n[superclasses]\nkick = ["kl", "kr"]\n')
    cfg = load_class_config(p)
    assert cfg.tau_for("sit") == 0.06 and cfg.tau_for("x") == 0.1
    assert cfg.superclasses == {"kick": ["kl", "kr"]}
    p.write_text("[tau]\ndefault = 'x'\n")
    with pytest.raises(MtannoError, match="must be a number ≥ 0"):
        load_class_config(p)
    p.write_text("[superclasses]\nkick = []\n")
    with pytest.raises(MtannoError, match="non-empty lists"):
        load_class_config(p)
    p.write_text("[taus]\n")
    with pytest.raises(MtannoError, match="unknown section"):
        load_class_config(p)
    p.write_text(f"[tuned_with]\nsit = \"{'ab' * 32}\"\n")
    assert load_class_config(p).tuned_with == {"sit": "ab" * 32}
    for bad in ("'abc'", "1", f"'{'AB' * 32}'", f"'{'ab' * 31}zz'"):
        p.write_text(f"[tuned_with]\nsit = {bad}\n")
        with pytest.raises(MtannoError, match=r"c.toml:2: \[tuned_with\] sit must be the SHA-256"):
            load_class_config(p)
    with pytest.raises(MtannoError, match="not found"):
        load_class_config(tmp_path / "missing.toml")
    assert ClassConfig().tau_for("any") == 0.13


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_annotation_table_round_trip(tmp_path, suffix):
    rows = [Annotation("doc1", 0, 9, "squat", 0.02), Annotation("doc1", 5, 20, "kick", 0.1)]
    p = tmp_path / f"a{suffix}"
    write_annotations(p, rows, native={"doc1": np.arange(1, 100, 4)})
    assert read_annotations(p) == rows
    import pyarrow.parquet as pq

    if suffix == ".parquet":
        t = pq.read_table(p).to_pydict()
        assert t["start"] == [1, 6] and t["start_native"] == [1, 21] and t["end_native"] == [37, 81]
    with pytest.raises(MtannoError, match="unknown table format '.txt'"):
        write_annotations(tmp_path / "a.txt", rows)


def test_class_deltas_with_candidate_windows():
    from mtanno.annotate import ClassModel, class_deltas
    from mtanno.templates.match import match_template

    rng = np.random.default_rng(3)
    X = (rng.random((40, 120)) < 0.4).astype(np.uint8)
    values = rng.choice([0.0, 0.5, 1.0], size=(40, 9))
    cm = ClassModel("a", values, np.ones(9))
    other = ClassModel("b", values[:, ::-1].copy(), np.ones(9))
    full = class_deltas(X, [cm, other])
    d0, s0 = match_template(values, np.ones(9), X)
    assert np.array_equal(full[0][0], d0) and np.array_equal(full[0][1], s0)
    (dw, sw), (db, _) = class_deltas(X, [cm, other], windows={"a": [(10, 50), (-5, 3), (90, 200)]})
    assert np.array_equal(db, full[1][0])  # no windows for b: matched everywhere
    for a, b in ((10, 50), (90, 119)):
        d, s = match_template(values, np.ones(9), X[:, a:b + 1])
        assert np.array_equal(dw[a:b + 1], d)
        assert np.array_equal(sw[a:b + 1][np.isfinite(d)], s[np.isfinite(d)] + a)
    assert np.isinf(dw[51:90]).all() and np.isinf(dw[4:10]).all()


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("resolve", [False, True])
def test_annotate_document_in_windows_equals_masked_distances(seed, resolve):
    """Annotation with keyframe windows equals the labelling of distance functions that are
    ∞ outside the windows, although the shared Δ buffer is not reset there (templates
    matched everywhere before leave finite values in it): the default decoder and the
    segment decoder (several templates of a class, frame evidence) read inside the spans."""
    from mtanno.annotate import ClassModel, annotate_document, class_deltas, label_document
    from mtanno.annotate.decode import EVIDENCE_MARGIN
    from mtanno.templates.match import pack_document

    rng = np.random.default_rng(seed)
    L = int(rng.integers(60, 200))
    X = (np.cumsum(rng.random((40, L)) < 0.08, axis=1) % 2).astype(np.uint8)
    names = ["a", "b", "a", "c"]
    models = [ClassModel(n, X[:, s:s + k].astype(float), np.ones(k))
              for n, s, k in zip(names, rng.integers(0, L - 12, 4), rng.integers(4, 12, 4))]
    windows = {"a": [(int(x), int(x) + int(rng.integers(5, 40))) for x in rng.integers(0, L, 3)],
               "c": [] if seed % 3 == 0 else [(0, int(rng.integers(10, L)))]}
    config = ClassConfig(resolve=resolve, refine=resolve, slack=2, frame_weight=0.5 * resolve,
                         tau={"a": 0.2, "b": 0.1, "c": 0.15})
    got = annotate_document("d", X, models, windows=windows, config=config)
    masked = class_deltas(X, models, windows=windows)  # fresh arrays, ∞ outside
    if resolve:
        from mtanno.annotate.decode import frame_evidence

        ev = [frame_evidence(pack_document(X, 40), m.values) for m in models]
        for i, m in enumerate(models):  # evidence only near the windows, as annotate has it
            if m.name in windows:
                keep = np.zeros(L, bool)
                for a, b in windows[m.name]:
                    keep[max(0, a - EVIDENCE_MARGIN):b + EVIDENCE_MARGIN + 1] = True
                ev[i] = np.where(keep, ev[i], np.inf)
    else:
        ev = [None] * 4
    want = label_document("d", names, ((m.name, d, s, e) for m, (d, s), e in
                                       zip(models, masked, ev)), L, config=config)
    assert got[0] == want[0]
    assert np.array_equal(got[2], want[2])
    # windows as (firsts, lasts) arrays, merged already (what class_spans gives): the same
    arrays = {c: merged_spans(w, L) for c, w in windows.items()}
    again = annotate_document("d", X, models, windows=arrays, config=config)
    assert again[0] == got[0] and np.array_equal(again[2], got[2])


@pytest.mark.parametrize("seed", range(4))
def test_labels_matched_into_the_decoder_rows_equal_folded_ones(seed):
    """annotate_document matches the only template of a label straight into the segment
    decoder's row and lets the decoder apply τ and ρ; label_document folding Δ/τ into the
    rows (what the tuner scores) gives the same segments, costs and Δ/τ matrix — with
    rejection ceilings, a superclass, a class of two templates and frame evidence."""
    from dataclasses import replace

    from mtanno.annotate import ClassModel, annotate_document, class_deltas, label_document
    from mtanno.annotate.decode import frame_evidence
    from mtanno.templates.match import pack_document

    rng = np.random.default_rng(seed)
    L = int(rng.integers(80, 220))
    X = (np.cumsum(rng.random((40, L)) < 0.08, axis=1) % 2).astype(np.uint8)
    names = ["a", "b", "a", "c", "d", "e"]
    models = [ClassModel(n, X[:, s:s + k].astype(float), np.ones(k))
              for n, s, k in zip(names, rng.integers(0, L - 12, 6), rng.integers(4, 12, 6))]
    config = ClassConfig(resolve=True, refine=True, slack=int(seed % 3),
                         frame_weight=0.3 * (seed % 2), segment_cost=2.0 * (seed > 1),
                         tau={"a": 0.2, "b": 0.3, "c": 0.15, "d": 0.12, "e": 0.3},
                         reject={"b": 0.08, "e": 0.1}, superclasses={"de": ["d", "e"]})
    got = annotate_document("d", X, models, config=config)
    open_b = annotate_document("d", X, models, config=replace(config, reject={"e": 0.1}))
    if seed < 2:  # without a segment cost b's ceiling rejects matches it would take
        assert open_b[0] != got[0]
    ev = [frame_evidence(pack_document(X, 40), m.values) for m in models]
    want = label_document("d", names, ((m.name, d, s, e) for m, (d, s), e in
                                       zip(models, class_deltas(X, models), ev)), L,
                          config=config)
    assert got[0] == want[0] and got[1] == want[1]
    assert np.array_equal(got[2], want[2])
    assert got[0]  # something is labelled


def check_rows_without_the_matrix(seed: int) -> None:
    """annotate_document(matrix=False) fills and reads each class's Δ̄ row inside its
    windows only: the same segments as with the matrix, for windows that overlap, touch,
    lie at the document's ends or are empty, classes without windows, the extension over
    unclaimed frames, and a hit cap."""
    from mtanno.annotate import ClassModel, annotate_document

    rng = np.random.default_rng(seed)
    L = int(rng.integers(40, 260))
    X = (np.cumsum(rng.random((40, L)) < 0.1, axis=1) % 2).astype(np.uint8)
    names = ["a", "b", "c", "d"]
    models = [ClassModel(n, X[:, s:s + k].astype(float), np.ones(k)) for n, s, k in
              zip(names, rng.integers(0, L - 14, 4), rng.integers(3, 14, 4))]
    windows = {}
    for n in names[:3]:
        cuts = np.sort(rng.choice(L + 1, size=2 * int(rng.integers(0, 4)), replace=False))
        w = [(int(a), int(b) - 1) for a, b in zip(cuts[::2], cuts[1::2]) if b > a]
        if w and rng.random() < 0.5:  # a window touching the one before
            w.append((w[-1][1] + 1, min(L - 1, w[-1][1] + int(rng.integers(1, 30)))))
        windows[n] = w
    config = ClassConfig(refine=bool(seed % 2), tau={"a": 0.2, "b": 0.15, "c": 0.3, "d": 0.1})
    cap = None if seed % 3 else 3
    want = annotate_document("d", X, models, windows=windows, config=config, max_hits=cap)
    got = annotate_document("d", X, models, windows=windows, config=config, max_hits=cap,
                            matrix=False)
    assert got[0] == want[0] and got[1] == want[1] and got[2] is None


@pytest.mark.parametrize("seed", range(40))
def test_rows_without_the_matrix(seed):
    check_rows_without_the_matrix(seed)


def test_rows_without_the_matrix_without_jit():
    run_without_jit("test_annotate", "check_rows_without_the_matrix", (0,), (1,), (5,))


@pytest.mark.parametrize("seed", range(40))
def test_segments_read_each_row_inside_its_spans_only(seed):
    """segments_from_labels with row_spans: values outside a row's spans (here garbage,
    even smaller than inside) are never read; the segments equal those of the matrix
    with ∞ there."""
    from mtanno.annotate.dbar import _row_spans

    rng = np.random.default_rng(seed)
    P, L = int(rng.integers(1, 5)), int(rng.integers(1, 120))
    dense = np.round(rng.random((P, L)) * 0.2, 2)
    garbage = dense.copy()
    per_row = []
    for p in range(P):
        if rng.random() < 0.2:
            per_row.append(None)  # a row valid everywhere
            continue
        cuts = np.sort(rng.choice(L + 1, size=2 * int(rng.integers(0, 4)), replace=False))
        a, b = cuts[::2], cuts[1::2] - 1
        keep = (b >= a) & np.concatenate(([True], a[1:] > b[:-1] + 1))  # not touching
        a, b = a[keep], b[keep]
        inside = np.zeros(L, bool)
        for x, y in zip(a, b):
            inside[x:y + 1] = True
        dense[p, ~inside] = INF
        garbage[p, ~inside] = rng.choice([-1.0, 0.0, np.nan], size=(~inside).sum())
        per_row.append((a.astype(np.int64), b.astype(np.int64)))
    names = [f"c{i}" for i in range(P)]
    for extend in (True, False, "unclaimed"):
        want = segments_from_labels("d", names, dense, extend=extend)
        got = segments_from_labels("d", names, garbage, extend=extend,
                                   row_spans=_row_spans(per_row, L))
        assert got == want


def test_touching_windows_are_joined_for_the_rows():
    """A window that touches the one before is one stretch of the row (the extension may
    walk across)."""
    from mtanno.annotate.dbar import _reference_in_spans

    delta = np.full(12, INF)
    first, last = _reference_in_spans(delta, np.full(12, -1), 0.13, None, np.empty(12),
                                      (np.array([0, 4, 6, 10]), np.array([3, 5, 8, 11])))
    assert first.tolist() == [0, 10] and last.tolist() == [8, 11]


def test_window_arrays_must_be_sorted_and_disjoint():
    from mtanno.annotate import ClassModel, annotate_document

    X = np.zeros((40, 30), np.uint8)
    models = [ClassModel("a", np.zeros((40, 3)), np.ones(3))]
    for bad in ((np.array([10, 0]), np.array([12, 5])), (np.array([0, 4]), np.array([5, 9])),
                (np.array([0]), np.array([30]))):
        with pytest.raises(MtannoError, match="spans must be sorted disjoint"):
            annotate_document("d", X, models, windows={"a": bad})


def test_segments_without_jit():
    from nojit import run_without_jit

    run_without_jit("test_annotate", "test_segments_match_naive", *[(s,) for s in range(8)])
