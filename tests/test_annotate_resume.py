"""Resumable annotation (issue 12, item 1): ``annotate --output-dir`` writes one table per
document, skips the documents whose table is up to date, survives SIGINT and SIGKILL (the
rerun computes only what is missing, and the union equals an uninterrupted run), and holds
the output folder's lock against a second run; ``evaluate`` and ``report`` read the folder.

The killed and concurrent runs are real processes held at a known point (:mod:`held`): the
run stops before a given document until the test lets it go on, so the test signals it or
starts a second run while it is surely still running, however loaded the machine.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from held import held_pids, lines_until, release, start_held
from world import cli, temporaries, wait_for

from mtanno.annotate import annotation_files, load_annotation_setup
from mtanno.annotate.folder import DocJob, annotate_folder, plan_folder, recipe, up_to_date
from mtanno.errors import MtannoError
from mtanno.features.store import read_features, write_features
from mtanno.util.tables import provenance_as_read

#: The function each document goes through (held before a given document).
PER_DOCUMENT = "mtanno.annotate.batch:_annotate_file"
N_DOCS = 40
#: Generous bound for a run to get somewhere (a hung run fails instead of hanging the suite).
HANG = 120.0


@pytest.fixture(scope="module")
def archive(world, tmp_path_factory):
    """40 documents (the test world's two, rolled by different amounts), half of them in
    a subfolder: a batch of about a second without the delay."""
    d = tmp_path_factory.mktemp("archive") / "feats"
    for i in range(N_DOCS):
        ff = read_features(world.doc_files[i % 2])
        meta = {k: v for k, v in ff.meta.items() if k != "schema"}
        X = np.roll(ff.X, 13 * i, axis=1)
        sub = d / "sub" if i >= N_DOCS // 2 else d
        write_features(sub / f"doc{i:02d}.parquet", X, ff.names, ff.native_frames, meta)
    return d


@pytest.fixture(scope="module")
def reference(world, archive, tmp_path_factory):
    """The tables of an uninterrupted run."""
    out = tmp_path_factory.mktemp("reference") / "out"
    r = cli("annotate", "--mt", world.mt, archive, "--output-dir", out, "-q")
    assert r.exit_code == 0, r.output
    return out


def tables(out: Path) -> dict[str, bytes]:
    """Table files (not sidecars) below ``out`` by relative path, with their bytes."""
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*.csv"))}


def provenances(out: Path) -> dict[str, dict]:
    """Sidecars below ``out`` without what differs from run to run (time, command line)."""
    return {str(p.relative_to(out)): {k: v for k, v in json.loads(p.read_text()).items()
                                      if k not in ("created", "command")}
            for p in sorted(out.rglob("*.meta.json"))}


def complete(out: Path) -> int:
    """Tables with their provenance (a table renamed into place whose sidecar is not yet
    there is not up to date: it is recomputed)."""
    return sum(Path(str(p) + ".meta.json").is_file() for p in out.rglob("*.csv"))


def summary(output: str) -> str:
    return next(ln for ln in output.splitlines() if ln.startswith("annotate:"))


def start_held_run(args, gate: Path, *, after: int) -> subprocess.Popen:
    """``mtanno ARGS`` held before its document ``after + 1`` until ``gate`` exists."""
    return start_held(args, hold=PER_DOCUMENT, after=after, gate=gate)


# --------------------------------------------------------------------------- plan and API


def test_plan_mirrors_the_input_tree(archive, world, tmp_path):
    jobs = plan_folder([archive, world.doc_files[0]], tmp_path / "out", fmt="parquet")
    names = {j.doc: j.dst.relative_to(tmp_path / "out").as_posix() for j in jobs}
    assert names["doc00"] == "doc00.parquet" and names["doc39"] == "sub/doc39.parquet"
    assert names[world.doc_files[0].stem] == f"{world.doc_files[0].stem}.parquet"
    assert [j.doc for j in jobs] == sorted(j.doc for j in jobs)
    with pytest.raises(MtannoError, match="unknown table format 'xlsx'"):
        plan_folder([archive], tmp_path / "out", fmt="xlsx")
    # an output folder inside the input folder is judged with every other output, by
    # annotate_to (tests/hostile/test_hostile_outputs.py, "inside an input folder")
    assert plan_folder([archive], archive / "annotations", fmt="parquet")


def test_recipe_is_the_content_not_the_place():
    prov = {"schema": "mtanno.provenance/1", "mtanno_version": "0.1.0", "command": ["a"],
            "created": "now", "inputs": [{"path": "x", "sha256": "1"}], "documents": {"x": 3},
            "templates": [{"class": "b", "path": "/m/b.json", "sha256": "2"},
                          {"class": "a", "path": "/m/a.json", "sha256": "3"}],
            "classes": {"path": "c.toml", "sha256": "4"}, "tau": 0.13}
    moved = {**prov, "command": ["b"], "created": "later", "inputs": [],
             "templates": [{"class": "a", "path": "/n/a.json", "sha256": "3"},
                           {"class": "b", "path": "/n/b.json", "sha256": "2"}],
             "classes": {"path": "/elsewhere/c.toml", "sha256": "4"}}
    assert recipe(prov) == recipe(moved)
    for change in ({"tau": 0.2}, {"mtanno_version": "0.2.0"},
                   {"classes": {"path": "c.toml", "sha256": "5"}},
                   {"templates": [{"class": "b", "sha256": "2"}]}):
        assert recipe({**prov, **change}) != recipe(prov), change
    assert recipe({**prov, "templates": "garbage"}) is None
    assert recipe({**prov, "classes": ["x"]}) is None


def test_up_to_date_judges_the_recorded_provenance(world, tmp_path):
    feats = tmp_path / "feats"
    shutil.copytree(world.docfeats, feats)
    setup = load_annotation_setup(world.mt)
    jobs = plan_folder([feats], tmp_path / "out")
    first = annotate_folder(jobs, setup)
    assert [o.status for o in first.outcomes] == ["computed"] * 2
    again = annotate_folder(jobs, setup)
    assert [o.status for o in again.outcomes] == ["skipped"] * 2
    assert [o.sha256 for o in again.outcomes] == [o.sha256 for o in first.outcomes]
    assert [o.frames for o in again.outcomes] == [o.frames for o in first.outcomes]
    expected = recipe(provenance_as_read(setup.provenance()))
    job = jobs[0]
    assert up_to_date(job, expected) is not None
    # a table older than a template (or anything else it was made from) is out of date
    assert up_to_date(job, expected, not_before=time.time_ns() + 10**9) is None
    # ... and so is one whose sidecar is missing, unreadable, of another document or
    # another feature file
    side = Path(str(job.dst) + ".meta.json")
    saved = side.read_text()
    for text in ("", "[]", '{"templates": 5}',
                 saved.replace(f'"{job.doc}"', '"someone_else"'),
                 saved.replace(first.outcomes[0].sha256, "0" * 64)):
        side.write_text(text)
        assert up_to_date(job, expected) is None, text
    side.unlink()
    assert up_to_date(job, expected) is None
    side.write_text(saved)
    assert up_to_date(job, expected) is not None
    # a feature file that changed (same name, other content) is annotated again
    ff = read_features(job.src)
    meta = {k: v for k, v in ff.meta.items() if k != "schema"}
    write_features(job.src, 1 - ff.X, ff.names, ff.native_frames, meta)
    os.utime(job.src, ns=(0, 0))  # even with an old time stamp
    assert up_to_date(job, expected) is None
    # a job without an output
    assert up_to_date(DocJob(job.src, tmp_path / "nothing.csv"), expected) is None


def test_annotation_files_of_a_folder(reference, tmp_path):
    files = annotation_files([reference])
    assert len(files) == N_DOCS and all(f.endswith(".csv") for f in files)
    (reference / ".doc00.csv.host-1.abc.tmp").write_text("x")  # a temporary: skipped
    try:
        assert annotation_files([reference]) == files
    finally:
        (reference / ".doc00.csv.host-1.abc.tmp").unlink()
    (tmp_path / "empty").mkdir()
    with pytest.raises(MtannoError, match="no annotation tables"):
        annotation_files([tmp_path / "empty"])
    assert annotation_files(["-", "x.csv"]) == ["-", "x.csv"]


# --------------------------------------------------------------------------- command line


def test_output_dir_and_table_together(world, archive, reference, tmp_path):
    single = tmp_path / "single.csv"
    assert cli("annotate", "--mt", world.mt, archive, "-o", single, "-q").exit_code == 0
    out = tmp_path / "out"
    r = cli("annotate", "--mt", world.mt, archive, "--output-dir", out, "-o", tmp_path / "a.csv")
    assert r.exit_code == 0, r.output
    line = summary(r.output)
    assert f"{N_DOCS} documents: {N_DOCS} computed" in line and "0 up to date" in line
    assert tables(out) == tables(reference) and provenances(out) == provenances(reference)
    # the table of all documents is the single-table output, also when assembled from
    # tables that were up to date
    assert (tmp_path / "a.csv").read_bytes() == single.read_bytes()
    r = cli("annotate", "--mt", world.mt, archive, "--output-dir", out, "-o", tmp_path / "b.csv")
    assert f"0 computed (0 segments), {N_DOCS} up to date" in summary(r.output)
    assert (tmp_path / "b.csv").read_bytes() == single.read_bytes()
    prov = json.loads((tmp_path / "b.csv.meta.json").read_text())
    assert len(prov["inputs"]) == N_DOCS and len(prov["documents"]) == N_DOCS
    assert all(i["sha256"] for i in prov["inputs"])
    # no lock file or temporary left
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".")) == []
    # the same tables from worker processes
    r = cli("annotate", "--mt", world.mt, archive, "--output-dir", tmp_path / "jobs2", "--jobs",
            "2", "-q")
    assert r.exit_code == 0, r.output
    assert tables(tmp_path / "jobs2") == tables(reference)


def test_what_makes_a_rerun_recompute(world, tmp_path):
    mt = tmp_path / "mt"
    shutil.copytree(world.mt, mt)
    feats = tmp_path / "feats"
    shutil.copytree(world.docfeats, feats)
    out = tmp_path / "out"

    def run(*extra):
        r = cli("annotate", "--mt", mt, feats, "--output-dir", out, *extra)
        assert r.exit_code == 0, r.output
        return int(summary(r.output).split(": ", 2)[2].split()[0])  # documents computed

    def age(*paths):  # as if the inputs had been edited long ago: only content counts
        for p in paths:
            os.utime(p, ns=(10**9, 10**9))

    assert run() == 2 and run() == 0
    assert run("--tau", "0.2") == 2 and run("--tau", "0.2") == 0 and run() == 2
    assert run("--delta", "0.1") == 2 and run() == 2
    assert run("--variant", "paper") == 2 and run("--single-label") == 2 and run() == 2
    assert run("--force") == 2
    # a template changed (same meaning, other bytes)
    tpl = mt / "squat.json"
    tpl.write_text(json.dumps(json.loads(tpl.read_text()), indent=2))
    age(tpl)
    assert run() == 2 and run() == 0
    # the templates moved elsewhere, unchanged (copied with their times): up to date
    moved = tmp_path / "moved" / "mt"
    shutil.copytree(mt, moved)
    r = cli("annotate", "--mt", moved, feats, "--output-dir", out)
    assert "0 computed" in summary(r.output)
    # a class configuration, then a change of it
    cfg = tmp_path / "classes.toml"
    cfg.write_text("[tau]\ndefault = 0.13\n")
    assert run("--classes", cfg) == 2 and run("--classes", cfg) == 0
    cfg.write_text("# edited\n[tau]\ndefault = 0.13\n")
    age(cfg)
    assert run("--classes", cfg) == 2
    # ... and a further template file it lists
    extra = tmp_path / "more" / "squat.2.json"
    shutil.copytree(mt, extra.parent)
    (extra.parent / "squat.json").rename(extra)
    cfg.write_text('[templates]\nsquat = ["more/squat.2.json"]\n')
    assert run("--classes", cfg) == 2 and run("--classes", cfg) == 0
    extra.write_text(json.dumps(json.loads(extra.read_text()), indent=3))
    age(extra, cfg)
    assert run("--classes", cfg) == 2
    prov = json.loads((out / f"{world.doc_files[0].stem}.csv.meta.json").read_text())
    assert prov["classes"]["sha256"] and prov["classes"]["path"] == str(cfg)
    assert {"class": "squat", "path": str(extra),
            "sha256": prov["templates"][-1]["sha256"]} == prov["templates"][-1]
    # a feature file touched (newer than its table) is annotated again
    os.utime(feats / world.doc_files[0].name)
    r = cli("annotate", "--mt", mt, feats, "--output-dir", out, "--classes", cfg)
    assert "1 computed" in summary(r.output) and "1 up to date" in summary(r.output)
    # another format is another set of tables
    r = cli("annotate", "--mt", mt, feats, "--output-dir", out, "--classes", cfg, "--format",
            "parquet")
    assert "2 computed" in summary(r.output)
    assert len(list(out.glob("*.parquet"))) == 2 and len(list(out.glob("*.csv"))) == 2
    r = cli("annotate", "--mt", mt, feats, "--output-dir", out, "--classes", cfg, "--format",
            "parquet")
    assert "0 computed" in summary(r.output)


def test_a_bad_document_is_reported_and_the_others_written(world, tmp_path):
    feats = tmp_path / "feats"
    shutil.copytree(world.docfeats, feats)
    (feats / "broken.parquet").write_bytes(b"not parquet")
    out = tmp_path / "out"
    for _ in range(2):  # the rerun reports it again and skips the others
        r = cli("annotate", "--mt", world.mt, feats, "--output-dir", out)
        assert r.exit_code == 1
        assert [ln for ln in r.output.splitlines() if ln.startswith("mtanno:")] == [
            ln for ln in r.output.splitlines() if "broken.parquet" in ln]
        assert "1 failed" in summary(r.output)
    assert "2 up to date" in summary(r.output)
    assert sorted(p.name for p in out.glob("*.csv")) == sorted(
        f"{p.stem}.csv" for p in world.doc_files)


def test_usage_errors(world, tmp_path):
    doc = world.doc_files[0]
    r = cli("annotate", "--mt", world.mt, doc)
    assert r.exit_code == 2 and "give -o TABLE" in r.output
    for flag in (["--format", "csv"], ["--force"], ["--wait"]):
        r = cli("annotate", "--mt", world.mt, doc, "-o", tmp_path / "a.csv", *flag)
        assert r.exit_code == 2 and f"{flag[0]} goes with --output-dir" in r.output
    # the same file named twice: as a document's table and as -o
    r = cli("annotate", "--mt", world.mt, doc, "--output-dir", tmp_path / "o", "-o",
            tmp_path / "o" / f"{doc.stem}.csv")
    assert r.exit_code == 2 and "named twice" in r.output
    # a folder of feature files is not an output folder for Parquet tables
    r = cli("annotate", "--mt", world.mt, world.docfeats, "--output-dir", world.docfeats,
            "--format", "parquet")
    assert r.exit_code == 2 and "output would overwrite an input" in r.output
    assert not (tmp_path / "o").exists()


def test_evaluate_and_report_read_a_folder(world, archive, reference, tmp_path):
    single = tmp_path / "single.csv"
    assert cli("annotate", "--mt", world.mt, archive, "-o", single, "-q").exit_code == 0
    truth = tmp_path / "truth.csv"  # the world's truth for the documents at roll 0
    truth.write_text("doc,start,end,label\ndoc00,1,40,squat\ndoc01,1,40,squat\n")
    a = cli("evaluate", reference, "--truth", truth, "--json", tmp_path / "a.json")
    b = cli("evaluate", single, "--truth", truth, "--json", tmp_path / "b.json")
    assert a.exit_code == b.exit_code == 0, a.output
    assert a.output == b.output

    def scores(p):
        return {k: v for k, v in json.loads(p.read_text()).items() if k != "provenance"}

    assert scores(tmp_path / "a.json") == scores(tmp_path / "b.json")
    assert len(json.loads((tmp_path / "a.json").read_text())["documents"]) == N_DOCS
    # a truth segment past the end of a document is noticed from the per-document tables
    truth.write_text("doc,start,end,label\ndoc00,1,100000,squat\n")
    r = cli("evaluate", reference, "--truth", truth)
    assert r.exit_code == 2 and "doc00" in r.output
    pytest.importorskip("matplotlib", reason="the 'plot' extra is not installed")
    out = tmp_path / "ann"
    assert cli("annotate", "--mt", world.mt, world.docfeats, "--output-dir", out,
               "-q").exit_code == 0
    r = cli("report", out, "--truth", world.truth, "-o", tmp_path / "report", "-q")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "report" / "index.html").is_file()


# --------------------------------------------------------------------------- interrupted


@pytest.mark.parametrize("name", ["SIGINT", "SIGKILL"])
def test_killed_run_resumes_with_the_missing_documents(world, archive, reference, tmp_path,
                                                       name):
    out = tmp_path / "out"
    gate = tmp_path / "gate"
    proc = start_held_run(["annotate", "--mt", world.mt, archive, "--output-dir", out], gate,
                          after=8)
    try:  # held before its ninth document: 8 tables written, the run still going
        wait_for(lambda: complete(out) >= 8 and held_pids(gate), proc, "8 tables written")
        proc.send_signal(getattr(signal, name))
        _, err = proc.communicate(timeout=HANG)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    if name == "SIGKILL":
        assert proc.returncode == -signal.SIGKILL
    else:
        assert proc.returncode == 130, err
        assert err.strip().splitlines()[-1].startswith("mtanno: interrupted (SIGINT)")
        assert temporaries(out) == [] and not (out / ".mtanno.lock").exists()
    done = complete(out)
    assert done == 8
    r = cli("annotate", "--mt", world.mt, archive, "--output-dir", out)
    assert r.exit_code == 0, r.output
    assert f"{N_DOCS - done} computed" in summary(r.output)
    assert f"{done} up to date" in summary(r.output)
    # the union is the uninterrupted run, and nothing of the killed run is left over
    assert tables(out) == tables(reference) and provenances(out) == provenances(reference)
    assert temporaries(out) == [] and not (out / ".mtanno.lock").exists()


# --------------------------------------------------------------------------- two runs


@pytest.mark.parametrize("wait", [False, True], ids=["exit 3", "--wait"])
def test_two_runs_on_one_folder(world, archive, reference, tmp_path, wait):
    """The first run is held after its first table, so the second meets its lock whatever
    the machine's load; it is let go once the second has exited (exit 3) or says it waits
    (--wait)."""
    out = tmp_path / "out"
    args = ["annotate", "--mt", world.mt, archive, "--output-dir", out]
    gate = tmp_path / "gate"
    first = start_held_run(args, gate, after=1)
    second = None
    try:
        wait_for(lambda: complete(out) >= 1 and held_pids(gate), first, "its first table")
        second = start_held_run([*args, *(["--wait"] if wait else [])], tmp_path / "never",
                                after=N_DOCS)
        seen = lines_until(second, "waiting for pid") if wait else []  # then it waits
        if not wait:
            _, err2 = second.communicate(timeout=HANG)  # refused while the first is held
        release(gate)
        _, err1 = first.communicate(timeout=HANG)
        if wait:
            _, rest = second.communicate(timeout=HANG)
            err2 = "".join(seen) + rest
    finally:
        for p in (first, second):
            if p is not None and p.poll() is None:
                p.kill()
                p.wait()
    assert first.returncode == 0, err1
    assert f"{N_DOCS} computed" in summary(err1)
    if wait:
        assert second.returncode == 0, err2
        assert "mtanno: waiting for pid" in err2
        assert f"0 computed (0 segments), {N_DOCS} up to date" in summary(err2)
    else:
        assert second.returncode == 3, err2
        lines = [ln for ln in err2.splitlines() if ln.startswith("mtanno:")]
        assert len(lines) == 1 and f"{out}: output folder is locked by pid {first.pid}" \
            in lines[0], err2
        assert "Traceback" not in err2
    assert tables(out) == tables(reference) and provenances(out) == provenances(reference)
    assert temporaries(out) == [] and not (out / ".mtanno.lock").exists()
