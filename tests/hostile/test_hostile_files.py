"""mtanno's own files made hostile (issue 22, FEAT): JSON nested thousands of levels deep in
every kind of mtanno JSON file, feature files whose metadata contradicts their rows,
keyframe queries that contradict themselves or their templates, template feature names
outside their feature set, and batches of feature inputs holding one input that is no
feature file. Each case runs through the commands that read it: no traceback, exactly one
``mtanno:`` line naming the bad file, the exit code of the guarantee (2 bad input, 1 a
batch that went on), nothing written, no input changed.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from world import assert_one_line, checksums, cli, temporaries

from mtanno.errors import MtannoError
from mtanno.features.store import read_features
from mtanno.index import open_index
from mtanno.keyframes import Gap, Keyframe, KeyframeQuery, load_keyframes, save_keyframes
from mtanno.keyframes.model import feature_groups_of
from mtanno.util.tables import read_table

#: JSON text nested far deeper than any parser's recursion allows.
DEEP = '{"schema": ' + "[" * 20000 + "]" * 20000 + "}"


def _checked(r, bad: Path, before: dict, roots, *, codes=(2,)) -> str:
    """One line naming ``bad``, the exit code in ``codes``, no input changed, no temporary
    left; returns the line."""
    line = assert_one_line(r, bad, codes=codes)
    assert "internal error" not in line, line
    assert checksums(*roots) == before, "an input was written"
    for root in roots:
        assert temporaries(root) == [], temporaries(root)
    return line


def _query(**kw) -> KeyframeQuery:
    """A valid keyframe query of class squat over the test world's features."""
    kfs = [Keyframe("lower", "*" * 5 + "11" + "*" * 5, 5), Keyframe("upper", "00" + "*" * 12, 12)]
    args = dict(class_name="squat", feature_set="mr06-ak40",
                groups=feature_groups_of("mr06-ak40"), keyframes=kfs,
                gaps=[Gap.from_stiffness(7, 0.5)], template_length=30)
    args.update(kw)
    return KeyframeQuery(**args)


# --------------------------------------------------------------------- 1. one JSON reader


def test_the_json_reader_measures_depth_without_recursion():
    """Depth is counted by a scan (brackets inside strings do not count), so any depth is
    one error with its line and column; a file at the limit reads."""
    from mtanno.errors import MAX_JSON_DEPTH, parse_json

    with pytest.raises(MtannoError, match="nested too deeply") as info:
        parse_json("\n" + DEEP, path="x.json")
    assert str(info.value).startswith("x.json:2: ")
    ok = "[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH
    assert parse_json(ok) == parse_json(ok)  # at the limit: read
    assert parse_json('["' + "[" * 50000 + '"]') == ["[" * 50000]  # inside a string
    for text, words in [("1" * 5000, "number too long"), ("", "empty"),
                        ('["\\ud800"]', "surrogate"), (b"\xff", "not a UTF-8")]:
        with pytest.raises(MtannoError, match=words):
            parse_json(text, path="x.json")
    assert parse_json('["\\ud83d\\ude00", "\\\\ud800"]') == ["\U0001F600", "\\ud800"]


TEMPLATE_COMMANDS = ["retrieve", "annotate", "mt show", "mt quantize", "mt mirror",
                     "mt scale", "evaluate-retrieval", "query --rank-mt", "report --mt",
                     "learn-keyframes", "tune"]


@pytest.mark.parametrize("command", TEMPLATE_COMMANDS)
def test_a_deeply_nested_template_is_one_line(world, tmp_path, command):
    """A template nested thousands of levels deep: RecursionError before, one line now,
    in every command that reads templates."""
    if command == "report --mt":
        pytest.importorskip("matplotlib", reason="the 'plot' extra is not installed")
    w, out = world, tmp_path / "out"
    mts = w.copy(w.mt, tmp_path / "mts")
    bad = mts / "zz_deep.json"
    bad.write_text(DEEP)
    good = w.doc_files[0]
    before = checksums(mts, w.root)
    args = {
        "retrieve": ["retrieve", "--mt", bad, good, "-o", out / "h.csv"],
        "annotate": ["annotate", "--mt", mts, good, "-o", out / "a.csv"],
        "mt show": ["mt", "show", bad],
        "mt quantize": ["mt", "quantize", bad, "--delta", "0.1", "-o", out / "q.json"],
        "mt mirror": ["mt", "mirror", bad, "-o", out / "m.json"],
        "mt scale": ["mt", "scale", bad, "--factor", "0.6", "-o", out / "s.json"],
        "evaluate-retrieval": ["evaluate-retrieval", good, "--mt", mts, "--truth", w.truth,
                               "--json", out / "r.json"],
        "query --rank-mt": ["query", w.index, "--example", good.stem, "--features",
                            "rknee_bent", "--rank-mt", bad, "-o", out / "h.csv"],
        "report --mt": ["report", w.annotation, "--truth", w.truth, "--mt", mts, "-o", out],
        "learn-keyframes": ["learn-keyframes", "--mt", mts, "--manifest", w.manifest,
                            "--features-dir", w.feats, "-o", out],
        "tune": ["tune", "--mt", mts, "--manifest", w.manifest, "--features-dir", w.feats,
                 "-o", out / "t.toml"],
    }[command]
    _checked(cli(*args), bad, before, [mts, w.root])
    assert not out.exists()


def _deep_keyframes(tmp_path):
    kf = tmp_path / "kf"
    kf.mkdir()
    (kf / "squat.json").write_text(DEEP)
    return kf / "squat.json"


@pytest.mark.parametrize("command", ["keyframes show", "query --keyframes",
                                     "annotate --keyframes"])
def test_a_deeply_nested_keyframe_query_is_one_line(world, tmp_path, command):
    bad = _deep_keyframes(tmp_path)
    before = checksums(bad.parent, world.root)
    out = tmp_path / "out.csv"
    args = {"keyframes show": ["keyframes", "show", bad],
            "query --keyframes": ["query", world.index, "--keyframes", bad, "-o", out],
            "annotate --keyframes": ["annotate", "--mt", world.mt, "--keyframes", bad.parent,
                                     world.doc_files[0], "-o", out]}[command]
    _checked(cli(*args), bad, before, [bad.parent, world.root])
    assert not out.exists()


def test_deeply_nested_query_manifest_and_labels_are_one_line(world, tmp_path):
    """The other JSON files mtanno reads: an index query file, an index manifest (a
    corrupt index), mocap6 labels."""
    q = tmp_path / "q.json"
    q.write_text(DEEP)
    before = checksums(q, world.root)
    _checked(cli("query", world.index, "--query", q, "-o", tmp_path / "h.csv"), q, before,
             [q, world.root])
    idx = world.copy(world.index, tmp_path / "idx")
    (idx / "manifest.json").write_text(DEEP)
    before = checksums(idx)
    line = _checked(cli("index", "info", idx), idx / "manifest.json", before, [idx])
    assert "corrupt index" in line and "nested too deeply" in line
    labels = tmp_path / "labels.json"
    labels.write_text(DEEP)
    _checked(cli("truth", "mocap6", labels, "-o", tmp_path / "t.csv"), labels,
             checksums(labels), [labels])
    assert not (tmp_path / "t.csv").exists() and not (tmp_path / "h.csv").exists()


def test_deeply_nested_metadata_and_sidecars(world, tmp_path):
    """JSON inside other files: a feature file's metadata is refused in one line; a
    provenance sidecar that cannot be read is no provenance (the table still reads), also
    for the up-to-date check of ``annotate --output-dir``."""
    ff = read_features(world.doc_files[0])
    bad = tmp_path / "deep.parquet"
    t = pa.table({"native_frame": pa.array(ff.native_frames.astype(np.int32)),
                  **{n: pa.array(ff.X[i].astype(bool)) for i, n in enumerate(ff.names)}})
    pq.write_table(t.replace_schema_metadata({b"mtanno": DEEP.encode()}), bad)
    _checked(cli("info", bad), bad, checksums(bad), [bad])
    ann = world.copy(world.annotation, tmp_path / "ann" / "a.csv")
    Path(f"{ann}.meta.json").write_text(DEEP)
    r = cli("evaluate", ann, "--truth", world.truth)
    assert r.exit_code == 0 and r.exception is None, r.output
    assert read_table(ann).provenance is None
    out = tmp_path / "od"
    assert cli("annotate", "--mt", world.mt, world.doc_files[0], "--output-dir", out,
               "-q").exit_code == 0
    table = out / f"{world.doc_files[0].stem}.csv"
    Path(f"{table}.meta.json").write_text(DEEP)
    r = cli("annotate", "--mt", world.mt, world.doc_files[0], "--output-dir", out)
    assert r.exit_code == 0 and r.exception is None, r.output
    assert "1 computed" in r.output  # no readable provenance: not up to date


# --------------------------------------------------------------------- 2. feature metadata


def _rewrite(src: Path, dst: Path, *, native=None, **meta_changes) -> Path:
    """``src`` written again as ``dst`` with its metadata changed (None removes a key)
    and, if given, another native_frame column: a file only a hand (or a bug) makes."""
    ff = read_features(src)
    meta = {k: v for k, v in ff.meta.items()}
    for k, v in meta_changes.items():
        if v is None:
            meta.pop(k, None)
        else:
            meta[k] = v
    col = pa.array(ff.native_frames.astype(np.int32) if native is None else native)
    t = pa.table({"native_frame": col,
                  **{n: pa.array(ff.X[i].astype(bool)) for i, n in enumerate(ff.names)}})
    dst.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(t.replace_schema_metadata({b"mtanno": json.dumps(meta).encode()}), dst)
    return dst


def _contradictions(src: Path, d: Path) -> dict[str, Path]:
    ff = read_features(src)
    n = ff.X.shape[1]
    ids = [f"F{i + 1:02d}" for i in range(len(ff.names))]
    return {
        "analysis_frames": _rewrite(src, d / "af.parquet", analysis_frames=99_999),
        "native_frames huge": _rewrite(src, d / "nh.parquet", native_frames=2**40),
        "native frame near 2**40": _rewrite(
            src, d / "n40.parquet", native_frames=None,
            native=np.arange(n, dtype=np.int64) * 4 + 2**40),
        "native frame past the count": _rewrite(src, d / "past.parquet",
                                                native=ff.native_frames.astype(np.int64) * 50),
        "native_fps": _rewrite(src, d / "nfps.parquet", native_fps=-120),
        "feature_ids twice": _rewrite(src, d / "ids2.parquet", feature_ids=["F01"] * len(ids)),
        "feature_ids of others": _rewrite(src, d / "idsx.parquet",
                                          feature_ids=[ids[1], ids[0], *ids[2:]]),
        "group of no column": _rewrite(src, d / "gx.parquet", groups={"upper": ["nose"]}),
        "groups of another set": _rewrite(src, d / "gs.parquet",
                                          groups={"all": list(ff.names)}),
    }


def test_feature_metadata_that_contradicts_the_rows_is_refused(world, tmp_path):
    """The reader refuses each contradiction in one line naming the file (read_features is
    every command's reader); the good files read."""
    for kind, bad in _contradictions(world.doc_files[0], tmp_path).items():
        with pytest.raises(MtannoError) as info:
            read_features(bad)
        assert str(info.value).startswith(f"{bad}: "), (kind, str(info.value))
    for f in [*world.doc_files, *sorted(world.feats.rglob("*.parquet"))]:
        read_features(f)


FEATURE_COMMANDS = ["info", "annotate", "retrieve", "index", "index add", "query --example",
                    "learn-mt", "align", "evaluate-retrieval"]


@pytest.mark.parametrize("command", FEATURE_COMMANDS)
def test_contradicting_feature_files_through_every_command(world, tmp_path, command):
    """Every command refuses them: a batch names the file and goes on (exit 1), a single
    input is exit 2; nothing is made from the bad file."""
    w, out = world, tmp_path / "out"
    good = w.copy(w.doc_files[0], tmp_path / "in" / "good.parquet")
    cases = _contradictions(w.doc_files[0], tmp_path / "in")
    before = checksums(tmp_path / "in", w.root)

    def check(r, bad, codes=(2,)):
        _checked(r, bad, before, [tmp_path / "in", w.root], codes=codes)

    for kind, bad in cases.items():
        if command == "info":
            check(cli("info", bad), bad)
        elif command == "annotate":
            check(cli("annotate", "--mt", w.mt, good, bad, "-o", out / "a.csv"), bad,
                  codes=(1,))
            assert {r["doc"] for r in read_table(out / "a.csv").rows} <= {"good"}
        elif command == "retrieve":
            check(cli("retrieve", "--mt", w.template, good, bad, "-o", out / "h.csv",
                      "--tau", "0.5"), bad, codes=(1,))
            assert {r["doc"] for r in read_table(out / "h.csv").rows} <= {"good"}
        elif command == "index":
            check(cli("index", good, bad, "-o", out / kind), bad, codes=(1,))
            assert [d.name for d in open_index(out / kind).documents] == ["good"]
        elif command == "index add":
            idx = w.copy(w.index, out / kind)
            check(cli("index", "add", idx, bad), bad, codes=(1,))
            assert [d.name for d in open_index(idx).documents] == \
                [d.name for d in open_index(w.index).documents]
        elif command == "query --example":
            check(cli("query", w.index, "--example", bad, "--features", "rknee_bent", "-o",
                      out / "q.csv"), bad)
        elif command == "learn-mt":
            tree = tmp_path / "tree" / kind.replace(" ", "_")
            w.copy(bad, tree / "squat" / bad.name)
            w.copy(good, tree / "kick" / "good.parquet")
            r = cli("learn-mt", tree, "-o", out / kind)
            assert_one_line(r, tree / "squat" / bad.name, codes=(1,))
            assert not (out / kind / "squat.json").exists()
        elif command == "align":
            check(cli("align", good, bad, "--cost", "features", "-o", out / "p.csv"), bad)
        elif command == "evaluate-retrieval":
            check(cli("evaluate-retrieval", good, bad, "--mt", w.mt, "--truth", w.truth,
                      "--json", out / "r.json"), bad, codes=(1,))
    if command in ("info", "query --example", "align"):
        assert not out.exists()


# --------------------------------------------------------------------- 3. keyframe queries


def _keyframe_cases(d: Path) -> dict[str, Path]:
    good = _query(provenance={"method": "heuristic", "template": {"class": "squat",
                                                                   "length": 30}}).to_dict()

    def case(name, edit):
        obj = json.loads(json.dumps(good))
        edit(obj)
        p = d / name / "squat.json"
        p.parent.mkdir(parents=True)
        p.write_text(json.dumps(obj, indent=1))
        return p

    return {
        "template_length 999": case("k999", lambda o: o.update(template_length=999)),
        "absurd template_length": case("kabs", lambda o: (o.update(template_length=10**12),
                                                         o.update(provenance={}))),
        "absurd extension": case("ext", lambda o: o.update(extension={"factor": 2,
                                                                      "offset": 10**15})),
        "no extension": case("noext", lambda o: o.pop("extension")),
        "no fps": case("nofps", lambda o: o.pop("fps")),
    }


@pytest.mark.parametrize("command", ["keyframes show", "query --keyframes",
                                     "annotate --keyframes"])
def test_keyframe_queries_that_contradict_themselves_are_refused(world, tmp_path, command):
    """A template length other than the one its provenance records, absurd lengths or
    widths, no extension or no frame rate (a default was used): refused when read."""
    for kind, bad in _keyframe_cases(tmp_path).items():
        with pytest.raises(MtannoError):
            load_keyframes(bad)
        out = tmp_path / "out.csv"
        before = checksums(bad.parent, world.root)
        args = {"keyframes show": ["keyframes", "show", bad],
                "query --keyframes": ["query", world.index, "--keyframes", bad, "-o", out],
                "annotate --keyframes": ["annotate", "--mt", world.mt, "--keyframes",
                                         bad.parent, world.doc_files[0], "-o", out]}[command]
        _checked(cli(*args), bad, before, [bad.parent, world.root])
        assert not out.exists(), kind


def test_keyframes_at_another_frame_rate_than_the_templates(world, tmp_path):
    """annotate (and tune) match a query's gaps and windows in frames of the templates'
    rate: a query at 25 Hz for 30 Hz templates is refused, naming it."""
    bad = tmp_path / "kf" / "squat.json"
    save_keyframes(bad, _query(fps=25.0))
    before = checksums(bad.parent, world.root)
    line = _checked(cli("annotate", "--mt", world.mt, "--keyframes", bad.parent,
                        world.doc_files[0], "-o", tmp_path / "a.csv"), bad, before,
                    [bad.parent, world.root])
    assert "25 Hz" in line and not (tmp_path / "a.csv").exists()
    save_keyframes(bad, _query())  # at 30 Hz: used
    r = cli("annotate", "--mt", world.mt, "--keyframes", bad.parent, world.doc_files[0],
            "-o", tmp_path / "a.csv")
    assert r.exit_code == 0, r.output


# --------------------------------------------------------------------- 4. template features


@pytest.mark.parametrize("command", ["mt quantize", "mt mirror", "mt show", "mt scale",
                                     "retrieve", "annotate"])
def test_template_features_outside_their_feature_set(world, tmp_path, command):
    """A template of mr06-ak40 naming a feature that set lacks: `mt mirror` refused it and
    `mt quantize` wrote it; now the template reader refuses it for every command."""
    d = json.loads(world.template.read_text())
    d["feature_names"][3] = "nose_wiggle"
    mts = world.copy(world.mt, tmp_path / "mts")
    bad = mts / "squat.json"
    bad.write_text(json.dumps(d))
    out = tmp_path / "out"
    before = checksums(mts, world.root)
    args = {"mt quantize": ["mt", "quantize", bad, "--delta", "0.1", "-o", out / "q.json"],
            "mt mirror": ["mt", "mirror", bad, "-o", out / "m.json"],
            "mt show": ["mt", "show", bad],
            "mt scale": ["mt", "scale", bad, "--factor", "0.6", "-o", out / "s.json"],
            "retrieve": ["retrieve", "--mt", bad, world.doc_files[0], "-o", out / "h.csv"],
            "annotate": ["annotate", "--mt", mts, world.doc_files[0], "-o", out / "a.csv"],
            }[command]
    line = _checked(cli(*args), bad, before, [mts, world.root])
    assert "nose_wiggle" in line and "not in the mr06-ak40 feature set" in line
    assert not out.exists()


@pytest.mark.parametrize("command", ["mt quantize", "mt mirror", "mt show", "mt scale",
                                     "retrieve", "annotate"])
def test_a_template_whose_feature_set_is_misnamed(world, tmp_path, command):
    """Issue 31: `feature_set = "bogus"` over the 40 annotation features was written by
    `mt quantize` (and refused by `mt mirror` without naming the file): no feature file
    would ever match it. A set that is none of mtanno's, over features all of one of
    mtanno's sets, is refused by the template reader for every command, at its line."""
    d = json.loads(world.template.read_text())
    d["feature_set"] = "bogus"
    mts = world.copy(world.mt, tmp_path / "mts")
    bad = mts / "squat.json"
    bad.write_text(json.dumps(d, indent=1))
    out = tmp_path / "out"
    before = checksums(mts, world.root)
    args = {"mt quantize": ["mt", "quantize", bad, "--delta", "0.1", "-o", out / "q.json"],
            "mt mirror": ["mt", "mirror", bad, "-o", out / "m.json"],
            "mt show": ["mt", "show", bad],
            "mt scale": ["mt", "scale", bad, "--factor", "0.6", "-o", out / "s.json"],
            "retrieve": ["retrieve", "--mt", bad, world.doc_files[0], "-o", out / "h.csv"],
            "annotate": ["annotate", "--mt", mts, world.doc_files[0], "-o", out / "a.csv"],
            }[command]
    line = _checked(cli(*args), bad, before, [mts, world.root])
    set_line = next(k for k, x in enumerate(bad.read_text().splitlines(), 1)
                    if '"feature_set"' in x)
    assert line.startswith(f"mtanno: {bad}:{set_line}: feature set 'bogus' is none of "), line
    assert not out.exists()


def test_mirroring_a_template_of_a_set_of_ones_own_names_the_file(world, tmp_path):
    """A template of a feature set of the user's own (its features none of mtanno's) is
    read and quantized; `mt mirror` has no mirror table for it and says so naming the
    file (it named none)."""
    d = json.loads(world.template.read_text())
    d["feature_set"] = "lab-set"
    d["feature_names"] = [f"f{i}" for i in range(len(d["feature_names"]))]
    bad = tmp_path / "lab.json"
    bad.write_text(json.dumps(d, indent=1))
    assert cli("mt", "quantize", bad, "--delta", "0.1", "-o", tmp_path / "q.json").exit_code == 0
    line = _checked(cli("mt", "mirror", bad, "-o", tmp_path / "m.json"), bad, checksums(bad),
                    [bad])
    assert line.startswith(f"mtanno: {bad}: no mirror table for feature set 'lab-set'"), line
    assert not (tmp_path / "m.json").exists()


# --------------------------------------------------------------------- 6. index --groups


@pytest.mark.parametrize("value", ["", ",", " , "])
def test_index_groups_naming_no_group_is_a_usage_error(world, tmp_path, value):
    """``index --groups ''`` built an index of every group; now it is refused before any
    work (exit 2, nothing written)."""
    out = tmp_path / "idx"
    r = cli("index", world.doc_files[0], "-o", out, "--groups", value)
    assert "none empty" in assert_one_line(r, "--groups", codes=(2,))  # (the NAMES type)
    assert not out.exists()
    r = cli("index", world.doc_files[0], "-o", out, "--groups", "lower", "-q")
    assert r.exit_code == 0 and list(open_index(out).groups) == ["lower"]


# --------------------------------------------------------------------- 5. batches go on


def _batch_inputs(world, d: Path, kind: str) -> tuple[Path, Path]:
    """(input folder holding a good feature file, the input that names no feature file)."""
    import os

    inp = d / "in"
    world.copy(world.doc_files[0], inp / "good.parquet")
    if kind == "empty folder x.parquet":
        bad = d / "x.parquet"
        bad.mkdir()
    elif kind == "missing":
        bad = d / "gone.parquet"
    else:  # a FIFO inside the input folder: reading it would block
        bad = inp / "fifo.parquet"
        os.mkfifo(bad)
    return inp, bad


BATCH_KINDS = ["empty folder x.parquet", "missing", "fifo in a folder"]


@pytest.mark.parametrize("kind", BATCH_KINDS)
@pytest.mark.parametrize("command", ["annotate", "annotate --output-dir", "retrieve", "index",
                                     "index add", "evaluate-retrieval"])
def test_an_input_naming_no_feature_file_does_not_stop_the_batch(world, tmp_path, command,
                                                                 kind):
    """An empty folder named ``x.parquet`` (or a missing input, or a FIFO found in a
    folder) ended the batch with exit 2 and none of the good inputs done; now it is one
    line naming it, the good file is processed, exit code 1."""
    w, out = world, tmp_path / "out"
    inp, bad = _batch_inputs(w, tmp_path, kind)
    before = checksums(inp, w.root)
    extra = [bad] if kind != "fifo in a folder" else []
    args = {
        "annotate": ["annotate", "--mt", w.mt, inp, *extra, "-o", out / "a.csv"],
        "annotate --output-dir": ["annotate", "--mt", w.mt, inp, *extra, "--output-dir", out],
        "retrieve": ["retrieve", "--mt", w.template, inp, *extra, "-o", out / "h.csv",
                     "--tau", "0.5"],
        "index": ["index", inp, *extra, "-o", out / "idx"],
        "index add": ["index", "add", out / "idx", inp, *extra],
        "evaluate-retrieval": ["evaluate-retrieval", inp, *extra, "--mt", w.mt, "--truth",
                               w.truth, "--json", out / "r.json"],
    }[command]
    if command == "index add":
        w.copy(w.index, out / "idx")
    r = cli(*args)
    assert_one_line(r, bad, codes=(1,))
    assert checksums(inp, w.root) == before and temporaries(tmp_path) == []
    if command == "annotate":
        assert {x["doc"] for x in read_table(out / "a.csv").rows} == {"good"}
    elif command == "annotate --output-dir":
        assert (out / "good.csv").is_file()
    elif command == "retrieve":
        assert {x["doc"] for x in read_table(out / "h.csv").rows} <= {"good"}
        assert "1 document(s)" in r.output and "1 failed" in r.output
    elif command in ("index", "index add"):
        assert "good" in [d.name for d in open_index(out / "idx").documents]
    else:
        assert json.loads((out / "r.json").read_text())["classes"]


def test_only_inputs_naming_no_feature_file_is_still_bad_input(world, tmp_path):
    """With no feature file at all the command has nothing to do: exit 2, the input
    named, nothing written (as before)."""
    bad = tmp_path / "x.parquet"
    bad.mkdir()
    r = cli("annotate", "--mt", world.mt, bad, "-o", tmp_path / "a.csv")
    assert "no feature files" in assert_one_line(r, bad, codes=(2,))
    assert not (tmp_path / "a.csv").exists()


def test_retrieve_takes_a_template_folder_holding_one_template(world, tmp_path):
    """``retrieve --mt MT/`` was a usage error for a folder ``annotate --mt`` takes: a
    folder of one template is that template; a folder of several retrieves every class
    (issue 25: a class column; ``tests/test_frictions2.py``)."""
    one = tmp_path / "one"
    world.copy(world.template, one / "squat.json")
    r = cli("retrieve", "--mt", one, world.doc_files[0], "-o", tmp_path / "h.csv", "-q")
    assert r.exit_code == 0, r.output
    want = cli("retrieve", "--mt", world.template, world.doc_files[0], "-o", tmp_path / "w.csv")
    assert read_table(tmp_path / "h.csv").rows == read_table(tmp_path / "w.csv").rows
    assert want.exit_code == 0
    r = cli("retrieve", "--mt", world.mt, world.doc_files[0], "-o", tmp_path / "x.csv")
    assert r.exit_code == 0 and read_table(tmp_path / "x.csv").columns[0] == "class"


def test_a_deeply_nested_class_configuration_is_one_line(world, tmp_path):
    """The class configuration (TOML) is mtanno's file too: arrays nested thousands deep
    were a RecursionError traceback in annotate --classes."""
    bad = tmp_path / "classes.toml"
    bad.write_text("[decoder]\ndelta = " + "[" * 5000 + "]" * 5000 + "\n")
    r = cli("annotate", "--mt", world.mt, world.doc_files[0], "--classes", bad, "-o",
            tmp_path / "a.csv")
    assert "nested too deeply" in _checked(r, bad, checksums(bad, world.root), [bad, world.root])
    assert not (tmp_path / "a.csv").exists()


# --------------------------------------------------------------------- 6. maps, banks, FIFOs


#: TOML nested far deeper than tomllib's recursion allows: arrays, and inline tables.
DEEP_TOML = {"arrays": "name = 'x'\ndetect = " + "[" * 10000 + "]" * 10000 + "\n",
             "tables": "name = 'x'\nheading = " + "{ a = " * 10000 + "1" + " }" * 10000 + "\n"}


def _cmu_bvh(path: Path, rename=lambda name: name) -> Path:
    """A one-frame BVH of the CMU layout, its joints renamed by ``rename``."""
    import re

    from test_bvh import CGSPEED_LIKE

    text = re.sub(r"(ROOT|JOINT) (\S+)", lambda m: f"{m.group(1)} {rename(m.group(2))}",
                  CGSPEED_LIKE)
    path.write_text(text + " ".join(["0"] * 96) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize("nesting", list(DEEP_TOML))
@pytest.mark.parametrize("command", ["info --skeleton", "features --skeleton",
                                     "info, a map on the search path",
                                     "skeleton guess, a map on the search path"])
def test_a_deeply_nested_skeleton_map_is_one_line(tmp_path, monkeypatch, command, nesting):
    """Issue 31: a skeleton map nested 10 000 deep ended in "internal error:
    RecursionError" naming the motion file (features) or a traceback (info, skeleton
    guess). Now one line naming the map: "nested too deeply"."""
    from mtanno import synthetic

    amc = synthetic.write_pair(tmp_path / "in", "walk", n_frames=24)
    bvh = _cmu_bvh(tmp_path / "in" / "c.bvh")
    bad = tmp_path / "maps" / "deep.toml"
    bad.parent.mkdir()
    bad.write_text(DEEP_TOML[nesting])
    before = checksums(tmp_path)
    if "search path" in command:
        monkeypatch.setenv("MTANNO_SKELETON_PATH", str(bad.parent))
    if command == "info --skeleton":
        r = cli("info", amc, "--skeleton", bad)
    elif command == "features --skeleton":
        r = cli("features", amc, "-o", tmp_path / "out", "--skeleton", bad)
    elif command.startswith("info"):
        r = cli("info", amc)
    else:
        r = cli("skeleton", "guess", bvh, "-o", tmp_path / "m.toml")
    line = _checked(r, bad, before, [tmp_path], codes=(1,) if "features" in command else (2,))
    assert "nested too deeply" in line, line
    assert not (tmp_path / "out").exists() and not (tmp_path / "m.toml").exists()


def test_a_deeply_nested_bank_metadata_is_one_line(tmp_path):
    """The verification bank's metadata (JSON in the Parquet file) was read with plain
    json.loads: nested thousands deep, a RecursionError. It goes through the one bounded
    JSON reader now: one error naming the bank."""
    from mtanno.confidence.verify import build_bank, read_bank, write_bank

    rng = np.random.default_rng(0)
    bank = build_bank([("kick", "a", rng.random((12, 6)).astype(np.float32))],
                      representation="features")
    path = tmp_path / "b.verify.parquet"
    write_bank(path, bank)
    assert read_bank(path).labels == ["kick"]
    table = pq.read_table(path)
    pq.write_table(table.replace_schema_metadata({b"mtanno": DEEP.encode()}), path)
    with pytest.raises(MtannoError, match="nested too deeply") as e:
        read_bank(path)
    assert str(e.value).startswith(f"{path}: verification bank metadata is malformed")


def _hang_safe(args, env=None):
    """Run mtanno ARGS as a process (a reader that blocked on a FIFO would hang this
    process, not the suite: the run is bounded by a generous timeout)."""
    import os
    import subprocess
    import sys

    code = "import sys; from mtanno.cli import main; sys.exit(main(prog_name='mtanno'))"
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True,
                          text=True, timeout=120, env={**os.environ, **(env or {})})


READERS = ["skeleton guess", "features --skeleton", "info --skeleton", "a map on the search path",
           "info --asf", "annotate --classes", "evaluate --truth", "mt show"]


@pytest.mark.parametrize("reader,what", [*((r, "FIFO") for r in READERS),
                                         *((r, "/dev/zero") for r in READERS[:4])])
def test_a_fifo_or_a_device_where_a_file_is_expected_is_refused(world, tmp_path, reader, what):
    """Issue 31: a FIFO (or /dev/zero) where a file is expected hung skeleton guess,
    features --skeleton and every command reading a map on the search path. Every reader
    opens its file through one helper (mtanno.errors.open_regular), which refuses what is not
    a regular file before reading a byte: one line naming it, no hang."""
    import os

    from mtanno import synthetic

    if what == "FIFO" and not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    if what == "/dev/zero" and not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero here")
    amc = synthetic.write_pair(tmp_path / "in", "walk", n_frames=24)
    suffix = {"skeleton guess": ".bvh", "info --asf": ".asf", "evaluate --truth": ".csv",
              "mt show": ".json"}.get(reader, ".toml")
    bad = tmp_path / "bad" / f"x{suffix}"
    bad.parent.mkdir()
    if what == "FIFO":
        os.mkfifo(bad)
    else:
        bad.symlink_to("/dev/zero")
    env = {"MTANNO_SKELETON_PATH": str(bad.parent)} if "search path" in reader else None
    args = {"skeleton guess": ["skeleton", "guess", bad],
            "features --skeleton": ["features", amc, "-o", tmp_path / "out", "--skeleton",
                                    bad],
            "info --skeleton": ["info", amc, "--skeleton", bad],
            "a map on the search path": ["info", amc],
            "info --asf": ["info", amc, "--asf", bad],
            "annotate --classes": ["annotate", "--mt", world.mt, world.doc_files[0],
                                   "--classes", bad, "-o", tmp_path / "a.csv"],
            "evaluate --truth": ["evaluate", world.annotation, "--truth", bad],
            "mt show": ["mt", "show", bad]}[reader]
    r = _hang_safe(args, env)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == (1 if reader.startswith("features") else 2), r.stderr
    assert "Traceback" not in r.stderr and len([x for x in lines if x.startswith("mtanno:")]) \
        == 1, r.stderr
    line = next(x for x in lines if x.startswith("mtanno:"))
    assert str(bad) in line and "not a regular file" in line, line
    assert not (tmp_path / "out").exists() and not (tmp_path / "a.csv").exists()


def test_skeleton_guess_writes_names_beyond_the_bmp_its_reader_reads(tmp_path):
    """Issue 31: joint names with characters beyond U+FFFF (emoji) were written as JSON's
    surrogate-pair escapes, which TOML (and so --skeleton) refuses; now as themselves, and
    the map reads back to the one the features use."""
    from mtanno.io import read_motion
    from mtanno.io.rigs import load_map

    src = _cmu_bvh(tmp_path / "e.bvh", lambda name: f"{name}\U0001F600\x7f")
    out = tmp_path / "map.toml"
    r = cli("skeleton", "guess", src, "-o", out)
    assert r.exit_code == 0, r.output
    smap = load_map(out)
    assert smap.joints["root"] == "Hips\U0001F600\x7f"
    assert smap.digest == read_motion(src).smap.digest
    r = cli("info", src, "--skeleton", out)
    assert r.exit_code == 0, r.output
