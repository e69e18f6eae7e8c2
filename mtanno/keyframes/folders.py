"""Folders of keyframe query files (``CLASS.json`` from ``mtanno learn-keyframes``): the
files of a folder, the queries by class (two files of one class are an error), and the
queries a batch annotates or tunes with, checked against the templates' feature set and
frame rate.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from mtanno.errors import MtannoError
from mtanno.keyframes.model import KeyframeQuery
from mtanno.keyframes.store import load_keyframes

__all__ = ["keyframe_files", "load_class_keyframes", "load_keyframe_folder"]


def _load_folder(folder: str | os.PathLike) -> dict[str, tuple[Path, KeyframeQuery]]:
    """Class name → (file, query) of every keyframe file of ``folder`` (or of one file), in
    file order; two files of one class are an error."""
    p = Path(folder)
    if not p.exists():
        raise MtannoError("keyframe folder or file not found", path=str(p))
    paths = keyframe_files(p)
    if not paths:
        raise MtannoError("no keyframe files (*.json) in this folder", path=str(p))
    out: dict[str, tuple[Path, KeyframeQuery]] = {}
    for f in paths:
        q = load_keyframes(f)
        if q.class_name in out:
            raise MtannoError(f"class '{q.class_name}' has two keyframe files: "
                              f"{out[q.class_name][0]} and {f}")
        out[q.class_name] = (f, q)
    return out


def load_keyframe_folder(folder: str | os.PathLike) -> dict[str, KeyframeQuery]:
    """Class name → query of every ``*.json`` in ``folder`` (or of one file). Two files
    of one class are an error."""
    return {c: q for c, (_, q) in _load_folder(folder).items()}


def keyframe_files(folder: str | os.PathLike) -> list[Path]:
    """The keyframe files of a folder (``*.json``, sorted), or the one file given."""
    p = Path(folder)
    return sorted(p.glob("*.json")) if p.is_dir() else [p]


def load_class_keyframes(folder: str | os.PathLike, classes: Sequence[str], *,
                         feature_set: str, fps: float | None = None,
                         ) -> tuple[dict[str, KeyframeQuery], list[dict], list[str], list[str]]:
    """The keyframe queries of a folder for annotating ``classes``: (class → query for the
    classes that have one; the files read with their SHA-256, for provenance; classes
    without a query; queries of classes not among ``classes``). Queries must be for
    ``feature_set`` and, when ``fps`` is given (the templates' frame rate), at that rate:
    their gaps and extensions count frames at it."""
    from mtanno.util.provenance import sha256_file

    queries, files = {}, []
    for f, q in _load_folder(folder).values():
        if q.feature_set != feature_set:
            raise MtannoError(f"keyframes of class '{q.class_name}' are for feature set "
                              f"'{q.feature_set}' but the templates use '{feature_set}'",
                              path=str(f))
        if fps is not None and float(q.fps) != float(fps):
            raise MtannoError(f"keyframes of class '{q.class_name}' are at {q.fps:g} Hz but "
                              f"the templates at {float(fps):g} Hz", path=str(f))
        queries[q.class_name] = q
        if q.class_name in classes:
            files.append({"path": str(f), "sha256": sha256_file(f), "class": q.class_name})
    missing = [c for c in classes if c not in queries]
    extra = sorted(set(queries) - set(classes))
    return {c: queries[c] for c in classes if c in queries}, files, missing, extra
