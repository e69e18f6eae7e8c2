"""Building and updating an index directory from feature files ([MRC05] §5.3, §6.1).

:func:`build_index` segments every feature file per group and writes a new index;
:func:`add_documents` and :func:`remove_documents` update one in place: they reuse the stored
segments of the documents already indexed (their feature files are not read again), and
produce exactly the index a full rebuild over the resulting documents would give, because
the index depends only on the set of documents (ordered by name). Every write is atomic
(:mod:`mtanno.index.storage`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from mtanno.errors import MtannoError
from mtanno.index.core import (
    Document,
    FeatureDoc,
    Index,
    assemble,
    check_compatible,
    collect_feature_files,
    read_feature_docs,
    resolve_groups,
    segment_documents,
)
from mtanno.index.storage import (
    is_index_dir,
    only_leftovers,
    read_index,
    read_index_manifest,
    remove_leftovers,
    write_index,
    write_lock,
)

GroupsArg = Mapping[str, Sequence[str]] | Sequence[str] | None


def _default_groups(doc: FeatureDoc) -> dict[str, list[str]]:
    """The groups of the file's (built-in) feature set, in its order, else the groups
    stored in the file's metadata."""
    from mtanno.features import FEATURE_SETS

    fs = FEATURE_SETS.get(doc.meta.get("feature_set", ""))
    if fs is not None and list(fs.names) == list(doc.names):
        return {g: [fs.names[i] for i in rows] for g, rows in fs.groups.items()}
    groups = doc.meta.get("groups")
    if isinstance(groups, dict) and groups:
        return {str(g): list(f) for g, f in groups.items()}
    raise MtannoError("feature file names no index groups; pass groups explicitly",
                      path=doc.path)


def _entries(docs: Sequence[FeatureDoc], groups: Mapping[str, Sequence[str]]) -> dict:
    """Name → (document record, group → segments) of freshly read feature files (all with
    the same columns, see :func:`check_compatible`)."""
    segs = segment_documents([d.X for d in docs], docs[0].names if docs else [], groups)
    return {d.name: (Document(d.name, d.sha256, int(d.X.shape[1]), os.path.abspath(d.path)),
                     sg) for d, sg in zip(docs, segs)}


def _existing_entries(index: Index) -> dict:
    out = {}
    for i, doc in enumerate(index.documents):
        out[doc.name] = (doc, {g: tuple(a.astype("int64") for a in gi.segments(i))
                               for g, gi in index.groups.items()})
    return out


def build_index(feature_files: Iterable[str | os.PathLike], out_dir: str | os.PathLike | None,
                *, groups: GroupsArg = None, failures: list[str] | None = None,
                wait: bool = False, on_wait=None,
                progress: Callable[[int, int], None] | None = None) -> Index:
    """Index feature files (files or directories searched for ``*.parquet``).

    ``groups``: None for the feature set's groups (lower/upper/mix), a list of some of their
    names, or a mapping group → feature names. All files must have the same feature set;
    document names (file stems) must be unique. Writes the index to ``out_dir`` (a new or
    empty directory, or an existing index, which is replaced atomically) unless it is None.
    With ``failures``, a file that cannot be read or does not fit the others is left out
    and its message appended there (a batch goes on past it); without, it is raised.
    ``progress(done, total)`` is called after each file read.
    """
    feature_files = list(feature_files)
    paths = collect_feature_files(feature_files, failures=failures)
    if not paths:
        raise MtannoError("no feature files given")
    root = None if out_dir is None else Path(out_dir)
    if root is not None:
        _check_target(root, paths, [f for f in feature_files if Path(f).is_dir()])
    docs = check_compatible(read_feature_docs(paths, failures=failures, progress=progress),
                            failures=failures)
    if not docs:
        raise MtannoError("no feature file could be indexed")
    first = docs[0]
    gs = resolve_groups(first.names, _default_groups(first), groups)
    index = assemble(first.meta.get("feature_set", "custom"),
                     int(first.meta.get("feature_set_version", 1)), first.names,
                     float(first.meta.get("analysis_fps", 30.0)), gs, _entries(docs, gs))
    if root is None:
        return index
    with write_lock(root, wait=wait, on_wait=on_wait):
        return write_index(index, root)


def _check_target(root: Path, paths: Sequence[Path], folders: Sequence[str | os.PathLike] = (),
                  ) -> None:
    """An index is written into a new or empty folder, or over an index, or over what a
    first build killed before its manifest left (:func:`mtanno.index.storage.only_leftovers`:
    rebuilt and cleaned); never into a folder holding anything else, nor where an input file
    is, nor inside a folder of feature files it reads (``folders``: the next build would
    read the index's Parquet files as feature files); and only where it can be written."""
    from mtanno.util.preflight import check_outputs

    if root.exists() and not root.is_dir():
        raise MtannoError("index path exists and is not a directory", path=str(root))
    if root.is_dir() and not is_index_dir(root) and not only_leftovers(root):
        raise MtannoError("directory is not empty and holds no index; choose a new directory",
                          path=str(root))
    check_outputs([], paths, folders={root: None}, scanned={f: (".parquet",) for f in folders})


def open_index(path: str | os.PathLike) -> Index:
    """Open the index in directory ``path`` (verified against its manifest)."""
    return read_index(path)


@dataclass
class UpdateReport:
    """What an update did: document names added, replaced (new content), unchanged, removed."""

    added: list[str] = field(default_factory=list)
    updated: list[str] = field(default_factory=list)
    unchanged: list[str] = field(default_factory=list)
    removed: list[str] = field(default_factory=list)

    def line(self) -> str:
        return (f"{len(self.added)} added, {len(self.updated)} updated, "
                f"{len(self.unchanged)} unchanged, {len(self.removed)} removed")


def add_documents(index_dir: str | os.PathLike, feature_files: Iterable[str | os.PathLike],
                  *, failures: list[str] | None = None, wait: bool = False,
                  on_wait=None, progress: Callable[[int, int], None] | None = None,
                  ) -> tuple[Index, UpdateReport]:
    """Add feature files to the index in ``index_dir``, in place and atomically. A document
    whose name is already indexed is replaced if its feature file changed (by SHA-256) and
    left alone otherwise. Only the new files are read. With ``failures``, a file that
    cannot be read or does not have the index's features is left out and its message
    appended there; without, it is raised. ``progress(done, total)``: after each file read."""
    from mtanno.features.store import FeatureLayout
    from mtanno.util.preflight import check_outputs

    root = Path(index_dir)
    feature_files = list(feature_files)
    paths = collect_feature_files(feature_files, failures=failures)
    # as for a build: no input inside the index, no index inside a folder of feature files
    # read here (the next add would read its Parquet files), and a writable index folder
    check_outputs([], paths, folders={root: None},
                  scanned={f: (".parquet",) for f in feature_files if Path(f).is_dir()})
    with write_lock(root, wait=wait, on_wait=on_wait):
        index = read_index(root)
        layout = FeatureLayout(index.feature_set, tuple(index.features), float(index.fps),
                               f"the index {root}")
        docs = check_compatible(read_feature_docs(paths, failures=failures, progress=progress),
                                layout=layout, failures=failures)
        gs = {g: gi.features for g, gi in index.groups.items()}
        entries = _existing_entries(index)
        report = UpdateReport()
        fresh = []
        for d in docs:
            old = entries.get(d.name)
            if old is None:
                report.added.append(d.name)
                fresh.append(d)
            elif old[0].sha256 != d.sha256:
                report.updated.append(d.name)
                fresh.append(d)
            else:
                report.unchanged.append(d.name)
        if not fresh:  # nothing to write: what a killed update left is removed all the same
            remove_leftovers(root, read_index_manifest(root)["directory"])
            return index, report
        entries.update(_entries(fresh, gs))
        new = assemble(index.feature_set, index.feature_set_version, index.features, index.fps,
                       gs, entries)
        return write_index(new, root), report


def remove_documents(index_dir: str | os.PathLike, names: Iterable[str], *,
                     wait: bool = False, on_wait=None) -> tuple[Index, UpdateReport]:
    """Remove documents (by name, or feature file path whose stem is the name) from the index
    in ``index_dir``, in place and atomically. Every name must be indexed."""
    root = Path(index_dir)
    wanted = []
    for n in names:
        n = str(n)
        wanted.append(Path(n).stem if n.endswith(".parquet") else n)
    if not wanted:
        raise MtannoError("no documents to remove")
    with write_lock(root, wait=wait, on_wait=on_wait):
        index = read_index(root)
        entries = _existing_entries(index)
        missing = [n for n in wanted if n not in entries]
        if missing:
            raise MtannoError(f"document '{missing[0]}' is not in the index", path=str(root))
        for n in wanted:
            entries.pop(n, None)
        gs = {g: gi.features for g, gi in index.groups.items()}
        new = assemble(index.feature_set, index.feature_set_version, index.features, index.fps,
                       gs, entries)
        report = UpdateReport(removed=sorted(set(wanted)))
        return write_index(new, root), report


@dataclass
class IndexInfo:
    """What ``mtanno index info`` shows of an index: its folder (as given), generation,
    the mtanno version that wrote it, the index itself, its bytes on disk and per group
    :func:`group_sizes`; as JSON (:meth:`as_dict`) or as text (:meth:`lines`)."""

    path: str
    index: Index
    version: str | None
    total: int
    rows: list[dict]

    def as_dict(self) -> dict:
        index = self.index
        return {"index": self.path, "generation": index.generation,
                "feature_set": index.feature_set, "documents": len(index.documents),
                "frames": index.frames, "frame_rate": index.fps, "bytes": self.total,
                "mtanno_version": self.version, "groups": self.rows}

    def lines(self) -> list[str]:
        index = self.index
        out = [f"index          {self.path} (generation {index.generation}, "
               f"mtanno {self.version})",
               f"feature set    {index.feature_set} v{index.feature_set_version}, "
               f"{len(index.features)} features",
               f"documents      {len(index.documents)}",
               f"frames         {index.frames} at {index.fps:g} Hz "
               f"({index.frames / index.fps / 60:.1f} min)",
               f"size           {self.total} bytes",
               f"{'group':<8} {'f':>3} {'segments':>9} {'seg/frame':>9} {'lists':>6} "
               f"{'of':>8} {'bytes':>9} {'B/segment':>9}"]
        out += [f"{r['group']:<8} {r['features']:>3} {r['segments']:>9} "
                f"{r['segments_per_frame']:>9.3f} {r['lists']:>6} {r['possible_lists']:>8} "
                f"{r['bytes']:>9} {r['bytes_per_segment']:>9.2f}" for r in self.rows]
        return out


def index_info(index_dir: str | os.PathLike, output: str | os.PathLike | None = None,
               ) -> IndexInfo:
    """The run of ``mtanno index info``: the index of ``index_dir`` read and described
    (:class:`IndexInfo`); with ``output`` its per-group table (:func:`group_sizes`) written
    there (suffix picks the format, ``-`` is CSV on standard output) with its provenance,
    the output checked against the index's files first."""
    from mtanno.util.preflight import check_outputs
    from mtanno.util.provenance import provenance
    from mtanno.util.tables import output_files, table_format, write_table

    if output is not None:
        table_format(output)
    import pyarrow as pa

    from mtanno.index.storage import group_sizes, index_files

    index = read_index(index_dir)
    manifest = read_index_manifest(index.root)
    info = IndexInfo(str(index_dir), index, manifest.get("mtanno_version"),
                     sum(e["bytes"] for e in manifest["files"].values()), group_sizes(index))
    if output is not None:
        check_outputs(output_files(output), index_files(index.root))
        write_table(output, pa.Table.from_pylist(info.rows), provenance=provenance(
            inputs=[index.root / "manifest.json"], index=str(index_dir),
            generation=index.generation, feature_set=index.feature_set))
    return info
