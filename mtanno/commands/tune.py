"""The ``tune`` command: annotation parameters learned by cross-validation inside
the training data, written as the class configuration ``annotate --classes`` reads.
Exit codes: 0 success, 1 a training folder gave no example (the others were used), 2 usage
error or bad input, 130 interrupted."""

from __future__ import annotations

import sys

import click

from mtanno.commands._common import (
    ARGUMENT_NAMES,
    Number,
    inside_input_option,
    scheduler_option,
    training_options,
    user_errors,
)
from mtanno.confidence.evidence import EVIDENCE
from mtanno.confidence.verify import INVARIANCES
from mtanno.errors import MtannoError
from mtanno.tuning.cv import DOCUMENT_MODES, MAX_EXAMPLES
from mtanno.tuning.run import VERIFY_MODES
from mtanno.tuning.search import METHODS, UNKNOWN_WEIGHT


@click.command("tune", epilog="Exit codes: 0 success, 1 a training folder gave no example "
                              "(the others were used), 2 usage error or bad input, 130 "
                              "interrupted.")
@click.argument("training", nargs=-1, metavar="[TRAINING]...")
@click.option("--mt", "mt_dir", required=True, type=click.Path(),
              help="Folder of class templates (CLASS.json from learn-mt): the classes tuned.")
@click.option("--keyframes", "kf_dir", type=click.Path(), default=None,
              help="Folder of keyframe queries (learn-keyframes): held-out documents are "
                   "matched only inside their windows, as annotate --keyframes does.")
@click.option("-o", "--output", required=True, type=click.Path(),
              help="Configuration folder to write (DIR/: classes.toml, templates/, "
                   "verify.parquet, named relative to each other: move or rename it as one; "
                   "`annotate --classes DIR`), or CONFIG.toml with CONFIG.templates/ and "
                   "CONFIG.verify.parquet beside it.")
@training_options(
    manifest_help="Manifest CSV (file,class[,actor,split]) listing the training clips; the "
                  "actor column names the performers held out in turn.",
    truth_help="Truth table; every labelled segment of the TRAINING feature files is an "
               "example, and each document is held out in turn.")
@click.option("--documents", type=click.Choice(DOCUMENT_MODES), default="composed",
              show_default=True,
              help="How held-out clips become documents: composed (concatenated in random "
                   "orders, like `mtanno compose`) or separate (one document per clip).")
@click.option("--disable", "disabled", multiple=True, type=click.Choice(METHODS),
              metavar="METHOD",
              help=f"Leave a method as in the reference annotation (repeatable): "
                   f"{', '.join(METHODS)}.")
@click.option("--unknown-weight", default=UNKNOWN_WEIGHT, show_default=True,
              type=Number(min=0),
              help="Weight w of the unknown-class rate in the objective (F1 + F2)/2 − w·U.")
@click.option("--ablation", "ablation_dir", type=click.Path(file_okay=False), default=None,
              help="Also tune with each method left out, and with none, on the same folds; "
                   "write DIR/without-METHOD.toml and DIR/none.toml (an ablation study). DIR "
                   "may not be, or lie inside, an input folder unless --inside-input says so.")
@click.option("--background", "background", multiple=True, type=click.Path(),
              metavar="PATH",
              help="Feature files (or folders of them) of motions that hold none of the "
                   "classes (repeatable): held out with the training performers, every label "
                   "on them counts as wrong; recorded with SHA-256 in [background].")
@click.option("--verify", type=click.Choice(VERIFY_MODES), default="auto", show_default=True,
              help="How each segment is verified for its confidence: against the training "
                   "examples (and background) by poses (mtanno features --poses), by the "
                   "boolean features, or not at all; auto: poses when every file has them.")
@click.option("--invariance", "invariance", multiple=True, type=click.Choice(INVARIANCES),
              help="Make the pose verification blind to what is not motion (repeatable): "
                   "retarget (compare poses on one canonical skeleton, whatever the rig's "
                   "proportions), mirror (a segment also verified mirrored, left and right "
                   "swapped). Recorded in the bank and [confidence].")
@click.option("--evidence", "evidence", multiple=True, type=click.Choice(EVIDENCE),
              help="The evidence the confidence may use (repeatable; default: cost, length, "
                   "verify, margin, background, as far as the inputs allow; classifier adds a "
                   "frame classifier, CONFIG.frames.parquet; docs/annotation.md, Confidence). "
                   "Recorded in [confidence].")
@click.option("--confidence/--no-confidence", default=True, show_default=True,
              help="Learn the confidence of each segment and the minimum confidence of an "
                   "output row ([confidence], bank CONFIG.verify.parquet beside CONFIG).")
@click.option("--max-examples", default=MAX_EXAMPLES, show_default=True,
              type=click.IntRange(min=0),
              help="Learn each template of the cross-validation (and each group template) "
                   "from at most N examples of its class, drawn evenly over the performers "
                   "(learning costs grow with the square of the examples); 0: all.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="Seed of the held-out document composition (same seed, same file).")
@click.option("-j", "--jobs", default=1, show_default=True, type=click.IntRange(min=1),
              help="Worker processes for learning and matching per fold and class.")
@click.option("-q", "--quiet", is_flag=True, help="No search log and no summary line.")
@inside_input_option
@scheduler_option
@user_errors(2)
def tune_cmd(training, mt_dir, kf_dir, output, manifest, features_dir, split, truth, documents,
             disabled, unknown_weight, ablation_dir, background, verify, invariance, evidence,
             confidence, max_examples, seed, jobs, quiet, inside_input, scheduler):
    """Learn the annotation parameters from the training data alone.

    Cross-validation inside the training examples: each performer (manifest actor, or
    truth document) is held out in turn; templates are learned from the others, the
    held-out examples are composed into documents and annotated, and the parameters that
    score best over all folds are kept — per-class tau, a rejection ceiling per class,
    the segment decoder (overlap resolution) and its cost per segment, boundary
    refinement, several templates per class (groups of similar examples, and copies
    time-scaled to 0.6 or 1.6 times the length for faster or slower performances, within
    a budget of 15 % more matched columns), frame-wise tie-breaking, the quantization
    delta. The objective is (F1 + F2)/2 − w·U with U the unknown-class rate (each class
    left out in turn).

    Training examples come as for learn-mt (a manifest with --features-dir, --truth with
    feature files, or CLASS/ folders; with --truth, segments of documents that are not
    among TRAINING are ignored and a note names those documents). Writes the class
    configuration (TOML: [decoder], [tau], [reject], [templates], [confidence], [inputs] —
    what the documents' feature files need, e.g. poses —, with the cross-validated scores
    and the training files as comments; docs/annotation.md) for `mtanno annotate --mt MT/
    --classes CONFIG`: a configuration folder for any OUTPUT not ending in .toml (its
    files named relative to each other, so that it moves as one), else the TOML file with
    its side files beside it.

    Example: mtanno tune --mt mts/ --manifest ../shared/data/hdm05_cut/clips.csv
    --features-dir feats/ --split train -o tuned/ --jobs 2
    """
    from mtanno.tuning.run import TuneOptions, tune_files
    from mtanno.util.provenance import command_line

    skipped: list[MtannoError] = []
    result = tune_files(
        training, mt_dir, output, TuneOptions(
            keyframes_dir=kf_dir, seed=seed, n_jobs=jobs,
            methods=[m for m in METHODS if m not in disabled], documents=documents,
            unknown_weight=unknown_weight, scheduler=scheduler, background=background,
            verify=verify, confidence=confidence, invariance=invariance,
            evidence=evidence or None, max_examples=max_examples),
        manifest=manifest, features_dir=features_dir, split=split, truth=truth,
        ablation_dir=ablation_dir, inside_input=inside_input,
        log=None if quiet else lambda line: click.echo(f"tune: {line}", err=True),
        command=command_line(), failures=skipped)
    for exc in skipped:
        click.echo(f"mtanno: {exc.for_command(ARGUMENT_NAMES)}", err=True)
    if result.not_validated:
        click.echo(f"tune: warning: class(es) {', '.join(result.not_validated)} could not be "
                   "cross-validated: all their examples come from one performer, so their "
                   "thresholds are learned only from the motions they must not label",
                   err=True)
    if not quiet:
        extra = (f", extra templates in {result.extra_folder}"
                 if result.extra_folder is not None else "")
        p1, r1, f1 = result.evaluation.counts.frame()
        p2, r2, f2 = result.evaluation.counts.segment()
        click.echo(f"tune: {len(result.classes)} classes, {len(result.folds)} folds, "
                   f"cross-validated F1 {f1:.3f} F2 {f2:.3f} unknown-class rate "
                   f"{result.evaluation.unknown:.3f} (reference: F1 "
                   f"{result.reference.counts.frame()[2]:.3f} F2 "
                   f"{result.reference.counts.segment()[2]:.3f}), {result.seconds:.1f} s -> "
                   f"{output}{extra}", err=True)
    sys.exit(1 if skipped else 0)

COMMANDS = [tune_cmd]
