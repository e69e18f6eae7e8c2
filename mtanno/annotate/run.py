"""The whole ``mtanno annotate`` run as one call, :func:`annotate_to`: the documents found,
every output checked against the inputs before any work, the setup loaded
(:func:`mtanno.annotate.load_annotation_setup`) as the
:class:`~mtanno.annotate.options.AnnotateOptions` say, and the documents annotated into the
tables of all documents (``outputs``) and/or one table per document in a folder
(``out_dir``: resumable, under the folder's lock; :mod:`mtanno.annotate.folder`).

A document that cannot be annotated fails alone, as does an input that names no feature
file: the batch goes on and :attr:`AnnotateRun.exit_code` says 1.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from mtanno.annotate.options import AnnotateOptions
from mtanno.annotate.setup import AnnotationSetup, load_annotation_setup
from mtanno.errors import MtannoError

__all__ = ["AnnotateRun", "annotate_to"]


@dataclass
class AnnotateRun:
    """What :func:`annotate_to` did.

    ``failed``: documents that failed (with only ``outputs``, the inputs naming no feature
    file count too); ``missing``: one message per input that names no feature file;
    ``what``: the run in words (``"10 documents, 123 segments"``, or the folder's summary);
    ``seconds``: of annotation (the compilation of a first run included); ``written``: the
    outputs (``out_dir`` first), or ``["nothing written"]`` when every document failed."""

    setup: AnnotationSetup
    documents: int
    failed: int
    what: str
    seconds: float
    written: list = field(default_factory=list)
    missing: list[str] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        """0 when every input was annotated (or up to date), else 1."""
        return 1 if self.failed or self.missing else 0


def _check_options(outputs, out_dir, fmt, force, wait) -> None:
    """The outputs' formats, and the options that go with ``out_dir`` only."""
    from mtanno.util.tables import table_format

    for out in outputs:
        table_format(out)
    if not outputs and out_dir is None:
        raise MtannoError("give {outputs} (one table of all documents), {out_dir} (one table "
                          "per document), or both", options=("outputs", "out_dir"))
    if out_dir is None:
        for name, given in (("fmt", fmt), ("force", force), ("wait", wait)):
            if given:
                raise MtannoError(f"{{{name}}} goes with {{out_dir}} (a table of all "
                                  "documents is always written anew, in the format of its "
                                  "suffix)", options=(name, "out_dir"))


def _check_outputs(features, paths, folder_jobs, outputs, out_dir, mt_dir, config_path,
                   kf_dir, inside_input) -> list:
    """Every output against the inputs (:func:`mtanno.util.preflight.check_outputs`); returns
    the files the run writes. A document's table that cannot be written fails alone: only
    the ``outputs`` are tried first; no output where the features are read from (Parquet
    tables of ``out_dir`` inside a folder of feature files), no ``out_dir`` that is or lies
    inside an input folder (the feature, template or keyframe folders) unless
    ``inside_input``, and no ``outputs`` table among the ``out_dir`` tables (`mtanno
    evaluate OUT/` would read its rows twice)."""
    from mtanno.annotate.tables import ANNOTATION_SUFFIXES
    from mtanno.keyframes import keyframe_files
    from mtanno.templates.store import template_files
    from mtanno.util.preflight import check_outputs
    from mtanno.util.tables import output_files

    tables = [f for out in outputs for f in output_files(out)]
    written = [*(f for j in folder_jobs for f in output_files(j.dst)), *tables]
    input_folders = {**{f: () for f in (mt_dir, kf_dir) if f and Path(f).is_dir()},
                     **{f: (".parquet",) for f in features if Path(f).is_dir()}}
    check_outputs(written, [mt_dir, *template_files(mt_dir), config_path, *paths,
                            *(keyframe_files(kf_dir) if kf_dir else [])],
                  folders={out_dir: []} if out_dir is not None else None,
                  scanned=input_folders, inside_input=inside_input, writable=False)
    check_outputs(tables, [], scanned={out_dir: ANNOTATION_SUFFIXES} if out_dir else None)
    return written


def annotate_to(features: Sequence[str | os.PathLike], mt_dir: str | os.PathLike,
                options: AnnotateOptions | None = None, *,
                outputs: Sequence[str | os.PathLike] = (),
                out_dir: str | os.PathLike | None = None, fmt: str | None = None,
                force: bool = False, wait: bool = False, inside_input: bool = False,
                on_start: Callable[[AnnotationSetup, list[str], int], None] | None = None,
                progress: Callable[[str, str | None], None] | None = None,
                on_wait: Callable[[str], None] | None = None) -> AnnotateRun:
    """Annotate the feature files named by ``features`` (files, folders searched
    recursively) with the templates of ``mt_dir`` as ``mtanno annotate`` does (module
    docstring), as ``options`` say (:class:`~mtanno.annotate.options.AnnotateOptions`:
    the setup that :func:`mtanno.annotate.load_annotation_setup` reads, the variants, and
    the worker processes or cluster).

    ``outputs``: tables of all documents (suffix picks the format, ``-`` is CSV on standard
    output; docs/formats.md). ``out_dir``: one table per document in format ``fmt``
    (default CSV), a document up to date skipped unless ``force``; the folder's lock is
    held (busy: :class:`mtanno.util.locks.LockBusy`, or with ``wait`` waited for after one
    ``on_wait(holder)`` call), and ``outputs`` are then assembled from the folder's tables.
    ``on_start(setup, missing, n)`` is called once the outputs are checked and the setup is
    read, before the first of ``n`` documents; ``progress(path, error)`` after each
    document (``error``: its failure's message, None when it succeeded or was up to
    date). ``out_dir`` may be, or lie inside, a folder of the feature files, templates or
    keyframe queries only with ``inside_input`` (and never when the next run would read
    its tables as feature files: Parquet inside a feature folder)."""
    o = options or AnnotateOptions()
    _check_options(outputs, out_dir, fmt, force, wait)
    missing: list[str] = []  # inputs naming no feature file: reported, the batch goes on
    if out_dir is not None:
        from mtanno.annotate.folder import plan_folder

        folder_jobs = plan_folder(features, out_dir, fmt=fmt or "csv", failures=missing)
        paths = [j.src for j in folder_jobs]
    else:
        from mtanno.features.inputs import document_files

        folder_jobs, paths = [], document_files(features, failures=missing)
    written = _check_outputs(features, paths, folder_jobs, outputs, out_dir, mt_dir,
                             o.config_path, o.keyframes_dir, inside_input)
    setup = load_annotation_setup(mt_dir, o)
    from mtanno.util.preflight import check_outputs

    check_outputs(written, setup.files(), writable=False)  # the configuration's templates
    if on_start:
        on_start(setup, missing, len(paths))
    if out_dir is None:
        run = _to_tables(setup, paths, outputs, o.n_jobs, o.scheduler, progress)
        run.failed += len(missing)
    else:
        run = _to_folder(setup, folder_jobs, out_dir, outputs, force, o.n_jobs, o.scheduler,
                         wait, on_wait, missing, progress)
    run.missing = missing
    return run


def _to_tables(setup, paths, outputs, n_jobs, scheduler, progress) -> AnnotateRun:
    """Annotate ``paths`` into the ``outputs`` tables (none written when every document
    failed)."""
    from mtanno.annotate.tables import write_annotations

    batch = setup.annotate(paths, n_jobs=n_jobs, scheduler=scheduler, progress=progress)
    failed = len(batch.failed)
    if paths and failed == len(paths):  # nothing annotated: no empty table
        return AnnotateRun(setup, len(paths), failed, "0 documents, 0 segments",
                           batch.seconds, ["nothing written"])
    prov = setup.provenance(inputs=batch.files, documents=batch.frames)
    for out in outputs:
        write_annotations(out, batch.rows, batch.native, provenance=prov)
    return AnnotateRun(setup, len(paths), failed,
                       f"{len(paths) - failed} documents, {len(batch.rows)} segments",
                       batch.seconds, list(outputs))


def _to_folder(setup, folder_jobs, out_dir, outputs, force, n_jobs, scheduler, wait, on_wait,
               missing, progress) -> AnnotateRun:
    """Annotate into ``out_dir`` (and the ``outputs`` tables assembled from it), holding
    its lock."""
    from mtanno.annotate.folder import annotate_folder, folder_table
    from mtanno.util.locks import folder_lock
    from mtanno.util.tables import write_table

    with folder_lock(out_dir, wait=wait, on_wait=on_wait):
        summary = annotate_folder(
            folder_jobs, setup, force=force, n_jobs=n_jobs, scheduler=scheduler,
            progress=None if progress is None else lambda o: progress(
                o.job.src, o.message if o.status == "failed" else None))
        if outputs:
            table, prov = folder_table(summary, setup)
            for out in outputs:
                write_table(out, table, provenance=prov)
    what = f"{len(folder_jobs)} documents: {summary.line()}" + (
        f", {len(missing)} input(s) without feature files" if missing else "")
    return AnnotateRun(setup, len(folder_jobs), len(summary.failed), what, summary.seconds,
                       [out_dir, *outputs])
