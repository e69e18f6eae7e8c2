"""Commands of the evaluation stage: evaluate, evaluate-retrieval, compose, truth and report
(docs/method.md §8, [MBS09] §7, [MR06] §5.4–5.5)."""

from __future__ import annotations

import sys

import click

from mtanno.commands._common import DELTA, TAU, ProgressBar, inside_input_option, stack, user_errors
from mtanno.evaluation.compose import DEFAULT_DOCS as COMPOSE_DOCS
from mtanno.evaluation.retrieval import DEFAULT_MAX_HITS as RETRIEVAL_MAX_HITS
from mtanno.templates.params import RETRIEVAL_DELTA

#: The flags of the API's names for the two further outputs (:func:`json_and_table_options`).
REPORT_FLAGS = {"json_path": "--json", "table_path": "-o"}


def json_and_table_options(*, json_what: str, schema: str, table_what: str):
    """``--json FILE`` and ``-o TABLE``: the two further outputs of evaluate and
    evaluate-retrieval (``-`` for standard output)."""
    return stack(
        click.option("--json", "json_path", default=None,
                     type=click.Path(dir_okay=False, allow_dash=True),
                     help=f"Also write {json_what} as JSON (schema {schema}; - for "
                          "standard output)."),
        click.option("-o", "--output", "table_path", default=None,
                     type=click.Path(dir_okay=False, allow_dash=True),
                     help=f"Also write {table_what} (.csv, .parquet, .jsonl, or - for "
                          "CSV on standard output)."))


@click.command("evaluate")
@click.argument("annotations", nargs=-1, required=True, metavar="ANNOTATIONS...",
                type=click.Path(allow_dash=True))
@click.option("--truth", "truth_path", required=True,
              type=click.Path(dir_okay=False, allow_dash=True),
              help="Ground truth table (doc,start,end,label[,fps]).")
@json_and_table_options(json_what="the report", schema="mtanno.evaluation/1",
                        table_what="the per-class table")
@click.option("--all-docs", is_flag=True,
              help="Count every truth document, also those not annotated at all (default: "
                   "the documents of ANNOTATIONS — with rows, or recorded in their "
                   "provenance as annotated without any — or those listed with --doc).")
@click.option("--doc", "docs", multiple=True, help="Evaluate only these documents.")
@user_errors(2, flags=REPORT_FLAGS)
def evaluate_cmd(annotations, truth_path, json_path, table_path, all_docs, docs):
    """Frame- and segment-level precision, recall and F-measure of annotation tables
    against ground truth, overall and per class, with support counts ([MBS09] §7), and the
    action-segmentation measures: frame accuracy, Edit score, F1@{10,25,50} (Lea et al.
    2017, as MS-TCN computes them; 0-1, "–" where undefined).

    ANNOTATIONS are annotation tables (from `mtanno annotate`; - reads CSV from standard
    input), e.g. the outputs of a run split over several machines, or folders: every table
    (.csv, .parquet, .jsonl) below a folder, such as the per-document tables of `mtanno
    annotate --output-dir`. A document may appear in only one table. When the annotations
    record their documents' lengths, a truth segment past the end of its document is an
    error.
    """
    from mtanno.evaluation.metrics import evaluate_to

    evaluate_to(annotations, truth_path, json_path=json_path, table_path=table_path, docs=docs,
                all_docs=all_docs,
                warn=lambda warning: click.echo(f"mtanno: warning: {warning}", err=True))


@click.command("evaluate-retrieval")
@click.argument("features", nargs=-1, required=True, metavar="FEATURES...")
@click.option("--mt", "mt_dir", required=True, type=click.Path(exists=True),
              help="Directory of class templates (CLASS.json) or one template.")
@click.option("--truth", "truth_path", required=True,
              type=click.Path(dir_okay=False, allow_dash=True),
              help="Ground truth of the documents (doc,start,end,label[,fps]).")
@click.option("--delta", type=DELTA, default=RETRIEVAL_DELTA, show_default=True,
              help=f"Quantization delta of the templates ([MR06] retrieval: {RETRIEVAL_DELTA:g}).")
@click.option("--max-hits", default=RETRIEVAL_MAX_HITS, show_default=True, type=click.IntRange(min=1),
              help="Hit cap per class and document.")
@click.option("--class", "classes", multiple=True, help="Only these classes.")
@json_and_table_options(json_what="the results", schema="mtanno.retrieval-evaluation/1",
                        table_what="the table, one row per class and tau")
@user_errors(2, flags=REPORT_FLAGS)
def evaluate_retrieval_cmd(features, mt_dir, truth_path, delta, max_hits, classes, json_path,
                           table_path):
    """Retrieval quality per class ([MR06] Tables 2 and 4): hits |H|, relevant hits |H+|,
    precision and recall for tau = 0.01 … 0.1, top-5/10/20 recall and the separation
    quotient, each template retrieved in all FEATURES documents. A feature file that
    cannot be used is reported and left out (exit code 1)."""
    from mtanno.evaluation.retrieval import evaluate_retrieval_to

    def start(missing: list[str]) -> None:
        for message in missing:
            click.echo(f"mtanno: {message}", err=True)

    run = evaluate_retrieval_to(features, mt_dir, truth_path, delta=delta, max_hits=max_hits,
                                classes=classes, json_path=json_path, table_path=table_path,
                                on_start=start,
                                progress=lambda m: click.echo(f"mtanno: {m}", err=True))
    sys.exit(run.exit_code)


@click.command("compose")
@click.argument("manifest", type=click.Path(exists=True, dir_okay=False))
@click.option("-o", "--output", "out_dir", required=True, type=click.Path(file_okay=False),
              help="Output directory for the documents, their ASF and truth.csv.")
@click.option("--actor", default=None, help="Use the clips of this actor only.")
@click.option("--split", default=None, help="Use the clips of this split only.")
@click.option("--root", type=click.Path(file_okay=False), default=None,
              help="Folder the manifest's file column is relative to [default: its folder].")
@click.option("--docs", "n_docs", default=COMPOSE_DOCS, show_default=True, type=click.IntRange(min=1),
              help="Number of documents.")
@click.option("--clips-per-doc", type=click.IntRange(min=1), default=None,
              help="Clips per document [default: all clips, each once].")
@click.option("--seed", default=0, show_default=True, type=int, help="Random seed.")
@click.option("--pause", default=0, show_default=True, type=click.IntRange(min=0),
              help="Native frames of stillness between clips (unlabelled).")
@click.option("--asf", type=click.Path(exists=True, dir_okay=False), default=None,
              help="ASF skeleton of the clips [default: found beside them].")
@click.option("--in-order", is_flag=True,
              help="Keep the manifest order instead of shuffling (e.g. one document of all "
                   "clips, for retrieval tables).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@inside_input_option
@user_errors(2)
def compose_cmd(manifest, out_dir, actor, split, root, n_docs, clips_per_doc, seed, pause, asf,
                in_order, quiet, inside_input):
    """Build long evaluation documents from labelled clips, with their exact ground truth.

    MANIFEST is a CSV with columns file,class[,actor,split] (e.g. the HDM05 clips.csv).
    Clips are drawn in a seeded random order; at every seam the root is turned and moved
    so the next clip starts where and facing how the previous one ended. Writes
    OUT/<ASF stem>_docNN.amc, the ASF, OUT/truth.csv (30 Hz) and OUT/compose.json. OUT may
    not be, or lie inside, a folder holding clips unless --inside-input says so: the
    documents would be read as clips by the next `mtanno features` over it.
    """
    from mtanno.evaluation.compose import ComposeOptions, compose_to

    with ProgressBar("compose", "file", quiet=quiet) as bar:
        docs, truth = compose_to(manifest, out_dir, root=root, actor=actor, split=split,
                                 asf=asf, options=ComposeOptions(
                                     n_docs=n_docs, clips_per_doc=clips_per_doc, seed=seed,
                                     pause=pause, shuffle=not in_order),
                                 inside_input=inside_input, progress=bar)
    if not quiet:
        click.echo(f"compose: {len(docs)} documents, {len(truth)} labelled segments -> "
                   f"{out_dir}", err=True)


@click.group("truth")
def truth_group():
    """Convert ground-truth labels into mtanno's truth table (doc,start,end,label,fps)."""


@truth_group.command("mocap6")
@click.argument("labels", type=click.Path(exists=True, dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, allow_dash=True),
              help="Truth table: .csv, .parquet or .jsonl, or - for CSV on standard output.")
@user_errors(2)
def truth_mocap6(labels, output):
    """CMU mocap6 labels.json → truth table at 30 Hz."""
    from mtanno.labels.truth import mocap6_to

    segs = mocap6_to(labels, output)
    click.echo(f"truth: {len(segs)} segments -> {output}", err=True)


@click.command("report", epilog="Exit codes: 0 success, 1 a feature or motion file could "
                                "not be read (the report was written without it), 2 bad "
                                "input or matplotlib missing.")
@click.argument("annotations", nargs=-1, required=True, metavar="ANNOTATIONS...",
                type=click.Path())
@click.option("--truth", "truth_path", default=None, type=click.Path(dir_okay=False),
              help="Ground truth table (doc,start,end,label[,fps]); without it the page "
                   "summarises the annotation (an archive nobody has labelled).")
@click.option("-o", "--output", "out_dir", required=True, type=click.Path(file_okay=False),
              help="Report folder (created): index.html, data/, tables, PNG and SVG figures.")
@click.option("--mt", "mt_dir", type=click.Path(exists=True), default=None,
              help="Template folder: adds each template as a heat map, and with --features "
                   "each class's Δ curve over every document.")
@click.option("--features", "features", multiple=True, type=click.Path(exists=True),
              help="Feature files or folders of the annotated documents: with --mt the Δ "
                   "curves; files with poses (features --poses) give the player its "
                   "motions; with --motions each motion is checked against the SHA-256 "
                   "its feature file records. "
                   "Repeatable.")
@click.option("--motions", "motions", multiple=True, type=click.Path(), metavar="PATH",
              help="Motion files (.amc, .bvh, .c3d) or folders of them, matched to the documents "
                   "by file name: the player shows each as a stick figure of its rig "
                   "(instead of the poses of --features). Repeatable.")
@click.option("--asf", type=click.Path(exists=True, dir_okay=False), default=None,
              help="ASF skeleton of AMC motions (default: found beside or above each).")
@click.option("--tau", type=TAU, default=None,
              help="Threshold drawn with the Δ curves [default: the annotation's tau, and "
                   "its per-class taus in the classes' colours].")
@click.option("--delta", type=DELTA, default=None,
              help="Quantization delta of the templates for the Δ curves [default: the "
                   "annotation's, else 0.05].")
@click.option("--title", default="mtanno annotation report", show_default=True,
              help="Title of the page.")
@click.option("-j", "--jobs", default=1, show_default=True, type=click.IntRange(min=1),
              help="Processes reading the motion files.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@inside_input_option
@user_errors(2)
def report_cmd(annotations, truth_path, out_dir, mt_dir, features, motions, asf, tau, delta,
               title, jobs, quiet, inside_input):
    """Write a report of annotation tables into a folder, against ground truth ([MBS09] §7)
    when --truth is given: a page to review thousands of documents, and tables for papers.

    \b
    index.html                 the page: open it in a browser (it needs its folder)
    data/HASH.js               the documents' poses and Δ curves, loaded by the page
    per_class.csv|.md|.tex     with --truth: P/R/F per class, frames and segments, support
    confusion.csv|.png|.svg    with --truth: frame confusion matrix, truth x annotation
    reliability.png|.svg       with --truth: how well the confidence column is calibrated
    summary.csv|.md            without --truth: per class segments, duration, share
    review.csv                 every row, the least confident first (the rows to check)
    template_CLASS.png|.svg    with --mt: the templates as heat maps
    figures.json               what each figure was drawn from: a rerun redraws only changes

    The page lists every document as a row with its timeline (opacity: confidence),
    filtered by label, name and confidence range, sorted, counted per class; the selected
    document plays beside the list (with --motions, or --features files that hold poses;
    with --mt and --features its Δ curves too). index.html#doc=NAME&frame=F opens a
    document at a frame, #autoplay plays it. Rows are accepted, rejected or relabelled at
    the keyboard (j/k, a, x, l), kept across reloads, and "Download truth" saves the
    accepted rows as a truth CSV for learn-mt, tune and evaluate --truth (a label beginning
    with = + - @ is refused there: a spreadsheet would run it). A motion whose frame count
    is not the annotation's is said and not played (exit code 1). Details:
    docs/annotation.md.

    ANNOTATIONS are annotation tables or folders of them (every .csv, .parquet and .jsonl
    table below a folder, such as the per-document tables of `mtanno annotate
    --output-dir`). The report folder may not be, or lie inside, a folder of the inputs
    (annotation tables, --features, --motions, --mt) unless --inside-input says so.

    Needs matplotlib (pip install 'mtanno[plot]'). For an exact confusion matrix annotate
    with --single-label; overlapping rows are resolved by segment cost (the page says so).
    """
    from mtanno.evaluation.report import ReportOptions, report_files

    failures: list[str] = []  # inputs that could not be used: reported, the report goes on
    with ProgressBar("report", "step", quiet=quiet) as bar:
        result, _ = report_files(annotations, out_dir, truth_path=truth_path, mt_dir=mt_dir,
                                 features=features, motions=motions, asf=asf,
                                 options=ReportOptions(tau=tau, delta=delta, title=title),
                                 inside_input=inside_input, jobs=jobs, progress=bar,
                                 failures=failures)
    for message in failures:
        click.echo(f"mtanno: {message}", err=True)
    if not quiet:  # the page's summary: documents annotated, those with rows, rows, F1
        click.echo(f"report: {result.summary}; {len(result.files)} files -> {result.page}",
                   err=True)
    sys.exit(1 if failures else 0)


COMMANDS = [evaluate_cmd, evaluate_retrieval_cmd, compose_cmd, truth_group, report_cmd]
