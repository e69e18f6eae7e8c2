"""Broken inputs of every kind issue 8 lists, made from good files of the test world.

Each maker takes a folder and the world and writes one broken file there, returning its
path. They are grouped by the kind of input (feature files, templates, query files,
truth tables, annotation tables, manifests, mocap6 labels, class configurations,
indexes), and the hostile tests run every command that reads that kind over each.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from mtanno.features.store import read_features, write_features

# --------------------------------------------------------------------- feature files


def _table(ff):
    cols = {"native_frame": pa.array(ff.native_frames.astype(np.int32))}
    for i, n in enumerate(ff.names):
        cols[n] = pa.array(ff.X[i].astype(bool))
    return pa.table(cols)


def _parquet(path: Path, table, meta) -> Path:
    raw = meta if isinstance(meta, bytes) else json.dumps(meta).encode()
    pq.write_table(table.replace_schema_metadata({b"mtanno": raw}), path)
    return path


def _good(w):
    ff = read_features(w.doc_files[0])
    return ff, _table(ff), dict(ff.meta)


def _feature_makers():
    def null_bools(d, w):
        ff, t, m = _good(w)
        col = pa.array([None, *([True] * (t.num_rows - 1))], pa.bool_())
        return _parquet(d / "zz_bad.parquet", t.set_column(5, ff.names[4], col), m)

    def meta_list(d, w):
        return _parquet(d / "zz_bad.parquet", _good(w)[1], [1, 2, 3])

    def meta_number(d, w):
        return _parquet(d / "zz_bad.parquet", _good(w)[1], 7)

    def meta_not_json(d, w):
        return _parquet(d / "zz_bad.parquet", _good(w)[1], b"{not json")

    def no_meta(d, w):
        pq.write_table(_good(w)[1], d / "zz_bad.parquet")
        return d / "zz_bad.parquet"

    def fps_text(d, w):
        _, t, m = _good(w)
        return _parquet(d / "zz_bad.parquet", t, {**m, "analysis_fps": "thirty"})

    def fps_missing(d, w):
        _, t, m = _good(w)
        m.pop("analysis_fps")
        return _parquet(d / "zz_bad.parquet", t, m)

    def fps_nan(d, w):
        _, t, m = _good(w)
        return _parquet(d / "zz_bad.parquet", t, {**m, "analysis_fps": float("nan")})

    def feature_set_list(d, w):
        _, t, m = _good(w)
        return _parquet(d / "zz_bad.parquet", t, {**m, "feature_set": ["x"]})

    def groups_wrong(d, w):
        _, t, m = _good(w)
        return _parquet(d / "zz_bad.parquet", t, {**m, "groups": "upper"})

    def native_null(d, w):
        _, t, m = _good(w)
        col = pa.array([None] * t.num_rows, pa.int32())
        return _parquet(d / "zz_bad.parquet", t.set_column(0, "native_frame", col), m)

    def native_nan(d, w):
        _, t, m = _good(w)
        col = pa.array([float("nan")] * t.num_rows)
        return _parquet(d / "zz_bad.parquet", t.set_column(0, "native_frame", col), m)

    def native_decreasing(d, w):
        _, t, m = _good(w)
        col = pa.array(np.arange(t.num_rows, 0, -1, dtype=np.int32))
        return _parquet(d / "zz_bad.parquet", t.set_column(0, "native_frame", col), m)

    def int_column(d, w):
        ff, t, m = _good(w)
        col = pa.array(ff.X[2].astype(np.int64) * 7)
        return _parquet(d / "zz_bad.parquet", t.set_column(3, ff.names[2], col), m)

    def truncated(d, w):
        data = w.doc_files[0].read_bytes()
        (d / "zz_bad.parquet").write_bytes(data[: len(data) // 2])
        return d / "zz_bad.parquet"

    def empty(d, w):
        (d / "zz_bad.parquet").write_bytes(b"")
        return d / "zz_bad.parquet"

    def text(d, w):
        (d / "zz_bad.parquet").write_text("doc,start\n")
        return d / "zz_bad.parquet"

    def other_set(d, w):
        ff, _, m = _good(w)
        m.pop("schema")
        write_features(d / "zz_bad.parquet", ff.X, ff.names, ff.native_frames,
                       {**m, "feature_set": "mrc05"})
        return d / "zz_bad.parquet"

    def at_120_hz(d, w):
        ff, _, m = _good(w)
        m.pop("schema")
        write_features(d / "zz_bad.parquet", ff.X, ff.names, ff.native_frames,
                       {**m, "analysis_fps": 120.0})
        return d / "zz_bad.parquet"

    def reordered(d, w):
        ff, _, m = _good(w)
        m.pop("schema")
        order = [1, 0, *range(2, len(ff.names))]
        write_features(d / "zz_bad.parquet", ff.X[order], [ff.names[i] for i in order],
                       ff.native_frames, m)
        return d / "zz_bad.parquet"

    return {f.__name__: f for f in (
        null_bools, meta_list, meta_number, meta_not_json, no_meta, fps_text, fps_missing,
        fps_nan, feature_set_list, groups_wrong, native_null, native_nan, native_decreasing,
        int_column, truncated, empty, text, other_set, at_120_hz, reordered)}


FEATURE_FILES = _feature_makers()

# --------------------------------------------------------------------- templates


def _template_maker(change, *, raw=False):
    """A template made from the world's squat template: ``change`` edits its JSON object
    (or, with ``raw``, maps its bytes to new bytes); bytes replace it whole."""
    def make(d, w):
        text = w.template.read_text()
        out = d / "zz_bad.json"
        if isinstance(change, bytes):
            out.write_bytes(change)
        elif raw:
            out.write_bytes(change(text.encode()))
        else:
            data = json.loads(text)
            change(data)
            out.write_text(json.dumps(data))
        return out
    return make


TEMPLATES = {
    "binary": _template_maker(b"\x00\x01\x02\xff"),
    "latin1": _template_maker(b'{"schema": "\xe9"}'),
    "truncated": _template_maker(lambda b: b[: len(b) // 2], raw=True),
    "empty": _template_maker(b""),
    "list": _template_maker(b"[1, 2]"),
    "huge weights": _template_maker(lambda d: d["weights"].__setitem__(0, 1e308)),
    "nan weight": _template_maker(lambda d: d["weights"].__setitem__(0, float("nan"))),
    "value 3": _template_maker(lambda d: d["values"][0].__setitem__(0, 3)),
    "values text": _template_maker(lambda d: d.__setitem__("values", "many")),
    "fps zero": _template_maker(lambda d: d.__setitem__("fps", 0)),
    "no weights": _template_maker(lambda d: d.pop("weights")),
    "names short": _template_maker(lambda d: d["feature_names"].pop()),
    "class empty": _template_maker(lambda d: d.__setitem__("class", "")),
    "training junk": _template_maker(lambda d: d.__setitem__("training", [{"file": 1}])),
}

# --------------------------------------------------------------------- query files


def _query_maker(content):
    def make(d, w):
        p = d / "q.json"
        p.write_bytes(content if isinstance(content, bytes) else json.dumps(content).encode())
        return p
    return make


QUERIES = {
    "binary": _query_maker(b"\xff\xfe\x00\x00"),
    "not json": _query_maker(b"{steps: 1"),
    "list": _query_maker([1, 2]),
    "empty object": _query_maker({}),
    "steps text": _query_maker({"features": ["rknee_bent"], "steps": "01"}),
    "unknown feature": _query_maker({"features": ["elbow_fly"], "steps": ["0"]}),
    "bad mode": _query_maker({"features": ["rknee_bent"], "steps": ["0"], "mode": "psychic"}),
    "mismatches": _query_maker({"features": ["rknee_bent"], "steps": ["0"],
                                "mismatches": -3}),
}

# --------------------------------------------------------------------- tables


def _text_maker(name, content):
    def make(d, w):
        p = d / name
        body = content(w) if callable(content) else content
        p.write_bytes(body if isinstance(body, bytes) else body.encode())
        return p
    return make


def _with_template(name, content, cls, target):
    """A class configuration beside a copy of the world's template of ``cls``."""
    def make(d, w):
        shutil.copyfile(w.mt / f"{cls}.json", d / target)
        return _text_maker(name, content)(d, w)
    return make


def _doc(w):
    return w.doc_files[0].stem


TRUTH_TABLES = {
    "huge end": _text_maker("t.csv", lambda w: f"doc,start,end,label\n{_doc(w)},1,{10**23},squat\n"),
    "start after end": _text_maker("t.csv", lambda w: f"doc,start,end,label\n{_doc(w)},9,2,squat\n"),
    "fps zero": _text_maker("t.csv", lambda w: f"doc,start,end,label,fps\n{_doc(w)},1,2,squat,0\n"),
    "fps nan": _text_maker("t.csv", lambda w: f"doc,start,end,label,fps\n{_doc(w)},1,2,squat,nan\n"),
    "start text": _text_maker("t.csv", lambda w: f"doc,start,end,label\n{_doc(w)},one,2,squat\n"),
    "start float": _text_maker("t.csv", lambda w: f"doc,start,end,label\n{_doc(w)},1.5,2,squat\n"),
    "no label column": _text_maker("t.csv", "doc,start,end\nx,1,2\n"),
    "empty label": _text_maker("t.csv", lambda w: f"doc,start,end,label\n{_doc(w)},1,2,\n"),
    "binary": _text_maker("t.csv", b"doc,start\x00,end\n"),
    "latin1": _text_maker("t.csv", b"doc,start,end,label\n\xe9,1,2,x\n"),
    "too many fields": _text_maker("t.csv", lambda w: f"doc,start,end,label\n{_doc(w)},1,2,x,9\n"),
    "empty": _text_maker("t.csv", b""),
    "past the end": _text_maker("t.csv", lambda w: f"doc,start,end,label\n{_doc(w)},1,99999,squat\n"),
    "parquet junk": _text_maker("t.parquet", b"PAR1 not really"),
    "suffix": _text_maker("t.txt", lambda w: f"doc,start,end,label\n{_doc(w)},1,2,squat\n"),
}

ANNOTATION_TABLES = {
    "start nan": _text_maker("a.csv", lambda w: f"doc,start,end,label\n{_doc(w)},nan,9,squat\n"),
    "start empty": _text_maker("a.csv", lambda w: f"doc,start,end,label\n{_doc(w)},,9,squat\n"),
    "start after end": _text_maker("a.csv", lambda w: f"doc,start,end,label\n{_doc(w)},9,3,squat\n"),
    "start zero": _text_maker("a.csv", lambda w: f"doc,start,end,label\n{_doc(w)},0,3,squat\n"),
    "cost text": _text_maker("a.csv", lambda w: f"doc,start,end,label,cost\n{_doc(w)},1,3,squat,low\n"),
    "no end": _text_maker("a.csv", "doc,start,label\nx,1,squat\n"),
    "binary": _text_maker("a.csv", b"\x00\x00\x00"),
    "jsonl list": _text_maker("a.jsonl", "[1, 2]\n"),
    "jsonl broken": _text_maker("a.jsonl", '{"doc": "x", "start": 1\n'),
    "parquet junk": _text_maker("a.parquet", b"PAR1\x00\x00PAR1"),
}

MANIFESTS = {
    "binary": _text_maker("m.csv", b"file,class\n\x00\x01,x\n"),
    "latin1": _text_maker("m.csv", b"file,class\n\xe9.amc,x\n"),
    "empty class": _text_maker("m.csv", "file,class,actor,split\nsquat/x.amc,,c,dev\n"),
    "no class column": _text_maker("m.csv", "file,label\nx.amc,y\n"),
    "absolute file": _text_maker("m.csv", "file,class\n/etc/passwd,x\n"),
    "parent file": _text_maker("m.csv", "file,class\n../x.amc,x\n"),
    "missing clip": _text_maker("m.csv", "file,class,actor,split\nsquat/nothere.amc,squat,c,dev\n"),
    "empty": _text_maker("m.csv", b""),
}

LABELS = {
    "fps zero": _text_maker("labels.json", json.dumps({"fps": 0, "documents": {}})),
    "list": _text_maker("labels.json", "[1, 2]"),
    "binary": _text_maker("labels.json", b"\x00\xff"),
    "start after end": _text_maker("labels.json", json.dumps({"documents": {"d": {
        "frames": 9, "segments": [{"label": "a", "start": 5, "end": 2}]}}})),
    "past the end": _text_maker("labels.json", json.dumps({"documents": {"d": {
        "frames": 9, "segments": [{"label": "a", "start": 5, "end": 90}]}}})),
    "unknown label": _text_maker("labels.json", json.dumps({"classes": ["b"], "documents": {
        "d": {"frames": 9, "segments": [{"label": "a", "start": 1, "end": 2}]}}})),
    "start text": _text_maker("labels.json", json.dumps({"documents": {"d": {
        "segments": [{"label": "a", "start": "1", "end": 2}]}}})),
}

CLASS_CONFIGS = {
    "binary": _text_maker("c.toml", b"\x00\x01"),
    "tau nan": _text_maker("c.toml", "[tau]\ndefault = nan\n"),
    "tau text": _text_maker("c.toml", '[tau]\nsquat = "low"\n'),
    "tau negative": _text_maker("c.toml", "[tau]\nsquat = -1\n"),
    "unknown class": _text_maker("c.toml", "[tau]\nsquatt = 0.1\n"),
    "unknown member": _text_maker("c.toml", '[superclasses]\nlegs = ["squat", "kik"]\n'),
    "tau not a table": _text_maker("c.toml", "tau = 3\n"),
    "bad toml": _text_maker("c.toml", "[tau\n"),
    # the methods of issue 10 (mtanno tune writes them)
    "unknown section": _text_maker("c.toml", "[decoders]\nresolve = true\n"),
    "decoder unknown key": _text_maker("c.toml", "[decoder]\nresolv = true\n"),
    "decoder wrong type": _text_maker("c.toml", "[decoder]\nresolve = 1\n"),
    "slack negative": _text_maker("c.toml", "[decoder]\nslack = -2\n"),
    "segment cost negative": _text_maker("c.toml", "[decoder]\nsegment_cost = -1.0\n"),
    "segment cost infinite": _text_maker("c.toml", "[decoder]\nsegment_cost = inf\n"),
    "delta out of range": _text_maker("c.toml", "[decoder]\ndelta = 0.7\n"),
    "tau zero for the decoder": _text_maker("c.toml", "[decoder]\nresolve = true\n[tau]\n"
                                                      "squat = 0.0\n"),
    "reject unknown class": _text_maker("c.toml", "[reject]\nsquatt = 0.1\n"),
    "reject negative": _text_maker("c.toml", "[reject]\ndefault = -0.1\n"),
    "templates unknown class": _text_maker("c.toml", '[templates]\nsquatt = ["x.json"]\n'),
    "templates not a list": _text_maker("c.toml", '[templates]\nsquat = "x.json"\n'),
    "templates missing file": _text_maker("c.toml", '[templates]\nsquat = ["nothere.json"]\n'),
    "templates of another class": _with_template("c.toml", '[templates]\nsquat = ["k.json"]\n',
                                                 "kickLFront", "k.json"),
}

# --------------------------------------------------------------------- indexes


def _index_maker(change):
    def make(d, w):
        root = d / "idx"
        shutil.copytree(w.index, root)
        change(root)
        return root / "manifest.json" if (root / "manifest.json").exists() else root
    return make


def _manifest_edit(edit):
    def change(root):
        m = json.loads((root / "manifest.json").read_text())
        edit(m)
        (root / "manifest.json").write_text(json.dumps(m))
    return change


def _gen_file(root: Path) -> Path:
    m = json.loads((root / "manifest.json").read_text())
    return root / m["directory"] / "lists-upper.parquet"


def _flip(p: Path) -> None:
    data = bytearray(p.read_bytes())
    data[len(data) // 2] ^= 0xFF
    p.write_bytes(bytes(data))


INDEXES = {
    "manifest garbage": _index_maker(lambda r: (r / "manifest.json").write_bytes(b"\x00{")),
    "manifest list": _index_maker(lambda r: (r / "manifest.json").write_text("[]")),
    "generation text": _index_maker(_manifest_edit(lambda m: m.__setitem__("generation", "7"))),
    "directory escape": _index_maker(_manifest_edit(
        lambda m: m.__setitem__("directory", "../../etc"))),
    "files not a dict": _index_maker(_manifest_edit(lambda m: m.__setitem__("files", []))),
    "frame rate zero": _index_maker(_manifest_edit(lambda m: m.__setitem__("frame_rate", 0))),
    "file missing": _index_maker(lambda r: _gen_file(r).unlink()),
    "file changed": _index_maker(lambda r: _flip(_gen_file(r))),
    "manifest missing": _index_maker(lambda r: (r / "manifest.json").unlink()),
    # issue 31: `index remove` took a copy whose manifest lists another feature set
    "another feature set": _index_maker(_manifest_edit(
        lambda m: m.__setitem__("feature_set", "mrc05"))),
    "feature set misnamed": _index_maker(_manifest_edit(
        lambda m: m.__setitem__("feature_set", "bogus"))),
}
