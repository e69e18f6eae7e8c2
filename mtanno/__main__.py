"""The ``mtanno`` program (console script and ``python -m mtanno``): the signal policy at the
edges of a command, before :mod:`mtanno.cli` and its heavy imports are loaded.

A command handles SIGINT, SIGTERM and SIGHUP through :func:`mtanno.util.workers.interruptible`
(temporary files removed, workers stopped, one line, exit 130 or 129). Outside it — while
Python imports click, numpy, numba and pyarrow (about a second), while Click parses the
command line, and after the command returned — the same signals are handled here: nothing
is being written then, so the handler prints the same one line and ends the process at
once. The handlers are the first thing this module sets, and the process ends with
:func:`os._exit` after doing what a normal interpreter shutdown would do (``atexit``
functions, flushing the output), so no late shutdown step runs with the default handlers
(Python restores them while it finalizes: SIGTERM then killed the process, exit −15), and
no library thread can abort the process while the interpreter is torn down.

This module imports only what is loaded already when it runs: os, signal, sys and
:mod:`mtanno.errors` (which the package imports), and the test hook
:mod:`mtanno.util.pause` (os and signal alone).
"""

from __future__ import annotations

import os
import signal
import sys

from mtanno.errors import interrupted_line  # (loaded already: the package imports it)
from mtanno.util.pause import pause_at

#: Exit codes of an interrupted command: 128 + the signal as shells report it, SIGTERM like
#: SIGINT ("interrupted"), SIGHUP its own.
EXIT_CODES = {"SIGINT": 130, "SIGTERM": 130, "SIGHUP": 129}

# Test hook (mtanno.util.pause): MTANNO_TEST_PAUSE=MOMENT:FILE makes the program create
# FILE at MOMENT (``imports``: handlers set, nothing imported yet; ``shutdown``: the command
# has returned) and wait there for a signal, so that tests can send one at that moment
# without guessing a time.


def _at_the_edge(signum, frame) -> None:
    # Nothing is being written outside a command: say so in one line and leave now.
    name = signal.Signals(signum).name
    try:
        os.write(2, (interrupted_line(name) + "\n").encode())
    finally:
        os._exit(EXIT_CODES.get(name, 128 + signum))


def install_edge_handlers() -> None:
    """Handle SIGINT, SIGTERM and SIGHUP outside a command (see the module docstring)."""
    for name in EXIT_CODES:
        signum = getattr(signal, name, None)
        if signum is not None:
            signal.signal(signum, _at_the_edge)


def _code(exc: SystemExit) -> int:
    """The exit status Python would give for ``sys.exit(exc.code)``."""
    if exc.code is None:
        return 0
    if isinstance(exc.code, int):
        return exc.code & 0xFF
    print(exc.code, file=sys.stderr)
    return 1


def _finish(code: int) -> None:
    """End the process as a normal shutdown would (``atexit`` functions, output flushed),
    then with :func:`os._exit`, so the edge handlers hold until the very end."""
    import atexit

    pause_at("shutdown")
    try:
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):  # a closed pipe (mtanno ... | head)
                pass
        os._exit(code)


def main() -> None:
    """Run the ``mtanno`` command line (:func:`mtanno.cli.main`) inside the edge policy."""
    install_edge_handlers()
    pause_at("imports")
    try:
        from mtanno.cli import main as cli_main

        cli_main(prog_name="mtanno")
        code = 0
    except SystemExit as exc:
        code = _code(exc)
    _finish(code)


if __name__ == "__main__":  # pragma: no cover
    main()
