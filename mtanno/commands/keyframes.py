"""Commands of the keyframe stage: ``learn-keyframes`` and ``keyframes show``.
Exit codes: 0 success, 1 some classes failed (the others were written), 2 usage error or
bad input."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click

from mtanno.commands._common import (
    ARGUMENT_NAMES,
    EXIT_BAD_INPUT,
    EXIT_PER_CLASS,
    inside_input_option,
    lock_output,
    scheduler_option,
    show_progress,
    training_argument,
    training_options,
    user_errors,
    wait_option,
)
from mtanno.errors import MtannoError
from mtanno.templates.model import class_file


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

    from mtanno.keyframes import save_keyframes
    from mtanno.keyframes.ga import GAParams
    from mtanno.keyframes.learn import keyframe_training_set, learn_keyframes
    from mtanno.templates.model import load_template_folder
    from mtanno.templates.training import collect_sources, group_by_class, input_folders, load_examples
    from mtanno.util.output import output_folder
    from mtanno.util.preflight import check_outputs

    bad_inputs: list[MtannoError] = []  # training folders without examples: the others go on
    sources = collect_sources(training, manifest=manifest, features_dir=features_dir,
                              split=split, truth=truth, failures=bad_inputs,
                              note=None if quiet else lambda m: click.echo(f"learn-keyframes: {m}", err=True))
    for exc in bad_inputs:
        click.echo(f"mtanno: {exc.for_command(ARGUMENT_NAMES)}", err=True)
    groups = group_by_class(sources, classes=list(classes) or None)
    templates = load_template_folder(mt_dir)
    all_groups = group_by_class(sources)
    examples = [ex for c in all_groups for ex in load_examples(all_groups[c])]
    by_class: dict[str, list] = {}
    for ex in examples:
        by_class.setdefault(ex.class_name, []).append(ex)
    mt0 = next(iter(templates.values()))
    if examples[0].feature_names != list(mt0.feature_names):
        raise MtannoError("training clips have other features than the templates "
                          f"(feature set {examples[0].feature_set} vs {mt0.feature_set})",
                          path=examples[0].file)
    if method == "ga" and len(by_class) < 2:
        raise MtannoError(f"the genetic algorithm needs training clips of at least two classes "
                          f"(only {', '.join(by_class)} found): the other classes are its "
                          "negatives")
    ts = keyframe_training_set(examples)
    params = GAParams(population=population, generations=generations)
    out = Path(outdir)
    todo = [c for c in groups if c in templates or classes]
    check_outputs([out / f"{c}.json" for c in todo if c and "/" not in c and "\0" not in c],
                  [*(s.path for s in sources), manifest, truth,
                   *(t.path for t in templates.values())], folders={out: []},
                  scanned=input_folders(training, features_dir, also=[mt_dir]),
                  inside_input=inside_input,
                  writable=False)  # a class whose file cannot be written fails alone
    total = len(todo) * (runs if method == "ga" else 1)
    bar = tqdm(total=total, unit="run" if method == "ga" else "class", desc="learn-keyframes",
               disable=not show_progress(quiet))
    # a run that writes nothing (every class failed, or interrupted) leaves no new folder
    with output_folder(out), lock_output(out, wait=wait):
        t0 = time.perf_counter()
        written, failed = [], []
        for cls in todo:
            bar.set_postfix_str(cls)
            try:
                if cls not in templates:
                    raise MtannoError(f"no template for class '{cls}' in {mt_dir}")
                target = class_file(out, cls)
                q = learn_keyframes(ts, cls, templates[cls], method=method, runs=runs, seed=seed,
                                    jobs=jobs, scheduler=scheduler, params=params,
                                columns=columns,
                                    examples=by_class.get(cls),
                                    progress=bar.update if method == "ga" else None)
                save_keyframes(target, q)
                written.append((cls, q))
            except MtannoError as exc:
                failed.append(cls)
                bar.write(f"mtanno: class {cls}: {exc}", file=sys.stderr)
            if method != "ga":
                bar.update(1)
    bar.close()
    if not quiet:
        for cls, q in written:
            f = q.provenance["fitness"]
            kfs = f"{q.n} keyframe{'s' if q.n != 1 else ' '}"
            click.echo(f"  {cls:<32s} {kfs}  training P {f['P']:.3f} R {f['R']:.3f} "
                       f"F2 {f['F']:.3f}", err=True)
        skipped = sorted(set(groups) - set(todo))
        note = f", {len(skipped)} without template skipped" if skipped else ""
        click.echo(f"learn-keyframes: {len(written)} class(es) ({method}) -> {out}, "
                   f"{len(failed)} failed{note}, {time.perf_counter() - t0:.1f} s", err=True)
    sys.exit(1 if failed or bad_inputs else 0)


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
    from mtanno.keyframes import format_query, keyframe_files, load_keyframes

    first = True
    for f in files:
        paths = keyframe_files(f)
        if not paths:
            raise MtannoError("no keyframe files (*.json) in this folder", path=f)
        for path in paths:
            q = load_keyframes(path)
            if not first:
                click.echo("")
            first = False
            click.echo(format_query(q, path=str(path)))


COMMANDS = [learn_keyframes_cmd, keyframes_group]
