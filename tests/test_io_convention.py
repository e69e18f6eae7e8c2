"""Issue 9 item 2: one I/O convention for every command that writes a table (annotate,
query, retrieve, evaluate, evaluate-retrieval, index info, truth): each rule is tested on
each command."""

from __future__ import annotations

import json
import math

import pyarrow.parquet as pq
import pytest
from world import cli

from mtanno.util.provenance import sha256_file
from mtanno.util.tables import _cell, read_table


def _commands(w, tmp):
    """Command → (arguments before the output, output option). The table goes after it."""
    return {
        "annotate": (["annotate", "--mt", w.mt, w.docfeats, "-q"], "-o"),
        "retrieve": (["retrieve", "--mt", w.template, w.docfeats, "--tau", "0.3", "-q"], "-o"),
        "query": (["query", w.index, "--example", w.doc_files[0].stem, "--features",
                   "rknee_bent,lknee_bent", "-q"], "-o"),
        "evaluate": (["evaluate", w.annotation, "--truth", w.truth], "-o"),
        "evaluate-retrieval": (["evaluate-retrieval", w.docfeats, "--mt", w.mt, "--truth",
                                w.truth], "-o"),
        "index info": (["index", "info", w.index], "-o"),
        "truth": (["truth", "mocap6", w.labels], "-o"),
    }


COMMANDS = ["annotate", "retrieve", "query", "evaluate", "evaluate-retrieval", "index info",
            "truth"]


def _run(w, tmp, name, out):
    args, opt = _commands(w, tmp)[name]
    return cli(*args, opt, out)


@pytest.mark.parametrize("name", COMMANDS)
def test_format_follows_suffix_with_the_same_rows(world, tmp_path, name):
    rows = {}
    for suffix in (".csv", ".parquet", ".jsonl"):
        out = tmp_path / f"t{suffix}"
        r = _run(world, tmp_path, name, out)
        assert r.exit_code == 0, r.output
        rows[suffix] = read_table(out).rows
    pq.read_table(tmp_path / "t.parquet")  # a real Parquet file
    ref = rows[".parquet"]
    assert ref, "the command wrote no rows; the comparison would prove nothing"
    assert [{k: _json(v) for k, v in a.items()} for a in ref] == rows[".jsonl"]
    assert [{k: _cell(v) or None for k, v in a.items()} for a in ref] == rows[".csv"]


def _json(v):
    return None if isinstance(v, float) and not math.isfinite(v) else v


@pytest.mark.parametrize("name", COMMANDS)
def test_unknown_suffix_is_an_error_and_writes_nothing(world, tmp_path, name):
    out = tmp_path / "t.txt"
    r = _run(world, tmp_path, name, out)
    assert r.exit_code == 2, r.output
    assert f"mtanno: {out}: unknown table format '.txt'" in r.output
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", COMMANDS)
def test_dash_is_standard_output_as_csv(world, tmp_path, name):
    r = _run(world, tmp_path, name, "-")
    assert r.exit_code == 0, r.output
    assert _run(world, tmp_path, name, tmp_path / "t.csv").exit_code == 0
    assert (tmp_path / "t.csv").read_text() in r.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv", "t.csv.meta.json"]


@pytest.mark.parametrize("name", COMMANDS)
def test_csv_quotes_only_when_needed(world, tmp_path, name):
    out = tmp_path / "t.csv"
    assert _run(world, tmp_path, name, out).exit_code == 0
    text = out.read_text()
    rows = read_table(out).rows
    needs = any(any(c in str(v) for c in ',"\n') for r in rows for v in r.values() if v)
    assert ('"' in text) == needs


def test_csv_quotes_a_value_that_needs_it(world, tmp_path):
    labels = tmp_path / "labels.json"
    labels.write_text(json.dumps({"fps": 30, "documents": {"d": {"frames": 9, "segments": [
        {"label": "jump, twice", "start": 1, "end": 4}, {"label": "say \"hi\"", "start": 5,
                                                         "end": 9}]}}}))
    out = tmp_path / "t.csv"
    assert cli("truth", "mocap6", labels, "-o", out).exit_code == 0
    assert out.read_text().splitlines() == ["doc,start,end,label,fps", 'd,1,4,"jump, twice",30',
                                            'd,5,9,"say ""hi""",30']


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".jsonl"])
def test_every_table_carries_its_provenance(world, tmp_path, name, suffix):
    out = tmp_path / f"t{suffix}"
    assert _run(world, tmp_path, name, out).exit_code == 0
    if suffix == ".parquet":
        prov = json.loads(pq.read_schema(out).metadata[b"mtanno"])
        assert not (tmp_path / f"t{suffix}.meta.json").exists()
    else:
        prov = json.loads((tmp_path / f"t{suffix}.meta.json").read_text())
    assert read_table(out).provenance == prov
    from mtanno import __version__

    assert prov["schema"] == "mtanno.provenance/1" and prov["mtanno_version"] == __version__
    args, opt = _commands(world, tmp_path)[name]
    assert prov["command"] == ["mtanno", *map(str, args), opt, str(out)]
    assert prov["inputs"]
    for rec in prov["inputs"]:
        if rec.get("sha256") is not None:
            assert rec["sha256"] == sha256_file(rec["path"])
    if name in ("annotate", "retrieve", "evaluate-retrieval"):
        assert prov["templates"] and all(t["sha256"] == sha256_file(t["path"])
                                         for t in prov["templates"])
        assert prov["delta"] > 0 and prov["feature_set"] == "mr06-ak40"
    if name in ("annotate", "retrieve"):
        assert prov["tau"] > 0


def test_evaluate_reads_standard_input_and_several_tables(world, tmp_path):
    a = world.annotation.read_text()
    r = cli("evaluate", "-", "--truth", world.truth, "--json", tmp_path / "r.json", input=a)
    assert r.exit_code == 0, r.output
    whole = json.loads((tmp_path / "r.json").read_text())
    assert whole["schema"] == "mtanno.evaluation/1"
    for c in whole["per_class"].values():
        assert set(c["frame"]) >= {"P", "R", "F", "support"} and c["segment"]["support"] >= 0
    # the same annotation split by document into two files gives the same report
    lines = a.splitlines()
    docs = sorted({ln.split(",")[0] for ln in lines[1:]})
    for i, d in enumerate(docs):
        (tmp_path / f"a{i}.csv").write_text("\n".join([lines[0]] + [ln for ln in lines[1:]
                                                                   if ln.startswith(d + ",")]))
    parts = [tmp_path / f"a{i}.csv" for i in range(len(docs))]
    r = cli("evaluate", *parts, "--truth", world.truth, "--json", tmp_path / "s.json")
    assert r.exit_code == 0, r.output
    split = json.loads((tmp_path / "s.json").read_text())
    for key in ("frame", "segment", "per_class"):
        assert split[key] == whole[key]
    # truth from standard input too, and JSON to standard output
    r = cli("evaluate", world.annotation, "--truth", "-", "--json", "-",
            input=world.truth.read_text())
    assert r.exit_code == 0 and json.loads(r.stdout)["frame"] == whole["frame"]
    # the same document in two files is refused
    r = cli("evaluate", parts[0], parts[0], "--truth", world.truth)
    assert r.exit_code == 2 and "is annotated in" in r.output
    r = cli("evaluate", world.annotation, parts[0], "--truth", world.truth)
    assert r.exit_code == 2 and "is annotated in" in r.output
