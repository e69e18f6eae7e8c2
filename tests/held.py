"""Hold a real ``mtanno`` process at a known point, so that a test acts on it at that point
instead of guessing a time (issue 31: a test that assumes one process outruns another is a
flake on a loaded machine).

:data:`HELD_MTANNO` is the ``mtanno`` program (:func:`mtanno.__main__.main`, the console
script's entry) with one function of the package wrapped, as named by the environment
variable ``MTANNO_TEST_HOLD=module:function:N:GATE``: the first ``N`` calls of the function
in each process run as usual; every later call first creates ``GATE.held-<pid>`` and then
waits until the file ``GATE`` exists. Workers are forked from the main process, so they
inherit the wrapped function, and a function sent to them by name resolves to the wrapper.

A test starts the program with :func:`start_held`, waits for an event (:func:`held_pids`,
outputs written, a line printed) with :func:`world.wait_for`, acts (a signal, a second run),
and then lets the run go on with :func:`release` — the run cannot finish before the test
acted, however slow or loaded the machine is.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

HOLD_VARIABLE = "MTANNO_TEST_HOLD"

_PROGRAM = """if True:
    import functools, importlib, os, sys, time
    target, fn_name, n, gate = os.environ["MTANNO_TEST_HOLD"].rsplit(":", 3)
    module = importlib.import_module(target)
    original = getattr(module, fn_name)
    calls = {}  # by process: a forked worker starts its own count

    @functools.wraps(original)
    def held(*args, **kwargs):
        pid = os.getpid()
        calls[pid] = calls.get(pid, 0) + 1
        if calls[pid] > int(n) and not os.path.exists(gate):
            open(f"{gate}.held-{os.getpid()}", "w").close()
            while not os.path.exists(gate):  # until the test releases the run
                time.sleep(0.005)
        return original(*args, **kwargs)

    setattr(module, fn_name, held)  # sent to workers by name: they find the wrapper
    from mtanno.__main__ import main
    main()
"""

#: The ``mtanno`` program with a hold point (see the module docstring).
HELD_MTANNO = [sys.executable, "-c", _PROGRAM]


def start_held(args, *, hold: str, after: int, gate: Path, **popen) -> subprocess.Popen:
    """Start ``mtanno ARGS`` holding every call of ``hold`` (``"module:function"``) after
    the first ``after`` calls in each process until ``gate`` exists. Standard output and
    error are pipes (text) unless ``popen`` says otherwise; the process leads its own
    session, so that a test can signal its whole group."""
    env = {**os.environ, HOLD_VARIABLE: f"{hold}:{after}:{gate}"}
    options = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, "text": True,
               "start_new_session": True, "env": env, **popen}
    return subprocess.Popen([*HELD_MTANNO, *map(str, args)], **options)


def held_pids(gate: Path) -> list[int]:
    """The processes waiting at the hold point of ``gate`` (or that have waited there)."""
    return sorted(int(p.name.rsplit("-", 1)[1])
                  for p in gate.parent.glob(f"{gate.name}.held-*"))


def release(gate: Path) -> None:
    """Let every process held at ``gate`` go on."""
    gate.touch()


def lines_until(proc: subprocess.Popen, text: str, *, hang: float = 120.0) -> list[str]:
    """Read ``proc``'s standard error line by line until a line holds ``text`` (the event a
    test waits for, instead of a fixed sleep); the lines read. Fails if the process ends
    first or nothing comes within ``hang`` seconds."""
    import threading

    import pytest

    lines: list[str] = []
    found = threading.Event()

    def read():
        for line in proc.stderr:
            lines.append(line)
            if text in line:
                found.set()
                return

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(hang)
    if not found.is_set():
        proc.kill()
        pytest.fail(f"no line with {text!r} from the run: {''.join(lines)}")
    return lines
