"""The index directory: Parquet tables per generation and an atomically replaced manifest.

Layout (``docs/index.md`` has the columns)::

    INDEX/
      manifest.json            what is in the index and which generation holds it
      gen-000007/
        documents.parquet      doc, name, sha256, frames, path
        groups.parquet         group, features, segments, lists
        segments-<group>.parquet   doc, segment, start, length, code (one row per F-segment)
        lists-<group>.parquet      code, rows (one row per inverted list L(code))

Frames, documents and segment numbers are 1-based in these files; ``rows`` are 0-based row
numbers of the group's segments table. An update writes a complete new generation
directory (files fsynced), renames it into place, then replaces ``manifest.json`` with
``os.replace`` (atomic), and only then deletes older generations: a crash at any point leaves
a manifest that names a complete generation, or, in the first build, a folder holding
nothing but the leftovers of that build (:func:`only_leftovers`), which the next build
takes and cleans. Every write point can be held for a test
(:func:`mtanno.util.pause.pause_at`: ``index-temporary``, ``index-table``,
``index-generation``, ``index-manifest``, ``index-switched``). Readers verify every file's size and SHA-256
against the manifest, so a damaged or half-copied index is reported, never half read.
Writers hold an exclusive ``fcntl`` lock on ``INDEX/.lock`` (released if the process dies).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from mtanno._version import __version__
from mtanno.errors import JSONError, MtannoError, read_input, read_json
from mtanno.index.core import Document, GroupIndex, Index
from mtanno.util.output import current_umask
from mtanno.util.pause import pause_at

INDEX_FORMAT = "mtanno.index/1"
MANIFEST = "manifest.json"
_GEN_PREFIX = "gen-"
_TMP_PREFIX = ".tmp-"


class CorruptIndex(MtannoError):
    """An index directory that cannot be read as a complete index."""


def write_lock(root: Path, *, wait: bool = False, on_wait=None):
    """Exclusive writer lock on ``root/.lock`` (:func:`mtanno.util.locks.folder_lock`: a dead
    process releases it; a busy index raises :class:`mtanno.util.locks.LockBusy`, exit code 3,
    naming the run that holds it, or waits with ``wait``)."""
    from mtanno.util.locks import folder_lock

    return folder_lock(root, wait=wait, what="index", name=LOCK_FILE, on_wait=on_wait)


def _fsync_dir(path: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _write_table(table: pa.Table, path: Path) -> dict:
    pq.write_table(table, path, compression="zstd")
    with open(path, "rb+") as fh:
        data = fh.read()
        os.fsync(fh.fileno())
    return {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def _text_column(values: list[str]) -> pa.Array:
    """A string column; or, when a value holds bytes of a file name that are not UTF-8
    (``os.fsdecode``'s surrogate escapes, which no Parquet string can hold), a binary
    column of the exact bytes (:func:`_texts` reads either back)."""
    try:
        return pa.array(values, pa.string())
    except (UnicodeEncodeError, pa.ArrowException):
        return pa.array([v.encode("utf-8", "surrogateescape") for v in values], pa.binary())


def _texts(column) -> list[str]:
    """The values of a column :func:`_text_column` wrote, as the names they were."""
    return [v.decode("utf-8", "surrogateescape") if isinstance(v, bytes) else v
            for v in column.to_pylist()]


def _tables(index: Index) -> dict[str, pa.Table]:
    docs = index.documents
    tables = {
        "documents.parquet": pa.table({
            "doc": pa.array(np.arange(1, len(docs) + 1, dtype=np.int32)),
            "name": _text_column([d.name for d in docs]),
            "sha256": pa.array([d.sha256 for d in docs], pa.string()),
            "frames": pa.array([d.frames for d in docs], pa.int32()),
            "path": _text_column([d.path for d in docs]),
        }),
        "groups.parquet": pa.table({
            "group": pa.array(list(index.groups), pa.string()),
            "features": pa.array([list(g.features) for g in index.groups.values()],
                                 pa.list_(pa.string())),
            "segments": pa.array([g.n_segments for g in index.groups.values()], pa.int64()),
            "lists": pa.array([g.n_lists for g in index.groups.values()], pa.int64()),
        }),
    }
    for name, g in index.groups.items():
        seg_no = np.arange(g.n_segments, dtype=np.int64) - np.repeat(
            g.doc_offsets[:-1], np.diff(g.doc_offsets))
        tables[f"segments-{name}.parquet"] = pa.table({
            "doc": pa.array(g.doc + 1),
            "segment": pa.array((seg_no + 1).astype(np.int32)),
            "start": pa.array(g.start + 1),
            "length": pa.array(g.length),
            "code": pa.array(g.code),
        })
        rows = pa.ListArray.from_arrays(pa.array(g.list_offsets.astype(np.int32)),
                                        pa.array(g.postings))
        tables[f"lists-{name}.parquet"] = pa.table({"code": pa.array(g.list_codes),
                                                    "rows": rows})
    return tables


def manifest_of(index: Index, generation: int, files: dict) -> dict:
    """The manifest JSON object of an index written as ``generation``."""
    return {
        "format": INDEX_FORMAT,
        "generation": generation,
        "directory": f"{_GEN_PREFIX}{generation:06d}",
        "mtanno_version": __version__,
        "feature_set": index.feature_set,
        "feature_set_version": index.feature_set_version,
        "features": list(index.features),
        "frame_rate": index.fps,
        "groups": {g.name: list(g.features) for g in index.groups.values()},
        "documents": [{"name": d.name, "sha256": d.sha256, "frames": d.frames, "path": d.path}
                      for d in index.documents],
        "totals": {"documents": len(index.documents), "frames": index.frames,
                   "segments": {g.name: g.n_segments for g in index.groups.values()}},
        "files": files,
    }


def read_index_manifest(root: Path) -> dict:
    """The manifest of the index in ``root`` (validated shape), or an error saying what is
    wrong with the directory."""
    path = root / MANIFEST
    if not root.is_dir():
        raise MtannoError("index directory not found", path=str(root))
    if not path.is_file():
        if any(p.name.startswith((_GEN_PREFIX, _TMP_PREFIX)) for p in root.iterdir()):
            raise CorruptIndex("partially written index: manifest.json is missing (a build "
                               "was stopped before it); build the index again",
                               path=str(root))
        raise MtannoError("not an index directory (no manifest.json)", path=str(root))
    try:
        manifest, _ = read_json(path, what="index manifest")
    except JSONError as exc:
        raise CorruptIndex(f"corrupt index: manifest.json is not valid JSON ({exc.message})",
                           path=str(path), line=exc.line) from None
    if not isinstance(manifest, dict) or manifest.get("format") != INDEX_FORMAT:
        fmt = manifest.get("format") if isinstance(manifest, dict) else None
        raise CorruptIndex(f"unsupported index format {fmt!r} (expected {INDEX_FORMAT})",
                           path=str(path))
    for key in ("directory", "files", "groups", "documents", "feature_set", "features"):
        if key not in manifest:
            raise CorruptIndex(f"corrupt index: manifest.json lacks '{key}'", path=str(path))
    shapes = {"directory": str, "files": dict, "groups": dict, "documents": list,
              "feature_set": str, "features": list}
    for key, kind in shapes.items():
        if not isinstance(manifest[key], kind):
            raise CorruptIndex(f"corrupt index: '{key}' in manifest.json must be a "
                               f"{kind.__name__}", path=str(path))
    for key, kind in (("generation", int), ("feature_set_version", int)):
        v = manifest.get(key, 0)
        if isinstance(v, bool) or not isinstance(v, kind) or v < 0:
            raise CorruptIndex(f"corrupt index: '{key}' in manifest.json must be an integer "
                               f"≥ 0, got {v!r}", path=str(path))
    fr = manifest.get("frame_rate", 30.0)
    if isinstance(fr, bool) or not isinstance(fr, (int, float)) or not fr > 0 \
            or fr == float("inf"):
        raise CorruptIndex(f"corrupt index: 'frame_rate' in manifest.json must be a positive "
                           f"number, got {fr!r}", path=str(path))
    from mtanno.features.compute import feature_set_mismatch

    wrong = feature_set_mismatch(manifest["feature_set"], manifest["features"])
    if wrong is not None:  # (a manifest edited or copied from another index)
        raise CorruptIndex(f"corrupt index: manifest.json: {wrong}", path=str(path))
    d = manifest["directory"]
    if "/" in d or "\\" in d or d in (".", "..") or not d.startswith(_GEN_PREFIX):
        raise CorruptIndex(f"corrupt index: 'directory' in manifest.json is {d!r}",
                           path=str(path))
    if not all(isinstance(e, dict) for e in manifest["files"].values()) or not all(
            isinstance(e, dict) and isinstance(e.get("name"), str)
            for e in manifest["documents"]):
        raise CorruptIndex("corrupt index: malformed 'files' or 'documents' in manifest.json",
                           path=str(path))
    return manifest


def _read_verified(gen_dir: Path, name: str, entry: dict) -> pa.Table:
    path = gen_dir / name
    if not path.exists() and not path.is_symlink():
        raise CorruptIndex("corrupt or partially written index: file missing", path=str(path))
    try:
        data = read_input(path, what="index file")  # a regular file: a FIFO would block
    except MtannoError as exc:
        raise CorruptIndex(f"corrupt index: {exc.message}", path=str(path)) from None
    if len(data) != entry.get("bytes") or hashlib.sha256(data).hexdigest() != entry.get("sha256"):
        raise CorruptIndex("corrupt index: file size or checksum differs from manifest.json",
                           path=str(path))
    try:
        # Read in this thread (as store.read_features does): pq.read_table's dataset
        # scanner may drop its last reference to ``data`` from an Arrow thread after it
        # returned, and that thread aborts the process (SIGABRT) if the interpreter is
        # shutting down by then — after a "corrupt index" error, say.
        return pq.ParquetFile(pa.BufferReader(data), pre_buffer=False).read(use_threads=False)
    except (pa.ArrowException, OSError, ValueError, IndexError) as exc:
        raise CorruptIndex(f"corrupt index: unreadable Parquet ({exc})", path=str(path)) from None


def _np(table: pa.Table, column: str, dtype) -> np.ndarray:
    return table.column(column).to_numpy().astype(dtype, copy=False)


def read_index(root: str | os.PathLike) -> Index:
    """Read and verify the index in ``root`` (see module docstring)."""
    root = Path(root)
    for attempt in range(2):  # a writer may replace the generation between our reads
        manifest = read_index_manifest(root)
        gen_dir = root / manifest["directory"]
        try:
            return _read_generation(root, gen_dir, manifest)
        except CorruptIndex:
            if attempt == 0 and read_index_manifest(root)["directory"] != manifest["directory"]:
                continue
            raise
    raise AssertionError("unreachable")  # pragma: no cover


def _read_generation(root: Path, gen_dir: Path, manifest: dict) -> Index:
    files = manifest["files"]
    where = str(root / MANIFEST)
    need = ["documents.parquet", "groups.parquet"]
    for g in manifest["groups"]:
        need += [f"segments-{g}.parquet", f"lists-{g}.parquet"]
    missing = [n for n in need if n not in files]
    if missing:
        raise CorruptIndex(f"corrupt index: manifest.json lists no {missing[0]}", path=where)
    t = {n: _read_verified(gen_dir, n, files[n]) for n in need}
    dt = t["documents.parquet"]
    docs = [Document(n, h, int(f), p) for n, h, f, p in zip(
        _texts(dt.column("name")), dt.column("sha256").to_pylist(),
        dt.column("frames").to_pylist(), _texts(dt.column("path")))]
    if [d["name"] for d in manifest["documents"]] != [d.name for d in docs]:
        raise CorruptIndex("corrupt index: documents.parquet and manifest.json disagree",
                           path=where)
    n_docs = len(docs)
    frames = np.array([d.frames for d in docs], dtype=np.int64)
    groups: dict[str, GroupIndex] = {}
    for g, feats in manifest["groups"].items():
        st, lt = t[f"segments-{g}.parquet"], t[f"lists-{g}.parquet"]
        doc = _np(st, "doc", np.int32) - 1
        start = _np(st, "start", np.int32) - 1
        length = _np(st, "length", np.int32)
        counts = np.bincount(doc, minlength=n_docs) if len(doc) else np.zeros(n_docs, np.int64)
        rows = lt.column("rows").combine_chunks()
        offsets = rows.offsets.to_numpy().astype(np.int64)
        postings = rows.values.to_numpy().astype(np.int32)
        ok = (len(counts) == n_docs and np.all(np.diff(doc) >= 0)
              and np.array_equal(np.bincount(doc, weights=length, minlength=n_docs)
                                 .astype(np.int64) if len(doc) else np.zeros(n_docs, np.int64),
                                 frames)
              and len(postings) == len(doc) and offsets[-1] == len(doc)
              and (len(postings) == 0 or (postings.min() >= 0 and postings.max() < len(doc))))
        if not ok:
            raise CorruptIndex(f"corrupt index: group '{g}' segments do not cover the documents",
                               path=str(gen_dir / f"segments-{g}.parquet"))
        groups[g] = GroupIndex(g, feats, doc, start, length, _np(st, "code", np.int64),
                               np.r_[0, np.cumsum(counts)].astype(np.int64),
                               _np(lt, "code", np.int64), offsets, postings)
    return Index(manifest["feature_set"], int(manifest.get("feature_set_version", 1)),
                 tuple(manifest["features"]), float(manifest.get("frame_rate", 30.0)), docs,
                 groups, root=root, generation=int(manifest.get("generation", 0)))


def write_index(index: Index, root: str | os.PathLike) -> Index:
    """Write ``index`` into ``root`` as a new generation and switch the manifest to it
    atomically; remove older generations afterwards. The caller holds :func:`write_lock`.
    Returns the index with ``root`` and ``generation`` set."""
    root = Path(root)
    try:
        return _write_index(index, root)
    except OSError as exc:
        raise MtannoError(f"cannot write the index: {exc.strerror or exc}",
                          path=str(exc.filename or root)) from None


def _write_index(index: Index, root: Path) -> Index:
    root.mkdir(parents=True, exist_ok=True)
    old_gen = 0
    if (root / MANIFEST).is_file():
        with contextlib.suppress(MtannoError):
            old_gen = int(read_index_manifest(root).get("generation", 0))
    existing = [int(p.name[len(_GEN_PREFIX):]) for p in root.glob(f"{_GEN_PREFIX}*")
                if p.name[len(_GEN_PREFIX):].isdigit()]
    gen = max([old_gen, *existing]) + 1
    final = root / f"{_GEN_PREFIX}{gen:06d}"
    tmp = Path(tempfile.mkdtemp(prefix=f"{_TMP_PREFIX}{final.name}-", dir=root))
    os.chmod(tmp, 0o777 & ~current_umask())  # mkdtemp's 0700 would hide a shared index
    mtmp, switched = None, False
    try:
        pause_at("index-temporary")
        files = {}
        for name, table in _tables(index).items():
            files[name] = _write_table(table, tmp / name)
            pause_at("index-table")
        _fsync_dir(tmp)
        os.replace(tmp, final)
        _fsync_dir(root)
        pause_at("index-generation")
        manifest = manifest_of(index, gen, files)
        fd, mtmp = tempfile.mkstemp(prefix=f"{_TMP_PREFIX}manifest-", dir=root)
        os.fchmod(fd, 0o666 & ~current_umask())
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(manifest, fh, indent=1)
            fh.write("\n")
            fh.flush()
            os.fsync(fh.fileno())
        pause_at("index-manifest")
        os.replace(mtmp, root / MANIFEST)
        mtmp, switched = None, True
        _fsync_dir(root)
        pause_at("index-switched")
    finally:  # after a failure or an interruption: nothing of this write is left
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
        if mtmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(mtmp)
        if not switched and final.exists():
            shutil.rmtree(final, ignore_errors=True)
    remove_leftovers(root, final.name)
    index.root, index.generation = root, gen
    return index


def remove_leftovers(root: Path, keep: str) -> None:
    """Remove every generation folder of the index in ``root`` but ``keep`` (the one its
    manifest names), and the leftovers of interrupted writes: what a write killed after
    switching the manifest, or before, leaves. The caller holds :func:`write_lock`."""
    for p in root.iterdir():
        if p.name != keep and p.name.startswith((_GEN_PREFIX, _TMP_PREFIX)):
            if p.is_dir():
                shutil.rmtree(p, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    p.unlink()


def index_files(root: str | os.PathLike) -> list[Path]:
    """The files of the index in ``root`` as it is now (manifest and current generation),
    for :func:`mtanno.util.preflight.check_outputs`; empty when there is no readable manifest."""
    root = Path(root)
    try:
        manifest = read_index_manifest(root)
    except MtannoError:
        return []
    gen = root / manifest["directory"]
    return [root / MANIFEST, *(gen / name for name in manifest["files"])]


def is_index_dir(root: Path) -> bool:
    return (root / MANIFEST).is_file()


#: The lock file of an index (:func:`write_lock`).
LOCK_FILE = ".lock"
_GEN_RE = re.compile(r"gen-\d{6}")
_TMP_RE = re.compile(r"\.tmp-(?:gen-\d{6}-|manifest-)[A-Za-z0-9_]+")
_GEN_FILE_RE = re.compile(r"(?:documents|groups|(?:segments|lists)-.+)\.parquet")


def only_leftovers(root: Path) -> bool:
    """True if folder ``root`` holds nothing but what an index write killed before its
    first manifest leaves: generation folders of index tables, the write's temporaries and
    the lock file. The next build takes such a folder (and removes them once its
    generation is in place), instead of refusing it as a folder holding something else."""
    try:
        entries = list(os.scandir(root))
    except OSError:
        return False
    for e in entries:
        if e.name == LOCK_FILE and e.is_file(follow_symlinks=False):
            continue
        if not e.is_dir(follow_symlinks=False):
            if _TMP_RE.fullmatch(e.name):
                continue
            return False
        if not (_GEN_RE.fullmatch(e.name) or _TMP_RE.fullmatch(e.name)):
            return False
        try:
            inside = list(os.scandir(e.path))
        except OSError:
            return False
        if not all(f.is_file(follow_symlinks=False) and _GEN_FILE_RE.fullmatch(f.name)
                   for f in inside):
            return False
    return True


def index_bytes(root: Path, manifest: dict) -> dict[str, int]:
    """Bytes on disk per file of the current generation (from the manifest)."""
    return {name: int(e["bytes"]) for name, e in manifest["files"].items()}


def group_sizes(index: Index) -> list[dict]:
    """Per group of an index (``index info``): features, frames, segments, inverted lists
    (and how many 2^f are possible), bytes on disk (segments and lists tables, from the
    manifest; 0 for an index in memory), bytes per segment and segments per frame."""
    files = read_index_manifest(index.root)["files"] if index.root is not None else {}
    rows = []
    for g in index.groups.values():
        size = sum(files.get(f"{k}-{g.name}.parquet", {}).get("bytes", 0)
                   for k in ("segments", "lists"))
        rows.append({"group": g.name, "features": len(g.features), "frames": index.frames,
                     "segments": g.n_segments, "lists": g.n_lists,
                     "possible_lists": 2 ** len(g.features), "bytes": size,
                     "bytes_per_segment": size / g.n_segments if g.n_segments else 0.0,
                     "segments_per_frame": g.n_segments / index.frames if index.frames else 0.0})
    return rows
