"""Δ̄ (reference variant) against the reference implementation's `classification_delta`
(../shared/data/reference/retrieval): Δ of the golden quantized templates on the concatenated
actor-mm document, then the cheapest-hit fill with τ = 0.13 and at most 2000 hits."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import REFERENCE, require_data

from mtanno.annotate import modified_delta
from mtanno.templates.match import match_template

RET = REFERENCE / "retrieval"
CASES = [(c, t, sep) for c in ("squat1Reps", "kickLFront1Reps", "jogLeftCircle4StepsRstart")
         for t in ("d010", "d005") for sep in ("", "_sep2")]


def _load(path):
    return np.genfromtxt(path, delimiter=",", names=True)


@pytest.mark.parametrize("cls,tag,sep", CASES)
def test_classification_delta(cls, tag, sep):
    require_data()
    mt = np.loadtxt(RET / f"{cls}_{tag}_mtbool.csv", delimiter=",", skiprows=1)
    weights, values = mt[:, 1], mt[:, 2:].T
    X = np.loadtxt(RET / "concat_doc_features.csv", delimiter=",", skiprows=1)[:, 1:].T
    X = X.astype(np.uint8)
    want = np.genfromtxt(RET / f"{cls}_{tag}{sep}_delta.csv", delimiter=",", skip_header=1)[:, 2]
    if not sep:
        delta, start = match_template(values, weights, X)
        got = modified_delta(delta, start, tau=0.13, max_hits=2000)
    else:
        # sep2: two separator columns after every clip; every clip is its own document
        import csv

        rows = list(csv.DictReader((RET / "concat_doc.csv").open()))
        got = np.full(want.shape[0], np.inf)
        for r in rows:
            a, b = int(r["doc_start"]) - 1, int(r["doc_end"])
            s = int(r["docsep2_start"]) - 1
            delta, start = match_template(values, weights, X[:, a:b])
            got[s:s + b - a] = modified_delta(delta, start, tau=0.13, max_hits=2000)
    finite = np.isfinite(want)
    assert np.array_equal(np.isfinite(got), finite)
    assert np.abs(got[finite] - want[finite]).max(initial=0) < 1e-9
