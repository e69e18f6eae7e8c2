"""Cron safety (issue 12): commands that write into a folder hold its lock; a second run
exits with code 3 naming the holder, or waits with --wait; a lock of a dead process is
taken over; nothing is lost."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading

import pytest
from held import lines_until
from world import cli

from mtanno.util.locks import EXIT_BUSY, LockBusy, folder_lock

MTANNO = [sys.executable, "-c", "import sys; from mtanno.cli import main; "
          "sys.exit(main(prog_name='mtanno'))"]
#: Generous bound on waiting for another process (a hung run fails instead of hanging).
HANG = 120.0


def test_second_holder_is_refused_with_the_holder_named(tmp_path):
    with folder_lock(tmp_path / "out"):
        holder = json.loads((tmp_path / "out" / ".mtanno.lock").read_text())
        assert holder["pid"] == os.getpid() and holder["host"]
        with pytest.raises(LockBusy, match=f"locked by pid {os.getpid()} on "):
            with folder_lock(tmp_path / "out"):
                pass
    assert not (tmp_path / "out" / ".mtanno.lock").exists()  # removed when released
    assert LockBusy("x").exit_code == EXIT_BUSY == 3


def test_wait_takes_the_lock_when_it_is_released(tmp_path):
    order = []
    notes = []
    first, waiting = threading.Event(), threading.Event()

    def holder():
        with folder_lock(tmp_path):
            first.set()
            waiting.wait(HANG)  # release only once the second says it waits
            order.append("first done")

    def on_wait(note):
        notes.append(note)
        waiting.set()

    t = threading.Thread(target=holder)
    t.start()
    first.wait()
    with folder_lock(tmp_path, wait=True, on_wait=on_wait):
        order.append("second in")
    t.join()
    assert order == ["first done", "second in"]
    assert len(notes) == 1 and f"pid {os.getpid()}" in notes[0]


def test_lock_of_a_dead_process_is_taken_over(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    (tmp_path / ".mtanno.lock").write_text(json.dumps({"pid": int(dead), "host": "x"}))
    with folder_lock(tmp_path):  # the kernel's lock died with its holder
        assert json.loads((tmp_path / ".mtanno.lock").read_text())["pid"] == os.getpid()


def test_commands_exit_3_or_wait(world, tmp_path):
    idx = tmp_path / "idx"
    assert cli("index", world.docfeats, "-o", idx, "-q").exit_code == 0
    out = tmp_path / "feats"
    with folder_lock(idx, name=".lock", what="index"):
        r = cli("index", "add", idx, world.doc_files[0], "-q")
        assert r.exit_code == 3 and "index is locked by pid" in r.output
        with folder_lock(out):
            r = cli("features", world.clips, "-o", out, "-q")
            assert r.exit_code == 3 and f"{out}: output folder is locked" in r.output
            r = cli("learn-mt", "--manifest", world.manifest, "--features-dir", world.feats,
                    "-o", out, "-q")
            assert r.exit_code == 3
    # with --wait, a run started while the lock is held finishes once it is released
    with folder_lock(out):
        proc = subprocess.Popen([*MTANNO, "learn-mt", "--manifest", str(world.manifest),
                                 "--features-dir", str(world.feats), "-o", str(out), "-q",
                                 "--wait"], stderr=subprocess.PIPE, text=True)
        lines = lines_until(proc, "waiting for pid")  # it reached the lock and waits
        assert proc.poll() is None  # still waiting
    _, err = proc.communicate(timeout=HANG)
    assert proc.returncode == 0, "".join(lines) + err
    assert sorted(p.name for p in out.glob("*.json"))


def test_two_index_adds_started_together(world, tmp_path):
    idx = tmp_path / "idx"
    docs = world.doc_files
    assert cli("index", docs[0], "-o", idx, "-q").exit_code == 0
    procs = [subprocess.Popen([*MTANNO, "index", "add", str(idx), str(d), "-q"],
                              stderr=subprocess.PIPE, text=True) for d in docs[1:3]]
    codes = [p.wait(timeout=120) for p in procs]
    assert set(codes) <= {0, 3}, [p.stderr.read() for p in procs]
    from mtanno.index import open_index

    names = {d.name for d in open_index(idx).documents}
    assert docs[0].stem in names
    for d, c in zip(docs[1:3], codes):
        assert (d.stem in names) == (c == 0)  # what succeeded is there, nothing half done
