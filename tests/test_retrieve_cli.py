"""``mtanno retrieve`` through the command line (click.testing.CliRunner)."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner
from naive_match import hits_naive, match_naive

from mtanno.cli import main
from mtanno.features import FEATURE_NAMES
from mtanno.features.store import write_features
from mtanno.templates.model import MotionTemplate, quantize
from mtanno.templates.store import save_template


def run(args):
    return CliRunner().invoke(main, args, catch_exceptions=False)


def write_doc(path, X, *, names=FEATURE_NAMES, fps=30.0, feature_set="mr06-ak40"):
    # 120 Hz source: analysis frame k (0-based) comes from native frame 4k + 1 (1-based)
    write_features(path, X, names, np.arange(1, 4 * X.shape[1], 4),
                   {"analysis_fps": fps, "feature_set": feature_set})


@pytest.fixture
def setup(tmp_path):
    """A quantized template cut from document A, and three documents containing it."""
    rng = np.random.default_rng(4)
    pattern = (rng.random((40, 14)) < 0.4).astype(np.uint8)
    values = pattern.astype(float)
    values[rng.random(values.shape) < 0.2] = 0.5
    mt = MotionTemplate("hop", list(FEATURE_NAMES), values, np.ones(14), quantized=True,
                        delta=0.1)
    save_template(tmp_path / "hop.json", mt)
    noise = lambda n: (rng.random((40, n)) < 0.4).astype(np.uint8)  # noqa: E731
    docs = {
        "feats/a/A.parquet": np.concatenate([noise(10), pattern, noise(20), pattern, noise(5)], 1),
        "feats/b/deep/B.parquet": np.concatenate([noise(3), pattern[:, ::-1], noise(30)], 1),
        "C.parquet": np.concatenate([noise(30), pattern], 1),
    }
    for rel, X in docs.items():
        write_doc(tmp_path / rel, X)
    return tmp_path, mt, docs


def expected_rows(mt, docs, order, tau, max_hits=1000):
    rows = []
    for i, rel in enumerate(order):
        X = docs[rel]
        d, s = match_naive(mt.values, mt.weights, X)
        hits, _ = hits_naive(d, s, tau=tau, mode="retrieval", max_hits=max_hits)
        stem = rel.rsplit("/", 1)[-1].removesuffix(".parquet")
        for r, (a, e, c) in enumerate(hits):
            rows.append((c, i, r, stem, a, e))
    rows.sort(key=lambda t: t[:3])
    return [{"doc": stem, "start": a + 1, "end": e + 1, "start_native": 4 * a + 1,
             "end_native": 4 * e + 1, "cost": c, "rank": k}
            for k, (c, _, _, stem, a, e) in enumerate(rows[:max_hits], 1)]


def parse_csv(text):
    rows = list(csv.DictReader(io.StringIO(text)))
    for r in rows:
        for k in ("start", "end", "start_native", "end_native", "rank"):
            r[k] = int(r[k])
        r["cost"] = float(r["cost"])
    return rows


def test_csv_on_stdout_ranks_all_documents(setup):
    tmp, mt, docs = setup
    r = run(["retrieve", "--mt", str(tmp / "hop.json"), str(tmp / "feats"), str(tmp / "C.parquet"),
             "--tau", "0.12"])
    assert r.exit_code == 0, r.output
    assert r.stdout.splitlines()[0] == "doc,start,end,start_native,end_native,cost,rank"
    rows = parse_csv(r.stdout)
    # folders are searched recursively and sorted; files come in the order given
    want = expected_rows(mt, docs, ["feats/a/A.parquet", "feats/b/deep/B.parquet", "C.parquet"],
                         0.12)
    assert rows == want
    exact = [(x["doc"], x["start"], x["end"]) for x in rows if x["cost"] == 0.0]
    assert sorted(exact) == [("A", 11, 24), ("A", 45, 58), ("C", 31, 44)]
    assert "3 document(s)" in r.stderr and "hop" in r.stderr


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".jsonl"])
def test_output_formats_hold_the_same_table(setup, suffix):
    tmp, mt, docs = setup
    out = tmp / f"hits{suffix}"
    r = run(["retrieve", "--mt", str(tmp / "hop.json"), str(tmp / "C.parquet"), str(tmp / "feats"),
             "-o", str(out), "-q"])
    assert r.exit_code == 0 and r.stdout == "" and r.stderr == ""
    if suffix == ".csv":
        rows = parse_csv(out.read_text())
    elif suffix == ".jsonl":
        rows = [json.loads(line) for line in out.read_text().splitlines()]
    else:
        table = pq.read_table(out)
        assert table.column_names == ["doc", "start", "end", "start_native", "end_native",
                                      "cost", "rank"]
        rows = table.to_pylist()
    want = expected_rows(mt, docs, ["C.parquet", "feats/a/A.parquet", "feats/b/deep/B.parquet"],
                         0.06)
    assert rows == want and len(rows) >= 3


def test_cap_is_reported(setup):
    tmp, _, _ = setup
    r = run(["retrieve", "--mt", str(tmp / "hop.json"), str(tmp / "feats"), "--max-hits", "1"])
    assert r.exit_code == 0
    assert len(parse_csv(r.stdout)) == 1
    assert "--max-hits 1 was reached" in r.stderr


def test_unquantized_template_is_quantized(setup, tmp_path):
    tmp, mt, docs = setup
    soft = MotionTemplate("hop", list(FEATURE_NAMES), np.where(mt.values == 0.5, 0.4, mt.values)
                          * 0.96 + 0.02, np.ones(14))
    save_template(tmp / "soft.json", soft)
    r = run(["retrieve", "--mt", str(tmp / "soft.json"), str(tmp / "C.parquet")])
    assert r.exit_code == 0
    q = quantize(soft, 0.1)
    assert np.array_equal(q.values, mt.values)
    assert parse_csv(r.stdout) == expected_rows(mt, docs, ["C.parquet"], 0.06)
    r = run(["retrieve", "--mt", str(tmp / "hop.json"), str(tmp / "C.parquet"), "--delta", "0.2"])
    assert r.exit_code == 2 and "already quantized" in r.stderr


@pytest.mark.parametrize("option", ["--match", "--variant"])  # --variant: former name
def test_paper_variant_option(setup, option):
    tmp, mt, docs = setup
    r = run(["retrieve", "--mt", str(tmp / "hop.json"), str(tmp / "C.parquet"), option,
             "paper", "--tau", "0.2"])
    assert r.exit_code == 0
    d, s = match_naive(mt.values, mt.weights, docs["C.parquet"], variant="paper")
    hits, _ = hits_naive(d, s, tau=0.2, mode="retrieval", max_hits=1000)
    assert [(x["start"] - 1, x["end"] - 1, x["cost"]) for x in parse_csv(r.stdout)] == hits
    # the former name is read and says so, in one line (commands._common.former_name)
    warnings = [line for line in r.stderr.splitlines() if "warning" in line]
    assert warnings == ([] if option == "--match" else [
        "mtanno: warning: --variant is the former name of --match (still read; write --match)"])


def test_mismatching_feature_files_are_rejected_naming_both(setup):
    tmp, _, docs = setup
    X = docs["C.parquet"]
    cases = {
        "set.parquet": (dict(feature_set="other-set"), "feature set 'other-set' differs"),
        "fps.parquet": (dict(fps=60.0), "frame rate 60 Hz differs"),
        "names.parquet": (dict(names=[n + "_x" if i == 3 else n for i, n in
                                      enumerate(FEATURE_NAMES)]), "feature 4 is"),
    }
    for name, (kw, message) in cases.items():
        write_doc(tmp / "bad" / name, X, **kw)
        r = run(["retrieve", "--mt", str(tmp / "hop.json"), str(tmp / "C.parquet"),
                 str(tmp / "bad" / name)])
        assert r.exit_code == 1  # the good file of the batch was still searched
        assert message in r.stderr and name in r.stderr and "hop.json" in r.stderr
        assert {x["doc"] for x in parse_csv(r.stdout)} <= {"C"}
    fewer = X[:20]
    write_features(tmp / "bad" / "few.parquet", fewer, FEATURE_NAMES[:20],
                   np.arange(1, 4 * X.shape[1], 4), {"analysis_fps": 30.0,
                                                     "feature_set": "mr06-ak40"})
    r = run(["retrieve", "--mt", str(tmp / "hop.json"), str(tmp / "bad" / "few.parquet")])
    assert r.exit_code == 1 and "feature 21 is missing here" in r.stderr


def test_bad_inputs(setup):
    tmp, _, _ = setup
    (tmp / "empty").mkdir()
    (tmp / "broken.json").write_text('{"schema": "mtanno.template/1",\n  "class": }\n')
    (tmp / "notfeatures.parquet").write_text("hello")
    mt = str(tmp / "hop.json")
    cases = [
        (["--mt", str(tmp / "missing.json"), str(tmp / "C.parquet")], "template file not found"),
        (["--mt", str(tmp / "broken.json"), str(tmp / "C.parquet")], "broken.json:2: malformed JSON"),
        (["--mt", mt, str(tmp / "empty")], "no feature files"),
        (["--mt", mt, str(tmp / "nowhere")], "nowhere: no such feature file or folder"),
        (["--mt", mt, str(tmp / "C.parquet"), "-o", str(tmp / "hits.txt")],
         "unknown table format '.txt'"),
        (["--mt", mt, str(tmp / "C.parquet"), "--tau", "nan"], "tau must be a number"),
    ]
    for args, message in cases:
        r = run(["retrieve", *args])
        assert r.exit_code == 2, args
        assert message in r.stderr, (args, r.stderr)
        assert r.stderr.startswith("mtanno: ") and "Traceback" not in r.output
    r = run(["retrieve", "--mt", mt])
    assert r.exit_code == 2 and "Missing argument" in r.stderr
    # an unreadable feature file fails alone (exit 1); the batch goes on
    r = run(["retrieve", "--mt", mt, str(tmp / "notfeatures.parquet"), str(tmp / "C.parquet")])
    assert r.exit_code == 1 and "notfeatures.parquet: not a readable" in r.stderr
    assert "1 failed" in r.stderr


@pytest.mark.realdata
def test_golden_hits_through_the_command_line(tmp_path):
    from conftest import REFERENCE, require_data

    require_data()
    ret = REFERENCE / "retrieval"
    a = np.loadtxt(ret / "concat_doc_features.csv", delimiter=",", skiprows=1)
    write_doc(tmp_path / "concat.parquet", a[:, 1:].T.astype(np.uint8))
    m = np.loadtxt(ret / "kickLFront1Reps_d010_mtbool.csv", delimiter=",", skiprows=1)
    save_template(tmp_path / "kick.json",
                  MotionTemplate("kickLFront1Reps", list(FEATURE_NAMES), m[:, 2:].T, m[:, 1],
                                 quantized=True, delta=0.1))
    r = run(["retrieve", "--mt", str(tmp_path / "kick.json"), str(tmp_path / "concat.parquet"),
             "--tau", "0.175", "--max-hits", "100"])
    assert r.exit_code == 0
    with open(ret / "kickLFront1Reps_d010_hits.csv", newline="") as fh:
        golden = [(int(g["rank"]), int(g["start"]), int(g["end"]), float(g["cost"]))
                  for g in csv.DictReader(fh)]
    rows = parse_csv(r.stdout)
    assert [(x["rank"], x["start"], x["end"]) for x in rows] == [g[:3] for g in golden]
    assert max(abs(x["cost"] - g[3]) for x, g in zip(rows, golden)) <= 1e-12
    assert all(x["start_native"] == 4 * x["start"] - 3 for x in rows)
