"""Commands of the keyframe stage: ``learn-keyframes`` and ``keyframes show``.
Exit codes: 0 success, 1 some classes failed (the others were written), 2 usage error or
bad input."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from mtanno.commands._common import (
    ARGUMENT_NAMES,
    EXIT_BAD_INPUT,
    EXIT_PER_CLASS,
    inside_input_option,
    scheduler_option,
    show_progress,
    training_argument,
    training_options,
    user_errors,
    wait_option,
    waiting_note,
)
from mtanno.errors import MtannoError


@click.command("learn-keyframes", epilog=EXIT_PER_CLASS)
@training_argument
@click.option("--mt", "mt_dir", required=True, type=click.Path(),
              help="Folder of class templates (CLASS.json from learn-mt); keyframe positions "
                   "refer to their columns.")
@click.option("-o", "--output", "outdir", required=True, type=click.Path(file_okay=False),
              help="Output folder; one CLASS.json keyframe query per class.")
@training_options(
    manifest_help="Manifest CSV (file,class[,split]) listing the training clips.",
    truth_help="Truth table; every labelled segment of the TRAINING feature files is a "
               "training clip of its label.")
@click.option("--method", type=click.Choice(["ga", "hard", "heuristic"]), default="ga",
              show_default=True,
              help="ga: genetic algorithm ([MBS09] §6); hard: hard-template columns (thesis); "
                   "heuristic: quantized-template columns ([MR06]).")
@click.option("--runs", default=100, show_default=True, type=click.IntRange(min=1),
              help="ga: independent runs per class; the query whose keyframes occur most "
                   "often among the winners is kept.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="ga: seed of the runs (the same seed gives the same files, whatever "
                   "--jobs is).")
@click.option("-j", "--jobs", default=1, show_default=True, type=click.IntRange(min=1),
              help="ga: worker processes the runs are spread over.")
@click.option("--generations", default=100, show_default=True, type=click.IntRange(min=1),
              help="ga: generations per run (G).")
@click.option("--population", default=50, show_default=True, type=click.IntRange(min=2),
              help="ga: population size (M).")
@click.option("--columns", default=3, show_default=True, type=click.IntRange(min=1),
              help="hard, heuristic: template columns to take as keyframes.")
@click.option("--class", "classes", multiple=True, metavar="NAME",
              help="Learn only this class (repeatable). Default: every class with a template.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@inside_input_option
@wait_option
@scheduler_option
@user_errors(2)
def learn_keyframes_cmd(training, mt_dir, outdir, manifest, features_dir, split, truth, method,
                        runs, seed, jobs, generations, population, columns, classes, quiet,
                        inside_input, wait, scheduler):
    """Learn a keyframe query per class ([MBS09] §6): a few key poses, each over one feature
    group, with gap bounds, that the class's training clips share and other classes' clips
    lack. `mtanno annotate --keyframes` matches templates only where they occur.

    Training clips come as for learn-mt (a manifest with --features-dir, --truth with
    feature files, or CLASS/ folders); every class's clips are the negatives of the
    others. Writes OUTDIR/CLASS.json (schema mtanno.keyframes/1: keyframes, gap bounds,
    template length, window extension, and how they were learned, with P/R/F2 on the
    training clips); see `mtanno keyframes show`. OUTDIR may not be, or lie inside, a
    folder of training clips or --mt unless --inside-input says so.

    Example: mtanno learn-keyframes --mt mts/ --manifest ../shared/data/hdm05_cut/clips.csv
    --features-dir feats/ --split train -o kf/ --jobs 2
    """
    from tqdm import tqdm

    from mtanno.keyframes.ga import GAParams
    from mtanno.keyframes.run import KeyframeOptions, learn_keyframes_to

    bar = None

    def start(n: int, skipped: list[MtannoError]) -> None:
        nonlocal bar
        for exc in skipped:  # training folders without examples: the others go on
            click.echo(f"mtanno: {exc.for_command(ARGUMENT_NAMES)}", err=True)
        bar = tqdm(total=n, unit="run" if method == "ga" else "class", desc="learn-keyframes",
                   disable=not show_progress(quiet))

    def progress(cls: str, steps: int, error: str | None) -> None:
        bar.set_postfix_str(cls)
        if error is not None:
            bar.write(f"mtanno: class {cls}: {error}", file=sys.stderr)
        bar.update(steps)

    options = KeyframeOptions(method=method, classes=classes, runs=runs, seed=seed,
                              ga=GAParams(population=population, generations=generations),
                              columns=columns, jobs=jobs, scheduler=scheduler,
                              inside_input=inside_input)
    try:
        run = learn_keyframes_to(
            training, mt_dir, outdir, manifest=manifest, features_dir=features_dir, split=split,
            truth=truth, options=options, wait=wait, on_wait=waiting_note(Path(outdir)),
            on_start=start, progress=progress,
            note=None if quiet else lambda m: click.echo(f"learn-keyframes: {m}", err=True))
    finally:
        if bar is not None:
            bar.close()
    if not quiet:
        for cls, q in run.written:
            f = q.provenance["fitness"]
            kfs = f"{q.n} keyframe{'s' if q.n != 1 else ' '}"
            click.echo(f"  {cls:<32s} {kfs}  training P {f['P']:.3f} R {f['R']:.3f} "
                       f"F2 {f['F']:.3f}", err=True)
        skipped = run.without_template
        note = f", {len(skipped)} without template skipped" if skipped else ""
        click.echo(f"learn-keyframes: {len(run.written)} class(es) ({method}) -> {Path(outdir)}, "
                   f"{len(run.failed)} failed{note}, {run.seconds:.1f} s", err=True)
    sys.exit(run.exit_code)


@click.group("keyframes")
def keyframes_group():
    """Inspect keyframe query files (CLASS.json from `mtanno learn-keyframes`)."""


@keyframes_group.command("show", epilog=EXIT_BAD_INPUT)
@click.argument("files", nargs=-1, required=True, type=click.Path(), metavar="KF.json...")
@user_errors(2)
def keyframes_show_cmd(files):
    """Print keyframe queries as readable tables: one row per keyframe (template position,
    group, gap bounds to the previous keyframe in frames at 30 Hz, vector), then one row
    per feature a keyframe fixes and one column per keyframe (1, 0, or · for a wildcard).
    A folder shows every query in it."""
    from mtanno.keyframes.describe import format_query_files

    for k, text in enumerate(format_query_files(files)):
        if k:
            click.echo("")
        click.echo(text)


COMMANDS = [learn_keyframes_cmd, keyframes_group]
