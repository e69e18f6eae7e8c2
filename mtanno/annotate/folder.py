"""Resumable annotation: one annotation table per document in a folder (``mtanno annotate
--output-dir``, ``docs/annotation.md``).

A batch over an archive is planned (:func:`plan_folder`: one output per feature file,
mirroring the inputs' tree), the documents whose output is up to date are skipped
(:func:`up_to_date`), and every other document's table is written, atomically, as soon as
it is annotated (:func:`annotate_folder`). A run that is interrupted or killed leaves the
tables it finished; the next run computes only the others. Every table records the same
provenance as a single annotation table (:meth:`mtanno.annotate.AnnotationSetup.provenance`)
for its one document: the feature file with its SHA-256 and frame count, the templates,
keyframe queries and class configuration with their SHA-256, and the options.

Up to date means: the output exists, is not older than any of its inputs (feature file,
templates, class configuration, keyframe queries), and its recorded provenance says it was
made from this feature file (SHA-256) with the same templates, keyframe queries and
configuration (SHA-256, wherever the files are now), the same options and the same mtanno
version (:func:`recipe`). The caller holds the folder's lock
(:func:`mtanno.util.locks.folder_lock`) so that two runs never work on one folder at once.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from mtanno.annotate.setup import AnnotationSetup
from mtanno.errors import MtannoError
from mtanno.util.outcomes import Outcomes

__all__ = ["FORMATS", "DocJob", "DocOutcome", "FolderSummary", "annotate_folder",
           "folder_table", "plan_folder", "recipe", "up_to_date"]

#: ``--format`` names and the suffix of the tables they give.
FORMATS = {"csv": ".csv", "parquet": ".parquet", "jsonl": ".jsonl"}
#: Provenance keys that say when, by which command line and of which document an output
#: was made, not how (:func:`recipe` leaves them out; the document is checked apart).
_NOT_RECIPE = ("schema", "command", "created", "inputs", "documents")


@dataclass(frozen=True)
class DocJob:
    """One document of a folder batch: its feature file and its annotation table."""

    src: Path
    dst: Path

    @property
    def doc(self) -> str:
        return self.src.stem


@dataclass
class DocOutcome:
    """What became of one document: ``status`` is ``"computed"``, ``"skipped"`` (up to
    date) or ``"failed"`` (``message`` says why); the feature file's SHA-256 and frame
    count, and the number of segments written (computed documents)."""

    job: DocJob
    status: str
    message: str = ""
    sha256: str | None = None
    frames: int = 0
    segments: int = 0


@dataclass
class FolderSummary(Outcomes[DocOutcome]):
    """Outcomes of a folder batch, in the order of the jobs (counts and the failed ones:
    :class:`mtanno.util.outcomes.Outcomes`); ``seconds`` is the time spent annotating (summed
    over the computed documents)."""

    seconds: float = 0.0

    @property
    def done(self) -> list[DocOutcome]:
        """The documents whose table is in the folder and up to date (computed or skipped)."""
        return [o for o in self.outcomes if o.status != "failed"]

    def line(self) -> str:
        segments = sum(o.segments for o in self.outcomes)
        return (f"{self.count('computed')} computed ({segments} segments), "
                f"{self.count('skipped')} up to date, {self.count('failed')} failed")


def plan_folder(inputs: Iterable[str | os.PathLike], outdir: str | os.PathLike, *,
                fmt: str = "csv", failures: list[str] | None = None) -> list[DocJob]:
    """One job per feature file named by ``inputs`` (files, folders searched recursively;
    :func:`mtanno.features.inputs.document_files_below`): a file ``F.parquet`` gives
    ``outdir/F.<fmt>``, a file found in folder ``D`` gives ``outdir/<its path below
    D>`` with the format's suffix (``failures``: as :func:`mtanno.features.inputs.feature_files`).
    Jobs are sorted by document name. (An ``outdir`` inside an input folder is judged with
    the other outputs: :func:`mtanno.annotate.run.annotate_to`.)
    """
    from mtanno.features.inputs import document_files_below

    if fmt not in FORMATS:
        raise MtannoError(f"unknown table format {fmt!r} (known: {', '.join(FORMATS)})")
    outdir = Path(outdir)
    jobs = [DocJob(src, outdir / rel.with_suffix(FORMATS[fmt]))
            for src, rel in document_files_below(inputs, failures=failures)]
    return sorted(jobs, key=lambda j: j.doc)


def recipe(prov: dict) -> dict | None:
    """How an annotation table was made, from its provenance: every option, the mtanno
    version, and the templates, keyframe queries and class configuration by content
    (class and SHA-256; not where the files were). Two tables with equal recipes of the
    same feature file hold the same annotation. None for a provenance that cannot be read
    as one."""
    try:
        out = {k: v for k, v in prov.items() if k not in _NOT_RECIPE}
        for key in ("templates", "keyframes"):
            out[key] = sorted(([r.get("class"), r.get("sha256")] for r in prov.get(key) or []),
                              key=json.dumps)
        classes = prov.get("classes")
        out["classes"] = classes.get("sha256") if classes else None
        conf = prov.get("confidence")
        if isinstance(conf, dict) and isinstance(conf.get("bank"), dict):
            out["confidence"] = {**conf, "bank": conf["bank"].get("sha256")}
    except (AttributeError, TypeError):
        return None
    return out


def _mtime_ns(path: str | os.PathLike) -> int:
    try:
        return os.stat(path).st_mtime_ns
    except OSError:
        return 0


def up_to_date(job: DocJob, expected: dict, *, not_before: int = 0) -> DocOutcome | None:
    """Whether ``job.dst`` holds the annotation this run would write (module docstring):
    it exists, its modification time is not before the feature file's nor ``not_before``
    (nanoseconds: the newest template, configuration or keyframe file), its provenance
    names this one document, made from the feature file as it is now (SHA-256), and its
    :func:`recipe` is ``expected``. Returns the ``"skipped"`` outcome (with the feature
    file's SHA-256 and the frame count recorded) when it is up to date, else None."""
    from mtanno.util.provenance import sha256_file
    from mtanno.util.tables import table_provenance

    try:
        made = os.stat(job.dst).st_mtime_ns
    except OSError:
        return None
    if made < max(not_before, _mtime_ns(job.src)):
        return None
    prov = table_provenance(job.dst)
    if prov is None or recipe(prov) != expected:
        return None
    documents, inputs = prov.get("documents"), prov.get("inputs")
    if not (isinstance(documents, dict) and list(documents) == [job.doc]
            and isinstance(documents[job.doc], int) and isinstance(inputs, list)
            and len(inputs) == 1 and isinstance(inputs[0], dict)):
        return None
    try:
        digest = sha256_file(job.src)
    except OSError:
        return None
    if inputs[0].get("sha256") != digest:
        return None
    return DocOutcome(job, "skipped", sha256=digest, frames=int(documents[job.doc]))


def annotate_folder(jobs: Sequence[DocJob], setup: AnnotationSetup, *, force: bool = False,
                    n_jobs: int = 1, scheduler: str | None = None,
                    progress: Callable[[DocOutcome], None] | None = None) -> FolderSummary:
    """Annotate every job's document with ``setup`` into its table, skipping those up to
    date (:func:`up_to_date`) unless ``force``. Documents run in ``n_jobs`` processes or on
    a dask cluster (``scheduler``), as :func:`mtanno.annotate.annotate_files`; each table is
    written atomically (:func:`mtanno.annotate.write_annotations`, format by the output's
    suffix) as soon as its document is done, with its provenance. A document that fails
    (unreadable, other features than the templates, unwritable output) is recorded and
    the batch goes on. ``progress`` is called once per job. Hold the output folder's lock
    (:func:`mtanno.util.locks.folder_lock`) around this call."""
    from mtanno.util.tables import provenance_as_read

    summary = FolderSummary()
    expected = recipe(provenance_as_read(setup.provenance()))
    not_before = max((_mtime_ns(f) for f in setup.files()), default=0)

    todo = []
    for job in jobs:
        skipped = None if force else up_to_date(job, expected, not_before=not_before)
        if skipped is not None:
            summary.record(skipped, progress)
        else:
            todo.append(job)
    # each table is written where its document is annotated (in the workers)
    for job, (_, result) in zip(todo, setup.iter_annotate(
            [j.src for j in todo], n_jobs=n_jobs, scheduler=scheduler,
            outputs=[j.dst for j in todo])):
        if isinstance(result, str):
            summary.record(DocOutcome(job, "failed", result), progress)
            continue
        _, n_rows, frames, digest, seconds = result
        summary.seconds += seconds
        summary.record(DocOutcome(job, "computed", sha256=digest, frames=frames,
                                  segments=n_rows), progress)
    summary.outcomes.sort(key=lambda o: o.job.doc)
    return summary


def folder_table(summary: FolderSummary, setup: AnnotationSetup):
    """The table of all documents of a folder batch that are done (computed or up to date),
    assembled from their tables (:func:`mtanno.annotate.merge_annotation_tables`: the rows
    ``annotate -o`` writes for them), and its provenance (every feature file with its
    SHA-256, every document's frame count)."""
    from mtanno.annotate import merge_annotation_tables

    done = summary.done
    table, frames = merge_annotation_tables([o.job.dst for o in done])
    return table, setup.provenance(
        inputs=[{"path": str(o.job.src), "sha256": o.sha256} for o in done], documents=frames)
