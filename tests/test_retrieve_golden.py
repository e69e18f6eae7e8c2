"""Δ curves and hit lists of the reference implementation (../shared/data/reference/retrieval/).

Every query (3 classes × δ 0.1 / 0.05) on the document without separators and on the "sep2"
document (2 NaN columns after every clip = every clip matched as its own document), plus the
reference's built-in default steps (`fndefaultsteps`). Δ must agree within 1e-6 where finite
(NaN there ↔ inf here); hit lists must agree exactly (start, end, order; cost within 1e-12).
"""

from __future__ import annotations

import csv
import functools

import numpy as np
import pytest
from conftest import REFERENCE, require_data

from mtanno.retrieve import extract_hits
from mtanno.templates.match import match_documents, match_template

RETRIEVAL = REFERENCE / "retrieval"
CLASSES = ["squat1Reps", "kickLFront1Reps", "jogLeftCircle4StepsRstart"]
TAGS = ["d010", "d005"]
CASES = [(c, t, doc) for c in CLASSES for t in TAGS for doc in ("plain", "sep2")]
RETRIEVAL_PARAMS = dict(tau=0.175, mode="retrieval", max_hits=100)  # motionTemplateIterativeWeighted
CLS_PARAMS = dict(tau=0.13, mode="classification", max_hits=2000)   # annotationScript


def _rows(name):
    with open(RETRIEVAL / name, newline="") as fh:
        return list(csv.DictReader(fh))


@functools.cache
def _document():
    require_data()
    a = np.loadtxt(RETRIEVAL / "concat_doc_features.csv", delimiter=",", skiprows=1)
    return np.ascontiguousarray(a[:, 1:].T.astype(np.uint8)), _rows("concat_doc.csv")


@functools.cache
def _template(cls, tag):
    a = np.loadtxt(RETRIEVAL / f"{cls}_{tag}_mtbool.csv", delimiter=",", skiprows=1)
    return a[:, 2:].T.copy(), a[:, 1].copy()


def _golden_delta(name):
    return np.array([float(r["delta"]) for r in _rows(name)])


def _golden_hits(name):
    return [(int(r["start"]) - 1, int(r["end"]) - 1, float(r["cost"])) for r in _rows(name)]


@functools.cache
def _match(cls, tag, doc, steps=None):
    """Our (Δ, start) on the plain or the sep2 document (frames of that document)."""
    X, clips = _document()
    V, w = _template(cls, tag)
    if doc == "plain":
        kw = {} if steps is None else dict(steps=steps, step_weights=(1, 1, 1))
        return match_template(V, w, X, **kw)
    pieces = match_documents(V, w, [X[:, int(r["doc_start"]) - 1:int(r["doc_end"])] for r in clips])
    n = int(clips[-1]["docsep2_end"]) + 2
    delta = np.full(n, np.inf)
    start = np.full(n, -1, dtype=np.int64)
    for r, (d, s) in zip(clips, pieces):
        b = int(r["docsep2_start"]) - 1
        delta[b:b + len(d)] = d
        start[b:b + len(d)] = np.where(s >= 0, s + b, -1)
    return delta, start


def _prefix(cls, tag, doc):
    return f"{cls}_{tag}" + ("_sep2" if doc == "sep2" else "")


def _assert_delta(ours, golden):
    assert ours.shape == golden.shape
    np.testing.assert_array_equal(np.isfinite(ours), ~np.isnan(golden))
    assert not np.any(np.isinf(golden))
    fin = np.isfinite(golden)
    assert np.max(np.abs(ours[fin] - golden[fin])) <= 1e-6


def _assert_hits(hits, golden):
    assert [(h.start, h.end) for h in hits] == [(s, e) for s, e, _ in golden]
    np.testing.assert_allclose([h.cost for h in hits], [c for _, _, c in golden], rtol=0, atol=1e-12)


@pytest.mark.realdata
@pytest.mark.parametrize("cls, tag, doc", CASES)
def test_delta_curves(cls, tag, doc):
    delta, start = _match(cls, tag, doc)
    _assert_delta(delta, _golden_delta(f"{_prefix(cls, tag, doc)}_delta.csv"))
    assert np.all((start >= 0) == np.isfinite(delta))
    idx = np.flatnonzero(np.isfinite(delta))
    assert np.all(start[idx] <= idx)


@pytest.mark.realdata
@pytest.mark.parametrize("cls, tag, doc", CASES)
def test_retrieval_hits(cls, tag, doc):
    hits = extract_hits(*_match(cls, tag, doc), **RETRIEVAL_PARAMS)
    _assert_hits(hits, _golden_hits(f"{_prefix(cls, tag, doc)}_hits.csv"))
    assert not hits.truncated


@pytest.mark.realdata
@pytest.mark.parametrize("cls, tag, doc", CASES)
def test_classification_hits(cls, tag, doc):
    hits = extract_hits(*_match(cls, tag, doc), **CLS_PARAMS)
    _assert_hits(hits, _golden_hits(f"{_prefix(cls, tag, doc)}_cls_hits.csv"))
    assert not hits.truncated


@pytest.mark.realdata
@pytest.mark.parametrize("cls", CLASSES)
@pytest.mark.parametrize("tag", TAGS)
def test_classification_hits_threshold_010_and_the_cap(cls, tag):
    delta, start = _match(cls, tag, "plain")
    golden = _golden_hits(f"{cls}_{tag}_cls_thr010_hits.csv")
    hits = extract_hits(delta, start, tau=0.1, mode="classification", max_hits=2000)
    _assert_hits(hits, golden)
    # motionClass_to_Delta's own cap of 100 is hit by kickLFront1Reps (the reference raises)
    capped = extract_hits(delta, start, tau=0.1, mode="classification", max_hits=100)
    assert capped.truncated == (len(golden) > 100)
    assert list(capped) == list(hits)[:100]


@pytest.mark.realdata
@pytest.mark.parametrize("cls", CLASSES)
def test_builtin_default_steps(cls):
    delta, start = _match(cls, "d010", "plain", steps=((1, 1), (0, 1), (1, 0)))
    _assert_delta(delta, _golden_delta(f"{cls}_d010_fndefaultsteps_delta.csv"))
    hits = extract_hits(delta, start, **RETRIEVAL_PARAMS)
    _assert_hits(hits, _golden_hits(f"{cls}_d010_fndefaultsteps_hits.csv"))


@pytest.mark.realdata
def test_paper_variant_ranks_the_same_class_first():
    # no golden output exists for the paper variant; it must still find the class's clips
    X, clips = _document()
    V, w = _template("kickLFront1Reps", "d010")
    delta, start = match_template(V, w, X, variant="paper")
    hits = extract_hits(delta, start, tau=0.2)
    kick = [(int(r["doc_start"]) - 1, int(r["doc_end"]) - 1) for r in clips
            if r["class"] == "kickLFront1Reps"]
    first = hits[:len(kick)]
    assert all(any(a <= h.end and h.start <= b for a, b in kick) for h in first)
