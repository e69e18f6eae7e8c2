"""Command: annotate ([MBS09] §4–5, docs/method.md §7)."""

from __future__ import annotations

import sys

import click

from mtanno.commands._common import (
    DELTA,
    TAU,
    Number,
    former_name,
    inside_input_option,
    scheduler_option,
    show_progress,
    user_errors,
    wait_option,
    waiting_note,
)
from mtanno.templates.params import ANNOTATION_DELTA, ANNOTATION_TAU


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
@click.option("--classes", "config_path", type=click.Path(), default=None,
              help="Class configuration: a TOML file, or a configuration folder that `mtanno "
                   "tune -o DIR/` writes (its classes.toml): per-class tau, superclasses, and "
                   "the methods tune learns (docs/annotation.md).")
@click.option("--tau", type=TAU, default=None,
              help=f"Threshold tau for every class without its own [default: {ANNOTATION_TAU:g}].")
@click.option("--delta", type=DELTA, default=None,
              help="Quantization delta of the templates [default: [decoder] delta of "
                   f"--classes, else {ANNOTATION_DELTA:g}].")
@click.option("--dbar", "variant", type=click.Choice(["reference", "paper"]),
              default="reference", show_default=True,
              help="Modified-distance (Δ̄) variant (docs/annotation.md).")
@former_name("--variant", "--dbar", "variant", type=click.Choice(["reference", "paper"]))
@click.option("--match", "match_variant", type=click.Choice(["reference", "paper"]),
              default="reference", show_default=True, help="Matching cost variant (docs/method.md §3.4).")
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
@inside_input_option
@wait_option
@scheduler_option
@user_errors(2, flags={"outputs": "-o TABLE", "out_dir": "--output-dir OUT/",
                        "fmt": "--format"})
def annotate_cmd(features, mt_dir, outputs, out_dir, fmt, force, kf_dir, config_path, tau,
                 delta, variant, match_variant, single_label, min_confidence,
                 jobs, quiet, inside_input, wait, scheduler):
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
    skipped, assembled from their tables. `mtanno evaluate OUT/` reads the folder. OUT/ may
    not be, or lie inside, a folder of FEATURES, --mt or --keyframes unless --inside-input
    says so (Parquet tables inside a FEATURES folder never: the next run would read them).

    Exit codes: 0 success, 1 some documents failed (the others were annotated), 2 bad
    input (nothing written), 3 OUT/ locked by another run, 130 interrupted (finished
    tables are complete and are skipped by the rerun).
    """
    from tqdm import tqdm

    from mtanno.annotate.options import AnnotateOptions
    from mtanno.annotate.run import annotate_to

    bar = None

    def write(line: str) -> None:
        if bar is None:
            click.echo(line, err=True)
        else:
            bar.write(line, file=sys.stderr)

    failures = _FailureLines(write)

    def start(setup, missing, n):
        nonlocal bar
        _notes(setup, missing, quiet)
        bar = tqdm(total=n, unit="doc", disable=not show_progress(quiet), desc="annotate")

    def note_failure(path, error):
        bar.update(1)
        failures.add(path, error)

    try:
        run = annotate_to(
            features, mt_dir, AnnotateOptions(
                config_path=config_path, keyframes_dir=kf_dir, tau=tau, delta=delta,
                dbar_variant=variant, match_variant=match_variant, single_label=single_label,
                min_confidence=min_confidence, n_jobs=jobs, scheduler=scheduler),
            outputs=outputs, out_dir=out_dir, fmt=fmt, force=force, wait=wait,
            inside_input=inside_input, on_start=start,
            progress=note_failure, on_wait=waiting_note(out_dir))
    finally:
        if bar is not None:
            bar.close()
        failures.finish()
    if not quiet:
        setup = run.setup
        kf = f", keyframes for {len(setup.keyframes)}" if setup.keyframes else ""
        tail = "" if out_dir is not None else f", {run.failed} failed"
        click.echo(f"annotate: {run.what}, {len(setup.classes)} classes{kf}{tail}, "
                   f"{run.seconds:.2f} s of annotation -> {', '.join(map(str, run.written))}",
                   err=True)
    sys.exit(run.exit_code)


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
