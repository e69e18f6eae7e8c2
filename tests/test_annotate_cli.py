"""The annotation pipeline through the command line on mtanno's synthetic clip set:
features → learn-mt → compose → annotate → evaluate (and evaluate-retrieval), plus the
bad-input paths of annotate and evaluate."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from mtanno import synthetic
from mtanno.cli import main
from mtanno.features.store import read_features, write_features


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def pipeline(tmp_path_factory):
    d = tmp_path_factory.mktemp("pipe")
    manifest = synthetic.write_class_set(d / "clips", actors=("a", "b", "c"), takes=3, seed=2)
    assert run("features", d / "clips", "-o", d / "feats", "-q").exit_code == 0
    r = run("learn-mt", "--manifest", manifest, "--features-dir", d / "feats", "--split", "train",
            "-o", d / "mt", "-q")
    assert r.exit_code == 0, r.output
    r = run("compose", manifest, "--actor", "c", "--docs", "3", "--seed", "5", "-o", d / "docs")
    assert r.exit_code == 0, r.output
    assert run("features", d / "docs", "-o", d / "docfeats", "-q").exit_code == 0
    return d


def test_annotate_and_evaluate(pipeline):
    d = pipeline
    r = run("annotate", "--mt", d / "mt", d / "docfeats", "-o", d / "a.csv", "-o",
            d / "a.parquet", "--jobs", "2")
    assert r.exit_code == 0, r.output
    assert "3 documents" in r.output and "5 classes" in r.output
    r = run("evaluate", d / "a.csv", "--truth", d / "docs" / "truth.csv", "--json", d / "rep.json")
    assert r.exit_code == 0, r.output
    rep = json.loads((d / "rep.json").read_text())
    assert set(rep) == {"schema", "documents", "frame", "segment", "per_class", "provenance",
                        "accuracy", "edit", "f1_10", "f1_25", "f1_50", "segmentation"}
    assert rep["schema"] == "mtanno.evaluation/1" and len(rep["documents"]) == 3
    assert set(rep["per_class"]) == set(synthetic.CLASSES)
    # held-out synthetic actor: the procedurally animated classes are easy
    assert rep["frame"]["F"] > 0.7 and rep["segment"]["F"] > 0.8
    assert "overall" in r.output
    # the Parquet table holds the same rows, with native frames
    import pyarrow.parquet as pq

    t = pq.read_table(d / "a.parquet").to_pydict()
    assert t["start"] == [int(x) for x in
                          np.loadtxt(d / "a.csv", delimiter=",", skiprows=1, usecols=1, ndmin=1)]
    assert all(e >= s for s, e in zip(t["start_native"], t["end_native"]))


def test_documents_annotated_without_rows_count_in_evaluate_and_report(pipeline, tmp_path):
    """A document that annotate labelled nothing in was still annotated: its truth is
    missed (recall falls), not dropped from the evaluation."""
    d = pipeline
    r = run("annotate", "--mt", d / "mt", d / "docfeats", "-o", tmp_path / "a.csv")
    assert r.exit_code == 0, r.output
    meta = json.loads((tmp_path / "a.csv.meta.json").read_text())
    docs = sorted(meta["documents"])
    lines = (tmp_path / "a.csv").read_text().splitlines()
    kept = [ln for ln in lines if not ln.startswith(docs[0] + ",")]  # docs[0] has no rows now
    (tmp_path / "b.csv").write_text("\n".join(kept) + "\n")
    (tmp_path / "b.csv.meta.json").write_text(json.dumps(meta))
    full = run("evaluate", tmp_path / "a.csv", "--truth", d / "docs" / "truth.csv", "--json",
               tmp_path / "a.json")
    part = run("evaluate", tmp_path / "b.csv", "--truth", d / "docs" / "truth.csv", "--json",
               tmp_path / "b.json")
    assert full.exit_code == 0 and part.exit_code == 0, part.output
    a, b = (json.loads((tmp_path / f"{x}.json").read_text()) for x in "ab")
    assert b["documents"] == a["documents"] == docs
    assert b["frame"]["R"] < a["frame"]["R"] and b["segment"]["R"] < a["segment"]["R"]


def test_annotate_single_label_partition(pipeline):
    """The default output overlaps; --single-label gives one label per frame, covering the
    same frames, and records the option in its provenance."""
    import csv

    d = pipeline
    r = run("annotate", "--mt", d / "mt", d / "docfeats", "-o", d / "multi.csv", "-q")
    assert r.exit_code == 0, r.output
    r = run("annotate", "--mt", d / "mt", d / "docfeats", "-o", d / "single.csv", "-q",
            "--single-label")
    assert r.exit_code == 0, r.output

    def frames(path):
        out = {}
        for row in csv.DictReader(path.open()):
            for f in range(int(row["start"]), int(row["end"]) + 1):
                out.setdefault((row["doc"], f), []).append(row["label"])
        return out

    multi, single = frames(d / "multi.csv"), frames(d / "single.csv")
    assert any(len(v) > 1 for v in multi.values())  # the reference output overlaps here
    assert all(len(v) == 1 for v in single.values())
    assert set(single) == set(multi)
    assert all(single[k][0] in multi[k] for k in single)
    prov = json.loads((d / "single.csv.meta.json").read_text())
    assert prov["single_label"] is True
    assert "single_label" not in json.loads((d / "multi.csv.meta.json").read_text())


def test_annotate_paper_variant_and_classes_config(pipeline):
    d = pipeline
    cfg = d / "classes.toml"
    cfg.write_text('[tau]\ndefault = 0.13\n[superclasses]\nlegs = ["squat", "kickLFront"]\n')
    r = run("annotate", "--mt", d / "mt", d / "docfeats", "-o", d / "b.csv", "--classes", cfg,
            "--variant", "paper", "-q")
    assert r.exit_code == 0, r.output
    import csv

    labels = {row["label"] for row in csv.DictReader((d / "b.csv").open())}
    assert "legs" in labels and not labels & {"squat", "kickLFront"}
    # --dbar is the option's name now, --variant its former one: the same table
    r = run("annotate", "--mt", d / "mt", d / "docfeats", "-o", d / "c.csv", "--classes", cfg,
            "--dbar", "paper", "-q")
    assert r.exit_code == 0 and (d / "c.csv").read_text() == (d / "b.csv").read_text()


def test_evaluate_retrieval(pipeline):
    d = pipeline
    r = run("evaluate-retrieval", d / "docfeats", "--mt", d / "mt", "--truth",
            d / "docs" / "truth.csv", "--json", d / "ret.json")
    assert r.exit_code == 0, r.output
    res = json.loads((d / "ret.json").read_text())
    assert res["schema"] == "mtanno.retrieval-evaluation/1"
    res = res["classes"]
    assert {c["class"] for c in res} == set(synthetic.CLASSES)
    for c in res:
        assert len(c["taus"]) == 10
        assert all(t["relevant"] <= min(t["hits"], t["occurrences"]) for t in c["taus"])


def test_annotate_bad_inputs(pipeline, tmp_path):
    d = pipeline
    doc = next((d / "docfeats").glob("*.parquet"))
    # missing template directory / no templates / malformed JSON
    r = run("annotate", "--mt", tmp_path / "nope", doc, "-o", tmp_path / "x.csv")
    assert r.exit_code == 2
    (tmp_path / "empty").mkdir()
    r = run("annotate", "--mt", tmp_path / "empty", doc, "-o", tmp_path / "x.csv")
    assert r.exit_code == 2 and "no templates" in r.output
    bad = tmp_path / "badmt"
    bad.mkdir()
    (bad / "squat.json").write_text('{"schema": "mtanno.template/1",\n "class": ')
    r = run("annotate", "--mt", bad, doc, "-o", tmp_path / "x.csv")
    assert r.exit_code == 2 and f"{bad / 'squat.json'}:" in r.output
    # empty inputs, wrong output suffix
    r = run("annotate", "--mt", d / "mt", tmp_path / "empty", "-o", tmp_path / "x.csv")
    assert r.exit_code == 2 and "no feature files" in r.output
    r = run("annotate", "--mt", d / "mt", doc, "-o", tmp_path / "x.txt")
    assert r.exit_code == 2 and "unknown table format '.txt'" in r.output
    # a feature file of another feature set, and one at another frame rate
    ff = read_features(doc)
    other = tmp_path / "other.parquet"
    meta = dict(ff.meta, feature_set="mrc05")
    meta.pop("schema")
    write_features(other, ff.X, ff.names, ff.native_frames, meta)
    r = run("annotate", "--mt", d / "mt", other, "-o", tmp_path / "x.csv")
    assert r.exit_code == 1 and f"{other}: feature set 'mrc05' differs" in r.output
    assert not (tmp_path / "x.csv").exists() or "0 segments" in r.output
    slow = tmp_path / "slow.parquet"
    meta = dict(ff.meta, analysis_fps=25.0)
    meta.pop("schema")
    write_features(slow, ff.X, ff.names, ff.native_frames, meta)
    r = run("annotate", "--mt", d / "mt", slow, doc, "-o", tmp_path / "y.csv")
    assert r.exit_code == 1 and "frame rate 25 Hz differs from 30 Hz of the templates" in r.output
    assert "1 failed" in r.output  # the other document was annotated


def test_evaluate_bad_inputs(pipeline, tmp_path):
    d = pipeline
    r = run("evaluate", tmp_path / "missing.csv", "--truth", d / "docs" / "truth.csv")
    assert r.exit_code == 2
    (tmp_path / "a.csv").write_text("doc,begin\nx,1\n")
    r = run("evaluate", tmp_path / "a.csv", "--truth", d / "docs" / "truth.csv")
    assert r.exit_code == 2 and "needs the columns" in r.output
    (tmp_path / "t.csv").write_text("doc,start,end,label\nx,5,2,j\n")
    r = run("annotate", "--mt", d / "mt", d / "docfeats", "-o", tmp_path / "b.csv", "-q")
    r = run("evaluate", tmp_path / "b.csv", "--truth", tmp_path / "t.csv")
    assert r.exit_code == 2 and f"{tmp_path / 't.csv'}:2: start 5 is after end 2" in r.output
