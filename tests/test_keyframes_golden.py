"""Keyframe search against the reference implementation (../shared/data/reference/keyframes/).

The reference's hand-made keyframe queries (`manual_keyframes.csv`, three tables) searched in
the 44 clips of actor mm must give every candidate window of `keyframe_segments.csv` (four
variants with their extension rules), through an index and by a direct scan; the index
segments must equal `index_segments_*.csv`; and the class templates matched inside the
`annotation` windows must give the hits of `keyframe_mt_hits.csv`.
"""

from __future__ import annotations

import csv
import functools

import numpy as np
import pytest
from conftest import REFERENCE, require_data

from mtanno.features import FEATURE_NAMES, GROUPS
from mtanno.index import index_from_matrices
from mtanno.keyframes import (
    Extension,
    Gap,
    Keyframe,
    KeyframeQuery,
    search_documents,
    search_index,
)
from mtanno.retrieve import extract_hits
from mtanno.templates.match import PreparedTemplate

KF = REFERENCE / "keyframes"
RETRIEVAL = REFERENCE / "retrieval"
#: Reference feature sets → (mtanno group name, feature rows).
SETS = {
    "AK_upper": ("upper", list(GROUPS["upper"])),
    "AK_lower": ("lower", list(GROUPS["lower"])),
    "AK_mix_avr": ("mix", list(GROUPS["mix"])),
    "AK_mix": ("mix39", list(range(26, 39))),  # F27–F39: MR06's mix without F40
}
VARIANTS = {  # variant → (keyframe table, extension)
    "annotation": ("manualKeyframesForAnnotation_AVR", Extension(2, 0)),
    "annotation_noextend": ("manualKeyframesForAnnotation_AVR", Extension(0, 0, 0, 0)),
    "classify": ("manualKeyframes", Extension(3, 3)),
    "annotation39": ("manualKeyframesForAnnotation", Extension(2, 0)),
}
CLASSES = ["squat1Reps", "kickLFront1Reps", "jogLeftCircle4StepsRstart"]


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@functools.cache
def clips():
    """(clip name → (40 × frames) features at 30 Hz, clip rows of concat_doc.csv)."""
    require_data()
    a = np.loadtxt(RETRIEVAL / "concat_doc_features.csv", delimiter=",", skiprows=1)
    X = np.ascontiguousarray(a[:, 1:].T.astype(np.uint8))
    rows = _rows(RETRIEVAL / "concat_doc.csv")
    return {r["clip"]: X[:, int(r["doc_start"]) - 1:int(r["doc_end"])] for r in rows}, rows


def reference_query(source: str, cls: str, extension: Extension) -> KeyframeQuery:
    """A KeyframeQuery from the rows of manual_keyframes.csv."""
    require_data()
    rows = [r for r in _rows(KF / "manual_keyframes.csv")
            if r["source"] == source and r["class"] == cls]
    rows.sort(key=lambda r: int(r["keyframe"]))
    groups = {g: tuple(FEATURE_NAMES[i] for i in feats) for g, feats in SETS.values()}
    kfs, gaps = [], []
    for j, r in enumerate(rows):
        kfs.append(Keyframe(SETS[r["feature_set"]][0], r["vector"], int(r["position"])))
        if j:
            d = kfs[-1].position - kfs[-2].position
            gaps.append(Gap.from_stiffness(d, rows[j - 1]["stiffness_to_next"]))
    return KeyframeQuery(cls, "mr06-ak40", groups, kfs, gaps, int(rows[0]["template_length"]),
                         extension)


@functools.cache
def index():
    mats, _ = clips()
    groups = {g: [FEATURE_NAMES[i] for i in feats] for g, feats in SETS.values()}
    return index_from_matrices(mats, FEATURE_NAMES, groups, feature_set="mr06-ak40")


def golden_windows(cls, variant):
    return sorted((r["clip"], int(r["start30"]) - 1, int(r["end30"]) - 1)
                  for r in _rows(KF / "keyframe_segments.csv")
                  if r["class"] == cls and r["variant"] == variant)


def as_windows(hits, widths):
    d, s, e = hits.windows(widths=widths)
    return sorted((hits.names[int(i)], int(a), int(b)) for i, a, b in zip(d, s, e))


@pytest.mark.realdata
@pytest.mark.parametrize("cls", CLASSES)
@pytest.mark.parametrize("variant", list(VARIANTS))
def test_reference_windows(cls, variant):
    source, ext = VARIANTS[variant]
    q = reference_query(source, cls, ext)
    summary = next(r for r in _rows(KF / "keyframe_summary.csv")
                   if r["class"] == cls and r["variant"] == variant)
    assert q.widths() == (int(summary["extend_left"]), int(summary["extend_right"]))
    want = golden_windows(cls, variant)
    by_index = search_index(index(), q)
    mats, _ = clips()
    by_scan = search_documents(list(mats.items()), FEATURE_NAMES, q)
    assert as_windows(by_index, None) == want
    assert as_windows(by_scan, None) == want
    assert len(want) == int(summary["num_segments"])


@pytest.mark.realdata
@pytest.mark.parametrize("ref_set", list(SETS))
def test_reference_index_segments(ref_set):
    """Our segmentation of each group equals the reference index (codes, starts, lengths)."""
    g, _ = SETS[ref_set]
    gi = index().groups[g]
    mats, rows = clips()
    got = []
    for r in rows:
        d = index().doc_number(r["clip"])
        start, length, code = gi.segments(d)
        got += [(int(r["doc_index"]), int(c), int(s) + 1, int(n))
                for s, n, c in zip(start, length, code)]
    want = [(int(r["doc_index"]), int(r["code"]), int(r["frame_start30"]),
             int(r["frame_length30"])) for r in _rows(KF / f"index_segments_{ref_set}.csv")]
    assert got == want


@pytest.mark.realdata
def test_template_hits_inside_reference_windows():
    """annotationScript's second step: each class MT (δ = 0.05) matched inside each
    `annotation` window, classification hits with τ = 0.13 (keyframe_mt_hits.csv)."""
    mats, rows = clips()
    offset = {r["clip"]: int(r["doc_start"]) - 1 for r in rows}
    got = []
    for cls in CLASSES:
        a = np.loadtxt(RETRIEVAL / f"{cls}_d005_mtbool.csv", delimiter=",", skiprows=1)
        prep = PreparedTemplate(a[:, 2:].T.copy(), a[:, 1].copy())
        q = reference_query(VARIANTS["annotation"][0], cls, VARIANTS["annotation"][1])
        for seg, (clip, s, e) in enumerate(as_windows(search_index(index(), q), None), 1):
            delta, start = prep.match(mats[clip][:, s:e + 1])
            hits = extract_hits(delta, start, tau=0.13, mode="classification", max_hits=2000)
            base = offset[clip] + s + 1
            got += [(cls, seg, rank, h.start + base, h.end + base, h.cost)
                    for rank, h in enumerate(hits, 1)]
    want = [(r["class"], int(r["segment"]), int(r["rank"]), int(r["doc_start"]),
             int(r["doc_end"]), float(r["cost"])) for r in _rows(KF / "keyframe_mt_hits.csv")]
    assert [g[:5] for g in got] == [w[:5] for w in want]
    assert np.allclose([g[5] for g in got], [w[5] for w in want], rtol=0, atol=1e-12)
