"""Frame accuracy, Edit score and F1@{10,25,50} (mtanno.evaluation.segmentation): hand-worked
cases with exact values, slow reference implementations written from the definitions
(docs/annotation.md) compared on random small inputs, edge cases, and the keys of
``mtanno evaluate --json``."""

from __future__ import annotations

import itertools
import json
from fractions import Fraction

import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from mtanno.evaluation.metrics import evaluate_annotations
from mtanno.evaluation.segmentation import (
    OVERLAPS,
    edit_score,
    frame_labels,
    levenshtein,
    overlap_counts,
    segmentation_scores,
)
from mtanno.labels.segments import Segment as S


def scores(truth, output, docs=None, frames=None):
    docs = docs if docs is not None else {s.doc for s in [*truth, *output]}
    return segmentation_scores(truth, output, docs, frames=frames)


# ---------------------------------------------------------------- hand-worked: F1@k


def test_f1_at_k_hand_worked():
    truth = [S("d", 1, 10, "a"), S("d", 21, 30, "a")]
    out = [S("d", 1, 8, "a"), S("d", 9, 12, "a"), S("d", 25, 40, "a")]
    # (1..8):   IoU with 1..10 = 8/10 = 0.8            → TP at every k, takes 1..10
    # (9..12):  IoU with 1..10 = 2/12, with 21..30 = 0 → best 1..10 is taken → FP
    # (25..40): IoU with 21..30 = 6/20 = 0.3           → TP at 10 and 25, FP at 50
    r = scores(truth, out)
    got = {k: r.overlap[k].as_dict() for k in OVERLAPS}
    assert got == {10: {"tp": 2, "fp": 1, "fn": 0}, 25: {"tp": 2, "fp": 1, "fn": 0},
                   50: {"tp": 1, "fp": 2, "fn": 1}}
    # F1 = 2TP / (2TP + FP + FN): 4/5 at 10 and 25, 2/5 at 50
    assert (r.f1(10), r.f1(25), r.f1(50)) == (pytest.approx(0.8), pytest.approx(0.8),
                                              pytest.approx(0.4))
    assert r.class_f1("a", 50) == pytest.approx(0.4) and r.class_f1("zzz", 50) is None


def test_f1_greedy_in_output_order():
    truth = [S("d", 1, 10, "a")]
    # in (start, end) order 1..4 comes first: IoU 0.4 takes the truth at k = 10 and 25, and
    # the exact 1..10 that follows is a false positive; at 50, 1..4 does not qualify (FP)
    # and 1..10 is the TP. Either way TP 1, FP 1, FN 0 → F1 = 2/3.
    out = [S("d", 1, 10, "a"), S("d", 1, 4, "a")]  # listed in the other order: same result
    for k in OVERLAPS:
        c = overlap_counts(truth, out, k)
        assert (c.tp, c.fp, c.fn) == (1, 1, 0)
        assert c.F == pytest.approx(2 / 3)


def test_f1_best_truth_taken_is_a_false_positive_even_if_another_qualifies():
    truth = [S("d", 1, 10, "a"), S("d", 11, 20, "a")]
    # 3..12: IoU with 1..10 = 8/12, with 11..20 = 2/20 → takes 1..10
    # 5..15: IoU with 1..10 = 6/15 = 0.4, with 11..20 = 5/20 = 0.25 → best 1..10 is taken: FP
    #        (11..20 would qualify at k = 10 and 25; the greedy rule does not look further)
    out = [S("d", 3, 12, "a"), S("d", 5, 15, "a")]
    c = overlap_counts(truth, out, 10)
    assert (c.tp, c.fp, c.fn) == (1, 1, 1) and c.F == pytest.approx(0.5)


def test_f1_iou_exactly_at_the_threshold_counts():
    # 1..1 in 1..4: IoU 1/4 exactly; 1..5 in 1..10: IoU 1/2 exactly (tested in integers)
    assert [overlap_counts([S("d", 1, 4, "a")], [S("d", 1, 1, "a")], k).tp
            for k in OVERLAPS] == [1, 1, 0]
    assert overlap_counts([S("d", 1, 10, "a")], [S("d", 1, 5, "a")], 50).tp == 1
    assert overlap_counts([S("d", 1, 10, "a")], [S("d", 1, 4, "a")], 50).tp == 0


def test_f1_equal_iou_takes_the_earlier_truth_segment():
    # 1..10 overlaps 1..5 and 6..10 with IoU 1/2 each: it takes 1..5; then 6..10 is free
    truth = [S("d", 6, 10, "a"), S("d", 1, 5, "a")]
    c = overlap_counts(truth, [S("d", 1, 10, "a"), S("d", 3, 5, "a")], 50)
    # 3..5: best is 1..5 (IoU 3/5), taken → FP; 6..10 never taken → FN
    assert (c.tp, c.fp, c.fn) == (1, 1, 1)


def test_f1_only_matches_within_a_label_and_a_document():
    truth = [S("d", 1, 10, "a"), S("e", 1, 10, "b")]
    out = [S("d", 1, 10, "b"), S("e", 1, 10, "b"), S("e", 1, 10, "a")]
    r = scores(truth, out)
    # b in e is the only TP; (d, b) and (e, a) are FPs; (d, a) is a FN
    assert r.overlap[50].as_dict() == {"tp": 1, "fp": 2, "fn": 1}
    assert r.class_overlap["a"][50].as_dict() == {"tp": 0, "fp": 1, "fn": 1}
    assert r.class_overlap["b"][50].as_dict() == {"tp": 1, "fp": 1, "fn": 0}
    assert r.class_f1("a", 10) == 0.0 and r.class_f1("b", 10) == pytest.approx(2 / 3)


# ---------------------------------------------------------------- hand-worked: Edit


def test_edit_hand_worked():
    assert levenshtein("abc", "ac") == 1 and levenshtein("", "abc") == 3
    assert levenshtein("kitten", "sitting") == 3
    assert edit_score(["a", "b", "c"], ["a", "c"]) == pytest.approx(1 - 1 / 3)
    assert edit_score(["a", "b", "c"], ["a", "x", "c"]) == pytest.approx(1 - 1 / 3)
    assert edit_score([], []) is None and edit_score(["a"], []) == 0.0
    truth = [S("d", 1, 10, "a"), S("d", 11, 20, "b"), S("d", 21, 30, "c"),
             S("e", 1, 30, "a")]
    # d: truth a b c, output a a b c (a cut in two: not merged) → D = 1, Edit 1 − 1/4
    # e: truth a, output b a → D = 1, Edit 1 − 1/2; mean (0.75 + 0.5) / 2 = 0.625
    # f: no segment on either side → left out of the mean
    out = [S("d", 1, 5, "a"), S("d", 6, 10, "a"), S("d", 11, 20, "b"), S("d", 21, 30, "c"),
           S("e", 10, 30, "a"), S("e", 1, 9, "b")]
    r = scores(truth, out, docs={"d", "e", "f"}, frames={"f": 50})
    assert r.edit_per_document == {"d": 0.75, "e": 0.5}
    assert r.edit == pytest.approx(0.625)


def test_edit_orders_by_start_then_end_then_label():
    # overlapping outputs: 1..5 b, 1..9 a, 3..4 c → order (1,5,b) (1,9,a) (3,4,c): b a c
    out = [S("d", 1, 9, "a"), S("d", 3, 4, "c"), S("d", 1, 5, "b")]
    truth = [S("d", 1, 3, "b"), S("d", 4, 6, "a"), S("d", 7, 9, "c")]
    assert scores(truth, out).edit == 1.0


# ---------------------------------------------------------------- hand-worked: accuracy


def test_frame_accuracy_hand_worked_with_overlap_and_unlabelled_frames():
    truth = [S("d", 1, 10, "a"), S("d", 11, 15, "b")]             # 16..20 unlabelled
    out = [S("d", 1, 12, "a"), S("d", 10, 14, "b")]               # overlap on 10..12
    # predicted: b starts later, so 1..9 a, 10..14 b, 15..20 none
    # truth:     1..10 a, 11..15 b, 16..20 none
    # right: 1..9 (9), 11..14 (4), 16..20 (5) = 18 of 20; wrong: 10 (a/b), 15 (b/none)
    r = scores(truth, out, frames={"d": 20})
    assert (r.correct, r.frames) == (18, 20) and r.accuracy == pytest.approx(0.9)
    # per class: of the 10 frames truly a, 9 predicted a; of 5 truly b, 4 predicted b
    assert r.class_accuracy("a") == pytest.approx(0.9)
    assert r.class_accuracy("b") == pytest.approx(0.8)
    # without the length the document ends at its last labelled frame, 15: 13 of 15
    r = scores(truth, out)
    assert (r.correct, r.frames) == (13, 15)


def test_frame_labels_tie_rules():
    rank = {"a": 0, "b": 1}
    # equal starts: the segment that ends first wins (b on 1..3), then a
    assert frame_labels([S("d", 1, 5, "a"), S("d", 1, 3, "b")], 6, rank).tolist() == \
        [1, 1, 1, 0, 0, -1]
    # equal starts and ends: the label first in alphabetical order
    assert frame_labels([S("d", 1, 3, "b"), S("d", 1, 3, "a")], 3, rank).tolist() == [0, 0, 0]
    # the later start wins, also inside a longer segment
    assert frame_labels([S("d", 1, 6, "a"), S("d", 3, 4, "b")], 6, rank).tolist() == \
        [0, 0, 1, 1, 0, 0]


def test_class_without_truth_frames_has_no_accuracy():
    r = scores([S("d", 1, 10, "a")], [S("d", 1, 10, "a"), S("d", 11, 12, "b")])
    assert r.class_accuracy("b") is None and r.class_accuracy("a") == 1.0
    assert r.accuracy == pytest.approx(10 / 12)


# ---------------------------------------------------------------- edge cases


def test_no_output():
    r = scores([S("d", 1, 10, "a")], [], frames={"d": 20})
    # 10 frames a predicted none (wrong), 10 none/none (right)
    assert r.accuracy == 0.5 and r.class_accuracy("a") == 0.0
    assert r.edit == 0.0 and r.f1(50) == 0.0
    assert r.overlap[10].as_dict() == {"tp": 0, "fp": 0, "fn": 1}


def test_no_truth():
    r = scores([], [S("d", 1, 10, "a")], frames={"d": 40})
    assert r.accuracy == pytest.approx(30 / 40) and r.class_accuracy("a") is None
    assert r.edit == 0.0 and r.f1(10) == 0.0 and r.overlap[10].fp == 1


def test_nothing_at_all():
    r = scores([], [], docs={"d"})
    assert (r.accuracy, r.edit, r.f1(10)) == (None, None, None)
    rep = evaluate_annotations([], [], documents=["d"])
    d = rep.as_dict()
    assert (d["accuracy"], d["edit"], d["f1_50"]) == (None, None, None)
    overall = rep.rows()[-1]
    assert overall["class"] == "overall" and overall["P1"] is None and overall["F1@50"] is None
    assert "–" in rep.table().splitlines()[-1]


def test_one_document_empty():
    truth = [S("d", 1, 10, "a")]
    out = [S("d", 1, 10, "a")]
    # e has 10 frames and no segments: its frames count (none = none: right) for accuracy,
    # it is left out of the Edit mean, adds nothing to F1@k
    r = scores(truth, out, docs={"d", "e"}, frames={"e": 10})
    assert (r.correct, r.frames) == (20, 20)
    assert r.edit_per_document == {"d": 1.0} and r.f1(50) == 1.0
    # an empty document named but of unknown length has no frames
    assert scores(truth, out, docs={"d", "e"}).frames == 10


def test_documents_outside_the_evaluation_are_ignored():
    truth = [S("d", 1, 10, "a"), S("x", 1, 10, "a")]
    rep = evaluate_annotations(truth, [S("d", 1, 10, "a")], documents=["d"])
    assert rep.segmentation.accuracy == 1.0 and rep.segmentation.f1(50) == 1.0


def test_overlapping_outputs_of_different_labels():
    truth = [S("d", 1, 10, "a"), S("d", 11, 20, "b")]
    out = [S("d", 1, 20, "a"), S("d", 11, 20, "b")]
    r = scores(truth, out)
    # a: 1..20 vs 1..10 IoU 1/2 → TP at 50; b exact. Frames: 11..20 go to b (later start)
    assert r.f1(50) == 1.0 and r.accuracy == 1.0
    # Edit: truth a b, output (1,20,a) (11,20,b) = a b
    assert r.edit == 1.0


# ---------------------------------------------------------------- Report, table, warnings


def test_report_rows_table_and_json_have_the_measures():
    truth = [S("d", 1, 10, "a"), S("d", 11, 20, "b")]
    out = [S("d", 1, 12, "a"), S("d", 13, 20, "b"), S("d", 30, 40, "c")]
    rep = evaluate_annotations(truth, out)
    # frames 1..40: right 1..10, 13..20, 21..29 = 27 of 40
    d = rep.as_dict()
    assert d["accuracy"] == pytest.approx(27 / 40)
    assert d["edit"] == pytest.approx(1 - 1 / 3)  # a b vs a b c
    assert d["f1_10"] == d["f1_25"] == d["f1_50"] == pytest.approx(0.8)  # TP 2, FP 1, FN 0
    assert d["segmentation"]["f1_counts"]["50"] == {"tp": 2, "fp": 1, "fn": 0}
    assert set(d["per_class"]["a"]) == {"frame", "segment", "accuracy", "f1_10", "f1_25",
                                        "f1_50", "segmentation"}
    assert d["per_class"]["b"]["accuracy"] == pytest.approx(0.8)
    assert d["per_class"]["c"]["accuracy"] is None and d["per_class"]["c"]["f1_50"] == 0.0
    json.dumps(d)
    head = rep.table().splitlines()[0].split()
    assert head[-5:] == ["Acc", "Edit", "F1@10", "F1@25", "F1@50"]
    rows = {r["class"]: r for r in rep.rows()}
    assert rows["overall"]["Edit"] == pytest.approx(2 / 3) and rows["a"]["Edit"] is None
    # class c has no truth: R1, R2 undefined ("–"), P 0; its F is 0, not undefined
    assert rows["c"]["R1"] is None and rows["c"]["P1"] == 0.0 and rows["c"]["F1"] == 0.0
    line_c = next(line for line in rep.table().splitlines() if line.startswith("c "))
    assert line_c.split()[1:4] == ["0.000", "–", "0.000"]
    assert rep.warnings == []


def test_warnings_when_truth_shares_no_label_or_is_empty():
    truth = [S("d", 1, 10, "walk")]
    rep = evaluate_annotations(truth, [S("d", 1, 10, "Walk")])
    assert len(rep.warnings) == 1 and "shares no label" in rep.warnings[0]
    assert "walk" in rep.warnings[0] and "Walk" in rep.warnings[0]
    rep = evaluate_annotations([S("x", 1, 10, "walk")], [S("d", 1, 10, "walk")],
                               documents=["d"])
    assert rep.warnings == ["the truth has no segment in the 1 document(s) evaluated"]
    assert evaluate_annotations(truth, []).warnings == []


# ---------------------------------------------------------------- slow references


def ref_levenshtein(a, b) -> int:
    """The full (|a|+1) × (|b|+1) table of the textbook recurrence."""
    D = [[0] * (len(b) + 1) for _ in range(len(a) + 1)]
    for i in range(len(a) + 1):
        D[i][0] = i
    for j in range(len(b) + 1):
        D[0][j] = j
    for i in range(1, len(a) + 1):
        for j in range(1, len(b) + 1):
            D[i][j] = min(D[i - 1][j] + 1, D[i][j - 1] + 1,
                          D[i - 1][j - 1] + (0 if a[i - 1] == b[j - 1] else 1))
    return D[len(a)][len(b)]


def ref_iou(x: S, y: S) -> Fraction:
    fx, fy = set(range(x.start, x.end + 1)), set(range(y.start, y.end + 1))
    return Fraction(len(fx & fy), len(fx | fy))


def ref_f1_counts(truth, output, k):
    """The greedy rule, literally: per document and label, outputs in (start, end) order
    take their best-IoU truth segment (first of equals in (start, end) order)."""
    tp = fp = fn = 0
    keys = {(s.doc, s.label) for s in [*truth, *output]}
    for doc, lab in keys:
        ts = sorted((s for s in truth if (s.doc, s.label) == (doc, lab)),
                    key=lambda s: (s.start, s.end))
        taken = [False] * len(ts)
        for o in sorted((s for s in output if (s.doc, s.label) == (doc, lab)),
                        key=lambda s: (s.start, s.end)):
            if not ts:
                fp += 1
                continue
            ious = [ref_iou(o, t) for t in ts]
            best = ious.index(max(ious))
            if ious[best] >= Fraction(k, 100) and not taken[best]:
                tp += 1
                taken[best] = True
            else:
                fp += 1
        fn += taken.count(False)
    return tp, fp, fn


def ref_best_matching(truth, output, k) -> int:
    """Brute force over every one-to-one assignment of outputs to truth segments (same
    document and label, IoU ≥ k/100): the largest number of matched pairs."""
    best = 0
    keys = {(s.doc, s.label) for s in [*truth, *output]}
    for doc, lab in keys:
        ts = [s for s in truth if (s.doc, s.label) == (doc, lab)]
        os_ = [s for s in output if (s.doc, s.label) == (doc, lab)]
        most = 0
        for r in range(min(len(ts), len(os_)), 0, -1):
            if any(all(ref_iou(o, t) >= Fraction(k, 100) for o, t in zip(oo, tt))
                   for oo in itertools.combinations(os_, r)
                   for tt in itertools.permutations(ts, r)):
                most = r
                break
        best += most
    return best


def ref_frames(truth, output, docs, frames):
    """Per frame: its covering segments, the winner the one with the latest start, then
    earliest end, then first label; compared frame by frame."""
    def label_at(segs, f):
        cover = [s for s in segs if s.start <= f <= s.end]
        return min(cover, key=lambda s: (-s.start, s.end, s.label)).label if cover else None

    total = right = 0
    per_true: dict[str, list[int]] = {}
    for d in docs:
        t = [s for s in truth if s.doc == d]
        o = [s for s in output if s.doc == d]
        n = max([frames.get(d, 0)] + [s.end for s in t + o])
        for f in range(1, n + 1):
            a, b = label_at(t, f), label_at(o, f)
            total += 1
            right += a == b
            if a is not None:
                c = per_true.setdefault(a, [0, 0])
                c[0] += a == b
                c[1] += 1
    return total, right, per_true


def ref_edit(truth, output, docs):
    vals = []
    for d in docs:
        t = [s.label for s in sorted((s for s in truth if s.doc == d),
                                     key=lambda s: (s.start, s.end, s.label))]
        o = [s.label for s in sorted((s for s in output if s.doc == d),
                                     key=lambda s: (s.start, s.end, s.label))]
        if t or o:
            vals.append(1 - Fraction(ref_levenshtein(t, o), max(len(t), len(o))))
    return sum(vals) / len(vals) if vals else None


segment = st.builds(lambda doc, start, length, label: S(doc, start, start + length - 1, label),
                    st.sampled_from("de"), st.integers(1, 30), st.integers(1, 12),
                    st.sampled_from("abc"))
tables = st.lists(segment, max_size=7)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from("abc"), max_size=8), st.lists(st.sampled_from("abc"), max_size=8))
def test_levenshtein_matches_the_full_table(a, b):
    assert levenshtein(a, b) == ref_levenshtein(a, b) == levenshtein(b, a)


@settings(max_examples=300, deadline=None)
@given(tables, tables, st.dictionaries(st.sampled_from("def"), st.integers(1, 50)))
def test_measures_match_the_references(truth, output, frames):
    docs = {"d", "e", "f"}
    r = segmentation_scores(truth, output, docs, frames=frames)
    for k in OVERLAPS:
        c = r.overlap[k]
        assert (c.tp, c.fp, c.fn) == ref_f1_counts(truth, output, k)
        per = {lab: r.class_overlap[lab][k] for lab in r.class_overlap}
        assert sum(x.tp for x in per.values()) == c.tp
    total, right, per_true = ref_frames(truth, output, docs, frames)
    assert (r.frames, r.correct) == (total, right)
    for lab, (ok, n) in per_true.items():
        assert (r.class_correct[lab], r.class_frames[lab]) == (ok, n)
    e = ref_edit(truth, output, docs)
    assert (r.edit is None) == (e is None)
    if e is not None:
        assert r.edit == pytest.approx(float(e))


@settings(max_examples=150, deadline=None)
@given(st.lists(segment, max_size=5), st.lists(segment, max_size=5))
def test_greedy_never_beats_the_best_assignment(truth, output):
    for k in OVERLAPS:
        tp, _, _ = ref_f1_counts(truth, output, k)
        assert tp <= ref_best_matching(truth, output, k)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 6), st.sampled_from("ab")), max_size=5),
       st.lists(segment, max_size=5))
def test_greedy_is_the_best_assignment_above_half_with_disjoint_truth(cuts, output):
    # truth of each label disjoint and IoU > 1/2: an output qualifies for at most one
    # truth segment, so taking it when free is a maximum matching
    truth, at = [], 1
    for length, lab in cuts:
        truth.append(S("d", at, at + length - 1, lab))
        at += length
    output = [S("d", s.start, s.end, s.label) for s in output]
    assert ref_f1_counts(truth, output, 51)[0] == overlap_counts_all(truth, output, 51) \
        == ref_best_matching(truth, output, 51)


def overlap_counts_all(truth, output, k):
    return sum(overlap_counts([t for t in truth if t.label == lab],
                              [o for o in output if o.label == lab], k).tp
               for lab in {s.label for s in [*truth, *output]})


# ---------------------------------------------------------------- the command


def test_evaluate_json_and_table_have_the_measures(tmp_path):
    from mtanno.annotate import Annotation, write_annotations
    from mtanno.cli import main

    (tmp_path / "truth.csv").write_text("doc,start,end,label\nd,1,10,a\nd,11,15,b\n")
    # 0-based rows: a on frames 1..12, b on 10..14 (the hand-worked accuracy case)
    write_annotations(tmp_path / "ann.csv", [Annotation("d", 0, 11, "a", 0.1),
                                             Annotation("d", 9, 13, "b", 0.2)],
                      provenance={"documents": {"d": 20}})
    r = CliRunner().invoke(main, ["evaluate", str(tmp_path / "ann.csv"), "--truth",
                                  str(tmp_path / "truth.csv"), "--json",
                                  str(tmp_path / "rep.json"), "-o", str(tmp_path / "t.csv")],
                           catch_exceptions=False)
    assert r.exit_code == 0, r.output
    rep = json.loads((tmp_path / "rep.json").read_text())
    assert {"accuracy", "edit", "f1_10", "f1_25", "f1_50"} <= set(rep)
    assert rep["accuracy"] == pytest.approx(0.9)  # the document's recorded 20 frames
    assert rep["edit"] == 1.0  # a b against a b
    # a: 1..12 vs 1..10 IoU 10/12; b: 10..14 vs 11..15 IoU 4/6 → both TPs at every k
    assert rep["f1_10"] == rep["f1_25"] == rep["f1_50"] == 1.0
    for c in ("a", "b"):
        assert {"accuracy", "f1_10", "f1_25", "f1_50"} <= set(rep["per_class"][c])
    assert rep["per_class"]["b"]["accuracy"] == pytest.approx(0.8)
    assert "F1@50" in r.output and "warning" not in r.output
    head = (tmp_path / "t.csv").read_text().splitlines()[0].split(",")
    assert head[-5:] == ["Acc", "Edit", "F1@10", "F1@25", "F1@50"]


def test_evaluate_warns_when_truth_shares_no_label(tmp_path):
    from mtanno.cli import main

    (tmp_path / "truth.csv").write_text("doc,start,end,label\nd,1,10,walk\n")
    (tmp_path / "ann.csv").write_text("doc,start,end,label,cost\nd,1,10,jump,0.1\n")
    try:
        runner = CliRunner(mix_stderr=False)  # Click 8.1
    except TypeError:
        runner = CliRunner()  # Click ≥ 8.2 keeps standard error apart
    r = runner.invoke(main, ["evaluate", str(tmp_path / "ann.csv"), "--truth",
                             str(tmp_path / "truth.csv")], catch_exceptions=False)
    assert r.exit_code == 0
    warnings = [line for line in r.stderr.splitlines() if "warning" in line]
    assert warnings == ["mtanno: warning: the truth shares no label with the annotation "
                        "(truth: walk; annotation: jump): no segment and no labelled frame "
                        "can count as right"]
    assert "warning" not in r.stdout and "overall" in r.stdout


def test_report_tables_have_the_measures_and_the_page_the_warning(tmp_path):
    pytest.importorskip("matplotlib")
    from mtanno.annotate import Annotation
    from mtanno.evaluation.report import write_report

    truth = [S("d", 1, 10, "a"), S("d", 11, 15, "b")]
    rows = [Annotation("d", 0, 11, "a", 0.1), Annotation("d", 9, 13, "b", 0.2),
            Annotation("d", 15, 19, "c", 0.3)]
    res = write_report(tmp_path / "r", truth, rows, frames={"d": 20})
    md = (tmp_path / "r" / "per_class.md").read_text().splitlines()
    assert md[0].endswith("| Acc | Edit | F1@10 | F1@25 | F1@50 |")
    assert all(line.count("|") == md[0].count("|") for line in md)
    # class c: no truth → R1, R2, Acc undefined; Edit only overall
    c = next(line for line in md if line.startswith("| c |")).split(" | ")
    assert c[2] == "–" and c[6] == "–" and c[9] == "–" and c[10] == "–"
    # the hand-worked accuracy case plus c on 16..20: right 1..9, 11..14 → 13 of 20
    assert res.evaluation.segmentation.accuracy == pytest.approx(13 / 20)
    tex = (tmp_path / "r" / "per_class.tex").read_text()
    assert "F1@50" in tex and tex.splitlines()[0] == r"\begin{tabular}{l" + "r" * 13 + "}"
    page = (tmp_path / "r" / "index.html").read_text()
    assert "<th>F1@50</th>" in page and ">None<" not in page
    assert not res.notes or all("shares no label" not in n for n in res.notes)
    other = write_report(tmp_path / "o", [S("d", 1, 10, "walk")], rows, frames={"d": 20})
    assert any("shares no label" in n for n in other.notes)
    assert "shares no label" in (tmp_path / "o" / "index.html").read_text()
