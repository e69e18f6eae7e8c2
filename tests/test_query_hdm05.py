"""Query by example on the 232 HDM05 clips (MRC05 §6.2, Fig. 8): a squat of actor bd finds
the squats of the other actors among its top hits. Needs ../shared/data."""

from __future__ import annotations

import pytest
from conftest import HDM05, require_data

from mtanno.features.batch import plan_batch, run_batch
from mtanno.index import build_index, example_query, search
from mtanno.index.core import read_feature_doc

EXAMPLE = "HDM_bd_squat1Reps_001_120"


@pytest.fixture(scope="module")
def hdm05_index(tmp_path_factory):
    require_data()
    tmp = tmp_path_factory.mktemp("hdm05")
    summary = run_batch(plan_batch([HDM05], tmp / "features"), n_jobs=2, feature_set="mrc05")
    assert summary.count("written") == 232, summary.line()
    index = build_index([tmp / "features"], tmp / "index")
    return index, tmp / "features" / "squat1Reps" / f"{EXAMPLE}.parquet"


def _top(index, example, features, n):
    ex = read_feature_doc(example)
    hits = search(index, example_query(index, ex.X, ex.names, features))
    names = [index.documents[d].name for d in hits.doc[:n]]
    return hits, names


def test_squat_by_example_paper_features(hdm05_index):
    # the five features of MRC05 Fig. 8: Fℓ5/Fℓ6 feet fast, Fℓ7 right knee bent,
    # Fℓ10 left leg sideways, Fℓ11 legs crossed
    index, example = hdm05_index
    hits, top = _top(index, example, ["Fl5", "Fl6", "Fl7", "Fl10", "Fl11"], 20)
    assert top[0] == EXAMPLE and hits.score[0] == 0
    assert all("_squat1Reps_" in n for n in top), top
    actors = {n.split("_")[1] for n in top}
    assert {"bk", "dg"} <= actors, top


def test_squat_by_example_knees_and_feet(hdm05_index):
    # both knees bent and both feet fast: squats of bk and dg rank right after the example
    index, example = hdm05_index
    hits, top = _top(index, example, ["rknee_bent", "lknee_bent", "rfoot_fast", "lfoot_fast"], 5)
    assert top[0] == EXAMPLE
    assert all("_squat1Reps_" in n for n in top), top
    assert {n.split("_")[1] for n in top[1:]} >= {"bk", "dg"}, top


def test_squat_by_example_knees_tolerates_transients(hdm05_index):
    """Issue 9: the bd squat with the two knee features. Without transitions (MRC05's
    rule) its one-frame transient (the left knee bends a frame early) is a query segment
    and only 5 of the 40 squat clips are found; with the default --min-segment they are
    at least 30, and squats are most of the hits."""
    from mtanno.index.example import DEFAULT_MIN_SEGMENT

    index, example = hdm05_index
    ex = read_feature_doc(example)
    names = [index.documents[d].name for d in search(
        index, example_query(index, ex.X, ex.names, ["rknee_bent", "lknee_bent"])).doc]
    assert len({n for n in names if "_squat1Reps_" in n}) < 10
    hits = search(index, example_query(index, ex.X, ex.names, ["rknee_bent", "lknee_bent"],
                                       min_segment=DEFAULT_MIN_SEGMENT))
    names = [index.documents[d].name for d in hits.doc]
    squats = [n for n in names if "_squat1Reps_" in n]
    assert len(set(squats)) >= 30, names
    assert len(squats) > len(names) / 2, names
    # hits are trimmed, spans are not: a trimmed hit lies inside its span
    assert (hits.span_start <= hits.start).all() and (hits.end <= hits.span_end).all()
    assert (hits.start > hits.span_start).any()
