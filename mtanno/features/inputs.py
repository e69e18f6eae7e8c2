"""The feature files an input names: a file, or every ``*.parquet`` below a folder, with
one message per input that gives none (saying what a wrong folder holds instead: templates,
keyframe queries, motion files). Used by every command that reads feature files."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from mtanno.errors import MtannoError

__all__ = ["document_files", "document_files_below", "feature_files"]


def _found_feature_files(inputs: Iterable[str | os.PathLike], failures: list[str] | None = None,
                         ) -> list[tuple[Path, Path]]:
    """(file, its path below the folder it was found in — its name for a file given as
    such) for every feature file named by ``inputs`` (see :func:`feature_files`)."""
    out: list[tuple[Path, Path]] = []
    problems: list[MtannoError] = []
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            found, odd = [], []
            for q in sorted(p.rglob("*.parquet")):
                if q.is_file():
                    found.append(q)
                elif not q.is_dir():  # a FIFO (reading it would block), device, broken link
                    odd.append(q)
            problems += [MtannoError("not a regular file (a FIFO, device or broken link)",
                                     path=str(q)) for q in odd]
            if not found and not odd:
                problems.append(_not_a_feature_folder(p))
            out.extend((q, q.relative_to(p)) for q in found)
        elif p.is_file():
            out.append((p, Path(p.name)))
        elif p.exists() or p.is_symlink():
            problems.append(MtannoError("not a regular file (a FIFO, device or broken link)",
                                        path=str(p)))
        else:
            problems.append(MtannoError("no such feature file or folder", path=str(p)))
        if problems and failures is None:
            raise problems[0]
    if not out:
        raise problems[0] if problems else MtannoError("no feature files (*.parquet) in the "
                                                       "inputs")
    if failures is not None:
        failures.extend(str(e) for e in problems)
    return out


#: What a folder given for feature files holds instead, by the schema its JSON files name
#: (``"schema": "mtanno.template/1"``): the message and the parameter it belongs to.
_OTHER_FOLDERS = (
    (b'"mtanno.template/', "a folder of motion templates, not of feature files (give it to "
     "{mt})", "mt"),
    (b'"mtanno.keyframes/', "a folder of keyframe queries, not of feature files (give it to "
     "{keyframes})", "keyframes"),
)


def _not_a_feature_folder(folder: Path) -> MtannoError:
    """The error for a folder without feature files, saying what it holds instead when
    that is something mtanno knows (templates, keyframe queries, motion files)."""
    from mtanno.io import MOCAP_SUFFIXES  # (on this error path only: io loads numba)

    for q in sorted(folder.rglob("*"))[:1000]:
        if q.suffix.lower() == ".json" and q.is_file():
            with open(q, "rb") as f:
                head = f.read(4096)
            for mark, message, option in _OTHER_FOLDERS:
                if mark in head:
                    return MtannoError(message, path=str(folder), options=(option,))
        elif q.suffix.lower() in MOCAP_SUFFIXES:
            return MtannoError("a folder of motion files, not of feature files (make them "
                               "with `mtanno features` first)", path=str(folder))
    return MtannoError("no feature files (*.parquet) in this folder", path=str(folder))


def feature_files(inputs: Iterable[str | os.PathLike], *,
                  failures: list[str] | None = None) -> list[Path]:
    """Feature files named by ``inputs``: files as given, directories searched recursively
    for ``*.parquet`` (sorted). The one expansion of every command's feature inputs.

    An input that names no feature file — missing, a folder without feature files (also
    one named ``x.parquet``), a FIFO or other non-regular file given or found — is an
    error; with ``failures``, a batch goes on past it: its message is appended there and
    the others are returned. No feature file at all is an error either way (the first
    problem, naming its input)."""
    return [f for f, _ in _found_feature_files(inputs, failures)]


def document_files_below(inputs: Iterable[str | os.PathLike], *,
                         failures: list[str] | None = None) -> list[tuple[Path, Path]]:
    """:func:`document_files` with each file's path below the folder it was found in (its
    name for a file given as such): for outputs that mirror the inputs' tree
    (``annotate --output-dir``)."""
    out: list[tuple[Path, Path]] = []
    names: dict[str, Path] = {}
    seen: set[Path] = set()
    for p, rel in _found_feature_files(inputs, failures):
        key = p.resolve()
        if key in seen:  # the same file given twice (a folder and a file in it)
            continue
        seen.add(key)
        if p.stem in names:
            raise MtannoError(f"two feature files name the same document '{p.stem}': "
                              f"{names[p.stem]} and {p}")
        names[p.stem] = p
        out.append((p, rel))
    return out


def document_files(inputs: Iterable[str | os.PathLike], *,
                   failures: list[str] | None = None) -> list[Path]:
    """:func:`feature_files`, where no two files may name the same document (file stem):
    for commands whose outputs are keyed by document name."""
    return [p for p, _ in document_files_below(inputs, failures=failures)]
