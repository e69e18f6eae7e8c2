"""Gathering training examples: folder tree, manifest CSV, annotated documents, and the
consistency checks between feature files."""

from __future__ import annotations

import numpy as np
import pytest

from mtanno.errors import MtannoError
from mtanno.features import FEATURE_NAMES
from mtanno.features.store import write_features
from mtanno.templates.learn import learn, learn_template
from mtanno.templates.training import (
    ExampleSource,
    group_by_class,
    load_examples,
    sources_from_manifest,
    sources_from_tree,
    sources_from_truth,
)
from mtanno.util.provenance import sha256_file


def write_doc(path, X, *, names=FEATURE_NAMES, fps=30.0, feature_set="mr06-ak40"):
    write_features(path, X, names, np.arange(1, 4 * X.shape[1], 4),
                   {"analysis_fps": fps, "feature_set": feature_set, "document": path.stem})
    return path


def rand_X(seed, n):
    return (np.random.default_rng(seed).random((len(FEATURE_NAMES), n)) < 0.3).astype(np.uint8)


@pytest.fixture
def tree(tmp_path):
    root = tmp_path / "feats"
    mats = {}
    for c, cls in enumerate(["squat", "jump"]):
        for k, name in enumerate(["HDM_dg_x_02", "HDM_bd_x_01", "HDM_bk_x_03"]):
            X = rand_X(10 * c + k, 8 + k)
            write_doc(root / cls / f"{name}.parquet", X)
            mats[(cls, name)] = X
    return root, mats


def test_tree_classes_and_file_name_order(tree):
    root, mats = tree
    groups = group_by_class(sources_from_tree([root]))
    assert list(groups) == ["jump", "squat"]
    ex = load_examples(groups["squat"])
    assert [e.document for e in ex] == ["HDM_bd_x_01", "HDM_bk_x_03", "HDM_dg_x_02"]
    for e in ex:
        assert np.array_equal(e.X, mats[("squat", e.document)])
        assert e.start == 1 and e.end == e.X.shape[1] and e.fps == 30.0
        assert e.sha256 == sha256_file(e.file) and e.feature_set == "mr06-ak40"
        assert e.record() == {"file": e.file, "document": e.document, "sha256": e.sha256,
                              "frames": [1, e.X.shape[1]]}
    assert list(group_by_class(sources_from_tree([root]), classes=["squat"])) == ["squat"]
    with pytest.raises(MtannoError, match="no training examples for class.*walk"):
        group_by_class(sources_from_tree([root]), classes=["walk"])


def test_tree_errors(tmp_path, tree):
    with pytest.raises(MtannoError, match="not found"):
        sources_from_tree([tmp_path / "nope"])
    f = tmp_path / "file.parquet"
    f.write_bytes(b"x")
    with pytest.raises(MtannoError, match="not a folder"):
        sources_from_tree([f])
    (tmp_path / "empty" / "cls").mkdir(parents=True)
    with pytest.raises(MtannoError, match="no CLASS/"):
        sources_from_tree([tmp_path / "empty"])


def test_manifest_with_split_filter(tmp_path, tree):
    root, mats = tree
    man = tmp_path / "clips.csv"
    man.write_text("file,actor,class,split\n"
                   "squat/HDM_bd_x_01.amc,bd,squat,train\n"
                   "squat/HDM_dg_x_02.amc,dg,squat,dev\n"
                   "jump/HDM_bk_x_03.amc,bk,jump,train\n")
    srcs = sources_from_manifest(man, features_dir=root, split="train")
    assert sorted((s.class_name, s.path) for s in srcs) == [
        ("jump", str(root / "jump" / "HDM_bk_x_03.parquet")),
        ("squat", str(root / "squat" / "HDM_bd_x_01.parquet"))]
    assert len(sources_from_manifest(man, features_dir=root)) == 3
    with pytest.raises(MtannoError, match="no rows with split 'test'.*dev, train"):
        sources_from_manifest(man, features_dir=root, split="test")


@pytest.mark.parametrize("text,message,line", [
    ("file,label\na.amc,x\n", "needs the columns file, class", 1),
    ("file,class\na.amc,\n", "empty class", 2),
    ("file,class\n/abs/a.amc,x\n", "relative path", 2),
    ("file,class\n", "lists no files", None),
])
def test_manifest_errors(tmp_path, text, message, line):
    man = tmp_path / "m.csv"
    man.write_text(text)
    with pytest.raises(MtannoError, match=message) as info:
        sources_from_manifest(man, features_dir=tmp_path)
    assert info.value.path == str(man) and info.value.line == line


def test_manifest_other_errors(tmp_path, tree):
    root, _ = tree
    man = tmp_path / "m.csv"
    man.write_text("file,class\nsquat/HDM_bd_x_01.amc,squat\nsquat/missing.amc,squat\n")
    with pytest.raises(MtannoError, match="no split column"):
        sources_from_manifest(man, features_dir=root, split="train")
    with pytest.raises(MtannoError, match="features folder not found"):
        sources_from_manifest(man, features_dir=tmp_path / "nope")
    with pytest.raises(MtannoError, match="manifest not found"):
        sources_from_manifest(tmp_path / "x.csv", features_dir=root)
    srcs = sources_from_manifest(man, features_dir=root)
    with pytest.raises(MtannoError, match="missing.parquet not found") as info:
        load_examples(srcs)
    assert info.value.path == str(man) and info.value.line == 3


def test_truth_segments_are_cut_in_order(tmp_path):
    docs = tmp_path / "docs"
    A = write_doc(docs / "a" / "docA.parquet", rand_X(1, 40))
    B = write_doc(docs / "docB.parquet", rand_X(2, 30))
    truth = tmp_path / "truth.csv"
    truth.write_text("doc,start,end,label\n"
                     "docB,3,9,squat\n"
                     "docA,20,31,squat\n"
                     "docA,2,10,squat\n"
                     "docA,12,16,jump\n"
                     "docB,11,20,jump\n")
    groups = group_by_class(sources_from_truth(truth, [docs]))
    squat = load_examples(groups["squat"])
    assert [(e.document, e.start, e.end) for e in squat] == [
        ("docA", 2, 10), ("docA", 20, 31), ("docB", 3, 9)]
    XA = rand_X(1, 40)
    assert np.array_equal(squat[0].X, XA[:, 1:10]) and np.array_equal(squat[1].X, XA[:, 19:31])
    assert squat[0].record()["frames"] == [2, 10] and squat[0].file == str(A)
    jump = load_examples(groups["jump"])
    assert [(e.document, e.start, e.end) for e in jump] == [("docA", 12, 16), ("docB", 11, 20)]
    assert jump[1].file == str(B)


def test_truth_errors(tmp_path):
    docs = tmp_path / "docs"
    write_doc(docs / "docA.parquet", rand_X(1, 20))
    truth = tmp_path / "truth.csv"
    truth.write_text("doc,start,end,label\ndocZ,1,5,squat\ndocY,1,5,squat\n")
    with pytest.raises(MtannoError, match="no feature file for document.*docY, docZ"):
        sources_from_truth(truth, [docs])
    truth.write_text("doc,start,end,label\ndocA,15,25,squat\n")
    with pytest.raises(MtannoError, match="outside its frames 1..20"):
        load_examples(sources_from_truth(truth, [docs]))
    write_doc(tmp_path / "other" / "docA.parquet", rand_X(2, 20))
    with pytest.raises(MtannoError, match="two feature files for document 'docA'"):
        sources_from_truth(truth, [docs, tmp_path / "other"])
    with pytest.raises(MtannoError, match="nope.parquet: no such feature file or folder"):
        sources_from_truth(truth, [tmp_path / "nope.parquet"])
    truth.write_text("doc,start,end,label\n")
    with pytest.raises(MtannoError, match="no segments"):
        sources_from_truth(truth, [docs])


def test_truth_rows_of_other_documents_are_ignored(tmp_path):
    """Issue 9: a truth table covering more documents than given is used for those given;
    the others are named once."""
    docs = tmp_path / "docs"
    write_doc(docs / "docA.parquet", rand_X(1, 20))
    truth = tmp_path / "truth.csv"
    truth.write_text("doc,start,end,label\ndocA,2,10,squat\ndocZ,1,5,squat\n"
                     "docZ,6,9,jump\ndocB,1,3,jump\n")
    ignored: list[str] = []
    srcs = sources_from_truth(truth, [docs], ignored=ignored)
    assert [(s.class_name, s.start, s.end) for s in srcs] == [("squat", 2, 10)]
    assert ignored == ["docB", "docZ"]
    from mtanno.templates.training import ignored_documents_note

    assert ignored_documents_note(ignored).endswith("are ignored: docB, docZ")
    assert ignored_documents_note([]) is None


@pytest.mark.parametrize("kwargs,message", [
    (dict(names=FEATURE_NAMES[:39]), "feature 40 is missing here"),
    (dict(fps=60.0), "60 Hz differs from 30 Hz"),
    (dict(feature_set="mrc05-31"), "feature set 'mrc05-31' differs"),
])
def test_inconsistent_examples_name_the_file(tmp_path, kwargs, message):
    a = write_doc(tmp_path / "c" / "a.parquet", rand_X(1, 5))
    X = rand_X(2, 5)[: len(kwargs.get("names", FEATURE_NAMES))]
    b = write_doc(tmp_path / "c" / "b.parquet", X, **kwargs)
    with pytest.raises(MtannoError, match=message) as info:
        load_examples([ExampleSource("c", str(b)), ExampleSource("c", str(a))])
    assert info.value.path == str(b) and str(a) in str(info.value)


def test_unreadable_feature_file(tmp_path):
    bad = tmp_path / "c" / "bad.parquet"
    bad.parent.mkdir()
    bad.write_bytes(b"not parquet")
    with pytest.raises(MtannoError, match="Parquet") as info:
        load_examples([ExampleSource("c", str(bad))])
    assert info.value.path == str(bad)


def test_learn_template_records_provenance(tree):
    root, mats = tree
    ex = load_examples(group_by_class(sources_from_tree([root]))["jump"])
    mt = learn_template(ex)
    ref = learn([e.X for e in ex])
    assert mt.class_name == "jump" and mt.kind == "soft" and not mt.quantized
    assert np.array_equal(mt.values, ref.values) and np.array_equal(mt.weights, ref.weights)
    assert mt.iterations == ref.iterations and mt.final_cost == ref.final_cost
    assert [t["document"] for t in mt.training] == ["HDM_bd_x_01", "HDM_bk_x_03",
                                                    "HDM_dg_x_02"]
    assert mt.feature_names == list(FEATURE_NAMES) and mt.fps == 30.0
    assert mt.history["max"] == ref.cost_max
    hard = learn_template(ex, hard=True)
    assert hard.kind == "hard" and hard.quantized and hard.delta == 0.0
    both = load_examples(sources_from_tree([root]))
    with pytest.raises(MtannoError, match="several classes"):
        learn_template(both)
    assert learn_template(both, class_name="all").class_name == "all"
    with pytest.raises(MtannoError, match="no training examples"):
        learn_template([])
