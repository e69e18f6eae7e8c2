"""Commands of the motion-template stage: ``learn-mt`` and the ``mt`` group (show, mirror, scale,
quantize). Exit codes: 0 success, 1 some classes failed (the others were written), 2 usage
error or bad input."""

from __future__ import annotations

import sys
from pathlib import Path

import click
import numpy as np

from mtanno.commands._common import (
    ARGUMENT_NAMES,
    DELTA,
    EXIT_BAD_INPUT,
    EXIT_BAD_INPUT_OR_PLOT,
    EXIT_PER_CLASS,
    Number,
    inside_input_option,
    show_progress,
    training_argument,
    training_options,
    user_errors,
    wait_option,
    waiting_note,
)
from mtanno.templates.describe import TOP_FEATURES
from mtanno.templates.learn import ITER_MAX, ITER_THRESH
from mtanno.templates.params import RETRIEVAL_DELTA


@click.command("learn-mt", epilog=EXIT_PER_CLASS)
@training_argument
@click.option("-o", "--output", "outdir", required=True, type=click.Path(file_okay=False),
              help="Output folder; one CLASS.json per class is written there.")
@training_options(
    manifest_help="Manifest CSV with columns file,class[,split,...] listing the examples (no "
                  "TRAINING arguments then).",
    truth_help="Truth table (doc,start,end,label[,fps]); every labelled segment of the "
               "TRAINING feature files is an example of its label.")
@click.option("--hard", is_flag=True,
              help="Learn hard templates (thesis §3.3: wildcard where examples disagree) "
                   "instead of soft ones ([MR06] §4.1).")
@click.option("--class", "classes", multiple=True, metavar="NAME",
              help="Learn only this class (repeatable). Default: every class found.")
@click.option("--iterations", default=ITER_MAX, show_default=True, type=click.IntRange(min=1),
              help="Maximum number of learning iterations.")
@click.option("--thresh", default=ITER_THRESH, show_default=True, type=Number(min=0),
              help="Stop once the largest normalised alignment cost is at most this.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@inside_input_option
@wait_option
@user_errors(2)
def learn_mt_cmd(training, outdir, manifest, features_dir, split, truth, hard, classes,
                 iterations, thresh, quiet, inside_input, wait):
    """Learn one motion template per class from example clips ([MR06] §4.1).

    Training examples come from one of:

    \b
      TRAINING...                  folders ROOT with ROOT/CLASS/*.parquet feature files;
                                   each file is one example of the class named by its
                                   folder (the layout `mtanno features` gives for a
                                   CLASS/*.amc tree)
      --manifest CSV --features-dir DIR [--split train]
                                   the rows of a manifest (file,class[,split]); the
                                   feature file of row `file` is DIR/<file>.parquet
      --truth TRUTH.csv TRAINING...
                                   labelled segments (30 Hz, 1-based inclusive) of the
                                   TRAINING feature files (files or folders), each cut
                                   out as an example of its label

    With --truth, segments of documents that are not among TRAINING are ignored (a note
    names those documents). A class learned from fewer than 3 examples gets a warning.
    Examples of a class are used in file-name order (segments by start frame); the
    template returned is the one learned with the first example as reference. Writes
    OUTDIR/CLASS.json (schema mtanno.template/1: values, weights, training files with
    SHA-256, parameters, iterations, final cost); see `mtanno mt show`. OUTDIR may not be,
    or lie inside, a TRAINING folder or --features-dir unless --inside-input says so.

    Example: mtanno learn-mt --manifest ../shared/data/hdm05_cut/clips.csv
    --features-dir feats/ --split train -o mts/
    """
    from tqdm import tqdm

    from mtanno.templates.learn import learn_to_folder

    bar = None

    def start(n: int) -> None:
        nonlocal bar
        bar = tqdm(total=n, unit="class", desc="learn-mt", disable=not show_progress(quiet))

    def progress(done, error):
        bar.update(1)
        bar.set_postfix_str(done.class_name)
        if error is not None:
            bar.write(f"mtanno: class {done.class_name}: {error}", file=sys.stderr)
        elif done.warning:
            bar.write(f"learn-mt: {done.warning}", file=sys.stderr)

    try:
        run = learn_to_folder(
            training, outdir, manifest=manifest, features_dir=features_dir, split=split,
            truth=truth, classes=classes, hard=hard, iter_max=iterations, thresh=thresh,
            wait=wait, on_wait=waiting_note(outdir), on_start=start, progress=progress,
            inside_input=inside_input,
            note=None if quiet else lambda m: click.echo(f"learn-mt: {m}", err=True))
    finally:
        if bar is not None:
            bar.close()
    for exc in run.skipped:
        click.echo(f"mtanno: {exc.for_command(ARGUMENT_NAMES)}", err=True)
    if not quiet:
        kind = "hard" if hard else "soft"
        click.echo(f"learn-mt: {len(run.written)} {kind} template(s) from {run.n_examples} "
                   f"examples -> {Path(outdir)}, {len(run.failed)} class(es) failed, "
                   f"{run.seconds:.1f} s", err=True)
    sys.exit(run.exit_code)


@click.group("mt")
def mt_group():
    """Inspect and transform motion-template files (CLASS.json from `mtanno learn-mt`)."""


@mt_group.command("show", epilog=EXIT_BAD_INPUT)
@click.argument("template", type=click.Path(dir_okay=False))
@click.option("--delta", type=DELTA, default=None,
              help="Quantization δ for the feature ranking and picture of an unquantized "
                   f"template  [default: {RETRIEVAL_DELTA:g}, MR06]")
@click.option("--top", default=TOP_FEATURES, show_default=True, type=click.IntRange(min=0),
              help="How many features to list.")
@click.option("--picture", is_flag=True,
              help="Draw the quantized template: one row per feature, one character per "
                   "column ('#' 1, '.' 0, '~' wildcard).")
@click.option("--files", is_flag=True, help="List every training file.")
@user_errors(2)
def mt_show_cmd(template, delta, top, picture, files):
    """Print a readable summary of a motion template.

    Shows the class, kind, length, the performance lengths a match can cover, weights,
    learning result (iterations and final spread = largest normalised alignment cost), the
    training files with their lengths, and the features
    with the most non-wildcard entries after quantization (those the matching relies
    on); --picture draws the quantized template.
    """
    from mtanno.templates.describe import format_template
    from mtanno.templates.model import load_template

    mt = load_template(template)
    click.echo(format_template(mt, path=template, delta=delta, top=top, picture=picture,
                               files=files))


@mt_group.command("mirror", epilog=EXIT_BAD_INPUT)
@click.argument("template", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output template file.")
@click.option("--name", default=None,
              help="Class name of the mirrored template  [default: the name with "
                   "'_mirrored' appended, or removed if present]")
@user_errors(2)
def mt_mirror_cmd(template, output, name):
    """Swap left and right in a template ([MR06] §5.4).

    The rows of every left/right feature pair (e.g. rhand_fast and lhand_fast) are
    swapped, so a template learned from left-handed examples finds the right-handed
    motion, without new training data.
    """
    from mtanno.templates.model import load_template, mirror, save_template
    from mtanno.util.preflight import check_outputs

    check_outputs([output], [template])
    mt = mirror(load_template(template), name=name)
    save_template(output, mt)
    click.echo(f"mt mirror: {mt.class_name} -> {output}", err=True)


@mt_group.command("scale", epilog=EXIT_BAD_INPUT)
@click.argument("template", type=click.Path(dir_okay=False))
@click.option("--factor", required=True, type=Number(0.1, 10),
              help="Performances this many times as long: 0.6 for faster ones, 1.6 for "
                   "slower ones (0.1–10).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output template file.")
@user_errors(2)
def mt_scale_cmd(template, factor, output):
    """Time-scale a template for faster or slower performers.

    Matching lets a match be half to twice as long as the template (the DTW steps), so a
    performer much faster or slower than every training example is not found at all. The
    copy has round(factor × length) columns, each the template's column nearest in time
    with its weight; it keeps the class name and records the factor as `time_scale`. List
    it under `[templates]` of an `annotate --classes` configuration to match it beside
    the template (`mtanno tune` makes such copies itself where cross-validation favours
    them).
    """
    from mtanno.templates.model import load_template, save_template
    from mtanno.templates.tempo import time_scaled
    from mtanno.util.preflight import check_outputs

    check_outputs([output], [template])
    mt = load_template(template)
    copy = time_scaled(mt, factor)
    save_template(output, copy)
    click.echo(f"mt scale: {mt.class_name}, {mt.length} -> {copy.length} columns "
               f"(factor {factor:g}) -> {output}", err=True)


@mt_group.command("quantize", epilog=EXIT_BAD_INPUT)
@click.argument("template", type=click.Path(dir_okay=False))
@click.option("--delta", required=True, type=DELTA,
              help="Entries ≤ δ become 0, entries ≥ 1−δ become 1, the rest the wildcard "
                   "0.5 (0.1 for retrieval, [MR06]; 0.05 for annotation, [MBS09]; 0 keeps only "
                   "unanimous entries).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output template file.")
@user_errors(2)
def mt_quantize_cmd(template, delta, output):
    """Quantize a template to 0, 1 and wildcard entries ([MR06] §5.2, docs/templates.md).

    The output records δ; matching uses a quantized template as it is.
    """
    from mtanno.templates.model import load_template, quantize, save_template
    from mtanno.util.preflight import check_outputs

    check_outputs([output], [template])
    mt = quantize(load_template(template), delta)
    save_template(output, mt)
    wild = int(np.sum(mt.values == 0.5))
    click.echo(f"mt quantize: {mt.class_name}, δ = {delta:g}, {wild} of {mt.values.size} "
               f"entries are wildcards -> {output}", err=True)


@mt_group.command("plot", epilog=EXIT_BAD_INPUT_OR_PLOT)
@click.argument("template", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Picture file: .png, .svg or .pdf.")
@click.option("--delta", type=DELTA, default=None,
              help="Quantize first with this δ (0: only unanimous entries stay 0 or 1).")
@user_errors(2)
def mt_plot_cmd(template, output, delta):
    """Draw a motion template as a heat map ([MR06] Fig. 4): one row per feature, one
    column per template column, black 0, white 1, grey in between (wildcards 0.5).
    Needs matplotlib (pip install 'mtanno[plot]')."""
    from mtanno.plot import plot_template, require_matplotlib, save_figure
    from mtanno.templates.model import load_template, quantize
    from mtanno.util.preflight import check_outputs

    require_matplotlib()
    check_outputs([output], [template])
    mt = load_template(template)
    if delta is not None:
        mt = quantize(mt, delta)
    save_figure(plot_template(mt), output)
    click.echo(f"mt plot: {mt.class_name} -> {output}", err=True)


COMMANDS = [learn_mt_cmd, mt_group]
