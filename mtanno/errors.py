"""The one exception type of mtanno.

Every error a user can cause (bad input file, unknown option value, missing joint in a
skeleton map) is raised as :class:`MtannoError`. Its string form is one line,
``path:line: what is wrong`` when a file position is known, so the command line prints it
as it is and never shows a traceback for user error.
"""

from __future__ import annotations


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
