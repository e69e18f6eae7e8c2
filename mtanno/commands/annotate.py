"""Commands: annotate, evaluate, compose, truth (algorithms.md §7–8)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from mtanno.annotate import DEFAULT_DELTA, DEFAULT_TAU, load_class_models
from mtanno.commands._common import (
    DELTA,
    TAU,
    lock_output,
    scheduler_option,
    show_progress,
    user_errors,
    wait_option,
)
from mtanno.errors import MtannoError
from mtanno.retrieve import DEFAULT_DELTA as RETRIEVAL_DELTA
from mtanno.templates.model import template_files
from mtanno.util.store import check_layout, document_files

# The helpers below live in the API; these names stay importable from here.
feature_paths = document_files
check_features = check_layout


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
                   "template is matched only inside its candidate windows (MBS09 §5).")
@click.option("--classes", "config_path", type=click.Path(dir_okay=False), default=None,
              help="Class configuration (TOML): per-class tau, superclasses, and the methods "
                   "`mtanno tune` writes (docs/annotation.md).")
@click.option("--tau", type=TAU, default=None,
              help=f"Threshold tau for every class without its own [default: {DEFAULT_TAU:g}].")
@click.option("--delta", type=DELTA, default=None,
              help="Quantization delta of the templates [default: [decoder] delta of "
                   f"--classes, else {DEFAULT_DELTA:g}].")
@click.option("--dbar", "--variant", "variant", type=click.Choice(["reference", "paper"]),
              default="reference", show_default=True,
              help="Modified-distance (Δ̄) variant (algorithms.md §7); --variant is its "
                   "former name.")
@click.option("--match", "match_variant", type=click.Choice(["reference", "paper"]),
              default="reference", show_default=True, help="Matching cost variant (§3.4).")
@click.option("--single-label", is_flag=True,
              help="One label per frame: where segments overlap, each frame keeps the class "
                   "with the smallest modified distance, so the rows form a partition (for "
                   "confusion matrices). Default: the overlapping reference output.")
@click.option("-j", "--jobs", default=1, show_default=True, type=click.IntRange(min=1),
              help="Worker processes (documents in parallel).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@wait_option
@scheduler_option
@user_errors(2)
def annotate_cmd(features, mt_dir, outputs, out_dir, fmt, force, kf_dir, config_path, tau,
                 delta, variant, match_variant, single_label, jobs, quiet, wait, scheduler):
    """Label every frame of documents with motion classes (MBS09 §4).

    FEATURES are feature files or directories of them. Every template is matched against
    every document; frames get the class whose modified distance is smallest (below tau),
    and the labelled runs are extended. Output rows: doc, start, end (1-based inclusive
    frames at 30 Hz), label, cost, start_native, end_native; rows may overlap, unless
    --single-label.

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
    from tqdm import tqdm

    from mtanno.annotate import (
        ANNOTATION_SUFFIXES,
        check_tau,
        load_annotation_setup,
        write_annotations,
    )
    from mtanno.keyframes import keyframe_files
    from mtanno.util.output import check_outputs
    from mtanno.util.tables import output_files, table_format

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
    if tau is not None:
        tau = check_tau(tau, what="--tau")
    missing: list[str] = []  # inputs naming no feature file: reported, the batch goes on
    if out_dir is not None:
        from mtanno.annotate.folder import plan_folder

        folder_jobs = plan_folder(features, out_dir, fmt=fmt or "csv", failures=missing)
        paths = [j.src for j in folder_jobs]
    else:
        folder_jobs, paths = [], feature_paths(features, failures=missing)
    tables = [f for out in outputs for f in output_files(out)]
    written = [*(f for j in folder_jobs for f in output_files(j.dst)), *tables]
    # a document's table that cannot be written fails alone: only -o is tried first; no
    # output where the features are read from, and no -o table among the --output-dir
    # tables (`mtanno evaluate OUT/` would read its rows twice)
    check_outputs(written, [mt_dir, *template_files(mt_dir), config_path, *paths,
                            *(keyframe_files(kf_dir) if kf_dir else [])],
                  scanned={f: (".parquet",) for f in features if Path(f).is_dir()},
                  writable=False)
    check_outputs(tables, [], scanned={out_dir: ANNOTATION_SUFFIXES} if out_dir else None)
    setup = load_annotation_setup(mt_dir, config_path=config_path, keyframes_dir=kf_dir,
                                  tau=tau, delta=delta, dbar_variant=variant,
                                  match_variant=match_variant, single_label=single_label)
    check_outputs(written, setup.files(), writable=False)  # the configuration's templates
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
    bar = tqdm(total=len(paths), unit="doc", disable=not show_progress(quiet), desc="annotate")

    def note_failure(error):
        bar.update(1)
        if error is not None:
            bar.write(f"mtanno: {error}", file=sys.stderr)

    if out_dir is None:
        batch = setup.annotate(paths, n_jobs=jobs, scheduler=scheduler,
                               progress=lambda path, error: note_failure(error))
        bar.close()
        prov = setup.provenance(inputs=batch.files, documents=batch.frames)
        for out in outputs:
            write_annotations(out, batch.rows, batch.native, provenance=prov)
        failed, what = len(batch.failed), f"{len(paths) - len(batch.failed)} documents, " \
                                              f"{len(batch.rows)} segments"
        seconds = batch.seconds
    else:
        from mtanno.annotate.folder import annotate_folder, folder_table
        from mtanno.util.tables import write_table

        with lock_output(out_dir, wait=wait):
            summary = annotate_folder(
                folder_jobs, setup, force=force, n_jobs=jobs, scheduler=scheduler,
                progress=lambda o: note_failure(o.message if o.status == "failed" else None))
            bar.close()
            if outputs:
                table, prov = folder_table(summary, setup)
                for out in outputs:
                    write_table(out, table, provenance=prov)
        failed, seconds = len(summary.failed), summary.seconds
        what = f"{len(folder_jobs)} documents: {summary.line()}" + (
            f", {len(missing)} input(s) without feature files" if missing else "")
        outputs = (out_dir, *outputs)
    if out_dir is None:
        failed += len(missing)
    if not quiet:
        kf = f", keyframes for {len(setup.keyframes)}" if setup.keyframes else ""
        tail = "" if out_dir is not None else f", {failed} failed"
        click.echo(f"annotate: {what}, {len(setup.classes)} classes{kf}{tail}, "
                   f"{seconds:.2f} s of annotation -> {', '.join(map(str, outputs))}", err=True)
    sys.exit(1 if failed or missing else 0)


@click.command("evaluate")
@click.argument("annotations", nargs=-1, required=True, metavar="ANNOTATIONS...",
                type=click.Path(allow_dash=True))
@click.option("--truth", "truth_path", required=True,
              type=click.Path(dir_okay=False, allow_dash=True),
              help="Ground truth table (doc,start,end,label[,fps]).")
@click.option("--json", "json_path", type=click.Path(dir_okay=False, allow_dash=True),
              default=None, help="Also write the report as JSON (schema mtanno.evaluation/1; "
                                 "- for standard output).")
@click.option("-o", "--output", "table_path", type=click.Path(dir_okay=False, allow_dash=True),
              default=None, help="Also write the per-class table (.csv, .parquet, .jsonl, "
                                 "or - for CSV on standard output).")
@click.option("--all-docs", is_flag=True,
              help="Count every truth document, also those not annotated at all (default: "
                   "the documents of ANNOTATIONS — with rows, or recorded in their "
                   "provenance as annotated without any — or those listed with --doc).")
@click.option("--doc", "docs", multiple=True, help="Evaluate only these documents.")
@user_errors(2)
def evaluate_cmd(annotations, truth_path, json_path, table_path, all_docs, docs):
    """Frame- and segment-level precision, recall and F-measure of annotation tables
    against ground truth, overall and per class, with support counts (MBS09 §7), and the
    action-segmentation measures: frame accuracy, Edit score, F1@{10,25,50} (Lea et al.
    2017, as MS-TCN computes them; 0-1, "–" where undefined).

    ANNOTATIONS are annotation tables (from `mtanno annotate`; - reads CSV from standard
    input), e.g. the outputs of a run split over several machines, or folders: every table
    (.csv, .parquet, .jsonl) below a folder, such as the per-document tables of `mtanno
    annotate --output-dir`. A document may appear in only one table. When the annotations
    record their documents' lengths, a truth segment past the end of its document is an
    error.
    """
    from mtanno.annotate import ANNOTATION_SUFFIXES, annotation_files
    from mtanno.evaluation.metrics import evaluate_files
    from mtanno.util.output import check_outputs, write_stdout
    from mtanno.util.tables import output_files, provenance, table_format, write_json, write_table

    if table_path is not None:
        table_format(table_path)
    scanned = {a: ANNOTATION_SUFFIXES for a in annotations if a != "-" and Path(a).is_dir()}
    annotations = annotation_files(annotations)
    inputs = [*annotations, truth_path]
    if sum(str(i) == "-" for i in inputs) > 1:
        raise MtannoError("standard input (-) can be read only once")
    check_outputs([json_path, *output_files(table_path)], inputs, scanned=scanned)
    if json_path == "-" and table_path == "-":
        raise MtannoError("--json - and -o - would both write to standard output")
    report = evaluate_files(annotations, truth_path, docs=docs, all_docs=all_docs)
    for warning in report.warnings:
        click.echo(f"mtanno: warning: {warning}", err=True)
    if json_path != "-" and table_path != "-":
        write_stdout(report.table() + "\n")  # a full device: one line saying so
    prov = provenance(inputs=inputs, truth=str(truth_path))
    if json_path:
        write_json(json_path, {**report.as_dict(), "provenance": prov})
    if table_path:
        import pyarrow as pa

        write_table(table_path, pa.Table.from_pylist(report.rows()), provenance=prov)


@click.command("evaluate-retrieval")
@click.argument("features", nargs=-1, required=True, metavar="FEATURES...")
@click.option("--mt", "mt_dir", required=True, type=click.Path(exists=True),
              help="Directory of class templates (CLASS.json) or one template.")
@click.option("--truth", "truth_path", required=True,
              type=click.Path(dir_okay=False, allow_dash=True),
              help="Ground truth of the documents (doc,start,end,label[,fps]).")
@click.option("--delta", type=DELTA, default=RETRIEVAL_DELTA, show_default=True,
              help=f"Quantization delta of the templates (MR06 retrieval: {RETRIEVAL_DELTA:g}).")
@click.option("--max-hits", default=2000, show_default=True, type=click.IntRange(min=1),
              help="Hit cap per class and document.")
@click.option("--class", "classes", multiple=True, help="Only these classes.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False, allow_dash=True),
              default=None, help="Also write the results as JSON (schema "
                                 "mtanno.retrieval-evaluation/1; - for standard output).")
@click.option("-o", "--output", "table_path", type=click.Path(dir_okay=False, allow_dash=True),
              default=None, help="Also write the table, one row per class and tau (.csv, "
                                 ".parquet, .jsonl, or - for CSV on standard output).")
@user_errors(2)
def evaluate_retrieval_cmd(features, mt_dir, truth_path, delta, max_hits, classes, json_path,
                           table_path):
    """Retrieval quality per class (MR06 Tables 2 and 4): hits |H|, relevant hits |H+|,
    precision and recall for tau = 0.01 … 0.1, top-5/10/20 recall and the separation
    quotient, each template retrieved in all FEATURES documents. A feature file that
    cannot be used is reported and left out (exit code 1)."""
    from mtanno.evaluation.retrieval import retrieval_evaluation, retrieval_report, retrieval_table
    from mtanno.evaluation.truth import check_within, read_truth
    from mtanno.util.output import check_outputs, write_stdout
    from mtanno.util.store import read_features
    from mtanno.util.tables import output_files, provenance, table_format, write_json, write_table

    if table_path is not None:
        table_format(table_path)
    if json_path == "-" and table_path == "-":
        raise MtannoError("--json - and -o - would both write to standard output")
    missing: list[str] = []  # inputs naming no feature file: reported, the batch goes on
    paths = feature_paths(features, failures=missing)
    check_outputs([json_path, *output_files(table_path)],
                  [mt_dir, *template_files(mt_dir), truth_path, *paths],
                  scanned={f: (".parquet",) for f in features if Path(f).is_dir()})
    models, key = load_class_models(mt_dir, delta=delta, classes=tuple(classes))
    truth = read_truth(truth_path)
    for message in missing:
        click.echo(f"mtanno: {message}", err=True)
    documents, files, failed = [], [], len(missing)
    for p in paths:
        try:
            ff = read_features(p, sha256=True)
            check_features(ff, key)
        except MtannoError as exc:
            failed += 1
            click.echo(f"mtanno: {exc}", err=True)
            continue
        documents.append((ff.document, ff.X))
        files.append({"path": str(p), "sha256": ff.sha256})
    check_within(truth, {name: X.shape[1] for name, X in documents}, path=truth_path)
    results = [retrieval_evaluation(m.name, m.values, m.weights, documents, truth,
                                    max_hits=max_hits) for m in models]
    if json_path != "-" and table_path != "-":
        write_stdout(retrieval_report(results) + "\n")
    prov = provenance(inputs=[*files, truth_path], templates=[m.record() for m in models],
                      delta=delta, max_hits=max_hits, feature_set=key.feature_set)
    if json_path:
        write_json(json_path, {"schema": "mtanno.retrieval-evaluation/1",
                               "classes": [r.as_dict() for r in results], "provenance": prov})
    if table_path:
        write_table(table_path, retrieval_table(results), provenance=prov)
    sys.exit(1 if failed else 0)


@click.command("compose")
@click.argument("manifest", type=click.Path(exists=True, dir_okay=False))
@click.option("-o", "--output", "out_dir", required=True, type=click.Path(file_okay=False),
              help="Output directory for the documents, their ASF and truth.csv.")
@click.option("--actor", default=None, help="Use the clips of this actor only.")
@click.option("--split", default=None, help="Use the clips of this split only.")
@click.option("--root", type=click.Path(file_okay=False), default=None,
              help="Folder the manifest's file column is relative to [default: its folder].")
@click.option("--docs", "n_docs", default=10, show_default=True, type=click.IntRange(min=1),
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
@user_errors(2)
def compose_cmd(manifest, out_dir, actor, split, root, n_docs, clips_per_doc, seed, pause, asf,
                in_order):
    """Build long evaluation documents from labelled clips, with their exact ground truth.

    MANIFEST is a CSV with columns file,class[,actor,split] (e.g. the HDM05 clips.csv).
    Clips are drawn in a seeded random order; at every seam the root is turned and moved
    so the next clip starts where and facing how the previous one ended. Writes
    OUT/<ASF stem>_docNN.amc, the ASF, OUT/truth.csv (30 Hz) and OUT/compose.json.
    """
    from mtanno.evaluation.compose import compose_documents, read_clips

    clips = read_clips(manifest, root=root, actor=actor, split=split)
    docs, truth = compose_documents(clips, out_dir, n_docs=n_docs, clips_per_doc=clips_per_doc,
                                    seed=seed, pause=pause, asf=asf, shuffle=not in_order,
                                    inputs=[manifest])
    click.echo(f"compose: {len(docs)} documents, {len(truth)} labelled segments -> {out_dir}",
               err=True)


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
    from mtanno.evaluation.truth import truth_from_mocap6, write_truth
    from mtanno.util.output import check_outputs
    from mtanno.util.tables import output_files, provenance, table_format

    table_format(output)
    check_outputs(output_files(output), [labels])
    segs = truth_from_mocap6(labels)
    write_truth(output, segs, provenance=provenance(inputs=[labels]))
    click.echo(f"truth: {len(segs)} segments -> {output}", err=True)


COMMANDS = [annotate_cmd, evaluate_cmd, evaluate_retrieval_cmd, compose_cmd, truth_group]
