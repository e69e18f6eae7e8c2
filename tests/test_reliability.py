"""Issue 8: one test (or more) per root cause, each through the command line or the one
helper that fixes the cause. The hostile-input suite (tests/hostile/) runs the broken
inputs of every kind over every command."""

from __future__ import annotations

import json
import os
import stat

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from world import assert_one_line, checksums, cli, temporaries

from mtanno.errors import MtannoError
from mtanno.features.store import read_features, write_features
from mtanno.util.output import _HOST, atomic_path, remove_stale_temporaries
from mtanno.util.preflight import check_outputs

# --------------------------------------------------------------------- 1: outputs = inputs


def _clobber_cases(w, tmp):
    """(command line, the input its output names) for every command that writes a file."""
    feat = w.copy(w.doc_files[0], tmp / "r.parquet")
    mt = w.copy(w.template, tmp / "squat.json")
    ann = w.copy(w.annotation, tmp / "a.csv")
    truth = w.copy(w.truth, tmp / "t.csv")
    labels = w.copy(w.labels, tmp / "labels.json")
    os.symlink(labels, tmp / "labels.csv")  # a table name that is the labels file
    return [
        (["retrieve", "--mt", mt, feat, "-o", feat], feat),
        (["annotate", "--mt", w.mt, feat, "-o", feat], feat),
        (["annotate", "--mt", w.mt, feat, "-o", tmp / "x.csv", "--classes", ann, "-o", ann],
         ann),
        (["query", w.index, "--example", feat, "--features", "rknee_bent", "-o", feat], feat),
        (["evaluate", ann, "--truth", truth, "--json", ann], ann),
        (["evaluate", ann, "--truth", truth, "-o", truth], truth),
        (["evaluate-retrieval", feat, "--mt", mt, "--truth", truth, "--json", truth], truth),
        (["truth", "mocap6", labels, "-o", tmp / "labels.csv"], tmp / "labels.csv"),
        (["mt", "quantize", mt, "--delta", "0.1", "-o", mt], mt),
        (["mt", "mirror", mt, "-o", mt], mt),
        (["mt", "scale", mt, "--factor", "0.6", "-o", mt], mt),
    ]


def test_an_output_that_is_an_input_is_refused_before_any_work(world, tmp_path):
    for args, victim in _clobber_cases(world, tmp_path):
        before = checksums(tmp_path)
        r = cli(*args)
        line = assert_one_line(r, victim, codes=(2,))
        assert "would overwrite an input" in line, (args, line)
        assert checksums(tmp_path) == before, args


def test_hard_and_symbolic_links_to_an_input_are_refused(world, tmp_path):
    feat = world.copy(world.doc_files[0], tmp_path / "r.parquet")
    os.link(feat, tmp_path / "hard.parquet")
    os.symlink(feat, tmp_path / "soft.parquet")
    before = checksums(tmp_path)
    for out in ("hard.parquet", "soft.parquet"):
        r = cli("retrieve", "--mt", world.template, feat, "-o", tmp_path / out)
        assert_one_line(r, tmp_path / out, codes=(2,))
    assert checksums(tmp_path) == before
    with pytest.raises(MtannoError, match="named twice"):
        check_outputs([tmp_path / "x.csv", tmp_path / "x.csv"], [])


def test_features_and_learn_mt_and_compose_refuse_their_inputs(world, tmp_path):
    clips = world.copy(world.clips, tmp_path / "clips")
    before = checksums(clips)
    # compose into the clips' folder would copy the ASF onto itself
    r = cli("compose", clips / "clips.csv", "--actor", "c", "-o", clips)
    assert r.exit_code == 2 and "would overwrite an input" in r.output
    # learn-mt whose class file is (a link to) the truth table it reads
    truth = world.copy(world.truth, tmp_path / "t.csv")
    (tmp_path / "m").mkdir()
    os.symlink(truth, tmp_path / "m" / "squat.json")
    r = cli("learn-mt", "--truth", truth, world.docfeats, "-o", tmp_path / "m")
    assert r.exit_code == 2 and "would overwrite an input" in r.output
    assert (tmp_path / "m" / "squat.json").is_symlink()
    assert checksums(clips) == before


# --------------------------------------------------------------------- 3: up to date
# (tests/test_cli.py::test_features_up_to_date_follows_the_recorded_provenance)

# --------------------------------------------------------------------- 4: unwritable


def _unwritable_cases(w, tmp):
    block = tmp / "file"
    block.write_text("a file, not a folder")
    out = block / "sub"
    feat = w.doc_files[0]
    return [
        ["features", w.docs, "-o", out],
        ["learn-mt", "--manifest", w.manifest, "--features-dir", w.feats, "-o", out],
        ["mt", "mirror", w.template, "-o", out / "m.json"],
        ["mt", "scale", w.template, "--factor", "1.6", "-o", out / "s.json"],
        ["mt", "quantize", w.template, "--delta", "0.1", "-o", out / "q.json"],
        ["retrieve", "--mt", w.template, feat, "-o", out / "h.csv"],
        ["annotate", "--mt", w.mt, feat, "-o", out / "a.csv"],
        ["evaluate", w.annotation, "--truth", w.truth, "--json", out / "e.json"],
        ["evaluate-retrieval", feat, "--mt", w.mt, "--truth", w.truth, "--json", out / "e.json"],
        ["compose", w.manifest, "--actor", "c", "--docs", "1", "-o", out],
        ["truth", "mocap6", w.labels, "-o", out / "t.csv"],
        ["index", feat, "-o", out],
        ["query", w.index, "--example", feat.stem, "--features", "rknee_bent", "-o",
         out / "q.csv"],
    ]


def test_an_unwritable_output_is_one_line_naming_it(world, tmp_path):
    for args in _unwritable_cases(world, tmp_path):
        r = cli(*args)
        line = assert_one_line(r, tmp_path / "file", codes=(2,))
        assert "internal error" not in line and "Traceback" not in r.output, line


def test_write_errors_of_the_file_system_are_one_error(tmp_path, monkeypatch):
    import mtanno.util.output as output

    def refuse(src, dst):
        raise PermissionError(13, "Permission denied", str(dst))

    monkeypatch.setattr(output.os, "replace", refuse)
    with pytest.raises(MtannoError, match="cannot write here: Permission denied") as e, \
            atomic_path(tmp_path / "x.csv") as tmp:
        tmp.write_text("x")
    assert str(e.value).startswith(str(tmp_path / "x.csv"))
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------- 8: temporaries


def test_stale_temporaries_of_dead_writers_are_removed(tmp_path):
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    stale = tmp_path / f".x.csv.{_HOST}-{dead}.abcd1234.tmp"
    live = tmp_path / f".x.csv.{_HOST}-{os.getppid()}.abcd1234.tmp"
    other_host = tmp_path / f".x.csv.otherhost-{dead}.abcd1234.tmp"
    mine = tmp_path / "x.csv.tmp"  # not a name mtanno gives its temporaries
    for p in (stale, live, other_host, mine):
        p.write_text("half")
    with atomic_path(tmp_path / "y.csv") as tmp:
        tmp.write_text("done")
    assert not stale.exists()
    assert live.exists() and other_host.exists() and mine.exists()
    assert remove_stale_temporaries(tmp_path, force=True) == []


def test_an_interrupted_write_leaves_no_temporary(tmp_path):
    with pytest.raises(KeyboardInterrupt), atomic_path(tmp_path / "x.parquet") as tmp:
        tmp.write_bytes(b"half")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("writer", ["atomic_path", "write_bytes"])
def test_an_interruption_as_the_temporary_is_created_leaves_none(tmp_path, monkeypatch, writer):
    """SIGINT or SIGTERM handled the moment open() has created the temporary file (before
    the writer holds its descriptor): the file is removed all the same."""
    import mtanno.util.output as output

    real = os.open

    def open_then_interrupt(path, flags, mode=0o777):
        os.close(real(path, flags, mode))
        raise KeyboardInterrupt

    monkeypatch.setattr(output.os, "open", open_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        if writer == "atomic_path":
            with atomic_path(tmp_path / "x.parquet") as tmp:
                tmp.write_bytes(b"never")
        else:
            output.write_bytes(tmp_path / "x.parquet", b"never")
    assert list(tmp_path.iterdir()) == []


def test_a_stopping_worker_ignores_a_second_sigterm():
    """The parent-death signal and the watchdog both send SIGTERM: the first unwinds the
    task, a second must not interrupt the unwinding (it would skip the removal of the
    task's temporary file)."""
    import subprocess
    import sys

    code = """if True:
        import os, signal, mtanno.util.workers as w
        signal.signal(signal.SIGTERM, w._worker_sigterm)
        w._IN_TASK = True
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(10 ** 6):
                pass
            print("not interrupted")
        except w.Interrupted:
            os.kill(os.getpid(), signal.SIGTERM)  # the second, during the unwinding
            for _ in range(10 ** 6):
                pass
            print("unwound")
    """
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=60)
    assert (r.returncode, r.stdout.strip()) == (0, "unwound"), r.stderr


def test_a_table_never_stands_beside_a_stale_provenance(tmp_path, monkeypatch):
    import mtanno.util.output as output
    from mtanno.util.tables import read_table, write_table

    out = tmp_path / "t.csv"
    write_table(out, pa.table({"a": [1]}), provenance={"run": 1})
    real = os.replace

    def interrupt_sidecar(src, dst):
        if str(dst).endswith(".meta.json"):
            raise KeyboardInterrupt
        return real(src, dst)

    monkeypatch.setattr(output.os, "replace", interrupt_sidecar)
    with pytest.raises(KeyboardInterrupt):
        write_table(out, pa.table({"a": [2]}), provenance={"run": 2})
    assert read_table(out).rows == [{"a": "2"}]
    assert not (tmp_path / "t.csv.meta.json").exists() and not temporaries(tmp_path)


# --------------------------------------------------------------------- 9: compose


def test_compose_with_a_missing_clip_writes_nothing(world, tmp_path):
    clips = world.copy(world.clips, tmp_path / "clips")
    victim = next(clips.glob("squat/*_c_*.amc"))
    victim.unlink()
    r = cli("compose", clips / "clips.csv", "--actor", "c", "-o", tmp_path / "out")
    line = assert_one_line(r, clips / "clips.csv", codes=(2,))
    assert "not found" in line and victim.name in line
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------- 10: umask


@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002])
def test_outputs_honour_the_umask(world, tmp_path, mask):
    old = os.umask(mask)
    try:
        assert cli("retrieve", "--mt", world.template, world.docfeats, "-o",
                   tmp_path / "h.csv", "-q").exit_code == 0
        assert cli("index", world.docfeats, "-o", tmp_path / "idx", "-q").exit_code == 0
        assert cli("features", world.docs, "-o", tmp_path / "f", "-q").exit_code == 0
    finally:
        os.umask(old)
    files = [tmp_path / "h.csv", tmp_path / "h.csv.meta.json", tmp_path / "idx" / "manifest.json",
             *(tmp_path / "f").glob("*.parquet")]
    gens = list((tmp_path / "idx").glob("gen-*"))
    files += [p for g in gens for p in g.iterdir()]
    for p in files:
        assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~mask, p
    for g in gens:
        assert stat.S_IMODE(g.stat().st_mode) == 0o777 & ~mask, g


# --------------------------------------------------------------------- 5: malformed files


def _feature_table(ff):
    cols = {"native_frame": pa.array(ff.native_frames.astype(np.int32))}
    for i, n in enumerate(ff.names):
        cols[n] = pa.array(ff.X[i].astype(bool))
    return pa.table(cols)


def _with_meta(table, meta):
    return table.replace_schema_metadata({b"mtanno": meta if isinstance(meta, bytes) else
                                          json.dumps(meta)})


def test_the_reader_refuses_malformed_feature_files_with_one_message(world, tmp_path):
    ff = read_features(world.doc_files[0])
    good = _feature_table(ff)
    meta = dict(ff.meta)
    nulls = good.set_column(3, ff.names[2], pa.array([None] + [True] * (good.num_rows - 1),
                                                     pa.bool_()))
    cases = {
        "null bools": (_with_meta(nulls, meta), "has 1 null value(s) (rows 1)"),
        "meta list": (_with_meta(good, [1, 2]), "must be a JSON object, got list"),
        "meta string": (_with_meta(good, json.dumps("x")), "must be a JSON object, got str"),
        "fps text": (_with_meta(good, {**meta, "analysis_fps": "fast"}), "analysis_fps"),
        "fps missing": (_with_meta(good, {k: v for k, v in meta.items()
                                          if k != "analysis_fps"}), "lacks analysis_fps"),
        "fps zero": (_with_meta(good, {**meta, "analysis_fps": 0}), "positive number"),
        "no set": (_with_meta(good, {**meta, "feature_set": None}), "feature_set"),
        "native null": (_with_meta(good.set_column(0, "native_frame", pa.array(
            [None] * good.num_rows, pa.int32())), meta), "native_frame' has"),
        "native float": (_with_meta(good.set_column(0, "native_frame", pa.array(
            [float("nan")] * good.num_rows)), meta), "not integer"),
        "native zero": (_with_meta(good.set_column(0, "native_frame", pa.array(
            np.zeros(good.num_rows, np.int32))), meta), "must be ≥ 1"),
        "bad version": (_with_meta(good, {**meta, "feature_set_version": "x"}), "integer"),
    }
    for name, (table, words) in cases.items():
        p = tmp_path / f"{name.replace(' ', '_')}.parquet"
        pq.write_table(table, p)
        with pytest.raises(MtannoError) as e:
            read_features(p)
        assert str(e.value).startswith(f"{p}: ") and words in str(e.value), (name, e.value)


# --------------------------------------------------------------------- 6, 7, 11: messages


def test_garbage_is_refused_with_one_line(world, tmp_path):
    feat = world.doc_files[0]
    doc = feat.stem
    # annotate --tau nan, unknown class names in a class configuration
    r = cli("annotate", "--mt", world.mt, feat, "-o", tmp_path / "a.csv", "--tau", "nan")
    assert r.exit_code == 2 and "--tau must be a number ≥ 0, got nan" in r.output
    cfg = tmp_path / "c.toml"
    cfg.write_text('[tau]\nsquatt = 0.1\n')
    r = cli("annotate", "--mt", world.mt, feat, "-o", tmp_path / "a.csv", "--classes", cfg)
    assert_one_line(r, cfg, codes=(2,))
    assert "unknown class(es) squatt" in r.output
    cfg.write_text('[superclasses]\nlegs = ["squat", "kik"]\n')
    r = cli("annotate", "--mt", world.mt, feat, "-o", tmp_path / "a.csv", "--classes", cfg)
    assert r.exit_code == 2 and "without a template: kik" in r.output
    # evaluate: start > end, --doc that matches nothing
    bad = tmp_path / "bad.csv"
    bad.write_text(f"doc,start,end,label\n{doc},9,3,squat\n")
    r = cli("evaluate", bad, "--truth", world.truth)
    assert "bad.csv:2: start 9 is after end 3" in assert_one_line(r, bad, codes=(2,))
    r = cli("evaluate", world.annotation, "--truth", world.truth, "--doc", "nosuchdoc")
    assert r.exit_code == 2 and "--doc nosuchdoc is in neither" in r.output
    # truth segments past a document's end (the annotation records the documents' lengths)
    frames = read_features(feat).X.shape[1]
    far = tmp_path / "far.csv"
    far.write_text(f"doc,start,end,label\n{doc},1,{frames + 500},squat\n")
    r = cli("evaluate", world.annotation, "--truth", far)
    assert "ends after its" in assert_one_line(r, far, codes=(2,))
    r = cli("evaluate-retrieval", feat, "--mt", world.mt, "--truth", far)
    assert "ends after its" in assert_one_line(r, far, codes=(2,))
    # truth mocap6: start > end, past the end, a label not in the class list, fps 0, a list
    for labels, words in [
        ({"fps": 120, "documents": {"d": {"frames": 9, "segments": [
            {"label": "a", "start": 5, "end": 2}]}}}, "not 1 ≤ start ≤ end"),
        ({"fps": 120, "documents": {"d": {"frames": 9, "segments": [
            {"label": "a", "start": 5, "end": 20}]}}}, "past the document's 9 frames"),
        ({"fps": 120, "classes": ["b"], "documents": {"d": {"frames": 9, "segments": [
            {"label": "a", "start": 1, "end": 2}]}}}, "not in the file's classes"),
        ({"fps": 0, "documents": {}}, "fps must be a positive number"),
        ([1, 2], "top level must be an object"),
    ]:
        p = tmp_path / "labels.json"
        p.write_text(json.dumps(labels))
        r = cli("truth", "mocap6", p, "-o", tmp_path / "t.csv")
        assert words in assert_one_line(r, p, codes=(2,)), (labels, r.output)
        assert not (tmp_path / "t.csv").exists()
    # compose with an empty class
    clips = world.copy(world.clips, tmp_path / "clips")
    text = (clips / "clips.csv").read_text().splitlines()
    row = text[1].split(",")
    row[2] = ""
    (clips / "clips.csv").write_text("\n".join([text[0], ",".join(row), *text[2:]]) + "\n")
    r = cli("compose", clips / "clips.csv", "-o", tmp_path / "docs")
    assert "clips.csv:2: empty class" in assert_one_line(r, clips / "clips.csv", codes=(2,))
    # a 120 Hz example against a 30 Hz index
    ff = read_features(feat)
    fast = tmp_path / "fast.parquet"
    meta = {k: v for k, v in ff.meta.items() if k != "schema"}
    write_features(fast, ff.X, ff.names, ff.native_frames, {**meta, "analysis_fps": 120.0})
    r = cli("query", world.index, "--example", fast, "--features", "rknee_bent")
    assert "frame rate 120 Hz differs from 30 Hz" in assert_one_line(r, fast, codes=(2,))


def test_tracebacks_of_the_issue_are_one_line(world, tmp_path):
    feat = world.doc_files[0]
    # huge but finite template weights
    mt = json.loads(world.template.read_text())
    mt["weights"][0] = 1e308
    heavy = tmp_path / "heavy.json"
    heavy.write_text(json.dumps(mt))
    r = cli("retrieve", "--mt", heavy, feat)
    assert "weights must be positive, finite and at most" in assert_one_line(r, heavy)
    # binary query file and compose manifest
    q = tmp_path / "q.json"
    q.write_bytes(b"\xff\xfe\x00\x01binary")
    r = cli("query", world.index, "--query", q)
    assert "binary" in assert_one_line(r, q, codes=(2,))
    m = tmp_path / "m.csv"
    m.write_bytes(b"file,class\n\xff\xfe,x\n")
    r = cli("compose", m, "-o", tmp_path / "o")
    assert "not a UTF-8" in assert_one_line(r, m, codes=(2,))
    # a truth end of 10**23
    t = tmp_path / "t.csv"
    t.write_text(f"doc,start,end,label\n{feat.stem},1,{10**23},squat\n")
    r = cli("evaluate", world.annotation, "--truth", t)
    assert "t.csv:2: end 100000000000000000000000 is too large" in assert_one_line(r, t)
    # non-numeric and NaN starts in an annotation table
    for start in ("x", "nan", ""):
        a = tmp_path / "a.csv"
        a.write_text(f"doc,start,end,label\n{feat.stem},{start},9,squat\n")
        r = cli("evaluate", a, "--truth", world.truth)
        assert "a.csv:2:" in assert_one_line(r, a, codes=(2,)), start
    # a non-integer generation in an index manifest
    idx = world.copy(world.index, tmp_path / "idx")
    man = json.loads((idx / "manifest.json").read_text())
    man["generation"] = "seven"
    (idx / "manifest.json").write_text(json.dumps(man))
    r = cli("index", "info", idx)
    assert "'generation' in manifest.json must be an integer" in \
        assert_one_line(r, idx / "manifest.json", codes=(2,))


def test_misleading_messages_are_fixed(world, tmp_path):
    ff = read_features(world.doc_files[0])
    meta = {k: v for k, v in ff.meta.items() if k != "schema"}
    # mixed frame rates: the odd file is named, whichever comes first
    odd = tmp_path / "a_odd.parquet"
    write_features(odd, ff.X, ff.names, ff.native_frames, {**meta, "analysis_fps": 120.0})
    good = world.copy(world.doc_files[1], tmp_path / "b_good.parquet")
    r = cli("index", odd, good, "-o", tmp_path / "idx")
    line = assert_one_line(r, odd, codes=(1,))
    assert "frame rate 120 Hz differs from 30 Hz" in line and str(good) not in line.split(":")[0]
    # reordered feature columns: say so, instead of "'mr06-ak40' but the templates use 'mr06-ak40'"
    order = list(range(len(ff.names)))
    order[0], order[1] = 1, 0
    swapped = tmp_path / "swapped.parquet"
    write_features(swapped, ff.X[order], [ff.names[i] for i in order], ff.native_frames, meta)
    r = cli("annotate", "--mt", world.mt, swapped, "-o", tmp_path / "x.csv")
    line = assert_one_line(r, swapped, codes=(1,))
    assert "feature 1 is" in line and "the same features in another order" in line
    # a truth fps of 0 is about fps, not a frame range
    t = tmp_path / "t.csv"
    t.write_text("doc,start,end,label,fps\nd,1,2,x,0\n")
    r = cli("evaluate", world.annotation, "--truth", t)
    assert "t.csv:2: fps must be a positive number" in assert_one_line(r, t)
    # line numbers count blank lines
    t.write_text("doc,start,end,label\n\nd,1,2,x\n\nd,5,x,x\n")
    r = cli("evaluate", world.annotation, "--truth", t)
    assert "t.csv:5: end must be an integer" in assert_one_line(r, t)
    # retrieve --tau inf: every hit, no internal message
    r = cli("retrieve", "--mt", world.template, world.doc_files[0], "--tau", "inf", "-q")
    assert r.exit_code == 0 and r.stdout.count("\n") > 1, r.output


# --------------------------------------------------------------------- 12: exit codes


def test_an_interruption_is_one_line_and_exit_130(world, tmp_path, monkeypatch):
    import mtanno.retrieve as retrieve

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(retrieve, "retrieve", interrupted)
    r = cli("retrieve", "--mt", world.template, world.docfeats, "-o", tmp_path / "h.csv")
    assert r.exit_code == 130
    assert r.output.splitlines() == ["mtanno: interrupted (SIGINT); finished outputs are "
                                     "complete, unfinished ones were not written"]
    assert list(tmp_path.iterdir()) == [] and not temporaries(tmp_path)
