"""``mtanno report``: HTML page, figures and paper tables of an annotation run."""

from __future__ import annotations

import click

from mtanno.commands._common import DELTA, TAU, user_errors
from mtanno.errors import MtannoError


@click.command("report", epilog="Exit codes: 0 success, 2 bad input or matplotlib missing.")
@click.argument("annotations", nargs=-1, required=True, metavar="ANNOTATIONS...",
                type=click.Path())
@click.option("--truth", "truth_path", required=True, type=click.Path(dir_okay=False),
              help="Ground truth table (doc,start,end,label[,fps]).")
@click.option("-o", "--output", "out_dir", required=True, type=click.Path(file_okay=False),
              help="Report folder (created): index.html, tables, PNG and SVG figures.")
@click.option("--mt", "mt_dir", type=click.Path(exists=True), default=None,
              help="Template folder: adds each template as a heat map, and with --features "
                   "each class's Δ curve over every document.")
@click.option("--features", "features", multiple=True, type=click.Path(exists=True),
              help="Feature files or folders of the annotated documents (with --mt). "
                   "Repeatable.")
@click.option("--tau", type=TAU, default=None,
              help="Threshold drawn in the Δ plots [default: the annotation's tau, and "
                   "its per-class taus in the classes' colours].")
@click.option("--delta", type=DELTA, default=None,
              help="Quantization delta of the templates for the Δ plots [default: the "
                   "annotation's, else 0.05].")
@click.option("--title", default="mtanno annotation report", show_default=True,
              help="Title of the page.")
@click.option("-q", "--quiet", is_flag=True, help="No summary line.")
@user_errors(2)
def report_cmd(annotations, truth_path, out_dir, mt_dir, features, tau, delta, title,
               quiet):
    """Write a report of annotation tables against ground truth (MBS09 §7) into a folder.

    \b
    index.html                 self-contained page (images inline): open it in a browser
    per_class.csv|.md|.tex     P/R/F per class, frames and segments, with support
    confusion.csv|.png|.svg    frame-level confusion matrix, truth x annotation, with "none"
    timeline_DOC.png|.svg      per document: truth against annotation
    template_CLASS.png|.svg    with --mt: the templates as heat maps
    delta_DOC.png|.svg         with --mt and --features: each class's Δ over the document

    ANNOTATIONS are annotation tables or folders of them (every .csv, .parquet and .jsonl
    table below a folder, such as the per-document tables of `mtanno annotate
    --output-dir`).

    Needs matplotlib (pip install 'mtanno[plot]'). For an exact confusion matrix annotate
    with --single-label; overlapping rows are resolved by segment cost (the page says so).
    """
    from pathlib import Path

    from mtanno.annotate import (
        ANNOTATION_SUFFIXES,
        DEFAULT_TAU,
        annotation_files,
        read_annotation_tables,
    )
    from mtanno.evaluation.report import REPORT_FILES, annotation_parameters, write_report
    from mtanno.evaluation.truth import check_within, read_truth
    from mtanno.plot import require_matplotlib
    from mtanno.templates.model import load_template_folder, template_files
    from mtanno.util.output import check_outputs
    from mtanno.util.store import document_files, read_features
    from mtanno.util.tables import provenance

    require_matplotlib()
    if features and not mt_dir:
        raise MtannoError("--features goes with --mt (the Δ curves need the templates)")
    paths = document_files(features) if features else []
    # folders read whole: an output there would be read by the next run
    scanned = {**{a: ANNOTATION_SUFFIXES for a in annotations if Path(a).is_dir()},
               **{f: (".parquet",) for f in features if Path(f).is_dir()}}
    annotations = annotation_files(annotations)
    check_outputs([], [*annotations, truth_path, *paths,
                       *(template_files(mt_dir) if mt_dir else [])],
                  folders={out_dir: REPORT_FILES}, scanned=scanned)
    rows, frames, provs = read_annotation_tables(annotations)
    recorded = annotation_parameters(provs)
    truth = read_truth(truth_path)
    check_within(truth, frames, path=truth_path)
    templates = load_template_folder(mt_dir) if mt_dir else None
    feats = {}
    for p in paths:
        ff = read_features(p)
        feats[ff.document] = ff.X
    if tau is None:  # the annotation's thresholds
        tau = DEFAULT_TAU if recorded["tau"] is None else recorded["tau"]
        per_class = recorded["tau_per_class"]
    else:
        per_class = {}
    result = write_report(out_dir, truth, rows, frames=frames, templates=templates,
                          features=feats or None, tau=tau, tau_per_class=per_class,
                          delta=delta if delta is not None else recorded["delta"],
                          extra_templates=recorded["extra_templates"],
                          title=title, provenance=provenance(
                              inputs=[*annotations, truth_path], truth=str(truth_path)))
    if not quiet:
        ov = result.evaluation.frame
        click.echo(f"report: {len(result.evaluation.documents)} documents, F1 {ov.F:.3f}, "
                   f"{len(result.files)} files -> {result.page}", err=True)


COMMANDS = [report_cmd]
