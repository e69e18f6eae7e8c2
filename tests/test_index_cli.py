"""``mtanno index`` and ``mtanno query`` on the command line: outputs, exit codes, messages."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest
from click.testing import CliRunner
from test_index import _random_docs, _write_docs

from mtanno.cli import main
from mtanno.features import get_feature_set
from mtanno.index import open_index, storage

MRC05 = get_feature_set("mrc05")


def run(args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture
def feats(tmp_path):
    rng = np.random.default_rng(4)
    docs = _random_docs(rng, 5, MRC05.names, frames=(40, 100), p=0.04)
    # a document with a clear squat-like knee pattern, copied (with other timing) into another
    X = np.zeros((31, 60), np.uint8)
    X[6:8, 20:40] = 1  # both knees bent for 20 frames
    Y = np.zeros((31, 70), np.uint8)
    Y[6:8, 25:50] = 1
    Y[14, :] = 1  # an unrelated upper-body feature on
    docs.update({"squatA": X, "squatB": Y})
    _write_docs(tmp_path / "f", docs)
    return tmp_path / "f"


def test_index_build_info_add_remove(feats, tmp_path):
    idx = tmp_path / "idx"
    files = sorted(feats.glob("*.parquet"))
    r = run(["index", *files[:4], "-o", idx])
    assert r.exit_code == 0, r.output
    assert "4 documents" in r.output and f"-> {idx}" in r.output
    r = run(["index", "add", idx, *files[4:]])
    assert r.exit_code == 0 and "3 added, 0 updated, 0 unchanged, 0 removed" in r.output
    r = run(["index", "remove", idx, "squatB"])
    assert r.exit_code == 0 and "1 removed" in r.output
    assert [d.name for d in open_index(idx).documents] == sorted(f.stem for f in files
                                                                 if f.stem != "squatB")
    r = run(["index", "info", idx])
    assert r.exit_code == 0
    assert "feature set    mrc05 v1, 31 features" in r.output and "documents      6" in r.output
    for g in ("lower", "upper", "mix"):
        assert any(line.startswith(g) for line in r.output.splitlines())
    info = json.loads(run(["index", "info", idx, "--json"]).output)
    assert [g["group"] for g in info["groups"]] == ["lower", "upper", "mix"]
    assert info["groups"][0]["features"] == 11 and info["groups"][0]["bytes_per_segment"] > 0
    assert info["generation"] == 3
    # "build" is also a subcommand name
    r = run(["index", "build", feats, "-o", tmp_path / "idx2", "--groups", "lower", "-q"])
    assert r.exit_code == 0 and r.output == ""
    assert list(open_index(tmp_path / "idx2").groups) == ["lower"]


def _csv(text):
    return list(csv.DictReader(io.StringIO(text)))


def test_query_by_example_and_json(feats, tmp_path):
    idx = tmp_path / "idx"
    run(["index", feats, "-o", idx, "-q"])
    r = run(["query", idx, "--example", feats / "squatA.parquet", "--features",
             "rknee_bent,Fl8"])
    assert r.exit_code == 0, r.output
    assert r.stdout.splitlines()[0] == \
        "doc,start,end,rank,score,span_start,span_end,boundaries"
    assert r.stderr.startswith("query: ") and "ms (adaptive; query segments: lower 3)" in r.stderr
    rows = _csv(r.stdout)
    assert rows[0]["doc"] == "squatA" and rows[0]["score"] == "0"
    assert {"squatA", "squatB"} <= {r["doc"] for r in rows}
    top = next(r for r in rows if r["doc"] == "squatB")
    # squatB: knees bent on frames 26–50 (1-based); the run before starts at frame 1 (the
    # untrimmed span), the hit keeps as many frames of the runs before and after the bent
    # knees as squatA has (20 and 20)
    assert (top["span_start"], top["span_end"]) == ("1", "70")
    assert top["start"] == "6" and top["end"] == "70"
    assert top["boundaries"] == "lower=6 26 51 70"
    # by document name, a frame range, to a file
    out = tmp_path / "hits.csv"
    r = run(["query", idx, "--example", "squatA", "--frames", "15:45", "--features",
             "rknee_bent,lknee_bent", "-o", out, "--top", "1", "-q", "--min-segment", "1"])
    assert r.exit_code == 0 and r.output == ""
    assert [x["doc"] for x in _csv(out.read_text())] == ["squatA"]
    q = tmp_path / "q.json"
    q.write_text(json.dumps({"feature_set": "mrc05", "features": ["rknee_bent", "lknee_bent"],
                             "steps": ["00", "11", "00"]}))
    r = run(["query", idx, "--query", q, "-q"])
    assert {x["doc"] for x in _csv(r.output)} >= {"squatA", "squatB"}
    assert _csv(r.output)[0]["score"] == ""  # no lengths in the query: document order
    r = run(["query", idx, "--query", q, "--mode", "fuzzy", "-q"])
    # fuzzy: one document segment per step; in squatA/B the other lower features are constant
    assert {x["doc"] for x in _csv(r.stdout)} == {"squatA", "squatB"}


@pytest.mark.parametrize("args, message", [
    (["--example", "{f}/squatA.parquet", "--features", "rknee_bent,nose"],
     "unknown feature 'nose' (feature set mrc05"),
    (["--example", "{f}/squatA.parquet"], "--example needs --features"),
    (["--features", "rknee_bent"], "give one of --example (with --features), --query or --keyframes"),
    (["--example", "{f}/squatA.parquet", "--features", "rknee_bent", "--frames", "50:99"],
     "--frames 50:99 is not a range inside 1:60"),
    (["--example", "{f}/squatA.parquet", "--features", "rknee_bent", "--frames", "x"],
     "--frames must be A:B"),
    (["--example", "nothing.parquet", "--features", "rknee_bent"],
     "example is neither a feature file nor an indexed document"),
    (["--example", "{f}/squatA.parquet", "--features", "rknee_bent", "--mode", "exact"],
     "exact mode needs every feature of group 'lower' fixed"),
    (["--example", "{f}/squatA.parquet", "--features", "rknee_bent", "--mismatches", "1"],
     "mismatches work with the exact and fuzzy modes, not adaptive"),
])
def test_query_bad_input(feats, tmp_path, args, message):
    idx = tmp_path / "idx"
    run(["index", feats, "-o", idx, "-q"])
    r = run(["query", idx, *[a.replace("{f}", str(feats)) for a in args]])
    assert r.exit_code == 2
    assert r.output.count("\n") == 1 and r.output.startswith("mtanno: ")
    assert message in r.output, r.output


def test_query_rejects_other_feature_set_and_empty_set(feats, tmp_path):
    idx = tmp_path / "idx"
    run(["index", feats, "-o", idx, "-q"])
    ak = get_feature_set("ak40")
    _write_docs(tmp_path / "ak", {"other": np.zeros((40, 10), np.uint8)}, ak)
    r = run(["query", idx, "--example", tmp_path / "ak" / "other.parquet", "--features",
             "rknee_bent"])
    assert r.exit_code == 2
    assert "feature set 'mr06-ak40' differs from 'mrc05' of the index" in r.output
    q = tmp_path / "q.json"
    q.write_text(json.dumps({"features": ["rknee_bent"], "steps": ["0", [], "0"]}))
    r = run(["query", idx, "--query", q])
    assert r.exit_code == 2 and f"{q}: step 2: empty fuzzy set" in r.output
    q.write_text(json.dumps({"feature_set": "mr06-ak40", "features": ["rknee_bent"],
                             "steps": ["0"]}))
    r = run(["query", idx, "--query", q])
    assert r.exit_code == 2 and "index holds 'mrc05'" in r.output
    r = run(["index", "add", idx, tmp_path / "ak"])
    assert r.exit_code == 1 and "feature set 'mr06-ak40' differs from 'mrc05'" in r.output


def test_query_and_info_report_corrupt_index(feats, tmp_path):
    idx = tmp_path / "idx"
    run(["index", feats, "-o", idx, "-q"])
    m = storage.read_index_manifest(idx)
    victim = idx / m["directory"] / "lists-upper.parquet"
    victim.write_bytes(victim.read_bytes()[:50])
    for args in (["query", idx, "--example", "squatA", "--features", "rknee_bent"],
                 ["index", "info", idx], ["index", "add", idx, feats]):
        r = run(args)
        assert r.exit_code == 2 and "corrupt index" in r.output and r.output.count("\n") == 1
    (idx / "manifest.json").unlink()
    r = run(["index", "info", idx])
    assert r.exit_code == 2 and "partially written index" in r.output
    r = run(["index", "info", feats])
    assert r.exit_code == 2 and "not an index directory" in r.output


def test_query_rank_by_template(feats, tmp_path):
    from mtanno.templates.model import MotionTemplate
    from mtanno.templates.store import save_template

    idx = tmp_path / "idx"
    run(["index", feats, "-o", idx, "-q"])
    # a template of squatB's timing: knees straight 25 frames, bent 25, straight 20
    mt = MotionTemplate("squat", ["rknee_bent", "lknee_bent"],
                        np.array([[0.0] * 5 + [1.0] * 5 + [0.0] * 4] * 2),
                        np.array([5.0] * 14), feature_set="mrc05", quantized=True, delta=0.1)
    save_template(tmp_path / "squat.json", mt)
    r = run(["query", idx, "--example", "squatA", "--features", "rknee_bent,lknee_bent",
             "--rank-mt", tmp_path / "squat.json"])
    assert r.exit_code == 0, r.output
    rows = _csv(r.stdout)
    assert list(rows[0]) == ["doc", "start", "end", "rank", "score", "mt_cost", "span_start",
                             "span_end", "boundaries"]
    costs = [float(x["mt_cost"]) for x in rows if x["mt_cost"]]
    assert costs == sorted(costs) and costs[0] == 0.0
    # hits too short for the template have no cost, come last, and a note counts them
    unfit = [x for x in rows if not x["mt_cost"]]
    assert all(not x["mt_cost"] for x in rows[len(costs):])
    if unfit:
        assert (f"cannot fit {len(unfit)} of {len(rows)} hits" in r.stderr), r.stderr
    else:
        assert "cannot fit" not in r.stderr
    assert {rows[0]["doc"], rows[1]["doc"]} == {"squatA", "squatB"}
    bad = MotionTemplate("x", ["rknee_bent"], np.zeros((1, 3)), np.ones(3), feature_set="mr06-ak40")
    save_template(tmp_path / "ak.json", bad)
    r = run(["query", idx, "--example", "squatA", "--features", "rknee_bent",
             "--rank-mt", tmp_path / "ak.json"])
    assert r.exit_code == 2 and "template is for feature set 'mr06-ak40'" in r.output


def test_query_output_to_fifo_is_not_replaced(feats, tmp_path):
    # -o to something that is not a regular file (a FIFO, a device) is written in place,
    # never renamed over
    import os
    import stat
    import threading

    idx = tmp_path / "idx"
    run(["index", feats, "-o", idx, "-q"])
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_text()))
    reader.start()
    r = run(["query", idx, "--example", "squatA", "--features", "rknee_bent", "-q", "-o", fifo])
    reader.join(timeout=30)
    assert r.exit_code == 0 and got and got[0].startswith("doc,start,end")
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)


def test_query_rank_mt_says_when_the_template_cannot_fit(feats, tmp_path):
    from mtanno.templates.model import MotionTemplate
    from mtanno.templates.store import save_template

    idx = tmp_path / "idx"
    run(["index", feats, "-o", idx, "-q"])
    # 200 columns: no hit of these short documents can hold a match
    mt = MotionTemplate("long", ["rknee_bent", "lknee_bent"], np.ones((2, 200)), np.ones(200),
                        feature_set="mrc05", quantized=True, delta=0.1)
    save_template(tmp_path / "long.json", mt)
    r = run(["query", idx, "--example", "squatA", "--features", "rknee_bent,lknee_bent",
             "--rank-mt", tmp_path / "long.json"])
    assert r.exit_code == 0, r.output
    rows = _csv(r.stdout)
    assert rows and all(x["mt_cost"] == "" for x in rows)
    assert (f"query: note: the template (200 columns) cannot fit {len(rows)} of {len(rows)} "
            "hits") in r.stderr
