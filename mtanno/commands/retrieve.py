"""``mtanno retrieve``: all occurrences of one motion class in feature files ([MR06] §5.4).

Exit codes: 0 success (also with no hits), 1 some feature files could not be used (the
others were searched), 2 usage error or bad input (unreadable template, no feature files).
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from mtanno.commands._common import DELTA, TAU, show_progress, user_errors
from mtanno.features.inputs import feature_files
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
@click.option("--variant", "former_variant", type=click.Choice(["reference", "paper"]),
              default=None, hidden=True, help="The former name of --match.")
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
def retrieve_cmd(features, mt_path, tau, max_hits, variant, former_variant, qdelta, output,
                 quiet):
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
    variant = former_variant or variant  # --variant: the former name of --match
    from tqdm import tqdm

    from mtanno.retrieve import (
        retrieval_template,
        retrieve_files,
        retrieve_files_classes,
        write_hits,
    )
    from mtanno.templates.model import load_template, load_template_folder, template_files
    from mtanno.templates.params import check_tau
    from mtanno.util.preflight import check_outputs
    from mtanno.util.tables import file_record, output_files, provenance, table_format

    table_format(output)
    tau = check_tau(tau, what="--tau")
    missing: list[str] = []  # inputs naming no feature file: reported, the batch goes on
    files = feature_files(features, failures=missing)
    check_outputs(output_files(output), [mt_path, *template_files(mt_path), *files],
                  scanned={f: (".parquet",) for f in features if Path(f).is_dir()})
    found = (load_template_folder(mt_path) if Path(mt_path).is_dir() else
             {"": load_template(mt_path)})
    mts = {m.class_name: retrieval_template(m, delta=qdelta) for m in found.values()}
    mt = next(iter(mts.values()))
    several = len(mts) > 1
    layout = mt.layout(f"template {mt.path}")
    for message in missing:
        click.echo(f"mtanno: {message}", err=True)
    bar = tqdm(total=len(files), unit="file", disable=not show_progress(quiet), desc="retrieve")

    def progress(path, error):
        bar.update(1)
        if error is not None:
            bar.write(f"mtanno: {error}", file=sys.stderr)

    if several:
        batch = retrieve_files_classes({c: (m.values, m.weights) for c, m in mts.items()},
                                       files, layout=layout, tau=tau, max_hits=max_hits,
                                       variant=variant, progress=progress)
    else:
        batch = retrieve_files(mt.values, mt.weights, files, layout=layout, tau=tau,
                               max_hits=max_hits, variant=variant, progress=progress)
    bar.close()
    hits = batch.hits
    deltas = sorted({m.delta for m in mts.values()})
    write_hits(output, batch.by_class if several else hits, batch.native,
               provenance=provenance(
        inputs=batch.files, templates=[{"class": c, **file_record(m.path)}
                                       for c, m in mts.items()],
        tau=tau, delta=deltas[0] if len(deltas) == 1 else deltas, variant=variant,
        max_hits=max_hits, feature_set=mt.feature_set, truncated=hits.truncated))
    if hits.truncated:
        click.echo(f"retrieve: the hit cap --max-hits {max_hits} was reached; more hits with "
                   f"cost ≤ {tau:g} exist", err=True)
    if not quiet:
        what = f"{len(mts)} classes" if several else mt.class_name
        click.echo(f"retrieve: {len(hits)} hit(s) of {what} in "
                   f"{len(files) - len(batch.failed)} document(s), tau {tau:g}, "
                   f"{len(batch.failed) + len(missing)} failed"
                   + (f" -> {output}" if output != "-" else ""), err=True)
    sys.exit(1 if batch.failed or missing else 0)

COMMANDS = [retrieve_cmd]
