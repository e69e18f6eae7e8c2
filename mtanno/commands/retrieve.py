"""``mtanno retrieve``: all occurrences of one motion class in feature files (MR06 §5.4).

Exit codes: 0 success (also with no hits), 2 usage error or bad input (unreadable or
mismatching template or feature file, no feature files).
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import click
import numpy as np

from mtanno.commands._common import show_progress, user_errors
from mtanno.errors import MtannoError
from mtanno.store import feature_files

COLUMNS = ("doc", "start", "end", "start_native", "end_native", "cost", "rank")
FORMATS = (".csv", ".parquet", ".jsonl")


def check_compatible(mt, mt_path: str, ff) -> None:
    """The template and a feature file must describe the same features at the same rate."""
    where = f"template {mt_path} ({mt.feature_set}, {len(mt.feature_names)} features, {mt.fps:g} Hz)"
    fset = ff.meta.get("feature_set")
    if fset != mt.feature_set:
        raise MtannoError(f"feature set {fset!r} differs from {where}", path=ff.path)
    if list(ff.names) != list(mt.feature_names):
        diff = next((i for i, (a, b) in enumerate(zip(ff.names, mt.feature_names)) if a != b),
                    min(len(ff.names), len(mt.feature_names)))
        have = ff.names[diff] if diff < len(ff.names) else "(none)"
        want = mt.feature_names[diff] if diff < len(mt.feature_names) else "(none)"
        raise MtannoError(f"feature names differ from {where}: feature {diff + 1} is "
                          f"{have!r} here, {want!r} in the template", path=ff.path)
    try:
        fps = ff.fps
    except (KeyError, TypeError, ValueError):
        raise MtannoError("feature file metadata lacks analysis_fps", path=ff.path) from None
    if abs(fps - float(mt.fps)) > 1e-9:
        raise MtannoError(f"frame rate {fps:g} Hz differs from {where}", path=ff.path)


def hit_rows(hits, native: list[np.ndarray]) -> list[dict]:
    """Output rows: 1-based inclusive 30 Hz frames, native frames, cost, rank."""
    rows = []
    for rank, h in enumerate(hits, 1):
        nat = native[h.doc_index]
        rows.append({"doc": str(h.doc), "start": h.start + 1, "end": h.end + 1,
                     "start_native": int(nat[h.start]), "end_native": int(nat[h.end]),
                     "cost": float(h.cost), "rank": rank})
    return rows


def write_rows(rows: list[dict], output: str | None) -> None:
    """Write the hit table as CSV (stdout when ``output`` is None), Parquet or JSON Lines."""
    if output is None:
        _write_csv(rows, sys.stdout)
        return
    from mtanno.store import atomic_path

    suffix = Path(output).suffix.lower()
    with atomic_path(output) as tmp:
        if suffix == ".csv":
            with open(tmp, "w", newline="", encoding="utf-8") as fh:
                _write_csv(rows, fh)
        elif suffix == ".jsonl":
            with open(tmp, "w", encoding="utf-8") as fh:
                for r in rows:
                    fh.write(json.dumps(r) + "\n")
        else:
            import pyarrow as pa
            import pyarrow.parquet as pq

            table = pa.table({
                "doc": pa.array([r["doc"] for r in rows], pa.string()),
                **{c: pa.array([r[c] for r in rows], pa.int64())
                   for c in ("start", "end", "start_native", "end_native")},
                "cost": pa.array([r["cost"] for r in rows], pa.float64()),
                "rank": pa.array([r["rank"] for r in rows], pa.int64()),
            })
            pq.write_table(table, tmp)


def _write_csv(rows: list[dict], fh) -> None:
    w = csv.writer(fh, lineterminator="\n")
    w.writerow(COLUMNS)
    for r in rows:
        w.writerow([r["doc"], r["start"], r["end"], r["start_native"], r["end_native"],
                    repr(r["cost"]), r["rank"]])


@click.command("retrieve", epilog="Exit codes: 0 success, 2 usage error or bad input.")
@click.argument("features", nargs=-1, required=True, metavar="FEATURES...")
@click.option("--mt", "mt_path", required=True, type=click.Path(dir_okay=False),
              help="Template JSON of the class (from learn-mt; quantized with its delta, or "
                   "with --delta, when it is not quantized yet).")
@click.option("--tau", default=0.06, show_default=True, type=float,
              help="Quality threshold: hits have cost Δ ≤ tau (MR06: 0.06; the reference "
                   "retrieval driver used 0.175).")
@click.option("--max-hits", default=1000, show_default=True, type=click.IntRange(min=1),
              help="Report at most this many hits (a note on stderr says when the cap cut "
                   "hits off).")
@click.option("--variant", default="reference", show_default=True,
              type=click.Choice(["reference", "paper"]),
              help="Matching variant: the reference implementation's (weights expand the "
                   "template) or the papers' as written (docs/retrieval.md).")
@click.option("--delta", "qdelta", default=None, type=click.FloatRange(0, 0.5),
              help="Quantize an unquantized template with this δ (default: the template's "
                   "own delta, else 0.1 as in MR06). A quantized template keeps its own delta.")
@click.option("-o", "--output", default=None, type=click.Path(dir_okay=False),
              help="Write the hit table here (.csv, .parquet or .jsonl) instead of CSV on "
                   "standard output.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@user_errors(2)
def retrieve_cmd(features, mt_path, tau, max_hits, variant, qdelta, output, quiet):
    """Find all occurrences of the class of a motion template in feature files (MR06 §5.4).

    FEATURES are feature files (.parquet, from `mtanno features`) or folders searched
    recursively. Each file is one document; matches never cross documents. Hits are
    found greedily by increasing cost Δ (algorithms.md §3.4–3.5) and ranked over all
    documents. Output columns: doc, start, end (1-based inclusive 30 Hz frames),
    start_native, end_native (frames of the source motion file), cost, rank.

    Example: mtanno retrieve --mt mts/squat1Reps.json feats/ --tau 0.06 -o squat_hits.csv
    """
    from tqdm import tqdm

    from mtanno.retrieve import retrieve
    from mtanno.store import read_features
    from mtanno.templates.model import load_template, quantize

    if output is not None and Path(output).suffix.lower() not in FORMATS:
        raise MtannoError(f"output must end in {', '.join(FORMATS)}", path=output)
    mt = load_template(mt_path)
    if mt.quantized:
        if qdelta is not None and qdelta != mt.delta:
            raise MtannoError(f"template is already quantized with delta {mt.delta:g}; "
                              "--delta only applies to unquantized templates", path=mt_path)
    else:
        mt = quantize(mt, qdelta if qdelta is not None else (mt.delta if mt.delta is not None
                                                              else 0.1))
    files = feature_files(features)
    native: list[np.ndarray] = []
    bar = tqdm(total=len(files), unit="file", disable=not show_progress(quiet), desc="retrieve")

    def documents():
        for f in files:
            ff = read_features(f)
            check_compatible(mt, mt_path, ff)
            native.append(ff.native_frames)
            yield ff.document, ff.X
            bar.update(1)

    hits = retrieve(mt.values, mt.weights, documents(), tau=tau, max_hits=max_hits,
                    variant=variant)
    bar.close()
    write_rows(hit_rows(hits, native), output)
    if hits.truncated:
        click.echo(f"retrieve: the hit cap --max-hits {max_hits} was reached; more hits with "
                   f"cost ≤ {tau:g} exist", err=True)
    if not quiet:
        click.echo(f"retrieve: {len(hits)} hit(s) of {mt.class_name} in {len(files)} "
                   f"document(s), tau {tau:g}" + (f" -> {output}" if output else ""), err=True)


COMMANDS = [retrieve_cmd]
