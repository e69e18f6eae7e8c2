"""``mtanno index`` (build, add, remove, info) and ``mtanno query``: thin layers over
:mod:`mtanno.index` ([MRC05] §5–6)."""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import click

from mtanno.commands._common import NAMES, ProgressBar, stack, user_errors, wait_option, waiting_note
from mtanno.errors import MtannoError
from mtanno.index.query import QUERY_MODES


class _IndexGroup(click.Group):
    """``mtanno index FEATURES... -o INDEX`` builds; ``mtanno index add|remove|info …``
    update or describe. Arguments that are not a subcommand name go to ``build``."""

    def parse_args(self, ctx, args):
        if args and args[0] not in self.commands and args[0] not in ("-h", "--help"):
            args = ["build", *args]
        return super().parse_args(ctx, args)


@click.group("index", cls=_IndexGroup, context_settings={"help_option_names": ["-h", "--help"]})
def index_group() -> None:
    """Build, update and describe a relational index ([MRC05] §5).

    \b
    mtanno index FEATURES... -o INDEX/     build (FEATURES = feature files or directories)
    mtanno index add INDEX FEATURES...     add or replace documents, in place
    mtanno index remove INDEX DOC...       remove documents by name, in place
    mtanno index info INDEX                frames, segments, lists, bytes per segment

    The index keeps, per feature group (lower/upper/mix), the documents' F-segments and the
    inverted lists over their feature vectors. Updates are atomic: an interrupted update
    leaves the previous index readable.
    """


def _groups_option(value: str | None):
    """``--groups G1,G2`` as a list of names; None when not given (every group). The NAMES
    type has refused a value that names no group (``''``, ``,``): it would have meant every
    group."""
    return None if value is None else value.split(",")


#: The INDEX argument of every command that reads or updates an index.
_INDEX = click.argument("index_dir", metavar="INDEX", type=click.Path(file_okay=False))


def _update_command(name: str, items: str, metavar: str, *, quiet_help: str):
    """The decorators of ``index add`` and ``index remove``, the two updates in place: INDEX,
    the items (one or more), ``-q``, ``--wait``; exit code 2 for bad input."""
    return stack(index_group.command(name), _INDEX,
                 click.argument(items, nargs=-1, required=True, metavar=metavar),
                 click.option("-q", "--quiet", is_flag=True, help=quiet_help),
                 wait_option, user_errors(2))


def _summary(index) -> str:
    segs = ", ".join(f"{g.name} {g.n_segments}" for g in index.groups.values())
    return (f"{len(index.documents)} documents, {index.frames} frames at {index.fps:g} Hz, "
            f"segments: {segs}")


@index_group.command("build")
@click.argument("features", nargs=-1, required=True, metavar="FEATURES...")
@click.option("-o", "--output", "out", required=True, type=click.Path(file_okay=False),
              help="Index directory (new, empty, or an index to replace).")
@click.option("--groups", default=None, metavar="G1,G2", type=NAMES,
              help="Index only these groups of the feature set (default: all).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@wait_option
@user_errors(2)
def build_cmd(features, out, groups, quiet, wait):
    """Index feature files (or directories of them) into OUTPUT. A file that cannot be
    read or has other features than most is reported and left out (exit code 1)."""
    from mtanno.index import build_index

    failures: list[str] = []
    with ProgressBar("index", "file", quiet=quiet) as bar:
        index = build_index(features, out, groups=_groups_option(groups), failures=failures,
                            wait=wait, on_wait=waiting_note(out), progress=bar)
    _finish(failures, None if quiet else
            f"index: {_summary(index)}, {len(failures)} failed -> {out}")


def _report(failures: list[str]) -> None:
    for message in failures:
        click.echo(f"mtanno: {message}", err=True)


def _finish(failures: list[str], summary: str | None) -> None:
    """The failures, one line each, the summary line, and exit code 1 if any failed."""
    _report(failures)
    if summary:
        click.echo(summary, err=True)
    sys.exit(1 if failures else 0)


@_update_command("add", "features", "FEATURES...",
                 quiet_help="No progress bar and no summary line.")
def add_cmd(index_dir, features, quiet, wait):
    """Add feature files to INDEX (a document already indexed is replaced if its file
    changed). Only the new files are read; one that cannot be read or lacks the index's
    features is reported and left out (exit code 1)."""
    from mtanno.index import add_documents

    failures: list[str] = []
    with ProgressBar("index add", "file", quiet=quiet) as bar:
        index, report = add_documents(index_dir, features, failures=failures, wait=wait,
                                      on_wait=waiting_note(index_dir), progress=bar)
    _finish(failures, None if quiet else
            f"index add: {report.line()}, {len(failures)} failed; {_summary(index)}")


@_update_command("remove", "docs", "DOC...", quiet_help="No summary line.")
def remove_cmd(index_dir, docs, quiet, wait):
    """Remove documents (names = feature file stems) from INDEX."""
    from mtanno.index import remove_documents

    index, report = remove_documents(index_dir, docs, wait=wait, on_wait=waiting_note(index_dir))
    if not quiet:
        click.echo(f"index remove: {report.line()}; {_summary(index)}", err=True)


@index_group.command("info")
@_INDEX
@click.option("--json", "as_json", is_flag=True, help="Print a JSON object instead.")
@click.option("-o", "--output", default=None, type=click.Path(dir_okay=False, allow_dash=True),
              help="Write the per-group table (.csv, .parquet, .jsonl, or - for CSV on "
                   "standard output) instead of the text.")
@user_errors(2)
def info_cmd(index_dir, as_json, output):
    """Describe INDEX: documents, frames, and per group segments, lists and sizes."""
    import pyarrow as pa

    from mtanno.index import open_index
    from mtanno.index.storage import group_sizes, index_files, read_index_manifest
    from mtanno.util.preflight import check_outputs
    from mtanno.util.tables import output_files, provenance, table_format, write_table

    if output is not None:
        table_format(output)
    index = open_index(index_dir)
    manifest = read_index_manifest(index.root)
    total = sum(e["bytes"] for e in manifest["files"].values())
    rows = group_sizes(index)
    if output is not None:
        check_outputs(output_files(output), index_files(index.root))
        write_table(output, pa.Table.from_pylist(rows), provenance=provenance(
            inputs=[index.root / "manifest.json"], index=str(index_dir),
            generation=index.generation, feature_set=index.feature_set))
        return
    if as_json:
        click.echo(json.dumps({"index": str(index_dir), "generation": index.generation,
                               "feature_set": index.feature_set, "documents": len(index.documents),
                               "frames": index.frames, "frame_rate": index.fps,
                               "bytes": total, "mtanno_version": manifest.get("mtanno_version"),
                               "groups": rows}, indent=1))
        return
    click.echo(f"index          {index_dir} (generation {index.generation}, "
               f"mtanno {manifest.get('mtanno_version')})")
    click.echo(f"feature set    {index.feature_set} v{index.feature_set_version}, "
               f"{len(index.features)} features")
    click.echo(f"documents      {len(index.documents)}")
    click.echo(f"frames         {index.frames} at {index.fps:g} Hz "
               f"({index.frames / index.fps / 60:.1f} min)")
    click.echo(f"size           {total} bytes")
    click.echo(f"{'group':<8} {'f':>3} {'segments':>9} {'seg/frame':>9} {'lists':>6} "
               f"{'of':>8} {'bytes':>9} {'B/segment':>9}")
    for r in rows:
        click.echo(f"{r['group']:<8} {r['features']:>3} {r['segments']:>9} "
                   f"{r['segments_per_frame']:>9.3f} {r['lists']:>6} {r['possible_lists']:>8} "
                   f"{r['bytes']:>9} {r['bytes_per_segment']:>9.2f}")


@click.command("query")
@_INDEX
@click.option("--example", default=None, metavar="FILE.parquet|DOC",
              help="Query by example: a feature file, or the name of an indexed document.")
@click.option("--frames", default=None, metavar="A:B",
              help="Example frames, 1-based inclusive at 30 Hz (default: all).")
@click.option("--features", "feature_list", default=None, metavar="NAME,...", type=NAMES,
              help="Features of the example that matter (names, ids such as F07, or [MRC05] "
                   "Table 1 names such as Fl7).")
@click.option("--query", "query_file", default=None, type=click.Path(dir_okay=False),
              metavar="Q.json", help="JSON query file (docs/index.md).")
@click.option("--keyframes", "kf_file", default=None, type=click.Path(dir_okay=False),
              metavar="KF.json", help="Keyframe query (learn-keyframes, docs/keyframes.md): "
                                      "hits are the spans of its keyframe chains.")
@click.option("--windows", is_flag=True,
              help="With --keyframes: write the candidate windows (hits widened by the "
                   "query's extension, merged) that annotate matches templates in.")
@click.option("--mode", type=click.Choice(QUERY_MODES), default=None,
              help="Hit type (default: adaptive, or the query file's mode).")
@click.option("--mismatches", type=click.IntRange(min=0), default=None, metavar="M",
              help="Allow up to M query segments to disagree (exact and fuzzy modes).")
@click.option("--min-segment", "min_segment", type=click.IntRange(min=1), default=None,
              metavar="N", help="Shortest phase in frames at 30 Hz: shorter example segments "
              "are transients, not query segments, and so are the documents' (adaptive "
              "mode); a query file's documents may pass through other vectors for up to N-1 "
              "frames between two query segments. "
              "[default: 3 with --example; the query file's min_segment, else 1, with "
              "--query]")
@click.option("--rank-mt", "rank_mt", default=None, type=click.Path(dir_okay=False),
              metavar="MT.json", help="Rank the hits by this motion template's cost.")
@click.option("--top", type=click.IntRange(min=1), default=None, metavar="N",
              help="Print only the N best hits.")
@click.option("-o", "--output", default="-", show_default=True,
              type=click.Path(dir_okay=False, allow_dash=True), metavar="HITS",
              help="Hit table: .csv, .parquet or .jsonl (with provenance, docs/formats.md), "
                   "or - for CSV on standard output.")
@click.option("-q", "--quiet", is_flag=True, help="No summary line on standard error.")
@user_errors(2)
def query_cmd(index_dir, example, frames, feature_list, query_file, kf_file, windows, mode,
              mismatches, min_segment, rank_mt, top, output, quiet):
    """Find motions in INDEX ([MRC05] §5–6): by example, with a JSON query file, or with a
    keyframe query ([MBS09] §5).

    \b
    mtanno query INDEX --example FILE.parquet [--frames A:B] --features NAME,...
    mtanno query INDEX --query Q.json
    mtanno query INDEX --keyframes KF.json [--windows]

    Hits are written as a table (CSV on standard output unless -o names a .csv, .parquet
    or .jsonl file): doc, start, end (1-based inclusive frames at 30 Hz), rank,
    score (sum of segment length differences to the example, [MRC05] §6.2; lower is better),
    mt_cost (with --rank-mt; empty where the template cannot fit the hit, which a note
    counts), span_start, span_end (queries with segment lengths: the hit before trimming),
    boundaries (per group: first frame of each matched segment, then the last frame; for
    keyframes, the frames of the earliest keyframe chain in the hit, then the hit's last
    frame).

    A query by example ignores transients: runs shorter than --min-segment frames, of the
    whole example and of every document, are given to the run before them, and the
    example is cut by --frames afterwards, so its own source is always the first hit, with
    score 0. The first and last query segments are scored against the whole runs the cut
    fell in. Hits are trimmed: they keep at most as many frames of the poses before and
    after the motion (the first and last query segments) as the example has; span_start
    and span_end give the untrimmed hit.
    """
    import time

    from mtanno.index import load_query, open_index, search
    from mtanno.index.example import DEFAULT_MIN_SEGMENT, example_file_query
    from mtanno.index.query import warm_up
    from mtanno.index.storage import index_files
    from mtanno.util.preflight import check_outputs
    from mtanno.util.tables import output_files, table_format

    if sum(x is not None for x in (example, query_file, kf_file)) != 1:
        raise MtannoError("give one of --example (with --features), --query or --keyframes")
    if windows and kf_file is None:
        raise MtannoError("--windows goes with --keyframes")
    table_format(output)
    index = open_index(index_dir)
    inputs = [*index_files(index.root), example, query_file, kf_file, rank_mt]
    check_outputs(output_files(output), [i for i in inputs if i is not None and Path(i).exists()])
    if kf_file is not None:
        if frames or feature_list or mode or mismatches is not None or min_segment:
            raise MtannoError("--frames, --features, --mode, --mismatches and --min-segment "
                              "do not go with --keyframes")
        return _keyframe_query(index, kf_file, windows=windows, rank_mt=rank_mt, top=top,
                               output=output, quiet=quiet)
    if example is not None:
        if not feature_list:
            raise MtannoError("--example needs --features NAME,...")
        query = example_file_query(index, example, feature_list.split(","), frames=frames,
                                   mode=mode or "adaptive", mismatches=mismatches or 0,
                                   min_segment=min_segment or DEFAULT_MIN_SEGMENT)
    else:
        if frames or feature_list:
            raise MtannoError("--frames and --features go with --example, not --query")
        query = load_query(query_file, index)
        if mode is not None or mismatches is not None or min_segment is not None:
            query = replace(query, mode=mode or query.mode,
                            mismatches=query.mismatches if mismatches is None else mismatches,
                            min_segment=min_segment or query.min_segment)
    warm_up()  # load the compiled kernels first: the time printed is the query's own
    t0 = time.perf_counter()
    hits = search(index, query)
    elapsed = time.perf_counter() - t0
    _write_hits(index, hits, output=output, rank_mt=rank_mt, top=top, quiet=quiet,
                inputs=[i for i in (example, query_file) if i is not None and Path(i).is_file()],
                mode=query.mode, mismatches=query.mismatches, min_segment=query.min_segment,
                frames=frames, features=feature_list, example=example)
    if not quiet:
        segs = ", ".join(f"{p.group} {len(p.normalized().sets)}" for p in query.parts)
        click.echo(f"query: {len(hits)} hits in {elapsed * 1000:.1f} ms ({query.mode}; query "
                   f"segments: {segs})" + (f" -> {output}" if output != "-" else ""), err=True)


def _write_hits(index, hits, *, output, rank_mt, top, quiet, inputs, **record) -> None:
    """Rank the hits by the ``--rank-mt`` template (a note counts the hits it cannot fit)
    and write them (:func:`mtanno.index.ranking.write_query_hits`)."""
    from mtanno.index.ranking import rank_by_template_file, write_query_hits

    if rank_mt is not None:
        hits, columns = rank_by_template_file(index, hits, rank_mt)
        if hits.unfit and not quiet:
            click.echo(f"query: note: the template ({columns} columns) cannot fit "
                       f"{hits.unfit} of {len(hits)} hits (too few frames for its steps); "
                       "they have no mt_cost and are ranked last", err=True)
    write_query_hits(output, index, hits, top=top, inputs=inputs, ranked_by=rank_mt, **record)


def _keyframe_query(index, kf_file, *, windows, rank_mt, top, output, quiet):
    """``query --keyframes``: search, optionally rank by a template, write the table."""
    import time

    from mtanno.keyframes import load_keyframes, search_index
    from mtanno.keyframes.search import warm_up

    q = load_keyframes(kf_file)
    try:
        warm_up()
        t0 = time.perf_counter()
        kh = search_index(index, q)
        elapsed = time.perf_counter() - t0
    except MtannoError as exc:
        raise MtannoError(exc.message, path=kf_file) from None
    hits = kh.as_hits(windows=windows)
    _write_hits(index, hits, output=output, rank_mt=rank_mt, top=top, inputs=[kf_file],
                keyframes=str(kf_file), windows=windows, quiet=quiet)
    if not quiet:
        what = "candidate windows" if windows else "hits"
        click.echo(f"query: {len(hits)} {what} in {elapsed * 1000:.2f} ms (keyframes: "
                   f"{q.n} of class {q.class_name}; {kh.frames} frames in hits)"
                   + (f" -> {output}" if output != "-" else ""), err=True)


COMMANDS = [index_group, query_cmd]
