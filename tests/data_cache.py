"""Unpack the shared data archives (``../shared/data/**/*.tar.xz``) into a local cache.

The shared data folder is read-only and must never be copied into the repository, so
archives are unpacked once into ``<repo>/.cache/data/<archive stem>/`` (the cache root holds
its own ``.gitignore`` with ``*``, so git never sees it). A marker file written after a
complete extraction makes repeated calls free; an interrupted extraction is redone.
Used by the tests and the benchmarks.
"""

from __future__ import annotations

import os
import shutil
import tarfile
import tempfile
from pathlib import Path

#: Project root (this file lives in ``<repo>/tests``).
REPO_ROOT = Path(__file__).resolve().parents[1]
#: Default cache root for unpacked archives.
CACHE_ROOT = REPO_ROOT / ".cache" / "data"
#: The read-only shared data folder beside the repository (``../shared/data``).
SHARED_DATA = REPO_ROOT.parent / "shared" / "data"

_MARKER = ".unpacked"
_ARCHIVE_SUFFIXES = (".tar.xz", ".tar.gz", ".tar.bz2", ".tgz", ".tar")


def archive_stem(archive: Path) -> str:
    """File name without the archive suffix: ``set1.tar.xz`` → ``set1``."""
    name = archive.name
    for suffix in _ARCHIVE_SUFFIXES:
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return archive.stem


def unpack_archive(archive: Path, cache_dir: Path | None = None) -> Path:
    """Unpack ``archive`` once into ``cache_dir/<archive stem>/`` and return that folder.

    Safe to call repeatedly and from concurrent processes: the archive is extracted into a
    temporary sibling folder which is renamed into place, and a marker file records a
    complete extraction. ``cache_dir`` defaults to ``<repo>/.cache/data``.
    """
    archive = Path(archive)
    cache_dir = Path(cache_dir) if cache_dir is not None else CACHE_ROOT
    target = cache_dir / archive_stem(archive)
    if (target / _MARKER).is_file():
        return target
    if not archive.is_file():
        raise FileNotFoundError(f"archive not found: {archive}")
    cache_dir.mkdir(parents=True, exist_ok=True)
    ignore = cache_dir.parent / ".gitignore" if cache_dir == CACHE_ROOT else None
    if ignore is not None and not ignore.exists():
        ignore.write_text("*\n")  # keep the whole cache out of git
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=cache_dir))
    try:
        with tarfile.open(archive) as tar:
            if hasattr(tarfile, "data_filter"):  # Python ≥ 3.10.12: refuse unsafe members
                tar.extractall(tmp, filter="data")
            else:  # pragma: no cover
                tar.extractall(tmp)  # noqa: S202
        (tmp / _MARKER).write_text(f"{archive.resolve()}\n")
        if target.exists():  # a previous, interrupted extraction (or a concurrent winner)
            if (target / _MARKER).is_file():
                return target
            shutil.rmtree(target)
        try:
            os.replace(tmp, target)
        except OSError:
            if not (target / _MARKER).is_file():  # lost a race to a concurrent extraction
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return target


def bandai_clips(archive_name: str, cache_dir: Path | None = None) -> list[Path]:
    """Sorted ``.bvh`` files of one Bandai archive (e.g. ``"set1.tar.xz"``), unpacked."""
    folder = unpack_archive(SHARED_DATA / "bandai" / archive_name, cache_dir)
    return sorted(folder.rglob("*.bvh"))
