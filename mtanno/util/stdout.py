"""Standard output that says so when it cannot be written: :func:`guarded_stdout`, which the
command line runs every command in, so that what a command prints (``click.echo``,
``print``: ``info``, ``show``, ``index info``, help texts) and fails on the device (a full
disk, ``/dev/full``) is one line, "cannot write to standard output: No space left on
device", as :func:`mtanno.util.output.write_stdout` says it for tables, instead of an error
naming nothing or a traceback.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from mtanno.errors import MtannoError

__all__ = ["guarded_stdout"]


class _GuardedStdout:
    """Standard output as :func:`guarded_stdout` hands it out: every attribute is the
    stream's own, but a failed ``write`` or ``flush`` (a full device, an I/O error) is one
    :class:`MtannoError` that says it was standard output. A closed pipe stays a
    :class:`BrokenPipeError` (the command's edge ends quietly then)."""

    def __init__(self, stream):
        self._stream = stream

    def _failed(self, exc: OSError) -> MtannoError:
        return MtannoError(f"cannot write to standard output: {exc.strerror or exc}")

    def write(self, text):
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise self._failed(exc) from None

    def writelines(self, lines) -> None:
        for line in lines:
            self.write(line)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise self._failed(exc) from None

    def __getattr__(self, name):
        return getattr(self._stream, name)


@contextlib.contextmanager
def guarded_stdout() -> Iterator[None]:
    """While inside, ``sys.stdout`` is a :class:`_GuardedStdout` of the stream it was (see
    the module docstring); the stream is put back on leaving."""
    import sys

    real = sys.stdout
    if real is None or isinstance(real, _GuardedStdout):
        yield
        return
    sys.stdout = _GuardedStdout(real)
    try:
        yield
    finally:
        if isinstance(sys.stdout, _GuardedStdout):
            sys.stdout = real
