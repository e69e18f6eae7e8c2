"""The hostile-input suite (issue 8): broken inputs of every kind (``hostile_kinds``), each
run through every command that reads that kind, through the command line. For each run:
no traceback, exit code 1 (a batch that went on) or 2 (bad input), exactly one
``mtanno:`` line and it names the broken file, the good inputs of the same batch still
processed, no input changed (checksums before and after), no temporary file left.
"""

from __future__ import annotations

import json

import pytest
from hostile_kinds import (
    ANNOTATION_TABLES,
    CLASS_CONFIGS,
    FEATURE_FILES,
    INDEXES,
    LABELS,
    MANIFESTS,
    QUERIES,
    TEMPLATES,
    TRUTH_TABLES,
)
from world import assert_one_line, checksums, cli, temporaries

from mtanno.index import open_index
from mtanno.util.tables import read_table


class Case:
    """A folder with the broken input and copies of the good inputs a command needs."""

    def __init__(self, world, tmp_path, maker):
        self.w = world
        self.dir = tmp_path
        (tmp_path / "in").mkdir()
        self.bad = maker(tmp_path / "in", world)
        self.good = world.copy(world.doc_files[0], tmp_path / "in" / "good.parquet")
        self.before = checksums(tmp_path / "in", world.root)

    def check(self, r, *, codes=(1, 2), named=None):
        line = assert_one_line(r, named or self.bad, codes=codes)
        assert checksums(self.dir / "in", self.w.root) == self.before, "an input was written"
        assert temporaries(self.dir) == [], temporaries(self.dir)
        return line


# --------------------------------------------------------------------- feature files

#: Well-formed feature files whose features differ from the others' (set, rate, order).
INCOMPATIBLE = ("other_set", "at_120_hz", "reordered")
FEATURE_COMMANDS = ["info", "show", "retrieve", "annotate", "index", "index add",
                    "query --example", "learn-mt", "evaluate-retrieval"]


@pytest.mark.parametrize("command,kind", [
    (c, k) for c in FEATURE_COMMANDS for k in FEATURE_FILES
    if not (c in ("info", "show") and k in INCOMPATIBLE)])  # well-formed: fine on their own
def test_broken_feature_file(world, tmp_path, kind, command):
    c = Case(world, tmp_path, FEATURE_FILES[kind])
    out = tmp_path / "out"
    w, bad, good = world, c.bad, c.good
    if command in ("info", "show"):
        c.check(cli(command, bad), codes=(2,))
    elif command == "retrieve":
        c.check(cli("retrieve", "--mt", w.template, good, bad, "-o", out / "h.csv",
                    "--tau", "0.5"), codes=(1,))
        assert {r["doc"] for r in read_table(out / "h.csv").rows} == {"good"}
    elif command == "annotate":
        c.check(cli("annotate", "--mt", w.mt, good, bad, "-o", out / "a.csv"), codes=(1,))
        assert {r["doc"] for r in read_table(out / "a.csv").rows} == {"good"}
    elif command == "index":
        c.check(cli("index", good, bad, "-o", out / "idx"), codes=(1,))
        assert [d.name for d in open_index(out / "idx").documents] == ["good"]
    elif command == "index add":
        idx = w.copy(w.index, out / "idx")
        names = [d.name for d in open_index(idx).documents]
        c.check(cli("index", "add", idx, good, bad), codes=(1,))
        assert [d.name for d in open_index(idx).documents] == sorted({*names, "good"})
    elif command == "query --example":
        c.check(cli("query", w.index, "--example", bad, "--features", "rknee_bent"), codes=(2,))
    elif command == "learn-mt":
        tree = tmp_path / "tree"
        for cls, files in (("squat", [good, bad]), ("kick", [good])):
            for f in files:
                w.copy(f, tree / cls / f.name)
        r = cli("learn-mt", tree, "-o", out)
        assert_one_line(r, tree / "squat" / bad.name, codes=(1,))
        assert (out / "kick.json").exists() and not (out / "squat.json").exists()
        assert temporaries(tmp_path) == []
    elif command == "evaluate-retrieval":
        c.check(cli("evaluate-retrieval", good, bad, "--mt", w.mt, "--truth", w.truth, "--json",
                    out / "r.json"), codes=(1,))
        assert json.loads((out / "r.json").read_text())["classes"]


# --------------------------------------------------------------------- templates


@pytest.mark.parametrize("kind", list(TEMPLATES))
@pytest.mark.parametrize("command", ["retrieve", "annotate", "mt show", "mt quantize",
                                     "mt mirror", "mt scale", "evaluate-retrieval",
                                     "query --rank-mt"])
def test_broken_template(world, tmp_path, kind, command):
    c = Case(world, tmp_path, TEMPLATES[kind])
    out, w = tmp_path / "out", world
    if command in ("annotate", "evaluate-retrieval"):
        mts = tmp_path / "in" / "mts"  # a folder of good templates and the broken one
        w.copy(w.mt, mts)
        c.bad = c.bad.rename(mts / "zz_bad.json")
        c.before = checksums(tmp_path / "in", w.root)
    args = {
        "retrieve": ["retrieve", "--mt", c.bad, c.good],
        "annotate": ["annotate", "--mt", tmp_path / "in" / "mts", c.good, "-o", out / "a.csv"],
        "mt show": ["mt", "show", c.bad],
        "mt quantize": ["mt", "quantize", c.bad, "--delta", "0.1", "-o", out / "q.json"],
        "mt mirror": ["mt", "mirror", c.bad, "-o", out / "m.json"],
        "mt scale": ["mt", "scale", c.bad, "--factor", "0.6", "-o", out / "s.json"],
        "evaluate-retrieval": ["evaluate-retrieval", c.good, "--mt", tmp_path / "in" / "mts",
                               "--truth", w.truth],
        "query --rank-mt": ["query", w.index, "--example", w.doc_files[0].stem, "--features",
                            "rknee_bent", "--rank-mt", c.bad],
    }[command]
    c.check(cli(*args), codes=(2,))
    assert not out.exists()


# --------------------------------------------------------------------- other kinds


@pytest.mark.parametrize("kind", list(QUERIES))
def test_broken_query_file(world, tmp_path, kind):
    c = Case(world, tmp_path, QUERIES[kind])
    c.check(cli("query", world.index, "--query", c.bad, "-o", tmp_path / "h.csv"), codes=(2,))
    assert not (tmp_path / "h.csv").exists()


@pytest.mark.parametrize("kind", list(TRUTH_TABLES))
@pytest.mark.parametrize("command", ["evaluate", "evaluate-retrieval", "learn-mt --truth",
                                     "report"])
def test_broken_truth_table(world, tmp_path, kind, command):
    if command == "report":
        pytest.importorskip("matplotlib", reason="the 'plot' extra is not installed")
    c = Case(world, tmp_path, TRUTH_TABLES[kind])
    w, out = world, tmp_path / "out"
    args = {
        "evaluate": ["evaluate", w.annotation, "--truth", c.bad, "--json", out / "r.json"],
        "evaluate-retrieval": ["evaluate-retrieval", w.doc_files[0], "--mt", w.mt, "--truth",
                               c.bad],
        "learn-mt --truth": ["learn-mt", "--truth", c.bad, w.doc_files[0], "-o", out],
        "report": ["report", w.annotation, "--truth", c.bad, "-o", out],
    }[command]
    r = cli(*args)
    if kind == "past the end" and command == "learn-mt --truth":
        c.check(r, codes=(1,))  # one class failed, named by the truth table
    else:
        c.check(r, codes=(2,))
        assert not out.exists()


def test_many_one_frame_truth_rows_learn_in_linear_memory(world, tmp_path):
    """Issue 31: 300 000 one-frame truth rows for learn-mt --truth ended in a MemoryError
    traceback: each learning iteration kept the N × N matrix of alignment costs (671 GiB).
    Only each reference's largest and summed cost is needed (N values): here 1 500
    one-frame examples learn with far less than one N × N matrix allocated, through the
    command line, and the learning itself is checked to stay below it."""
    import tracemalloc

    import numpy as np

    from mtanno.templates.learn import learn

    n = 1500
    rng = np.random.default_rng(0)
    examples = [rng.integers(0, 2, (40, 1)).astype(float) for _ in range(n)]
    learn(examples[:3], iter_max=1)  # the kernels compiled (or loaded) first
    tracemalloc.start()
    try:
        result = learn(examples, iter_max=1)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < n * n * 8 / 4, f"{peak / 1e6:.1f} MB: an N × N matrix came back"
    assert result.cost_max[0] >= result.cost_mean[0] >= 0
    doc = world.doc_files[0]
    truth = tmp_path / "truth.csv"
    truth.write_text("doc,start,end,label\n" + "".join(
        f"{doc.stem},{1 + i % 500},{1 + i % 500},c{i % 2}\n" for i in range(600)))
    r = cli("learn-mt", "--truth", truth, doc, "-o", tmp_path / "mt", "-q")
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in (tmp_path / "mt").iterdir()) == ["c0.json", "c1.json"]


@pytest.mark.parametrize("kind", list(ANNOTATION_TABLES))
@pytest.mark.parametrize("command", ["evaluate", "report"])
def test_broken_annotation_table(world, tmp_path, kind, command):
    c = Case(world, tmp_path, ANNOTATION_TABLES[kind])
    out = tmp_path / "out"
    if command == "evaluate":
        c.check(cli("evaluate", c.bad, "--truth", world.truth, "--json", out), codes=(2,))
    else:
        pytest.importorskip("matplotlib", reason="the 'plot' extra is not installed")
        c.check(cli("report", c.bad, "--truth", world.truth, "-o", out), codes=(2,))
    assert not out.exists()


@pytest.mark.parametrize("kind", list(MANIFESTS))
@pytest.mark.parametrize("command", ["compose", "learn-mt --manifest"])
def test_broken_manifest(world, tmp_path, kind, command):
    c = Case(world, tmp_path, MANIFESTS[kind])
    if command == "compose":
        r = cli("compose", c.bad, "--root", world.clips, "-o", tmp_path / "docs")
    else:
        r = cli("learn-mt", "--manifest", c.bad, "--features-dir", world.feats, "-o",
                tmp_path / "docs")
    # learn-mt with a listed file that has no features fails that class only
    c.check(r, codes=(1,) if (kind, command) == ("missing clip", "learn-mt --manifest")
            else (2,))
    if r.exit_code == 2:
        assert not (tmp_path / "docs").exists()


@pytest.mark.parametrize("kind", list(LABELS))
def test_broken_mocap6_labels(world, tmp_path, kind):
    c = Case(world, tmp_path, LABELS[kind])
    c.check(cli("truth", "mocap6", c.bad, "-o", tmp_path / "t.csv"), codes=(2,))
    assert not (tmp_path / "t.csv").exists()


@pytest.mark.parametrize("kind", list(CLASS_CONFIGS))
def test_broken_class_configuration(world, tmp_path, kind):
    c = Case(world, tmp_path, CLASS_CONFIGS[kind])
    c.check(cli("annotate", "--mt", world.mt, c.good, "--classes", c.bad, "-o",
                tmp_path / "a.csv"), codes=(2,))
    assert not (tmp_path / "a.csv").exists()


@pytest.mark.parametrize("kind", list(INDEXES))
@pytest.mark.parametrize("command", ["index info", "query", "index add", "index remove"])
def test_corrupt_index(world, tmp_path, kind, command):
    c = Case(world, tmp_path, INDEXES[kind])
    root = tmp_path / "in" / "idx"
    args = {
        "index info": ["index", "info", root],
        "query": ["query", root, "--example", c.good, "--features", "rknee_bent"],
        "index add": ["index", "add", root, c.good],
        "index remove": ["index", "remove", root, world.doc_files[1].stem],
    }[command]
    c.check(cli(*args), codes=(2,), named=root)


def test_a_held_index_lock_is_one_line(world, tmp_path):
    import fcntl

    idx = world.copy(world.index, tmp_path / "idx")
    with open(idx / ".lock", "a+") as fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        r = cli("index", "add", idx, world.doc_files[0])
    assert "index is locked by" in assert_one_line(r, idx, codes=(3,))


# --------------------------------------------------------------------- output folders


@pytest.mark.parametrize("kind", ["a file", "below a file", "read-only", "a table's name is a "
                                  "folder"])
def test_unusable_annotation_folder(world, tmp_path, kind):
    """annotate --output-dir into a folder it cannot use: one line naming it, nothing
    written; a document whose table cannot be written fails alone."""
    import os

    docs = [world.copy(f, tmp_path / "in" / f.name) for f in world.doc_files]
    out, named, codes = tmp_path / "out", tmp_path / "out", (2,)
    if kind == "a file":
        out.write_text("a file, not a folder")
    elif kind == "below a file":
        (tmp_path / "file").write_text("a file, not a folder")
        out, named = tmp_path / "file" / "out", tmp_path / "file"
    elif kind == "read-only":
        out.mkdir()
        out.chmod(0o555)
        if os.access(out, os.W_OK):
            pytest.skip("this user may write into read-only folders (root)")
    else:
        named, codes = out / f"{docs[0].stem}.csv", (1,)
        named.mkdir(parents=True)
    before = checksums(tmp_path)
    try:
        r = cli("annotate", "--mt", world.mt, tmp_path / "in", "--output-dir", out)
    finally:
        if kind == "read-only":
            out.chmod(0o755)
    line = assert_one_line(r, named, codes=codes)
    assert "Traceback" not in r.output and "internal error" not in line
    assert temporaries(tmp_path) == []
    if kind == "a table's name is a folder":  # the other document was annotated
        assert "output is a folder" in line
        assert (out / f"{docs[1].stem}.csv").is_file() and "1 failed" in r.output
        assert checksums(tmp_path / "in") == {k: v for k, v in before.items()
                                             if k.startswith(str(tmp_path / "in"))}
    else:
        assert checksums(tmp_path) == before  # nothing written, no input changed
