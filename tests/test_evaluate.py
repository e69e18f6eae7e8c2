"""Evaluation measures (docs/method.md §8) on hand-made tables with overlaps."""

from __future__ import annotations

import math

import pytest

from mtanno.evaluation.metrics import evaluate_annotations, frame_level, segment_level
from mtanno.evaluation.retrieval import retrieval_rows, separation_quotient, top_k_recall
from mtanno.labels.segments import Segment as S


def test_frame_level_with_overlapping_labels():
    truth = [S("d", 1, 10, "a"), S("d", 11, 20, "b"), S("e", 1, 5, "a")]
    # output: a on 1..15 (overlaps b's frames), b on 11..20, a on d frames 5..6 twice
    out = [S("d", 1, 15, "a"), S("d", 11, 20, "b"), S("d", 5, 6, "a"), S("e", 4, 8, "b")]
    total, per = frame_level(truth, out)
    # A = {(d,1..15,a)}=15, {(d,11..20,b)}=10, {(e,4..8,b)}=5 → 30 pairs; M = 10+10+5 = 25
    # M∩A = (d,1..10,a)=10 + (d,11..20,b)=10 = 20
    assert (total.tp_p, total.n_p, total.n_r) == (20, 30, 25)
    assert total.P == pytest.approx(20 / 30) and total.R == pytest.approx(20 / 25)
    assert total.F == pytest.approx(2 * (2 / 3) * 0.8 / (2 / 3 + 0.8))
    assert per["a"].P == pytest.approx(10 / 15) and per["a"].R == pytest.approx(10 / 15)
    assert per["b"].P == pytest.approx(10 / 15) and per["b"].R == 1.0


def test_segment_level():
    truth = [S("d", 1, 10, "a"), S("d", 20, 30, "a"), S("d", 40, 50, "b")]
    out = [S("d", 5, 8, "a"), S("d", 9, 12, "a"), S("d", 31, 39, "a"), S("d", 45, 45, "b"),
           S("x", 1, 100, "b")]
    total, per = segment_level(truth, out)
    # correct outputs: (5..8,a), (9..12,a), (45,b) → 3 of 5; found truth: (1..10,a), (40..50,b)
    assert (total.tp_p, total.n_p) == (3, 5)
    assert (total.tp_r, total.n_r) == (2, 3)
    assert per["a"].P == pytest.approx(2 / 3) and per["a"].R == pytest.approx(1 / 2)
    assert per["b"].P == pytest.approx(1 / 2) and per["b"].R == 1.0


def test_report_dict_and_table():
    truth = [S("d", 1, 10, "a")]
    r = evaluate_annotations(truth, [S("d", 1, 10, "a")])
    d = r.as_dict()
    assert {k: d["frame"][k] for k in "PRF"} == {"P": 1.0, "R": 1.0, "F": 1.0}
    assert d["segment"]["F"] == 1.0 and d["schema"] == "mtanno.evaluation/1"
    assert d["per_class"]["a"]["frame"]["P"] == 1.0
    assert "overall" in r.table()
    empty = evaluate_annotations(truth, [])
    assert empty.frame.P == 0.0 and empty.frame.F == 0.0
    only = evaluate_annotations(truth + [S("z", 1, 2, "a")], [S("z", 1, 2, "a")], documents=["z"])
    assert only.frame.F == 1.0


def test_retrieval_rows_and_quotients():
    truth = [S("d", 10, 20, "jump"), S("d", 50, 60, "jump"), S("d", 80, 90, "kick")]
    hits = [S("d", 12, 18, "jump"), S("d", 13, 21, "jump"), S("d", 82, 88, "jump"),
            S("d", 55, 70, "jump")]
    costs = [0.01, 0.03, 0.05, 0.08]
    rows = retrieval_rows("jump", hits, costs, truth, taus=(0.02, 0.05, 0.1))
    assert [(r.hits, r.relevant, r.occurrences) for r in rows] == [(1, 1, 2), (3, 1, 2), (4, 2, 2)]
    assert rows[1].P == pytest.approx(1 / 3) and rows[2].R == 1.0
    assert top_k_recall(hits, truth, "jump", 1) == 0.5
    assert top_k_recall(hits, truth, "jump", 5) == 1.0
    # correct hits among the top 10: costs 0.01, 0.03, 0.08 → median 0.03
    assert separation_quotient(0.3, hits, costs, truth, "jump") == pytest.approx(10.0)
    assert math.isnan(separation_quotient(0.3, hits[2:3], [0.05], truth, "jump"))


def test_relevant_hits_claim_one_occurrence_each():
    truth = [S("d", 1, 10, "squat"), S("d", 11, 20, "squat"), S("d", 21, 30, "squat")]
    hits = [S("d", 5, 15, "squat"), S("d", 8, 9, "squat")]  # the first overlaps two
    rows = retrieval_rows("squat", hits, [0.01, 0.02], truth, taus=(0.1,))
    assert (rows[0].hits, rows[0].relevant) == (2, 2) and rows[0].P == 1.0
    rows = retrieval_rows("squat", hits[:1], [0.01], truth, taus=(0.1,))
    assert (rows[0].hits, rows[0].relevant) == (1, 1) and rows[0].R == pytest.approx(1 / 3)
