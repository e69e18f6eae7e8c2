"""``mtanno learn-mt`` and ``mtanno mt show|mirror|scale|quantize`` through the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import HDM05, REFERENCE, require_data

from mtanno.cli import main
from mtanno.features import FEATURE_NAMES
from mtanno.features.store import write_features
from mtanno.templates.model import mirror, quantize
from mtanno.templates.store import load_template


def run(args):
    return CliRunner().invoke(main, args, catch_exceptions=False)


def write_doc(path, X):
    write_features(path, X, FEATURE_NAMES, np.arange(1, 4 * X.shape[1], 4),
                   {"analysis_fps": 30.0, "feature_set": "mr06-ak40"})


@pytest.fixture
def tree(tmp_path):
    root = tmp_path / "feats"
    rng = np.random.default_rng(0)
    for cls in ("jump", "squat"):
        for k in range(3):
            write_doc(root / cls / f"{cls}_{k}.parquet",
                      (rng.random((40, 6 + k)) < 0.3).astype(np.uint8))
    return root


def test_learn_mt_tree(tree, tmp_path):
    out = tmp_path / "mts"
    r = run(["learn-mt", str(tree), "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in out.iterdir()) == ["jump.json", "squat.json"]
    mt = load_template(out / "squat.json")
    assert mt.class_name == "squat" and mt.kind == "soft" and len(mt.training) == 3
    assert "learn-mt: 2 soft template(s) from 6 examples" in r.output
    assert "0 class(es) failed" in r.output


def test_learn_mt_options(tree, tmp_path):
    out = tmp_path / "mts"
    r = run(["learn-mt", str(tree), "-o", str(out), "--class", "jump", "--hard",
             "--iterations", "1", "-q"])
    assert r.exit_code == 0 and r.output == ""
    assert [p.name for p in out.iterdir()] == ["jump.json"]
    mt = load_template(out / "jump.json")
    assert mt.kind == "hard" and mt.iterations == 1 and mt.params["iter_max"] == 1
    assert np.isin(mt.values, (0, 0.5, 1)).all()


def test_learn_mt_one_class_fails(tree, tmp_path):
    (tree / "jump" / "broken.parquet").write_bytes(b"not parquet")
    out = tmp_path / "mts"
    r = run(["learn-mt", str(tree), "-o", str(out)])
    assert r.exit_code == 1
    assert "class jump:" in r.output and "broken.parquet" in r.output
    assert [p.name for p in out.iterdir()] == ["squat.json"]
    assert "1 class(es) failed" in r.output


def test_learn_mt_truth(tmp_path):
    rng = np.random.default_rng(1)
    for d in ("d1", "d2"):
        write_doc(tmp_path / "docs" / f"{d}.parquet",
                  (rng.random((40, 50)) < 0.3).astype(np.uint8))
    truth = tmp_path / "truth.csv"
    truth.write_text("doc,start,end,label\nd1,1,10,a\nd1,20,31,b\nd2,5,14,a\n")
    out = tmp_path / "mts"
    r = run(["learn-mt", "--truth", str(truth), str(tmp_path / "docs"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    a = load_template(out / "a.json")
    assert [t["frames"] for t in a.training] == [[1, 10], [5, 14]]
    assert load_template(out / "b.json").length == 12
    # few examples: one warning per class, naming it
    assert "learn-mt: warning: class a is learned from 2 examples only" in r.output
    assert "learn-mt: warning: class b is learned from 1 example only" in r.output
    assert "ignored" not in r.output


def test_learn_mt_truth_of_more_documents(tmp_path):
    """The truth table names documents that are not given: their rows are ignored and the
    documents named once; only the given document's segments are learned from."""
    rng = np.random.default_rng(1)
    for d in ("d1", "d2", "d3"):
        write_doc(tmp_path / "docs" / f"{d}.parquet",
                  (rng.random((40, 50)) < 0.3).astype(np.uint8))
    truth = tmp_path / "truth.csv"
    truth.write_text("doc,start,end,label\nd1,1,10,a\nd1,20,31,a\nd2,5,14,a\nd3,1,9,a\n"
                     "x9,1,5,a\nx9,8,12,b\nx8,1,4,b\n")
    out = tmp_path / "mts"
    r = run(["learn-mt", "--truth", str(truth), str(tmp_path / "docs"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert r.output.count("ignored") == 1
    assert ("learn-mt: note: the truth table's segments of 2 document(s) without a feature "
            "file among the inputs are ignored: x8, x9") in r.output
    assert sorted(p.name for p in out.iterdir()) == ["a.json"]
    assert len(load_template(out / "a.json").training) == 4
    assert "warning" not in r.output  # 4 examples are enough
    r = run(["learn-mt", "--truth", str(truth), str(tmp_path / "docs" / "d1.parquet"), "-o",
             str(tmp_path / "m2"), "-q"])
    assert r.exit_code == 0 and "ignored" not in r.output  # -q: no note


@pytest.mark.parametrize("args,message", [
    ([], "TRAINING"),
    (["--manifest", "m.csv", "x"], "no TRAINING arguments"),
    (["--manifest", "m.csv"], "--features-dir"),
    (["x", "--split", "train"], "go with --manifest"),
    (["--manifest", "m.csv", "--truth", "t.csv"], "exclude each other"),
    (["--iterations", "0", "x"], "--iterations"),
])
def test_learn_mt_usage_errors(tmp_path, args, message):
    r = run(["learn-mt", "-o", str(tmp_path / "o"), *args])
    assert r.exit_code == 2 and message in r.output


def test_learn_mt_bad_input_exit_2(tree, tmp_path):
    r = run(["learn-mt", str(tmp_path / "nope"), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "training folder not found" in r.output
    r = run(["learn-mt", str(tree), "-o", str(tmp_path / "o"), "--class", "walk"])
    assert r.exit_code == 2 and "no training examples for class(es) walk" in r.output
    man = tmp_path / "m.csv"
    man.write_text("file,kind\n")
    r = run(["learn-mt", "--manifest", str(man), "--features-dir", str(tree), "-o",
             str(tmp_path / "o")])
    assert r.exit_code == 2 and f"{man}:1: needs the columns file, class" in r.output


@pytest.fixture
def mt_file(tree, tmp_path):
    out = tmp_path / "mts"
    assert run(["learn-mt", str(tree), "-o", str(out), "-q"]).exit_code == 0
    return out / "squat.json"


def test_mt_show(mt_file):
    r = run(["mt", "show", str(mt_file)])
    assert r.exit_code == 0
    mt = load_template(mt_file)
    assert "template      squat (soft, not quantized)" in r.output
    assert f"length        {mt.length} columns" in r.output
    assert f"final cost {mt.final_cost:.6g}" in r.output
    assert "3 example(s), 6-8 frames" in r.output and "squat_0" in r.output
    from mtanno.templates.match import match_lengths

    lo, hi = match_lengths(mt.weights)
    assert f"matches       performances of {lo}-{hi} frames" in r.output
    assert "examples near the matchable lengths" not in r.output  # 6-8 frames well inside
    assert "features with most non-wildcard entries (δ = 0.1" in r.output
    r = run(["mt", "show", str(mt_file), "--picture", "--delta", "0", "--top", "0",
             "--files"])
    q = quantize(mt, 0)
    row = dict(line.split(None, 1) for line in r.output.splitlines()
               if line.startswith("  rhand_forward "))["rhand_forward"]
    assert row == "".join({0.0: ".", 1.0: "#", 0.5: "~"}[x] for x in q.values[0])
    assert "features with most" not in r.output and "squat_2" in r.output


def test_mt_quantize_and_mirror(mt_file, tmp_path):
    q = tmp_path / "q.json"
    r = run(["mt", "quantize", str(mt_file), "--delta", "0.05", "-o", str(q)])
    assert r.exit_code == 0 and "δ = 0.05" in r.output
    assert load_template(q) == quantize(load_template(mt_file), 0.05)
    r = run(["mt", "show", str(q)])
    assert "(soft, quantized, δ = 0.05)" in r.output
    m = tmp_path / "m.json"
    r = run(["mt", "mirror", str(mt_file), "-o", str(m)])
    assert r.exit_code == 0 and load_template(m) == mirror(load_template(mt_file))
    r = run(["mt", "mirror", str(m), "-o", str(m), "--name", "pose"])
    # an output that is the input is refused before any work (issue 8, root cause 1)
    assert r.exit_code == 2 and "would overwrite an input" in r.output
    assert load_template(m) == mirror(load_template(mt_file))
    r = run(["mt", "mirror", str(m), "-o", str(tmp_path / "p.json"), "--name", "pose"])
    assert load_template(tmp_path / "p.json").class_name == "pose"


def test_mt_scale(mt_file, tmp_path):
    from mtanno.templates.tempo import time_scaled

    mt = load_template(mt_file)
    for factor in (0.6, 1.6):
        out = tmp_path / f"s{factor}.json"
        r = run(["mt", "scale", str(mt_file), "--factor", str(factor), "-o", str(out)])
        assert r.exit_code == 0
        got = load_template(out)
        assert got == time_scaled(mt, factor)
        assert got.class_name == mt.class_name and got.params["time_scale"] == factor
        assert f"{mt.length} -> {got.length} columns" in r.output
        # the copy's matchable lengths no longer hold its training examples comfortably
        shown = run(["mt", "show", str(out), "--top", "0"]).output
        assert "examples near the matchable lengths" in shown
    # the copy is one of the class's templates in an annotation configuration
    cfg = tmp_path / "classes.toml"
    cfg.write_text('[templates]\nsquat = ["s1.6.json"]\n')
    doc = tmp_path / "doc.parquet"
    write_doc(doc, (np.random.default_rng(1).random((40, 30)) < 0.3).astype(np.uint8))
    table = tmp_path / "ann.csv"
    r = run(["annotate", "--mt", str(mt_file.parent), "--classes", str(cfg), str(doc), "-o",
             str(table), "-q"])
    assert r.exit_code == 0
    meta = json.loads((tmp_path / "ann.csv.meta.json").read_text())
    assert any(t["path"].endswith("s1.6.json") for t in meta["templates"])
    # bad factors and an output that is the input: one line, exit 2, nothing written
    for factor in ("0", "-1", "nan", "11"):
        r = run(["mt", "scale", str(mt_file), "--factor", factor, "-o", str(tmp_path / "x.json")])
        assert r.exit_code == 2 and "factor" in r.output and "Traceback" not in r.output
    r = run(["mt", "scale", str(mt_file), "--factor", "0.6", "-o", str(mt_file)])
    assert r.exit_code == 2 and "would overwrite an input" in r.output
    assert load_template(mt_file) == mt and not (tmp_path / "x.json").exists()


def test_mt_bad_input_exit_2(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{\n  "schema": "mtanno.template/1",\n  oops\n}')
    for args in (["show", str(bad)], ["mirror", str(bad), "-o", str(tmp_path / "o.json")],
                 ["scale", str(bad), "--factor", "0.6", "-o", str(tmp_path / "o.json")],
                 ["quantize", str(bad), "--delta", "0.1", "-o", str(tmp_path / "o.json")]):
        r = run(["mt", *args])
        assert r.exit_code == 2 and f"{bad}:3: malformed JSON" in r.output
    assert not (tmp_path / "o.json").exists()
    r = run(["mt", "quantize", str(bad), "--delta", "0.7", "-o", str(tmp_path / "o.json")])
    assert r.exit_code == 2
    r = run(["mt", "show", str(tmp_path / "missing.json")])
    assert r.exit_code == 2 and "template file not found" in r.output


def test_help_texts():
    for args in (["learn-mt"], ["mt"], ["mt", "show"], ["mt", "mirror"], ["mt", "scale"],
                 ["mt", "quantize"]):
        r = run([*args, "--help"])
        assert r.exit_code == 0 and "Usage:" in r.output
    text = run(["learn-mt", "--help"]).output
    for word in ("--manifest", "--features-dir", "--split", "--truth", "--hard", "--class",
                 "--iterations", "Exit codes"):
        assert word in text


def test_features_then_learn_mt_reproduces_golden_templates(tmp_path):
    """mtanno's own feature files, listed by the HDM05 manifest (train split), give the
    reference implementation's templates exactly."""
    require_data()
    classes = ["rotateArmsBothBackward1Reps", "sneak2StepsLStart"]
    feats = tmp_path / "feats"
    for cls in classes:
        r = run(["features", str(HDM05 / cls), "-o", str(feats / cls), "-q"])
        assert r.exit_code == 0, r.output
    out = tmp_path / "mts"
    args = ["learn-mt", "--manifest", str(HDM05 / "clips.csv"), "--features-dir", str(feats),
            "--split", "train", "-o", str(out), "-q"]
    for cls in classes:
        args += ["--class", cls]
    r = run(args)
    assert r.exit_code == 0, r.output
    for cls in classes:
        mt = load_template(out / f"{cls}.json")
        gold = np.loadtxt(REFERENCE / "mt" / f"{cls}.csv", delimiter=",", skiprows=1)
        assert np.array_equal(mt.values, gold[:, 2:].T) and np.array_equal(mt.weights,
                                                                           gold[:, 1])
        info = (REFERENCE / "mt" / f"{cls}_info.txt").read_text()
        assert f"iterations={mt.iterations}\n" in info
        order = [line.split()[1] for line in info.splitlines()
                 if line[:1].isdigit() and "HDM_" in line]
        assert [t["document"] for t in mt.training] == order
        assert json.loads((out / f"{cls}.json").read_text())["schema"] == "mtanno.template/1"
