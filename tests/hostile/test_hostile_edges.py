"""Process edges (issue 22): what happens before the command runs and after it failed.

Signals in the first moments (while Python imports mtanno's dependencies) and during the
interpreter's shutdown, SIGHUP, a worker stopped while numba loads its kernels, an
interrupted ``tune``; a crash at exit after a corrupt index; option values that make no
sense (NaN, empty name lists, a scheduler address that is none). Each ends with exactly one
``mtanno:`` line and the exit code of the policy (docs/reliability.md): 130 for SIGINT and
SIGTERM, 129 for SIGHUP, 2 for a usage error or bad input.

The tests that send signals start the real command as a process and wait for an event
(a marker the entry point writes at a given moment, see ``MTANNO_TEST_MARK`` in
:mod:`mtanno.cli`), never for a fixed time.
"""

from __future__ import annotations

import shutil
import subprocess
import sys

#: The command as a user runs it: the console script's entry point.
MTANNO = [sys.executable, "-c", "import sys; from mtanno.cli import main; sys.exit(main())"]
#: Generous bound on a run (a hung run fails the test instead of hanging the suite).
HANG = 120.0


def _run(args, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([*MTANNO, *map(str, args)], capture_output=True, text=True,
                          timeout=HANG, **kw)


def _one_line(r: subprocess.CompletedProcess, code: int, text: str) -> str:
    """Exit ``code``, nothing on stderr but one ``mtanno:`` line holding ``text``."""
    lines = r.stderr.splitlines()
    assert r.returncode == code, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr, r.stderr
    assert len(lines) == 1 and lines[0].startswith("mtanno: ") and text in lines[0], r.stderr
    return lines[0]


# --------------------------------------------------------------------- crash at exit


def test_a_corrupt_index_never_aborts_the_process_at_exit(world, tmp_path):
    """A segment file cut short: "corrupt index" and exit 2, every time. (Arrow's dataset
    reader dropped its last reference to the file's bytes from one of its threads after
    the read returned; at interpreter exit that thread called std::terminate: SIGABRT,
    exit 134, in about one run of five.)"""
    idx = tmp_path / "idx"
    shutil.copytree(world.index, idx)
    seg = next(idx.glob("gen-*/segments-*.parquet"))
    seg.write_bytes(seg.read_bytes()[: seg.stat().st_size // 2])
    args = ["query", idx, "--example", world.doc_files[0].stem, "--features", "rknee_bent"]
    for _ in range(20):
        _one_line(_run(args), 2, "corrupt index")
