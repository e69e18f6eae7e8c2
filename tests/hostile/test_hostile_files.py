"""mtanno's own files made hostile (issue 22, FEAT): JSON nested thousands of levels deep in
every kind of mtanno JSON file, feature files whose metadata contradicts their rows,
keyframe queries that contradict themselves or their templates, template feature names
outside their feature set, and batches of feature inputs holding one input that is no
feature file. Each case runs through the commands that read it: no traceback, exactly one
``mtanno:`` line naming the bad file, the exit code of the guarantee (2 bad input, 1 a
batch that went on), nothing written, no input changed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from world import assert_one_line, checksums, cli, temporaries

from mtanno.errors import MtannoError
from mtanno.keyframes import Gap, Keyframe, KeyframeQuery
from mtanno.keyframes.model import feature_groups_of
from mtanno.store import read_features
from mtanno.tables import read_table

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
