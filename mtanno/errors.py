"""The one exception type of mtanno.

Every error a user can cause (bad input file, unknown option value, missing joint in a
skeleton map) is raised as :class:`MtannoError`. Its string form is one line,
``path:line: what is wrong`` when a file position is known, so the command line prints it
as it is and never shows a traceback for user error.
"""

from __future__ import annotations

import os
from pathlib import Path


class MtannoError(Exception):
    """An error caused by input a user can fix.

    Parameters
    ----------
    message:
        What is wrong, as one sentence without a trailing period.
    path:
        The file the error is about, if any.
    line:
        The 1-based line number in ``path``, if known.
    """

    def __init__(self, message: str, *, path: str | None = None, line: int | None = None):
        self.message = message
        self.path = None if path is None else str(path)
        self.line = line
        super().__init__(str(self))

    def __str__(self) -> str:
        if self.path is None:
            return self.message
        if self.line is None:
            return f"{self.path}: {self.message}"
        return f"{self.path}:{self.line}: {self.message}"


def read_input(path: str | os.PathLike, *, what: str = "file") -> bytes:
    """The bytes of an input file; a missing or unreadable file is a :class:`MtannoError`
    naming it (``what`` names the kind of file in the message)."""
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        raise MtannoError(f"{what} not found", path=str(path)) from None
    except OSError as exc:
        raise MtannoError(f"cannot read {what}: {exc.strerror or exc}", path=str(path)) from None


def read_text_input(path: str | os.PathLike, *, what: str = "file") -> bytes:
    """:func:`read_input` for a text format: also rejects an empty file and one with a NUL
    byte (binary), naming the line."""
    raw = read_input(path, what=what)
    if not raw or raw.isspace():  # (as ``not raw.strip()``, without copying the bytes)
        raise MtannoError("file is empty", path=str(path), line=1)
    nul = raw.find(b"\x00")
    if nul >= 0:
        raise MtannoError("binary data (NUL byte) in a text file", path=str(path),
                          line=raw[:nul].count(b"\n") + 1)
    return raw
