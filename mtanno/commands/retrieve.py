"""``mtanno retrieve``: all occurrences of one motion class in feature files ([MR06] §5.4).

Exit codes: 0 success (also with no hits), 1 some feature files could not be used (the
others were searched), 2 usage error or bad input (unreadable template, no feature files).
"""

from __future__ import annotations

import sys

import click

from mtanno.commands._common import DELTA, TAU, former_name, show_progress, user_errors
from mtanno.retrieve import DEFAULT_MAX_HITS
from mtanno.templates.params import RETRIEVAL_DELTA, RETRIEVAL_TAU


@click.command("retrieve", epilog="Exit codes: 0 success, 1 some feature files failed (the "
               "others were searched), 2 usage error or bad input.")
@click.argument("features", nargs=-1, required=True, metavar="FEATURES...")
@click.option("--mt", "mt_path", required=True, type=click.Path(),
              help="Template JSON of the class (from learn-mt; quantized with its delta, or "
                   "with --delta, when it is not quantized yet), or a folder of templates "
                   "(as annotate --mt takes): every class is retrieved, the table gets a "
                   "class column.")
@click.option("--tau", default=RETRIEVAL_TAU, show_default=True, type=TAU,
              help="Quality threshold: hits have cost Δ ≤ tau ([MR06]: 0.06; the reference "
                   "retrieval driver used 0.175; inf: every local best match).")
@click.option("--max-hits", default=DEFAULT_MAX_HITS, show_default=True, type=click.IntRange(min=1),
              help="Report at most this many hits (a note on stderr says when the cap cut "
                   "hits off).")
@click.option("--match", "variant", default="reference", show_default=True,
              type=click.Choice(["reference", "paper"]),
              help="Matching variant (as annotate --match): the reference implementation's "
                   "(weights expand the template) or the papers' as written "
                   "(docs/retrieval.md).")
@former_name("--variant", "--match", "variant", type=click.Choice(["reference", "paper"]))
@click.option("--delta", "qdelta", default=None, type=DELTA,
              help="Quantize an unquantized template with this δ (default: the template's "
                   f"own delta, else {RETRIEVAL_DELTA:g} as in [MR06]). A quantized template keeps "
                   "its own delta.")
@click.option("-o", "--output", default="-", show_default=True,
              type=click.Path(dir_okay=False, allow_dash=True),
              help="Hit table: .csv, .parquet or .jsonl (with provenance, docs/formats.md), "
                   "or - for CSV on standard output.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@user_errors(2)
def retrieve_cmd(features, mt_path, tau, max_hits, variant, qdelta, output, quiet):
    """Find all occurrences of the class of a motion template in feature files ([MR06] §5.4).

    FEATURES are feature files (.parquet, from `mtanno features`) or folders searched
    recursively. Each file is one document; matches never cross documents. Hits are
    found greedily by increasing cost Δ ([MR06] §5.4–5.5, docs/retrieval.md) and ranked over all
    documents. Output columns: doc, start, end (1-based inclusive 30 Hz frames),
    start_native, end_native (frames of the source motion file), cost, rank. With a
    folder of several templates (--mt MT/, as annotate takes) each class is retrieved and
    a first column, class, names it; ranks and --max-hits count per class.

    A FEATURES path that names no feature file, or a file that cannot be used, is
    reported in one line and the others are searched (exit code 1); with no usable
    feature file at all the exit code is 2.

    Example: mtanno retrieve --mt mts/squat1Reps.json feats/ --tau 0.06 -o squat_hits.csv
    """
    from tqdm import tqdm

    from mtanno.retrieve import retrieve_to

    bar = None

    def start(missing: list[str], n: int) -> None:
        nonlocal bar
        for message in missing:
            click.echo(f"mtanno: {message}", err=True)
        bar = tqdm(total=n, unit="file", disable=not show_progress(quiet), desc="retrieve")

    def progress(path, error):
        bar.update(1)
        if error is not None:
            bar.write(f"mtanno: {error}", file=sys.stderr)

    try:
        run = retrieve_to(features, mt_path, output, tau=tau, delta=qdelta, max_hits=max_hits,
                          variant=variant, on_start=start, progress=progress)
    finally:
        if bar is not None:
            bar.close()
    if run.truncated:
        click.echo(f"retrieve: the hit cap --max-hits {max_hits} was reached; more hits with "
                   f"cost ≤ {run.tau:g} exist", err=True)
    if not quiet:
        what = f"{len(run.classes)} classes" if len(run.classes) > 1 else run.classes[0]
        click.echo(f"retrieve: {run.hits} hit(s) of {what} in {run.documents} document(s), "
                   f"tau {run.tau:g}, {len(run.failed) + len(run.missing)} failed"
                   + (f" -> {output}" if output != "-" else ""), err=True)
    sys.exit(run.exit_code)


COMMANDS = [retrieve_cmd]
