"""The whole ``mtanno query`` run, from file names to the hit table: a query by example, a
JSON query file ([MRC05] §5–6, :mod:`mtanno.index`) or a keyframe query ([MBS09] §5,
:func:`mtanno.keyframes.search_index`) answered on an index, the hits optionally ranked by a
motion template (:mod:`mtanno.index.ranking`) and written with their provenance.

It lives here, above :mod:`mtanno.index`, because one of its three kinds of query is a
keyframe query and keyframes rank above the index (docs/architecture.md, "Layers").
:class:`QueryOptions` holds the query and its output options; :func:`query_to` is the run;
:class:`QueryRun` what it found.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from mtanno.errors import MtannoError

__all__ = ["QueryOptions", "QueryRun", "query_to"]

PathLike = str | os.PathLike


@dataclass(frozen=True)
class QueryOptions:
    """What :func:`query_to` asks and writes (``mtanno query``'s options; docs/index.md).

    One of ``example`` (a feature file or an indexed document's name, with ``features``:
    the names, ids or aliases that matter, and ``frames``: ``"A:B"``, 1-based inclusive,
    default all), ``query_file`` (a JSON query) or ``keyframes`` (a keyframe query file;
    ``windows``: write its candidate windows instead of its hits). ``mode``,
    ``mismatches``, ``min_segment``: the search (None: the query by example's defaults, or
    the query file's own); they do not go with ``keyframes``. ``rank_mt``: rank the hits by
    this template's cost; ``top``: write only the best ``top`` hits."""

    example: PathLike | None = None
    frames: str | None = None
    features: Sequence[str] | None = None
    query_file: PathLike | None = None
    keyframes: PathLike | None = None
    windows: bool = False
    mode: str | None = None
    mismatches: int | None = None
    min_segment: int | None = None
    rank_mt: PathLike | None = None
    top: int | None = None


@dataclass
class QueryRun:
    """What :func:`query_to` found: the number of hits written before ``top`` (candidate
    windows with ``windows``), the seconds of the search alone, and for the summary: the
    search mode and the segments per group of the query (by example, query file), or the
    keyframe query's number of keyframes, class and frames in hits; with ``rank_mt`` the
    template's columns and the hits it cannot fit (ranked last, without cost)."""

    hits: int
    seconds: float
    mode: str | None = None
    segments: list[tuple[str, int]] | None = None
    keyframes: int = 0
    class_name: str | None = None
    frames: int = 0
    columns: int = 0
    unfit: int = 0


def query_to(index_dir: PathLike, output: PathLike = "-", *,
             options: QueryOptions | None = None) -> QueryRun:
    """Answer the query of ``options`` (:class:`QueryOptions`) on the index ``index_dir``
    and write the hit table to ``output`` (suffix picks the format, ``-`` is CSV on
    standard output; docs/formats.md) with its provenance; every output is checked
    against the inputs first. The kernels are loaded before the clock starts, so
    :attr:`QueryRun.seconds` is the search's own time."""
    from mtanno.index import open_index
    from mtanno.index.storage import index_files
    from mtanno.util.preflight import check_outputs
    from mtanno.util.tables import output_files, table_format

    o = options or QueryOptions()
    if sum(x is not None for x in (o.example, o.query_file, o.keyframes)) != 1:
        raise MtannoError("give one of {example} (with {features}), {query_file} or "
                          "{keyframes}", options=("example", "features", "query_file",
                                                  "keyframes"))
    if o.windows and o.keyframes is None:
        raise MtannoError("{windows} goes with {keyframes}", options=("windows", "keyframes"))
    table_format(output)
    index = open_index(index_dir)
    inputs = [*index_files(index.root), o.example, o.query_file, o.keyframes, o.rank_mt]
    check_outputs(output_files(output), [i for i in inputs if i is not None and Path(i).exists()])
    if o.keyframes is not None:
        if o.frames or o.features or o.mode or o.mismatches is not None or o.min_segment:
            raise MtannoError("{frames}, {features}, {mode}, {mismatches} and {min_segment} "
                              "do not go with {keyframes}",
                              options=("frames", "features", "mode", "mismatches",
                                       "min_segment", "keyframes"))
        return _keyframe_query(index, o, output)
    return _index_query(index, o, output)


def _index_query(index, o: QueryOptions, output: PathLike) -> QueryRun:
    """A query by example or a query file: searched, ranked, written."""
    from mtanno.index import load_query, search
    from mtanno.index.example import DEFAULT_MIN_SEGMENT, example_file_query
    from mtanno.index.query import warm_up

    if o.example is not None:
        if not o.features:
            raise MtannoError("{example} needs {features} NAME,...",
                              options=("example", "features"))
        query = example_file_query(index, o.example, list(o.features), frames=o.frames,
                                   mode=o.mode or "adaptive", mismatches=o.mismatches or 0,
                                   min_segment=o.min_segment or DEFAULT_MIN_SEGMENT)
    else:
        if o.frames or o.features:
            raise MtannoError("{frames} and {features} go with {example}, not {query_file}",
                              options=("frames", "features", "example", "query_file"))
        query = load_query(o.query_file, index)
        if o.mode is not None or o.mismatches is not None or o.min_segment is not None:
            query = replace(query, mode=o.mode or query.mode,
                            mismatches=query.mismatches if o.mismatches is None
                            else o.mismatches,
                            min_segment=o.min_segment or query.min_segment)
    warm_up()  # load the compiled kernels first: the time measured is the query's own
    t0 = time.perf_counter()
    hits = search(index, query)
    run = QueryRun(len(hits), time.perf_counter() - t0, mode=query.mode,
                   segments=[(p.group, len(p.normalized().sets)) for p in query.parts])
    _write_hits(index, hits, o, output, run,
                inputs=[i for i in (o.example, o.query_file) if i is not None
                        and Path(i).is_file()],
                mode=query.mode, mismatches=query.mismatches, min_segment=query.min_segment,
                frames=o.frames, features=None if o.features is None else ",".join(o.features),
                example=o.example)
    return run


def _keyframe_query(index, o: QueryOptions, output: PathLike) -> QueryRun:
    """A keyframe query: searched, its hits (or candidate windows) ranked and written."""
    from mtanno.keyframes.search import search_index, warm_up
    from mtanno.keyframes.store import load_keyframes

    q = load_keyframes(o.keyframes)
    try:
        warm_up()
        t0 = time.perf_counter()
        kh = search_index(index, q)
        seconds = time.perf_counter() - t0
    except MtannoError as exc:
        raise MtannoError(exc.message, path=o.keyframes) from None
    hits = kh.as_hits(windows=o.windows)
    run = QueryRun(len(hits), seconds, keyframes=q.n, class_name=q.class_name,
                   frames=kh.frames)
    _write_hits(index, hits, o, output, run, inputs=[o.keyframes], keyframes=str(o.keyframes),
                windows=o.windows)
    return run


def _write_hits(index, hits, o: QueryOptions, output: PathLike, run: QueryRun, *, inputs,
                **record) -> None:
    """Rank the hits by ``o.rank_mt`` (the hits it cannot fit counted in ``run``) and write
    them (:func:`mtanno.index.ranking.write_query_hits`)."""
    from mtanno.index.ranking import rank_by_template_file, write_query_hits

    if o.rank_mt is not None:
        hits, run.columns = rank_by_template_file(index, hits, o.rank_mt)
        run.unfit = hits.unfit
    write_query_hits(output, index, hits, top=o.top, inputs=inputs, ranked_by=o.rank_mt,
                     **record)
