"""Interruptions (issue 8): SIGINT, SIGTERM and SIGKILL to ``mtanno features --jobs 2`` and
``mtanno annotate --jobs 2`` while their workers are busy. Afterwards no process of the
run may be alive a second after the parent ended, no output may be partial (every output
file present reads as a complete file, none has a temporary left), and the rerun
completes. SIGINT and SIGTERM end the run with exit code 130 and one line.

These tests start real processes and send real signals. The runs are held at a known point
(:mod:`held`: each worker stops before a given document until released, which these tests
never do), so the signal always reaches a run that is still working, however loaded the
machine; no time limit is checked.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from held import held_pids, start_held
from world import build_world, children, temporaries

from mtanno import synthetic
from mtanno.features.store import read_features, write_features

MTANNO = [sys.executable, "-c", "import sys; from mtanno.cli import main; "
          "sys.exit(main(prog_name='mtanno'))"]


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"  # a zombie has ended


#: Generous bound on how long a run may take to get busy or to end after a signal (a hung
#: run fails the test instead of hanging the suite).
HANG = 120.0


def _wait_until(condition, proc, what: str) -> None:
    """Poll until ``condition()``; the run must still be going (else the test would not
    interrupt anything)."""
    deadline = time.monotonic() + HANG
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"the run did not get to '{what}' in {HANG:.0f} s")
        if proc.poll() is not None:
            out, err = proc.communicate()
            pytest.fail(f"the run ended (exit {proc.returncode}) before {what}: {err}")
        time.sleep(0.02)


def _interrupt(args, sig, ready, *, hold, gate, group=False, work=None):
    """Start mtanno ARGS with every worker held after some documents (``hold``: the
    function and how many calls go through, see :func:`held.start_held`; never released),
    wait for ``ready()`` and two workers, send ``sig`` (to the whole process group with
    ``group``, as Ctrl-C in a terminal does). Returns the exit code, the
    standard error and how much work the workers did after the parent ended: ``work()``
    (e.g. the outputs written) once they are gone, less its value when the parent ended
    (issue 8: workers die with their parent; no wall-clock bound, which a loaded machine
    would break: a worker that went on would keep writing)."""
    function, after = hold
    proc = start_held(args, hold=function, after=after, gate=gate)
    try:
        _wait_until(lambda: len(children(proc.pid)) >= 2, proc, "its workers started")
        _wait_until(ready, proc, "it was busy")
        workers = children(proc.pid)
        if group:
            os.killpg(proc.pid, sig)
        else:
            proc.send_signal(sig)
        try:
            _, err = proc.communicate(timeout=HANG)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the run did not end within {HANG:.0f} s of {sig!r}")
        at_end = work() if work else 0
        deadline = time.monotonic() + HANG
        while any(_alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not any(_alive(w) for w in workers), f"workers still running after {HANG} s"
        return proc.returncode, err, (work() if work else 0) - at_end
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


@pytest.fixture(scope="module")
def motion_batch(tmp_path_factory):
    """100 motion files (one long AMC and links to it): a few seconds of work."""
    d = tmp_path_factory.mktemp("motions")
    (d / "synth.asf").write_text(synthetic.asf_text())
    (d / "base.amc").write_text(synthetic.amc_text(3000, 1))
    for i in range(100):
        os.symlink("base.amc", d / f"m{i:03d}.amc")
    return d


CASES = [("SIGINT", False), ("SIGINT", True), ("SIGTERM", False), ("SIGKILL", False)]


@pytest.mark.parametrize("name,group", CASES, ids=["SIGINT", "Ctrl-C", "SIGTERM", "SIGKILL"])
def test_features_jobs_2(motion_batch, tmp_path, name, group):
    out = tmp_path / "out"
    sig = getattr(signal, name)
    written = lambda: len(list(out.glob("*.parquet")))  # noqa: E731
    code, err, after = _interrupt(
        ["features", motion_batch, "-o", out, "--jobs", "2"], sig,
        lambda: written() >= 3, hold=("mtanno.features.batch:_extract_one", 2),
        gate=tmp_path / "gate", group=group, work=written)
    # at most the file each worker was renaming into place when its parent ended
    assert after <= 2, f"the workers wrote {after} files after their parent ended"
    if sig == signal.SIGKILL:
        assert code == -signal.SIGKILL
    else:
        assert code == 130, err
        assert err.strip().splitlines()[-1].startswith(f"mtanno: interrupted ({name})")
        assert "Traceback" not in err
    done = sorted(out.glob("*.parquet"))
    assert 3 <= len(done) < 101
    for p in done:  # no partial output
        read_features(p)
    assert temporaries(out) == []
    r = subprocess.run([*MTANNO, "features", str(motion_batch), "-o", str(out), "--jobs", "2"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert f"{101 - len(done)} written" in r.stderr and f"{len(done)} up to date" in r.stderr
    assert len(list(out.glob("*.parquet"))) == 101 and temporaries(out) == []


@pytest.fixture(scope="module")
def long_documents(tmp_path_factory):
    """Templates of the test world and 12 long documents: seconds of annotation."""
    d = tmp_path_factory.mktemp("annotate")
    w = build_world(d / "world")
    ff = read_features(w.doc_files[0])
    meta = {k: v for k, v in ff.meta.items() if k != "schema"}
    X = np.tile(ff.X, (1, 400))
    long = d / "long"
    for i in range(12):
        write_features(long / f"d{i:02d}.parquet", X, ff.names, np.arange(1, X.shape[1] + 1),
                       {**meta, "native_frames": int(X.shape[1]),
                        "analysis_frames": int(X.shape[1])})
    return w.mt, long


@pytest.mark.parametrize("name,group", [c for c in CASES if c != ("SIGINT", False)],
                         ids=["Ctrl-C", "SIGTERM", "SIGKILL"])
def test_annotate_jobs_2(long_documents, tmp_path, name, group):
    mt, docs = long_documents
    out = tmp_path / "a.parquet"
    sig = getattr(signal, name)
    gate = tmp_path.parent / f"{tmp_path.name}.gate"  # outside the folder checked below
    code, err, _ = _interrupt(["annotate", "--mt", mt, docs, "-o", out, "--jobs", "2"],
                              sig, lambda: held_pids(gate), group=group, gate=gate,
                              hold=("mtanno.annotate.batch:_annotate_file", 1))
    assert code == (-signal.SIGKILL if sig == signal.SIGKILL else 130), err
    if sig != signal.SIGKILL:
        assert err.strip().splitlines()[-1].startswith(f"mtanno: interrupted ({name})")
    assert list(tmp_path.iterdir()) == []  # no partial output, no temporary
    r = subprocess.run([*MTANNO, "annotate", "--mt", str(mt), str(docs), "-o", str(out),
                        "--jobs", "2", "-q"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.parquet"]


def test_workers_stop_when_the_parent_dies_without_the_kernels_help(tmp_path):
    """The watchdog alone (no PR_SET_PDEATHSIG, as on systems other than Linux) stops a
    busy worker when its parent is killed."""
    script = tmp_path / "parent.py"
    busy = tmp_path / "busy"
    script.write_text(
        "import os, sys, time\n"
        "import mtanno.util.workers as w\n"
        f"HANG = {HANG}\n"
        "def task(path):\n"
        "    open(path, 'w').close()  # the worker is in its task\n"
        "    time.sleep(10 * HANG)  # far beyond the wait below: only the watchdog ends it\n"
        "w._set_parent_death_signal = lambda signum: False\n"
        "pool = w.WorkerPool(1)\n"
        f"pool.submit(task, {str(busy)!r})\n"
        "while not pool._pool._processes: time.sleep(0.01)\n"
        "print(*pool._pool._processes, flush=True)\n"
        "time.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    worker = int(proc.stdout.readline())
    assert _alive(worker)
    _wait_until(busy.exists, proc, "the worker was in its task")
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + HANG  # the event, not a wall-clock bound on the watchdog
    while _alive(worker) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not _alive(worker)
