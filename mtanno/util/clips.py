"""Clip manifests and frame ranges: the small inputs that name clips — a manifest of
clips with their class, actor and split (HDM05's ``clips.csv``; :func:`read_clip_manifest`,
the one manifest reader of ``learn-mt``, ``tune`` and ``compose``) and a ``--frames A:B``
range (:func:`parse_frame_range`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from mtanno.errors import MtannoError
from mtanno.util.tables import Table, parse_text, read_table

__all__ = ["ManifestRow", "parse_frame_range", "read_clip_manifest"]


@dataclass(frozen=True)
class ManifestRow:
    """One row of a clip manifest: ``file`` (relative path), ``class`` and the optional
    ``actor`` and ``split`` columns, with the line it was read from."""

    file: str
    label: str
    actor: str
    split: str
    line: int | None


def read_clip_manifest(path: str | os.PathLike) -> tuple[Table, list[ManifestRow]]:
    """Read a clip manifest (columns ``file,class[,actor,split,...]``, e.g. HDM05's
    ``clips.csv``): the one manifest reader of ``learn-mt`` and ``compose``. Every row
    needs a file (a relative path inside the data folder) and a class."""
    table = read_table(path, what="manifest")
    table.require(["file", "class"])
    out = []
    for i, row in enumerate(table.rows):
        f = parse_text(table, i, "file")
        label = parse_text(table, i, "class")
        rel = Path(f)
        if rel.is_absolute() or ".." in rel.parts:
            raise table.error(i, f"file {f!r} must be a relative path inside the data folder")
        out.append(ManifestRow(f, label, str(row.get("actor") or "").strip(),
                               str(row.get("split") or "").strip(), table.lines[i]))
    if not out:
        raise MtannoError("manifest lists no files", path=table.path)
    return table, out


def parse_frame_range(text: str | None, n: int) -> tuple[int, int] | None:
    """``'A:B'`` (1-based, inclusive, as every file gives frames; either side may be empty)
    → 0-based (a, b) inside a document of ``n`` frames; None for None (``--frames``)."""
    if text is None:
        return None
    a, sep, b = text.partition(":")
    try:
        lo = int(a) if a.strip() else 1
        hi = int(b) if b.strip() else n
    except ValueError:
        raise MtannoError(f"{{frames}} must be A:B with 1-based frame numbers, got '{text}'",
                          options=("frames",)) from None
    if not sep or lo < 1 or hi < lo or hi > n:
        raise MtannoError(f"{{frames}} {text} is not a range inside 1:{n}", options=("frames",))
    return lo - 1, hi - 1

