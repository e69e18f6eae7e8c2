"""Gathering the training examples of motion-template learning.

Three ways to say which frames are an example of which class (issue 3, ``learn-mt``):

* a folder tree ``ROOT/CLASS/*.parquet`` — every feature file is one example of the class
  named by its folder (:func:`sources_from_tree`);
* a manifest CSV with columns ``file,class`` (more columns allowed, e.g. ``split``), such
  as ``hdm05_cut/clips.csv`` whose ``file`` is ``class/HDM_..._120.amc``; the feature file
  of an entry is ``FEATURES_DIR/<file with suffix .parquet>``, the path ``mtanno features``
  writes for that motion file (:func:`sources_from_manifest`);
* annotated documents: a truth table (``mtanno.labels.truth.read_truth``: doc, start, end,
  label at 30 Hz, 1-based inclusive) and the documents' feature files; every labelled
  segment is cut out as one example of its label (:func:`sources_from_truth`).

Collecting gives :class:`ExampleSource` records (cheap, nothing read yet);
:func:`load_examples` reads the feature files, cuts the segments, checks that every
example has the same feature names, feature set and frame rate, and orders them by file
name, then start frame — the order the golden templates were learned in (the first
example is the reference whose template MT learning returns, [MR06] §4.1).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.features.inputs import feature_files
from mtanno.features.store import FeatureLayout, read_features
from mtanno.labels.truth import read_truth
from mtanno.util.provenance import sha256_file

__all__ = [
    "MIN_EXAMPLES", "ExampleSource", "TrainingExample", "check_consistent", "collect_sources",
    "few_examples_warning", "group_by_class", "ignored_documents_note", "input_folders",
    "load_examples", "sources_from_manifest", "sources_from_tree", "sources_from_truth",
]


@dataclass(frozen=True)
class ExampleSource:
    """Where one training example is: a feature file, optionally a frame range.

    ``start``/``end`` are 1-based inclusive analysis frames (30 Hz); None means the whole
    file. ``origin``/``origin_line`` name the manifest or truth file that listed it (for
    error messages). ``performer`` groups examples that share a performer or recording
    (a manifest's ``actor`` column, a truth segment's document; None when unknown):
    keyframe learning validates on held-out performers.
    """

    class_name: str
    path: str
    start: int | None = None
    end: int | None = None
    origin: str | None = None
    origin_line: int | None = None
    performer: str | None = None

    def sort_key(self) -> tuple:
        return (Path(self.path).name, self.path, self.start or 0, self.end or 0)


@dataclass
class TrainingExample:
    """One training example, read: its (features × frames) 0/1 matrix and provenance.

    ``start``/``end`` are the 1-based inclusive frames (at ``fps``) of the file that ``X``
    holds. ``poses``: the normalised poses of the same frames ((frames × 22 × 3) float32, in
    leg lengths, :mod:`mtanno.features.poses`) when loaded with ``poses=True`` from a feature
    file that has a pose block (``mtanno features --poses``); else None.
    """

    class_name: str
    X: np.ndarray
    file: str
    document: str
    sha256: str
    start: int
    end: int
    feature_names: list[str]
    feature_set: str
    fps: float
    performer: str | None = None
    poses: np.ndarray | None = None

    def layout(self) -> FeatureLayout:
        """The example's :class:`~mtanno.features.store.FeatureLayout` (named after its file)."""
        return FeatureLayout(self.feature_set, tuple(self.feature_names), float(self.fps),
                             f"feature file {self.file}")

    def record(self) -> dict:
        """The template's ``training`` entry for this example."""
        return {"file": self.file, "document": self.document, "sha256": self.sha256,
                "frames": [self.start, self.end]}


# --------------------------------------------------------------------------- collecting


def sources_from_tree(roots: Iterable[str | os.PathLike], *,
                      failures: list[MtannoError] | None = None) -> list[ExampleSource]:
    """One example per ``ROOT/CLASS/*.parquet`` file; the class is the folder name.

    A root that is missing, not a folder or without such files is an error; with
    ``failures`` it is appended there instead and the others are used (a batch goes on
    past a bad input), unless no root gives an example."""
    out: list[ExampleSource] = []
    errors: list[MtannoError] = []
    for root in roots:
        root = Path(root)
        if not root.exists():
            errors.append(MtannoError("training folder not found", path=str(root)))
        elif not root.is_dir():
            errors.append(MtannoError("not a folder (expected ROOT/CLASS/*.parquet; use "
                                      "{truth} for annotated documents)", path=str(root),
                                      options=("truth",)))
        else:
            found = [ExampleSource(cls_dir.name, str(f))
                     for cls_dir in sorted(p for p in root.iterdir() if p.is_dir())
                     for f in sorted(cls_dir.glob("*.parquet"))]
            if not found:
                errors.append(MtannoError("no CLASS/*.parquet feature files in this folder",
                                          path=str(root)))
            out.extend(found)
        if errors and failures is None:
            raise errors[0]
    if errors and not out:
        raise errors[0]
    if failures is not None:
        failures.extend(errors)
    return out


def sources_from_manifest(manifest: str | os.PathLike, *, features_dir: str | os.PathLike,
                          split: str | None = None) -> list[ExampleSource]:
    """Examples listed in a manifest CSV (columns ``file,class[,split,...]``).

    The feature file of a row is ``features_dir / file`` with the suffix replaced by
    ``.parquet``. With ``split``, only rows whose ``split`` column equals it are used.
    """
    from mtanno.util.clips import read_clip_manifest

    table, rows = read_clip_manifest(manifest)
    spath = table.path
    if split is not None and "split" not in table.columns:
        raise MtannoError("manifest has no split column to filter by {split}", path=spath,
                          line=table.header_line, options=("split",))
    fdir = Path(features_dir)
    if not fdir.is_dir():
        raise MtannoError("features folder not found", path=str(fdir))
    out: list[ExampleSource] = []
    seen_splits: set[str] = set()
    for row in rows:
        if split is not None:
            seen_splits.add(row.split)
            if row.split != split:
                continue
        out.append(ExampleSource(row.label, str(fdir / Path(row.file).with_suffix(".parquet")),
                                 origin=spath, origin_line=row.line,
                                 performer=row.actor or None))
    if not out:
        if split is not None:
            raise MtannoError(f"no rows with split {split!r} (splits present: "
                              f"{', '.join(sorted(seen_splits)) or 'none'})", path=spath)
        raise MtannoError("manifest lists no files", path=spath)
    return out


#: Fewer examples than this make a template that has seen too little variation ([MR06] §4
#: learns from 7–26); learn-mt warns for such classes.
MIN_EXAMPLES = 3


def few_examples_warning(class_name: str, n: int) -> str | None:
    """The warning for a class learned from fewer than :data:`MIN_EXAMPLES` examples (None
    when there are enough)."""
    if n >= MIN_EXAMPLES:
        return None
    return (f"warning: class {class_name} is learned from {n} example{'s' if n != 1 else ''} "
            f"only; a template needs at least {MIN_EXAMPLES} to average over the variation "
            "of a motion ([MR06] §4.1)")


def ignored_documents_note(ignored: Sequence[str]) -> str | None:
    """One note naming the truth table's documents that had no feature file among the
    inputs (None when there are none)."""
    if not ignored:
        return None
    more = f" and {len(ignored) - 10} more" if len(ignored) > 10 else ""
    return (f"note: the truth table's segments of {len(ignored)} document(s) without a feature "
            f"file among the inputs are ignored: {', '.join(ignored[:10])}{more}")


def sources_from_truth(truth: str | os.PathLike, features: Iterable[str | os.PathLike], *,
                       ignored: list[str] | None = None) -> list[ExampleSource]:
    """One example per labelled segment of a truth table, cut from the feature file of
    its document (documents are named by feature file stem; ``features`` are files or
    folders searched recursively). Segments of documents without a feature file are
    skipped (a truth table usually covers more documents than one run uses); their
    document names are appended to ``ignored`` (sorted) when it is given. No feature file
    for any document is an error."""
    segments = read_truth(truth)
    if not segments:
        raise MtannoError("truth table has no segments", path=str(truth))
    by_doc: dict[str, Path] = {}
    for f in feature_files(features):
        prev = by_doc.get(f.stem)
        if prev is not None and prev.resolve() != f.resolve():
            raise MtannoError(f"two feature files for document {f.stem!r}: {prev} and {f}")
        by_doc[f.stem] = f
    missing = sorted({s.doc for s in segments if s.doc not in by_doc})
    if len(missing) == len({s.doc for s in segments}):
        more = f" and {len(missing) - 5} more" if len(missing) > 5 else ""
        raise MtannoError(f"no feature file for document(s) {', '.join(missing[:5])}{more} "
                          f"(give the documents' feature files or folders)", path=str(truth))
    if ignored is not None:
        ignored.extend(missing)
    return [ExampleSource(s.label, str(by_doc[s.doc]), s.start, s.end, origin=str(truth),
                          performer=s.doc) for s in segments if s.doc in by_doc]


def input_folders(training: Sequence[str | os.PathLike] = (),
                  features_dir: str | os.PathLike | None = None, *,
                  also: Sequence[str | os.PathLike | None] = (),
                  ) -> dict[str | os.PathLike, tuple[str, ...]]:
    """The folders training examples are read from (``TRAINING`` folders,
    ``features_dir``), each with the suffix read there, and the folders of ``also`` (the
    templates' or keyframe queries' folder: no suffix, nothing in them is scanned), as
    :func:`mtanno.util.preflight.check_outputs` takes them (``scanned``): no output folder
    among the inputs unless the user says so."""
    return {**{f: () for f in also if f is not None and Path(f).is_dir()},
            **{f: (".parquet",) for f in [*training, features_dir]
               if f is not None and Path(f).is_dir()}}


def collect_sources(training: Sequence[str | os.PathLike] = (), *,
                    manifest: str | os.PathLike | None = None,
                    features_dir: str | os.PathLike | None = None, split: str | None = None,
                    truth: str | os.PathLike | None = None,
                    ignored: list[str] | None = None,
                    note: Callable[[str], None] | None = None,
                    failures: list[MtannoError] | None = None) -> list[ExampleSource]:
    """Training examples named the three ways learn-mt, learn-keyframes and tune accept
    (module docstring): a manifest with its features folder (and split), a truth table with
    the documents' feature files or folders (``ignored`` receives the truth's documents
    without one, :func:`sources_from_truth`; ``note`` is called with one line naming them,
    :func:`ignored_documents_note`), or class folders (``failures``: as
    :func:`sources_from_tree`). Contradictory combinations are errors saying which options
    go together."""
    if manifest is not None and truth is not None:
        raise MtannoError("{manifest} and {truth} exclude each other",
                          options=("manifest", "truth"))
    if manifest is not None:
        if training:
            raise MtannoError("no {training} arguments with {manifest} (it lists the files)",
                              options=("training", "manifest"))
        if features_dir is None:
            raise MtannoError("{manifest} needs {features_dir} (the folder of its feature files)",
                              options=("manifest", "features_dir"))
        return sources_from_manifest(manifest, features_dir=features_dir, split=split)
    if features_dir is not None or split is not None:
        raise MtannoError("{features_dir} and {split} go with {manifest}",
                          options=("features_dir", "split", "manifest"))
    if not training:
        raise MtannoError("give {training} folders or files (or {manifest})",
                          options=("training", "manifest"))
    if truth is None:
        return sources_from_tree(training, failures=failures)
    missing: list[str] = []
    sources = sources_from_truth(truth, training, ignored=missing)
    if ignored is not None:
        ignored.extend(missing)
    line = ignored_documents_note(missing)
    if note is not None and line:
        note(line)
    return sources


def group_by_class(sources: Iterable[ExampleSource], *,
                   classes: Sequence[str] | None = None) -> dict[str, list[ExampleSource]]:
    """Sources per class (classes sorted by name, sources by :meth:`ExampleSource.sort_key`);
    with ``classes``, only those (each must be present)."""
    out: dict[str, list[ExampleSource]] = {}
    for s in sources:
        out.setdefault(s.class_name, []).append(s)
    if classes:
        unknown = [c for c in classes if c not in out]
        if unknown:
            raise MtannoError(f"no training examples for class(es) {', '.join(unknown)} "
                              f"(classes found: {', '.join(sorted(out)) or 'none'})")
        out = {c: out[c] for c in classes}
    return {c: sorted(out[c], key=ExampleSource.sort_key) for c in sorted(out)}


# --------------------------------------------------------------------------- loading


def load_examples(sources: Iterable[ExampleSource], *,
                  poses: bool = False) -> list[TrainingExample]:
    """Read the feature files of ``sources``, cut their frame ranges, check consistency
    (:func:`check_consistent`) and return the examples in :meth:`ExampleSource.sort_key`
    order. Each file is read and hashed once.

    ``poses``: also cut each example's normalised poses (``TrainingExample.poses``, the
    frames of ``X``) from files that have a pose block; examples from files without one
    get None. Without it pose blocks are not read."""
    cache: dict[str, tuple] = {}
    out: list[TrainingExample] = []
    for src in sorted(sources, key=ExampleSource.sort_key):
        if src.path not in cache:
            try:
                ff = read_features(src.path, poses=poses)
            except MtannoError as exc:
                if src.origin is not None and not Path(src.path).exists():
                    raise MtannoError(f"feature file {src.path} not found (run `mtanno "
                                      f"features` first?)", path=src.origin,
                                      line=src.origin_line) from None
                raise exc from None
            cache[src.path] = (ff, sha256_file(src.path))
        ff, digest = cache[src.path]
        n = ff.X.shape[1]
        if n == 0:
            raise MtannoError("feature file has no frames", path=src.path)
        start = 1 if src.start is None else src.start
        end = n if src.end is None else src.end
        if not 1 <= start <= end <= n:
            raise MtannoError(f"segment {start}..{end} of document {ff.document!r} "
                              f"(class {src.class_name}) lies outside its frames 1..{n}",
                              path=src.origin or src.path, line=src.origin_line)
        out.append(TrainingExample(
            class_name=src.class_name, X=np.ascontiguousarray(ff.X[:, start - 1:end]),
            file=src.path, document=ff.document, sha256=digest, start=start, end=end,
            feature_names=list(ff.names), feature_set=str(ff.meta.get("feature_set", "")),
            fps=ff.fps, performer=src.performer,
            poses=None if ff.poses is None else np.ascontiguousarray(ff.poses[start - 1:end])))
    check_consistent(out)
    return out


def check_consistent(examples: Sequence[TrainingExample], *,
                     like: TrainingExample | None = None) -> None:
    """All examples (and ``like``, if given) have the same feature names, feature set and
    frame rate; otherwise an error names the first file that differs."""
    if not examples:
        return
    from mtanno.features.store import check_layout, common_layout

    ref = like.layout() if like is not None else common_layout([e.layout() for e in examples])
    for ex in examples:
        check_layout(ex.layout(), ref, path=ex.file)
