"""A one-line note on standard error while numba compiles mtanno's kernels.

mtanno's kernels are compiled by numba on first use and cached on disk (``cache=True``),
so the first run after installing or upgrading spends 20–30 s compiling (most of it in
``mtanno features``) and later runs load the cache in well under a second. The command line
installs :class:`CompileNote` so that this pause is explained: numba reports every
compilation as a ``numba:compile`` event (a kernel found in the cache is not compiled and
sends none), and the note is printed at the first such event of an mtanno kernel — once per
command, also when the compiling happens in worker processes (they are forked from the
command and share its flag). A command run with ``-q``/``--quiet`` never prints it
(:func:`silence`: cron logs stay empty).
"""

from __future__ import annotations

import multiprocessing
import sys
from typing import TextIO

#: The note (not an ``mtanno:`` line: those are errors, one per bad input).
NOTE = ("note: compiling mtanno's numba kernels (first run after installing or upgrading, "
        "up to a minute; later runs use the cache)")

_installed: CompileNote | None = None


def _listener_base():
    from numba.core import event

    return event.Listener


class CompileNote(_listener_base()):
    """numba event listener that writes :data:`NOTE` to ``stream`` (standard error by
    default) at the first compilation of a function of a module whose name starts with
    ``prefix``. The flag saying it was written lives in shared memory, so forked worker
    processes do not repeat it."""

    def __init__(self, *, prefix: str = "mtanno", stream: TextIO | None = None):
        self.prefix = prefix
        self.stream = stream
        self._done = multiprocessing.get_context("fork").Value("b", 0)
        self._quiet = multiprocessing.get_context("fork").Value("b", 0)

    def set_quiet(self, quiet: bool) -> None:
        """Print nothing (``quiet``) or the note (the default) from now on, in this process
        and the workers it forks."""
        self._quiet.value = int(bool(quiet))

    def on_start(self, event) -> None:
        dispatcher = (event.data or {}).get("dispatcher")
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
        if not module.startswith(self.prefix):
            return
        with self._done.get_lock():
            if self._done.value or self._quiet.value:
                return
            self._done.value = 1
        stream = self.stream if self.stream is not None else sys.stderr
        stream.write(NOTE + "\n")
        stream.flush()

    def on_end(self, event) -> None:
        pass


def install_compile_note() -> CompileNote:
    """Register the process-wide :class:`CompileNote` (once; later calls return it)."""
    global _installed
    if _installed is None:
        from numba.core import event

        _installed = CompileNote()
        event.register("numba:compile", _installed)
    return _installed


def silence() -> None:
    """No note for the rest of the command (it runs with ``-q``/``--quiet``; the command
    line calls this while it parses the options, before any kernel is compiled)."""
    if _installed is not None:
        _installed.set_quiet(True)
