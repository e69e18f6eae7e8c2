"""The test hook that holds a process at a known point: ``MTANNO_TEST_PAUSE=MOMENT:FILE``
makes :func:`pause_at` create FILE when the process reaches MOMENT and wait there for a
signal (which ends it, or is handled as it would be at that point). Tests of what a signal
or a kill does at a given moment use it instead of guessing a time. The moments are named
where :func:`pause_at` is called (``imports`` and ``shutdown``: :mod:`mtanno.__main__`;
``index-*``: :mod:`mtanno.index.storage`). Without the variable it does nothing.

Imports only :mod:`os` and :mod:`signal` (the program's entry point uses it before the
heavy imports).
"""

from __future__ import annotations

import os
import signal

__all__ = ["PAUSE_VARIABLE", "pause_at"]

#: The environment variable of the hook: ``MOMENT:FILE``.
PAUSE_VARIABLE = "MTANNO_TEST_PAUSE"


def pause_at(moment: str) -> None:
    """If ``MTANNO_TEST_PAUSE`` names ``moment``, create its FILE and wait for signals
    until one ends the process (a handler that raises ends the wait as well)."""
    want, _, marker = os.environ.get(PAUSE_VARIABLE, "").partition(":")
    if want != moment or not marker:
        return
    with open(marker, "w"):
        pass
    while True:
        signal.pause()
