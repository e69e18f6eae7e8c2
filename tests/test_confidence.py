"""Confidence per segment (issue 26, part 1): the column in every table format, the
evidence of hand-made segments, the single-label choice by confidence, the configuration's
[confidence] and [background] sections, and the uncalibrated score."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mtanno.annotate import Annotation, read_annotations, write_annotations
from mtanno.annotate.config import ClassConfig, class_config_text, load_class_config
from mtanno.confidence.calibration import Calibrator, uncalibrated_confidence
from mtanno.confidence.evidence import EVIDENCE, label_facts, register_evidence, segment_evidence
from mtanno.confidence.model import ConfidenceModel, check_min_confidence
from mtanno.confidence.score import single_label_by_confidence
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
    facts = label_facts({"kick": 30}, tau_for=lambda c: 0.1)
    E = segment_evidence(rows, facts, names=("cost", "length"))
    assert E[0].tolist() == pytest.approx([0.5, 0.0])
    assert E[1, 0] == 10.0 and E[1, 1] == pytest.approx(math.log(0.5))
    none = label_facts({}, tau_for=lambda c: 0.1)
    with pytest.raises(MtannoError, match="needs a bank"):
        segment_evidence(rows, none, names=("verify",))
    with pytest.raises(MtannoError, match="unknown evidence"):
        segment_evidence(rows, none, names=("speed",))


def test_label_facts_of_superclasses_use_the_median_base_template():
    facts = label_facts({"kickL": 20, "kickR": 40, "walk": 31},
                        tau_for=lambda c: {"kick": 0.2}.get(c, 0.1),
                        superclasses={"kick": ["kickL", "kickR"]})
    assert facts.lengths == {"kick": 30.0, "walk": 31.0}
    assert facts.members == {"kick": ("kickL", "kickR"), "walk": ("walk",)}
    assert facts.taus == {"kick": 0.2, "walk": 0.1}


def test_the_evidence_registry_is_ordered_and_extensible():
    assert EVIDENCE == ("cost", "length", "verify", "margin", "background", "classifier")
    import mtanno.confidence.evidence as ev

    @register_evidence("frames")
    def _frames(s):
        return float(s.row.end - s.row.start + 1)

    try:
        rows = [Annotation("d", 0, 29, "kick", 0.05)]
        E = segment_evidence(rows, label_facts({"kick": 30}, tau_for=lambda c: 0.1),
                             names=("frames", "cost"))
        assert E.tolist() == [[30.0, 0.5]]
    finally:
        del ev._KINDS["frames"]


def test_background_evidence_changes_a_decision():
    """A background example like the segment makes its background evidence large."""
    from mtanno.confidence.verify import build_bank

    rng = np.random.default_rng(0)
    kick = rng.random((12, 6)).astype(np.float32)
    other = rng.random((12, 6)).astype(np.float32) + 1.0
    seg = kick[2:10] + 0.2  # a segment a little off the kick examples
    ex = [("kick", p, kick + 0.01 * i) for i, p in enumerate(("a", "b"))]
    rows = [Annotation("d", 0, 7, "kick", 0.05)]

    def evidence(background):
        bank = build_bank(ex, background, representation="features")
        facts = label_facts({"kick": 12}, tau_for=lambda c: 0.1)
        return segment_evidence(rows, facts, bank=bank, query=lambda r: seg,
                                names=("verify", "background"))[0]

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
    from mtanno.confidence.calibration import fit_calibrated

    rng = np.random.default_rng(0)
    E = rng.random((40, 2))
    fit = fit_calibrated(E, (E[:, 0] > 0.5).astype(float), names=("cost", "length"), rng=0)
    table = {"evidence": ["cost", "length"], "min_confidence": 0.3,
             "calibrator": fit.calibrator.to_dict()}
    model = ConfidenceModel.from_table(table)
    assert isinstance(model.calibrator, Calibrator) and model.evidence == ("cost", "length")
    cfg = ClassConfig(background={"bg/a.parquet": "a" * 64}, confidence=model)
    path = tmp_path / "c.toml"
    path.write_text(class_config_text(cfg))
    back = load_class_config(path)
    assert back.background == cfg.background
    assert back.confidence.to_table() == model.to_table()
    assert (back.confidence.evidence, back.confidence.min_confidence) == (("cost", "length"),
                                                                         0.3)


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


def test_tune_and_annotate_build_the_same_evidence_inputs(world, tmp_path):
    """The evidence of the same segments is equal whether tune builds its inputs (the
    template folder's templates, the tuned τ) or annotate does (its class models, extra
    templates of the configuration included, under the configuration): the length of a
    label is its base template's in both (issue 32: annotate took the median over the
    extra templates too)."""
    from mtanno.annotate import annotation_setup
    from mtanno.confidence.evidence import document_evidence
    from mtanno.confidence.score import annotation_facts
    from mtanno.features.store import read_features
    from mtanno.templates.store import load_template_folder, save_template
    from mtanno.templates.tempo import time_scaled

    templates = load_template_folder(world.mt)
    cls = sorted(templates)[0]
    slow = tmp_path / "slow.json"
    save_template(slow, time_scaled(templates[cls], 1.6))
    cfg = ClassConfig(tau={c: 0.1 + 0.01 * i for i, c in enumerate(sorted(templates))},
                      templates={cls: [str(slow)]})
    setup = annotation_setup(templates, config=cfg)
    assert sum(m.extra for m in setup.models) == 1  # the slow copy is matched too
    annotate_facts = annotation_facts(setup.models, setup.config)
    tune_facts = label_facts({c: mt.values.shape[1] for c, mt in templates.items()},
                             tau_for=cfg.tau_for)
    assert annotate_facts == tune_facts
    ff = read_features(world.doc_files[0])
    rows = [Annotation(ff.path, 0, 29, cls, 0.05), Annotation(ff.path, 10, 99, cls, 0.2)]
    both = [document_evidence(rows, f, X=ff.X, poses=None, names=("cost", "length"))
            for f in (annotate_facts, tune_facts)]
    np.testing.assert_array_equal(*both)


def test_config_invariance_round_trips_and_is_checked(tmp_path):
    """Issue 35: [confidence] invariance is written in INVARIANCES order, read back, and
    refused when unknown, repeated or without a bank."""
    from mtanno.confidence.calibration import fit_calibrated

    rng = np.random.default_rng(1)
    E = rng.random((40, 2))
    fit = fit_calibrated(E, (E[:, 0] > 0.5).astype(float), names=("cost", "verify"), rng=0)
    table = {"evidence": ["cost", "verify"], "bank": "b.parquet", "bank_sha256": "a" * 64,
             "invariance": ["mirror", "retarget"], "calibrator": fit.calibrator.to_dict()}
    model = ConfidenceModel.from_table(table)
    assert model.invariance == ("retarget", "mirror")
    path = tmp_path / "c.toml"
    path.write_text(class_config_text(ClassConfig(confidence=model)))
    assert load_class_config(path).confidence.invariance == ("retarget", "mirror")
    assert 'invariance = ["retarget", "mirror"]' in path.read_text()
    for bad, msg in ((["scale"], "invariance must list"), (["mirror", "mirror"], "distinct"),
                     (["mirror"], "invariance needs a verification bank")):
        t = {**table, "invariance": bad}
        if "needs" in msg:
            t = {k: v for k, v in t.items() if not k.startswith("bank")}
        with pytest.raises(MtannoError, match=msg):
            ConfidenceModel.from_table(t)
