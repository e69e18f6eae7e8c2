"""The note on standard error while numba compiles mtanno's kernels (issue 9)."""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys

import numba
import pytest
from numba.core import event

from mtanno.util.jitnote import NOTE, CompileNote


def _function(module: str, k: int):
    src = f"def f(x):\n    return x + {k}\n"
    ns: dict = {}
    exec(src, ns)  # a fresh function each time: numba compiles it anew
    ns["f"].__module__ = module
    return numba.njit(ns["f"])


@pytest.fixture
def note(tmp_path):
    path = tmp_path / "stderr.txt"
    with path.open("a") as stream:
        listener = CompileNote(stream=stream)
        event.register("numba:compile", listener)
        try:
            yield path
        finally:
            event.unregister("numba:compile", listener)


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="no JIT, no compiling")
def test_note_once_for_mtanno_kernels_also_across_forked_workers(note):
    _function("other.package", 1)(1)
    assert note.read_text() == ""  # someone else's kernel: no note
    ctx = multiprocessing.get_context("fork")
    child = ctx.Process(target=lambda: _function("mtanno.fake", 2)(1))
    child.start()
    child.join()
    assert child.exitcode == 0
    assert note.read_text() == NOTE + "\n"  # the worker compiled first and said so
    _function("mtanno.fake", 3)(1)
    _function("mtanno.other", 4)(2.5)
    assert note.read_text() == NOTE + "\n"  # once per command


def test_cli_says_nothing_once_the_kernels_are_cached(world):
    """A command run a second time loads its kernels from numba's cache and prints no
    compile note (whether the first run compiled depends on what ran before it)."""
    cmd = [sys.executable, "-m", "mtanno.cli", "query", str(world.index), "--example",
           str(world.doc_files[0]), "--features", "rknee_bent", "-q"]
    for _ in range(2):
        r = subprocess.run(cmd, capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        assert r.stderr.count("compiling") <= 1
    assert "compiling" not in r.stderr
