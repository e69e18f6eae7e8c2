"""Command: annotate ([MBS09] §4–5, algorithms.md §7)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from mtanno.annotate import DEFAULT_DELTA, DEFAULT_TAU
from mtanno.commands._common import (
    DELTA,
    TAU,
    Number,
    lock_output,
    scheduler_option,
    show_progress,
    user_errors,
    wait_option,
)
from mtanno.errors import MtannoError
from mtanno.templates.model import template_files
from mtanno.util.store import document_files


@click.command("annotate")
@click.argument("features", nargs=-1, required=True, metavar="FEATURES...")
@click.option("--mt", "mt_dir", required=True, type=click.Path(exists=True),
              help="Directory of class templates (CLASS.json) from learn-mt.")
@click.option("-o", "--output", "outputs", multiple=True,
              help="Annotation table of all documents: .csv, .parquet or .jsonl, or - for CSV "
                   "on standard output (repeat for several; docs/formats.md).")
@click.option("--output-dir", "out_dir", default=None, metavar="OUT/",
              help="One annotation table per document in OUT/ (names mirror the feature "
                   "files' paths below the folders given), written as each document is done; "
                   "a rerun computes only documents whose table is missing or out of date.")
@click.option("--format", "fmt", type=click.Choice(["csv", "parquet", "jsonl"]), default=None,
              help="Format of the --output-dir tables [default: csv].")
@click.option("-f", "--force", is_flag=True,
              help="With --output-dir: recompute tables that are up to date.")
@click.option("--keyframes", "kf_dir", type=click.Path(), default=None,
              help="Folder of keyframe queries (CLASS.json from learn-keyframes): a class's "
                   "template is matched only inside its candidate windows ([MBS09] §5).")
@click.option("--classes", "config_path", type=click.Path(dir_okay=False), default=None,
              help="Class configuration (TOML): per-class tau, superclasses, and the methods "
                   "`mtanno tune` writes (docs/annotation.md).")
@click.option("--tau", type=TAU, default=None,
              help=f"Threshold tau for every class without its own [default: {DEFAULT_TAU:g}].")
@click.option("--delta", type=DELTA, default=None,
              help="Quantization delta of the templates [default: [decoder] delta of "
                   f"--classes, else {DEFAULT_DELTA:g}].")
@click.option("--dbar", "variant", type=click.Choice(["reference", "paper"]),
              default="reference", show_default=True,
              help="Modified-distance (Δ̄) variant (algorithms.md §7).")
@click.option("--variant", "former_variant", type=click.Choice(["reference", "paper"]),
              default=None, hidden=True, help="The former name of --dbar.")
@click.option("--match", "match_variant", type=click.Choice(["reference", "paper"]),
              default="reference", show_default=True, help="Matching cost variant (§3.4).")
@click.option("--single-label", is_flag=True,
              help="One label per frame: where segments overlap, each frame keeps the class "
                   "with the smallest modified distance (with a tuned confidence: the more "
                   "confident segment), so the rows form a partition (for confusion "
                   "matrices). Default: the overlapping reference output.")
@click.option("--min-confidence", type=Number(min=0, max=1), default=None, metavar="P",
              help="Drop rows whose confidence is below P (0 to 1) [default: the minimum "
                   "`mtanno tune` chose, else 0].")
@click.option("-j", "--jobs", default=1, show_default=True, type=click.IntRange(min=1),
              help="Worker processes (documents in parallel).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@wait_option
@scheduler_option
@user_errors(2)
def annotate_cmd(features, mt_dir, outputs, out_dir, fmt, force, kf_dir, config_path, tau,
                 delta, variant, former_variant, match_variant, single_label, min_confidence,
                 jobs, quiet, wait, scheduler):
    """Label every frame of documents with motion classes ([MBS09] §4).

    FEATURES are feature files or directories of them. Every template is matched against
    every document; frames get the class whose modified distance is smallest (below tau),
    and the labelled runs are extended. Output rows: doc, start, end (1-based inclusive
    frames at 30 Hz), label, cost, confidence, start_native, end_native; rows may overlap,
    unless --single-label. The confidence (0 to 1) is the probability that the row's label
    is right when --classes holds a tuned confidence (`mtanno tune`), else the uncalibrated
    score 1 - cost/tau (docs/annotation.md).

    With --keyframes, each class that has a keyframe query is first searched for its key
    poses (a fast scan of the features), and its template is matched only inside the
    windows found (widened by the query's extension); classes without a query are matched
    everywhere, with a note.

    Give -o TABLE (one table of all documents), --output-dir OUT/ (one table per
    document), or both. With --output-dir the run is resumable: a document is skipped when
    its table is not older than its inputs and its recorded provenance matches the run (the
    feature file's SHA-256; the templates, keyframe queries and class configuration by
    SHA-256; tau, delta, variants; mtanno version); --force recomputes every document. The
    run holds OUT/'s lock: another run writing into OUT/ makes it exit with code 3 (or wait,
    with --wait). -o with --output-dir writes the table of all documents, computed and
    skipped, assembled from their tables. `mtanno evaluate OUT/` reads the folder.

    Exit codes: 0 success, 1 some documents failed (the others were annotated), 2 bad
    input (nothing written), 3 OUT/ locked by another run, 130 interrupted (finished
    tables are complete and are skipped by the rerun).
    """
    variant = former_variant or variant  # --variant: the former name of --dbar
    from tqdm import tqdm

    from mtanno.annotate import check_tau, load_annotation_setup
    from mtanno.util.output import check_outputs

    _check_options(outputs, out_dir, fmt, force, wait)
    if tau is not None:
        tau = check_tau(tau, what="--tau")
    missing: list[str] = []  # inputs naming no feature file: reported, the batch goes on
    if out_dir is not None:
        from mtanno.annotate.folder import plan_folder

        folder_jobs = plan_folder(features, out_dir, fmt=fmt or "csv", failures=missing)
        paths = [j.src for j in folder_jobs]
    else:
        folder_jobs, paths = [], document_files(features, failures=missing)
    written = _check_outputs(features, paths, folder_jobs, outputs, out_dir, mt_dir,
                             config_path, kf_dir)
    setup = load_annotation_setup(mt_dir, config_path=config_path, keyframes_dir=kf_dir,
                                  tau=tau, delta=delta, dbar_variant=variant,
                                  match_variant=match_variant, single_label=single_label,
                                  min_confidence=min_confidence)
    check_outputs(written, setup.files(), writable=False)  # the configuration's templates
    _notes(setup, missing, quiet)
    bar = tqdm(total=len(paths), unit="doc", disable=not show_progress(quiet), desc="annotate")
    failures = _FailureLines(lambda line: bar.write(line, file=sys.stderr))

    def note_failure(path, error):
        bar.update(1)
        failures.add(path, error)

    if out_dir is None:
        failed, what, seconds = _to_tables(setup, paths, outputs, jobs, scheduler,
                                           note_failure, bar, failures)
        if failed < 0:  # nothing annotated: no empty table
            failed, outputs = -failed, ["nothing written"]
    else:
        failed, what, seconds = _to_folder(setup, folder_jobs, out_dir, outputs, force, jobs,
                                           scheduler, wait, missing, note_failure, bar,
                                           failures)
        outputs = (out_dir, *outputs)
    if out_dir is None:
        failed += len(missing)
    if not quiet:
        kf = f", keyframes for {len(setup.keyframes)}" if setup.keyframes else ""
        tail = "" if out_dir is not None else f", {failed} failed"
        click.echo(f"annotate: {what}, {len(setup.classes)} classes{kf}{tail}, "
                   f"{seconds:.2f} s of annotation -> {', '.join(map(str, outputs))}", err=True)
    sys.exit(1 if failed or missing else 0)


def _to_tables(setup, paths, outputs, jobs, scheduler, note_failure, bar, failures):
    """Annotate ``paths`` into the -o tables: (failed documents — negative when all
    failed and nothing was written —, what was done, seconds of annotation)."""
    from mtanno.annotate import write_annotations

    batch = setup.annotate(paths, n_jobs=jobs, scheduler=scheduler, progress=note_failure)
    bar.close()
    failures.finish()
    prov = setup.provenance(inputs=batch.files, documents=batch.frames)
    failed = len(batch.failed)
    if paths and failed == len(paths):
        return -failed, "0 documents, 0 segments", batch.seconds
    for out in outputs:
        write_annotations(out, batch.rows, batch.native, provenance=prov)
    return failed, f"{len(paths) - failed} documents, {len(batch.rows)} segments", batch.seconds


def _to_folder(setup, folder_jobs, out_dir, outputs, force, jobs, scheduler, wait, missing,
               note_failure, bar, failures):
    """Annotate into ``out_dir`` (and the -o tables assembled from it), holding its lock:
    (failed documents, what was done, seconds of annotation)."""
    from mtanno.annotate.folder import annotate_folder, folder_table
    from mtanno.util.tables import write_table

    with lock_output(out_dir, wait=wait):
        summary = annotate_folder(
            folder_jobs, setup, force=force, n_jobs=jobs, scheduler=scheduler,
            progress=lambda o: note_failure(o.job.src,
                                            o.message if o.status == "failed" else None))
        bar.close()
        failures.finish()
        if outputs:
            table, prov = folder_table(summary, setup)
            for out in outputs:
                write_table(out, table, provenance=prov)
    what = f"{len(folder_jobs)} documents: {summary.line()}" + (
        f", {len(missing)} input(s) without feature files" if missing else "")
    return len(summary.failed), what, summary.seconds


class _FailureLines:
    """The ``mtanno:`` lines of a batch's failing documents, each as it comes, except that
    while every document so far failed for the same reason (a feature-set mismatch with
    the templates: the same message but for the path) the lines are held back; if the whole
    batch fails so, :meth:`finish` writes one line naming the first file and the count."""

    def __init__(self, write):
        self.write = write
        self.held: list[str] = []  # the lines held back
        self.reason: str | None = None  # their message without the path
        self.holding = True

    def add(self, path, error: str | None) -> None:
        """One document done: ``error`` is its failure's message (None: it succeeded)."""
        reason = None if error is None else error.removeprefix(f"{path}: ")
        if self.holding and error is not None and self.reason in (None, reason):
            self.reason = reason
            self.held.append(f"mtanno: {error}")
            return
        self._release()
        if error is not None:
            self.write(f"mtanno: {error}")

    def _release(self) -> None:
        self.holding = False
        for line in self.held:
            self.write(line)
        self.held = []

    def finish(self) -> None:
        """The batch is done: the lines still held, as one line when there are several."""
        if len(self.held) > 1:
            self.write(f"{self.held[0]} (the same for all {len(self.held)} documents)")
            self.held = []
        self._release()


def _check_options(outputs, out_dir, fmt, force, wait) -> None:
    """The outputs' formats, and the options that go with --output-dir only."""
    from mtanno.util.tables import table_format

    for out in outputs:
        table_format(out)
    if not outputs and out_dir is None:
        raise MtannoError("give -o TABLE (one table of all documents), --output-dir OUT/ "
                          "(one table per document), or both")
    if out_dir is None:
        for flag, given in (("--format", fmt), ("--force", force), ("--wait", wait)):
            if given:
                raise MtannoError(f"{flag} goes with --output-dir (an -o table is always "
                                  "written anew, in the format of its suffix)")


def _check_outputs(features, paths, folder_jobs, outputs, out_dir, mt_dir, config_path,
                   kf_dir) -> list:
    """Every output against the inputs (:func:`mtanno.util.output.check_outputs`); returns
    the files the run writes. A document's table that cannot be written fails alone: only
    -o is tried first; no output where the features are read from, and no -o table among
    the --output-dir tables (`mtanno evaluate OUT/` would read its rows twice)."""
    from mtanno.annotate import ANNOTATION_SUFFIXES
    from mtanno.keyframes import keyframe_files
    from mtanno.util.output import check_outputs
    from mtanno.util.tables import output_files

    tables = [f for out in outputs for f in output_files(out)]
    written = [*(f for j in folder_jobs for f in output_files(j.dst)), *tables]
    check_outputs(written, [mt_dir, *template_files(mt_dir), config_path, *paths,
                            *(keyframe_files(kf_dir) if kf_dir else [])],
                  scanned={f: (".parquet",) for f in features if Path(f).is_dir()},
                  writable=False)
    check_outputs(tables, [], scanned={out_dir: ANNOTATION_SUFFIXES} if out_dir else None)
    return written


def _notes(setup, missing, quiet) -> None:
    """Warnings and notes of the setup, and the inputs naming no feature file."""
    for warning in setup.warnings:
        click.echo(f"annotate: warning: {warning}", err=True)
    if not quiet and setup.keyframes_missing:
        click.echo(f"annotate: note: no keyframe query for {', '.join(setup.keyframes_missing)}"
                   "; matched everywhere", err=True)
    if not quiet and setup.keyframes_extra:
        click.echo("annotate: note: keyframe queries without a template ignored: "
                   f"{', '.join(setup.keyframes_extra)}", err=True)
    for message in missing:
        click.echo(f"mtanno: {message}", err=True)


COMMANDS = [annotate_cmd]
