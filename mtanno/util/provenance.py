"""The provenance of outputs (``docs/formats.md``): what every table, template and index
records about how it was made — mtanno version, command line, UTC time, the inputs with
their SHA-256 and the parameters that shaped it (:func:`provenance`). Tables carry it as
:mod:`mtanno.util.tables` writes them.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import os
import sys
from collections.abc import Iterable, Sequence
from typing import Any

from mtanno.errors import open_regular

__all__ = ["PROVENANCE_SCHEMA", "command_line", "file_record", "provenance",
           "set_command_line", "sha256_file", "utc_now"]

#: Schema name of the provenance object.
PROVENANCE_SCHEMA = "mtanno.provenance/1"

_COMMAND_LINE: list[str] | None = None


def sha256_file(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open_regular(path) as fh:  # a regular file: a FIFO would block (OSError else)
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def set_command_line(argv: Sequence[str]) -> None:
    """Record the command line that outputs will name in their provenance (the command
    line layer calls this; API users may)."""
    global _COMMAND_LINE
    _COMMAND_LINE = [str(a) for a in argv]


def command_line() -> list[str]:
    """The recorded command line, else this process's ``sys.argv``."""
    return list(_COMMAND_LINE) if _COMMAND_LINE is not None else list(sys.argv)


def file_record(path: str | os.PathLike, *, sha256: str | None = None) -> dict:
    """``{"path": ..., "sha256": ...}`` of an input file (hashed unless given)."""
    if sha256 is None:
        try:
            sha256 = sha256_file(path)
        except OSError:
            sha256 = None
    return {"path": str(path), "sha256": sha256}


def utc_now() -> str:
    """The time of a provenance's ``created``: UTC, ISO 8601, to the second."""
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def provenance(*, inputs: Iterable[dict | str | os.PathLike] = (),
               templates: Iterable[dict] = (), **params: Any) -> dict:
    """The provenance object of an output table: schema, mtanno version, command line, UTC
    time, ``inputs`` (file records, see :func:`file_record`; paths are hashed),
    ``templates`` (class, path, SHA-256) and the parameters that shaped the table (τ, δ,
    feature set, …, given as keywords; None values are left out)."""
    from mtanno._version import __version__

    recs = [i if isinstance(i, dict) else file_record(i) for i in inputs]
    out = {"schema": PROVENANCE_SCHEMA, "mtanno_version": __version__,
           "command": command_line(),
           "created": utc_now(),
           "inputs": recs}
    templates = list(templates)
    if templates:
        out["templates"] = templates
    out.update({k: v for k, v in params.items() if v is not None})
    return out
