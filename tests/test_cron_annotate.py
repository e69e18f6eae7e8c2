"""The cron recipe (issue 12, item 2): ``scripts/cron_annotate.sh INBOX/ WORK/`` on a tiny
synthetic inbox. The first run computes features, builds the index, annotates and writes
today's evaluation; the second does nothing new and exits 0; a run that finds another one
working ends quietly; a missing set-up is one log line and exit code 2."""

from __future__ import annotations

import datetime
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import mtanno
from mtanno.util.locks import folder_lock

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "cron_annotate.sh"
pytestmark = pytest.mark.skipif(shutil.which("bash") is None, reason="bash is not installed")


@pytest.fixture
def setup(world, tmp_path):
    """INBOX (the test world's composed documents: AMC, ASF, truth.csv), WORK with the
    world's templates, and an mtanno executable running this checkout."""
    inbox = world.copy(world.docs, tmp_path / "inbox")
    work = tmp_path / "work"
    world.copy(world.mt, work / "mt")
    exe = tmp_path / "bin" / "mtanno"
    exe.parent.mkdir()
    root = Path(mtanno.__file__).resolve().parents[1]
    exe.write_text("#!/bin/sh\n"
                   f"PYTHONPATH={root}${{PYTHONPATH:+:$PYTHONPATH}} exec {sys.executable} -c "
                   "\"import sys; from mtanno.cli import main; "
                   "sys.exit(main(prog_name='mtanno'))\" \"$@\"\n")
    exe.chmod(0o755)
    return inbox, work, exe


def run(inbox, work, exe):
    r = subprocess.run(["bash", str(SCRIPT), str(inbox), str(work)], capture_output=True,
                       text=True, env={**os.environ, "MTANNO": str(exe)}, timeout=300)
    lines = r.stdout.splitlines()
    assert all(" cron_annotate: " in ln for ln in lines), r.stdout
    return r, [ln.split(" cron_annotate: ", 1)[1] for ln in lines]


def test_two_runs(setup, world):
    inbox, work, exe = setup
    days = {datetime.date.today().isoformat()}
    r, log = run(inbox, work, exe)
    days.add(datetime.date.today().isoformat())
    assert r.returncode == 0, r.stdout + r.stderr
    n = len(world.doc_files)
    assert log[0].startswith(f"features: {n} written")
    assert log[1].startswith(f"index: {n} documents")
    assert log[2].startswith(f"annotate: {n} documents: {n} computed")
    assert log[3].startswith("evaluate: overall")
    assert log[4].startswith(f"evaluate: {n} documents with truth -> {work}/reports/")
    assert len(log) == 5
    reports = list((work / "reports").glob("*.json"))
    assert [p.stem for p in reports] == [p.stem for p in reports if p.stem in days] != []
    assert len(json.loads(reports[0].read_text())["documents"]) == n
    assert len(list((work / "annotations").glob("*.csv"))) == n
    # the second run finds nothing new
    r, log = run(inbox, work, exe)
    assert r.returncode == 0, r.stdout + r.stderr
    assert log[0].startswith(f"features: 0 written (0 frames at 30 Hz), {n} up to date")
    assert log[1].startswith(f"index add: 0 added, 0 updated, {n} unchanged")
    assert log[2].startswith(f"annotate: {n} documents: 0 computed (0 segments), {n} up to date")
    assert "Traceback" not in r.stderr


def test_a_run_that_finds_another_working_ends_quietly(setup):
    inbox, work, exe = setup
    with folder_lock(work / "annotations"):
        r, log = run(inbox, work, exe)
    assert r.returncode == 0, r.stdout + r.stderr
    assert log[0].startswith("features: ") and log[1].startswith("index: ")
    assert "output folder is locked by pid" in log[2]
    assert log[3] == "annotate: another run is working here; leaving the rest to it"
    assert len(log) == 4 and not (work / "reports").exists()


def test_set_up_errors_and_an_empty_inbox(setup, tmp_path):
    inbox, work, exe = setup
    empty = tmp_path / "empty"
    empty.mkdir()
    r, log = run(empty, work, exe)
    assert r.returncode == 0 and log == [f"features: no motion files in {empty} yet"]
    r, log = run(tmp_path / "missing", work, exe)
    assert r.returncode == 2 and log == [f"setup: {tmp_path / 'missing'} is not a folder"]
    shutil.rmtree(work / "mt")
    r, log = run(inbox, work, exe)
    assert r.returncode == 2 and log == [
        f"setup: no class templates in {work}/mt (mtanno learn-mt ... -o {work}/mt)"]
    assert not (work / "features").exists()


def test_a_bad_motion_file_fails_alone(setup, world):
    inbox, work, exe = setup
    (inbox / "SYN_c_broken.amc").write_text("not an AMC file\n")
    r, log = run(inbox, work, exe)
    assert r.returncode == 1, r.stdout + r.stderr
    assert any(ln.startswith("features: mtanno: ") and "SYN_c_broken.amc" in ln for ln in log)
    n = len(world.doc_files)
    assert any(ln.startswith(f"annotate: {n} documents: {n} computed") for ln in log)
    assert any(ln.startswith(f"evaluate: {n} documents with truth") for ln in log)


def test_the_recipe_with_a_tuned_configuration_moved_and_renamed(setup, world, tmp_path):
    """Issue 34: `tune -o DIR/` (a configuration that verifies segments by poses, with its
    bank, tuned elsewhere), moved and renamed to WORK/classes/: the recipe computes the
    features it needs (poses, by features --classes) and annotates every document with it."""
    from world import cli

    from mtanno.features.store import read_features

    inbox, work, exe = setup
    feats = tmp_path / "posed"
    assert cli("features", world.clips, "-o", feats, "--poses", "-q").exit_code == 0
    tuned = tmp_path / "elsewhere" / "tuned"
    r = cli("tune", "--mt", world.mt, "--manifest", world.manifest, "--features-dir", feats,
            "--split", "train", "-o", f"{tuned}/", "-q")
    assert r.exit_code == 0, r.output
    text = (tuned / "classes.toml").read_text()
    assert 'bank = "verify.parquet"' in text and "[inputs]" in text and "poses = true" in text
    shutil.move(tuned, work / "classes")  # moved and renamed as one
    r, log = run(inbox, work, exe)
    assert r.returncode == 0, r.stdout + r.stderr
    n = len(world.doc_files)
    assert log[2].startswith(f"annotate: {n} documents: {n} computed"), log
    for f in (work / "features").glob("*.parquet"):
        assert read_features(f, poses=True).poses is not None
    table = next((work / "annotations").glob("*.csv"))
    prov = json.loads(Path(f"{table}.meta.json").read_text())
    assert prov["classes"]["path"] == str(work / "classes" / "classes.toml")
    assert prov["confidence"]["bank"]["path"] == str(work / "classes" / "verify.parquet")
