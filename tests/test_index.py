"""The index: segmentation, inverted lists, storage, atomic updates, incremental == rebuild,
corrupt directories, and the reference implementation's segments (keyframes/index_segments_*)."""

from __future__ import annotations

import csv
import json
import os

import numpy as np
import pytest
from conftest import HDM05, REFERENCE, require_data
from hypothesis import given, settings
from hypothesis import strategies as st

from mtanno.errors import MtannoError
from mtanno.features import get_feature_set
from mtanno.features.store import write_features
from mtanno.index import (
    CorruptIndex,
    add_documents,
    build_index,
    index_from_matrices,
    open_index,
    remove_documents,
    segment,
    storage,
)
from mtanno.index.core import frame_codes

MRC05 = get_feature_set("mrc05")


def _segments_naive(codes):
    out = []
    for t, c in enumerate(codes):
        if out and out[-1][2] == c:
            out[-1][1] += 1
        else:
            out.append([t, 1, c])
    return out


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 3), max_size=40))
def test_segment_is_maximal_runs(codes):
    s, l, c = segment(np.array(codes, dtype=np.int64))
    assert [list(x) for x in zip(s.tolist(), l.tolist(), c.tolist())] == _segments_naive(codes)


def test_frame_codes_bit_order():
    X = np.array([[1, 0, 1], [0, 1, 1], [1, 1, 0]], dtype=np.uint8)
    # code = Σ_k X[rows[k]]·2^k (the reference implementation's index_segments code)
    assert frame_codes(X, [0, 1]).tolist() == [1, 2, 3]
    assert frame_codes(X, [2, 0]).tolist() == [3, 1, 2]


def _random_docs(rng, n_docs, names, frames=(5, 60), p=0.15):
    """Feature matrices with runs: each feature flips with probability p per frame."""
    docs = {}
    for d in range(n_docs):
        T = int(rng.integers(*frames))
        flips = rng.random((len(names), T)) < p
        X = (np.cumsum(flips, axis=1) % 2).astype(np.uint8)
        docs[f"doc{d:02d}"] = X
    return docs


def test_index_structure_matches_naive():
    rng = np.random.default_rng(0)
    names = ["a", "b", "c", "d", "e"]
    groups = {"g1": ["a", "b", "c"], "g2": ["e", "d"]}
    docs = _random_docs(rng, 5, names)
    idx = index_from_matrices(docs, names, groups)
    assert [d.name for d in idx.documents] == sorted(docs)
    for gname, feats in groups.items():
        g = idx.groups[gname]
        rows = [names.index(f) for f in feats]
        want = []
        for d, name in enumerate(sorted(docs)):
            segs = _segments_naive(frame_codes(docs[name], rows).tolist())
            assert g.segments(d)[0].tolist() == [s[0] for s in segs]
            want += [(d, s[0], s[1], s[2]) for s in segs]
        got = list(zip(g.doc.tolist(), g.start.tolist(), g.length.tolist(), g.code.tolist()))
        assert got == want
        # every segment in exactly one list, lists ascending, list = rows with that code
        assert sorted(g.postings.tolist()) == list(range(g.n_segments))
        for v, code in enumerate(g.list_codes.tolist()):
            lst = g.postings[g.list_offsets[v]:g.list_offsets[v + 1]].tolist()
            assert lst == [r for r in range(g.n_segments) if g.code[r] == code]
            assert g.list_of(code).tolist() == lst
        assert g.list_of(999).size == 0
    # the index rebuilds the features of its groups
    for name, X in docs.items():
        assert np.array_equal(idx.feature_matrix(name), X)
        assert np.array_equal(idx.feature_matrix(name, ["d", "a"]), X[[3, 0]])


def test_intervals_are_merged_runs_of_matching_frames():
    # keyframe search (docs/method.md §5): union of lists → frame intervals, neighbours merged
    rng = np.random.default_rng(3)
    names = ["a", "b", "c", "d"]
    docs = _random_docs(rng, 4, names, p=0.3)
    idx = index_from_matrices(docs, names, {"g": names})
    g = idx.groups["g"]
    for patterns in ([(0b0011, 0b0001)], [(0b1111, 0b0110), (0b1000, 0b1000)], [(0, 0)]):
        doc, start, end = g.intervals(patterns)
        want = []
        for d, name in enumerate(sorted(docs)):
            codes = frame_codes(docs[name], range(4))
            ok = [any(c & m == v for m, v in patterns) for c in codes.tolist()]
            t = 0
            while t < len(ok):
                if ok[t]:
                    u = t
                    while u + 1 < len(ok) and ok[u + 1]:
                        u += 1
                    want.append((d, t, u))
                    t = u + 1
                else:
                    t += 1
        assert list(zip(doc.tolist(), start.tolist(), end.tolist())) == want


def test_document_numbers_outside_the_index_are_refused():
    """rows/segments and feature_matrix of a document number the index lacks raise (−1
    would read the row count as a first row)."""
    idx = index_from_matrices({"d": np.array([[0, 1, 1]], np.uint8)}, ["a"], {"g": ["a"]})
    g = idx.groups["g"]
    assert g.rows(0) == range(0, 2) and idx.feature_matrix(0).tolist() == [[0, 1, 1]]
    for d in (1, -1):
        with pytest.raises(MtannoError, match=rf"document number {d} outside 0\.\.0"):
            g.segments(d)
        with pytest.raises(MtannoError, match=rf"document number {d} outside 0\.\.0"):
            idx.feature_matrix(d)


# --- files, manifest, incremental updates ------------------------------------------------

def _write_docs(folder, docs, feature_set=MRC05):
    folder.mkdir(parents=True, exist_ok=True)
    meta = {"feature_set": feature_set.name, "feature_set_version": feature_set.version,
            "analysis_fps": 30.0,
            "groups": {g: [feature_set.names[i] for i in r] for g, r in feature_set.groups.items()}}
    paths = []
    for name, X in docs.items():
        p = folder / f"{name}.parquet"
        write_features(p, X, feature_set.names, np.arange(X.shape[1]) * 4 + 1,
                       {**meta, "document": name})
        paths.append(p)
    return paths


@pytest.fixture
def feature_dir(tmp_path):
    rng = np.random.default_rng(11)
    docs = _random_docs(rng, 6, MRC05.names, frames=(20, 120), p=0.05)
    _write_docs(tmp_path / "feats", docs)
    return tmp_path / "feats"


def _strip(manifest):
    return {k: v for k, v in manifest.items() if k not in ("generation", "directory")}


def _same_index(a, b):
    ma, mb = storage.read_index_manifest(a), storage.read_index_manifest(b)
    assert _strip(ma) == _strip(mb)  # includes every file's SHA-256: byte-identical tables


def test_build_writes_manifest_and_tables(feature_dir, tmp_path):
    idx = build_index([feature_dir], tmp_path / "idx")
    m = json.loads((tmp_path / "idx" / "manifest.json").read_text())
    assert m["format"] == "mtanno.index/1" and m["feature_set"] == "mrc05"
    assert m["frame_rate"] == 30.0 and m["generation"] == 1
    assert list(m["groups"]) == ["lower", "upper", "mix"]
    assert [len(v) for v in m["groups"].values()] == [11, 12, 8]
    assert [d["name"] for d in m["documents"]] == [f"doc{i:02d}" for i in range(6)]
    assert all(len(d["sha256"]) == 64 for d in m["documents"])
    assert m["mtanno_version"]
    gen = tmp_path / "idx" / m["directory"]
    assert sorted(p.name for p in gen.iterdir()) == sorted(m["files"])
    again = open_index(tmp_path / "idx")
    for g in idx.groups:
        for attr in ("doc", "start", "length", "code", "doc_offsets", "list_codes",
                     "list_offsets", "postings", "seg_list"):
            assert np.array_equal(getattr(idx.groups[g], attr), getattr(again.groups[g], attr))
    assert again.documents == idx.documents


def test_incremental_add_remove_equals_rebuild(feature_dir, tmp_path):
    files = sorted(feature_dir.glob("*.parquet"))
    build_index(files, tmp_path / "full")
    build_index(files[:2], tmp_path / "inc")
    _, rep = add_documents(tmp_path / "inc", files[4:])
    assert rep.added == [f.stem for f in files[4:]]
    _, rep = add_documents(tmp_path / "inc", files[2:4] + files[:1])
    assert rep.added == [f.stem for f in files[2:4]] and rep.unchanged == [files[0].stem]
    _same_index(tmp_path / "full", tmp_path / "inc")
    assert storage.read_index_manifest(tmp_path / "inc")["generation"] == 3
    # remove two documents == rebuild without them
    remove_documents(tmp_path / "inc", [files[1].stem, str(files[4])])
    build_index(files[:1] + files[2:4] + files[5:], tmp_path / "rebuilt")
    _same_index(tmp_path / "rebuilt", tmp_path / "inc")
    # only one generation directory is kept
    assert len([p for p in (tmp_path / "inc").iterdir() if p.name.startswith("gen-")]) == 1


def test_add_replaces_changed_document(feature_dir, tmp_path):
    files = sorted(feature_dir.glob("*.parquet"))
    build_index(files, tmp_path / "idx")
    X = np.zeros((31, 9), dtype=np.uint8)
    X[6, 3:] = 1
    newdir = tmp_path / "new"
    _write_docs(newdir, {files[2].stem: X})
    idx, rep = add_documents(tmp_path / "idx", [newdir])
    assert rep.updated == [files[2].stem]
    assert np.array_equal(idx.feature_matrix(files[2].stem), X)
    build_index(files[:2] + [newdir / files[2].name] + files[3:], tmp_path / "rebuilt")
    _same_index(tmp_path / "rebuilt", tmp_path / "idx")


def test_custom_and_subset_groups(feature_dir, tmp_path):
    idx = build_index([feature_dir], None, groups=["upper"])
    assert list(idx.groups) == ["upper"]
    idx = build_index([feature_dir], None, groups={"knees": ["lknee_bent", "rknee_bent"]})
    assert idx.groups["knees"].features == ("lknee_bent", "rknee_bent")
    with pytest.raises(MtannoError, match="unknown group 'legs'"):
        build_index([feature_dir], None, groups=["legs"])
    with pytest.raises(MtannoError, match="unknown feature 'nose'"):
        build_index([feature_dir], None, groups={"x": ["nose"]})


def test_build_rejects_mixed_feature_sets_and_duplicates(feature_dir, tmp_path):
    ak = get_feature_set("ak40")
    other = tmp_path / "ak"
    _write_docs(other, {"zz": np.zeros((40, 5), np.uint8)}, ak)
    with pytest.raises(MtannoError, match="feature set 'mr06-ak40' differs from 'mrc05'"):
        build_index([feature_dir, other], None)
    build_index([feature_dir], tmp_path / "idx")
    with pytest.raises(MtannoError, match="differs from 'mrc05'"):
        add_documents(tmp_path / "idx", [other])
    dup = tmp_path / "dup"
    _write_docs(dup, {"doc00": np.zeros((31, 5), np.uint8)})
    with pytest.raises(MtannoError, match="document name 'doc00' appears twice"):
        build_index([feature_dir, dup], None)
    with pytest.raises(MtannoError, match="not in the index"):
        remove_documents(tmp_path / "idx", ["nope"])
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "x.txt").write_text("x")
    with pytest.raises(MtannoError, match="not empty and holds no index"):
        build_index([feature_dir], tmp_path / "junk")


def test_crash_during_update_leaves_old_index(feature_dir, tmp_path, monkeypatch):
    files = sorted(feature_dir.glob("*.parquet"))
    build_index(files[:3], tmp_path / "idx")
    before = storage.read_index_manifest(tmp_path / "idx")
    real_replace = os.replace

    def crash_on_manifest(src, dst):
        if str(dst).endswith("manifest.json"):
            raise KeyboardInterrupt("simulated crash")
        return real_replace(src, dst)

    monkeypatch.setattr(storage.os, "replace", crash_on_manifest)
    with pytest.raises(KeyboardInterrupt):
        add_documents(tmp_path / "idx", files[3:])
    monkeypatch.setattr(storage.os, "replace", real_replace)
    assert storage.read_index_manifest(tmp_path / "idx") == before

    def entries():
        return sorted(p.name for p in (tmp_path / "idx").iterdir() if p.name != ".lock")

    assert entries() == ["gen-000001", "manifest.json"]  # nothing of the failed write is left
    assert [d.name for d in open_index(tmp_path / "idx").documents] == [f.stem for f in files[:3]]

    calls = []
    real_write = storage._write_table

    def crash_midway(table, path):
        calls.append(path)
        if len(calls) == 3:
            raise OSError("disk full")
        return real_write(table, path)

    monkeypatch.setattr(storage, "_write_table", crash_midway)
    with pytest.raises(MtannoError, match="cannot write the index: disk full"):
        add_documents(tmp_path / "idx", files[3:])
    monkeypatch.setattr(storage, "_write_table", real_write)
    assert storage.read_index_manifest(tmp_path / "idx") == before
    assert entries() == ["gen-000001", "manifest.json"]
    open_index(tmp_path / "idx")
    add_documents(tmp_path / "idx", files[3:])
    assert entries() == ["gen-000002", "manifest.json"]
    build_index(files, tmp_path / "full")
    _same_index(tmp_path / "full", tmp_path / "idx")


def test_corrupt_or_partial_index_is_reported(feature_dir, tmp_path):
    root = tmp_path / "idx"
    build_index([feature_dir], root)
    m = storage.read_index_manifest(root)
    seg = root / m["directory"] / "segments-lower.parquet"
    data = seg.read_bytes()
    seg.write_bytes(data[:-10])
    with pytest.raises(CorruptIndex, match="checksum differs"):
        open_index(root)
    seg.unlink()
    with pytest.raises(CorruptIndex, match="file missing"):
        open_index(root)
    (root / "manifest.json").unlink()
    with pytest.raises(CorruptIndex, match="partially written index: manifest.json is missing"):
        open_index(root)
    (root / "manifest.json").write_text("{not json")
    with pytest.raises(CorruptIndex, match="not valid JSON"):
        open_index(root)
    (root / "manifest.json").write_text(json.dumps({"format": "other/9"}))
    with pytest.raises(CorruptIndex, match="unsupported index format"):
        open_index(root)
    with pytest.raises(MtannoError, match="not an index directory"):
        open_index(feature_dir)
    with pytest.raises(MtannoError, match="index directory not found"):
        open_index(tmp_path / "nothing")


def test_consistent_tables_with_wrong_content_are_reported(feature_dir, tmp_path):
    # a manifest that matches its files but whose segments do not cover the documents
    root = tmp_path / "idx"
    build_index([feature_dir], root)
    m = storage.read_index_manifest(root)
    gen = root / m["directory"]
    import pyarrow as pa
    import pyarrow.parquet as pq

    t = pq.read_table(gen / "segments-upper.parquet")
    t = t.set_column(3, "length", pa.array(np.ones(t.num_rows, dtype=np.int32)))
    m["files"]["segments-upper.parquet"] = storage._write_table(t, gen / "segments-upper.parquet")
    (root / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(CorruptIndex, match="group 'upper' segments do not cover"):
        open_index(root)


# --- reference implementation: index segments of the 44 dev clips (keyframes/README.md) ----

def _reference_segments(name):
    rows = list(csv.DictReader((REFERENCE / "keyframes" / f"index_segments_{name}.csv").open()))
    out: dict[int, list] = {}
    for r in rows:
        out.setdefault(int(r["doc_index"]), []).append(
            (int(r["segment"]), int(r["code"]), int(r["frame_start30"]), int(r["frame_length30"])))
    return out


def test_segments_match_reference_index(tmp_path):
    require_data()
    from mtanno.features.batch import plan_batch, run_batch

    docs = list(csv.DictReader((REFERENCE / "retrieval" / "concat_doc.csv").open()))
    amcs = [HDM05 / d["class"] / f"{d['clip']}.amc" for d in docs]
    summary = run_batch(plan_batch(amcs, tmp_path / "f"), n_jobs=1)
    assert summary.count("written") == 44
    ak = get_feature_set("ak40")
    groups = {"AK_upper": ak.names[0:14], "AK_lower": ak.names[14:26],
              "AK_mix_avr": ak.names[26:40], "AK_mix": ak.names[26:39]}
    idx = build_index([tmp_path / "f"], tmp_path / "idx", groups=groups)
    expected_counts = {"AK_upper": 877, "AK_lower": 562, "AK_mix_avr": 604, "AK_mix": 582}
    for gname, count in expected_counts.items():
        ref = _reference_segments(gname)
        g = idx.groups[gname]
        assert g.n_segments == count
        for d in docs:
            n = idx.doc_number(d["clip"])
            start, length, code = g.segments(n)
            got = [(i + 1, int(c), int(s) + 1, int(ln))
                   for i, (s, ln, c) in enumerate(zip(start, length, code))]
            assert got == ref[int(d["doc_index"])], (gname, d["clip"])


@settings(max_examples=100, deadline=None)
@given(st.lists(st.lists(st.integers(0, 3), max_size=12), min_size=1, max_size=5))
def test_batch_segmentation_equals_per_document(docs):
    from mtanno.index.core import doc_segments, segment_documents

    names = ["a", "b"]
    mats = [np.array([[c & 1 for c in d], [c >> 1 for c in d]], np.uint8).reshape(2, -1)
            for d in docs]
    groups = {"g": ["a", "b"], "h": ["b"]}
    batch = segment_documents(mats, names, groups)
    for X, got in zip(mats, batch):
        want = doc_segments(X, names, groups)
        for g in groups:
            for a, b in zip(got[g], want[g]):
                assert a.tolist() == b.tolist()
