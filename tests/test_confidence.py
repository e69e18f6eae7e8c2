"""Confidence per segment (issue 26, part 1): the column in every table format, the
evidence of hand-made segments, the single-label choice by confidence, the configuration's
[confidence] and [background] sections, and the uncalibrated score."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mtanno.annotate import Annotation, read_annotations, write_annotations
from mtanno.annotate.calibration import uncalibrated_confidence
from mtanno.annotate.confidence import (
    check_min_confidence,
    segment_evidence,
    single_label_by_confidence,
)
from mtanno.annotate.config import ClassConfig, class_config_text, load_class_config
from mtanno.errors import MtannoError

ROWS = [Annotation("d1", 0, 9, "kick", 0.05, 0.91), Annotation("d1", 5, 20, "walk", 0.02, 0.25),
        Annotation("d2", 3, 4, "kick", math.inf, math.nan)]


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".jsonl"])
def test_confidence_column_round_trips(tmp_path, suffix):
    path = tmp_path / f"a{suffix}"
    write_annotations(path, ROWS)
    back = read_annotations(path)
    assert [r.confidence for r in back[:2]] == [0.91, 0.25]
    assert math.isnan(back[2].confidence)
    assert [r[:4] for r in back] == [r[:4] for r in ROWS]


def test_confidence_out_of_range_is_refused_with_its_line(tmp_path):
    path = tmp_path / "a.csv"
    path.write_text("doc,start,end,label,cost,confidence\nd,1,5,kick,0.1,1.5\n")
    with pytest.raises(MtannoError, match=r"a.csv:2: confidence must be in \[0, 1\]"):
        read_annotations(path)


def test_uncalibrated_confidence_is_monotone_in_cost():
    assert uncalibrated_confidence(0.0) == 1.0
    assert uncalibrated_confidence(1.0) == 0.0
    assert uncalibrated_confidence(0.25) == pytest.approx(0.75)
    assert uncalibrated_confidence(math.inf) == 0.0 and uncalibrated_confidence(-1) == 1.0


def test_min_confidence_checked():
    assert check_min_confidence(0.5) == 0.5
    for bad in (-0.1, 1.1, float("nan"), "x"):
        with pytest.raises(MtannoError, match=r"in \[0, 1\]"):
            check_min_confidence(bad)


def test_evidence_of_hand_made_segments():
    rows = [Annotation("d", 0, 29, "kick", 0.05), Annotation("d", 30, 44, "kick", math.inf)]
    E = segment_evidence(rows, taus={"kick": 0.1}, lengths={"kick": 30.0},
                         names=("cost", "length"))
    assert E[0].tolist() == pytest.approx([0.5, 0.0])
    assert E[1, 0] == 10.0 and E[1, 1] == pytest.approx(math.log(0.5))
    with pytest.raises(MtannoError, match="needs a bank"):
        segment_evidence(rows, taus={}, lengths={}, names=("verify",))
    with pytest.raises(MtannoError, match="unknown evidence"):
        segment_evidence(rows, taus={}, lengths={}, names=("speed",))


def test_background_evidence_changes_a_decision():
    """A background example like the segment makes its background evidence large."""
    from mtanno.annotate.verify import build_bank

    rng = np.random.default_rng(0)
    kick = rng.random((12, 6)).astype(np.float32)
    other = rng.random((12, 6)).astype(np.float32) + 1.0
    seg = kick[2:10] + 0.2  # a segment a little off the kick examples
    ex = [("kick", p, kick + 0.01 * i) for i, p in enumerate(("a", "b"))]
    rows = [Annotation("d", 0, 7, "kick", 0.05)]

    def evidence(background):
        bank = build_bank(ex, background, representation="features")
        return segment_evidence(rows, taus={"kick": 0.1}, lengths={"kick": 12.0}, bank=bank,
                                query=lambda r: seg, names=("verify", "background"))[0]

    without = evidence([other])
    with_like = evidence([other, seg.copy()])  # background holds this very motion
    assert without[1] < 0 < with_like[1]
    assert with_like[0] == pytest.approx(without[0])


def test_single_label_prefers_the_more_confident_segment():
    rows = [Annotation("d", 0, 9, "kick", 0.05, 0.4), Annotation("d", 5, 14, "walk", 0.01, 0.9),
            Annotation("d", 20, 24, "kick", 0.05, 0.7)]
    out = single_label_by_confidence(rows)
    assert [(r.start, r.end, r.label, r.confidence) for r in out] == [
        (0, 4, "kick", 0.4), (5, 14, "walk", 0.9), (20, 24, "kick", 0.7)]


def test_config_confidence_and_background_round_trip(tmp_path):
    cfg = ClassConfig(background={"bg/a.parquet": "a" * 64},
                      confidence={"evidence": ["cost", "length"], "min_confidence": 0.3,
                                  "calibrator": {"method": "platt", "names": ["cost", "length"],
                                                 "logistic": {"coef": [1.0, -2.0]}}})
    path = tmp_path / "c.toml"
    path.write_text(class_config_text(cfg))
    back = load_class_config(path)
    assert back.background == cfg.background and back.confidence == cfg.confidence


@pytest.mark.parametrize("text, msg", [
    ("[confidence]\nspeed = 1\n", "unknown key 'speed'"),
    ("[confidence]\nevidence = ['speed']\n[confidence.calibrator]\nmethod = 'platt'\n",
     "evidence must list"),
    ("[confidence]\nevidence = ['cost']\nmin_confidence = 2\n[confidence.calibrator]\n"
     "method = 'platt'\n", r"in \[0, 1\]"),
    ("[confidence]\nevidence = ['cost']\n", "needs a \\[confidence.calibrator\\]"),
    ("[confidence]\nevidence = ['cost']\nbank = 'b.parquet'\n[confidence.calibrator]\n"
     "method = 'platt'\n", "go together"),
    ("[background]\n'x.parquet' = 'abc'\n", "SHA-256"),
])
def test_bad_confidence_sections(tmp_path, text, msg):
    path = tmp_path / "c.toml"
    path.write_text(text)
    with pytest.raises(MtannoError, match=msg):
        load_class_config(path)
