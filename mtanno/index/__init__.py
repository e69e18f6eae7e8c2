"""Relational index and queries ([MRC05] §4–6, docs/method.md §4): the Python API behind
``mtanno index`` and ``mtanno query``.

* :func:`build_index`, :func:`open_index`, :func:`add_documents`, :func:`remove_documents`
  (:mod:`~mtanno.index.build`): feature files → index directory, updated atomically.
* :class:`Index` / :class:`GroupIndex` (:mod:`~mtanno.index.core`): documents, per-group
  F-segments (start frame, length, vector code) and inverted lists, in memory; also what
  keyframe search uses (:meth:`GroupIndex.intervals`).
* :func:`search` with a :class:`Query` (:mod:`~mtanno.index.query`): exact, fuzzy, adaptive
  fuzzy and m-mismatch hits over one or several groups.
* :mod:`~mtanno.index.example`: :func:`example_query` (query by example;
  :func:`example_matrix` reads its source), :func:`load_query` and :func:`parse_query`
  (JSON query files).
* :mod:`~mtanno.index.ranking`: :func:`rank_by_template` (:func:`rank_by_template_file` with
  a template file), :func:`write_query_hits` (the hit table).
* :func:`group_sizes` (``index info``).
* :mod:`~mtanno.index.storage` — the index folder on disk: generations, segment files and
  ``manifest.json``, read and written atomically.
* ``_kernels`` — numba kernels of segmentation and the inverted lists (private).
"""

__all__ = [
    "INDEX_FORMAT", "QUERY_MODES", "CorruptIndex", "Document", "FuzzySet", "GroupHits",
    "GroupIndex", "GroupQuery", "Hits", "Index", "Query", "UpdateReport", "add_documents",
    "build_index", "example_matrix", "example_query", "frame_codes", "group_sizes",
    "index_from_matrices", "load_query", "open_index", "parse_query", "rank_by_template",
    "rank_by_template_file", "remove_documents", "resolve_features", "run_group", "search",
    "segment", "write_query_hits",
]

from mtanno.index.build import (
    UpdateReport,
    add_documents,
    build_index,
    open_index,
    remove_documents,
)
from mtanno.index.core import (
    Document,
    GroupIndex,
    Index,
    frame_codes,
    index_from_matrices,
    segment,
)
from mtanno.index.example import (
    example_matrix,
    example_query,
    load_query,
    parse_query,
    resolve_features,
)
from mtanno.index.query import (
    QUERY_MODES,
    FuzzySet,
    GroupHits,
    GroupQuery,
    Hits,
    Query,
    run_group,
    search,
)
from mtanno.index.ranking import rank_by_template, rank_by_template_file, write_query_hits
from mtanno.index.storage import INDEX_FORMAT, CorruptIndex, group_sizes
from mtanno.util.lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)  # the modules not imported above, on first use
