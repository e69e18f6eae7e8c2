"""Keyframe queries: search and learning ([MBS09] §5–6, thesis ch. 4 and 6, docs/method.md
§5–6) — the preselection stage in front of template matching.

* :mod:`~mtanno.keyframes.model` — :class:`KeyframeQuery` (keyframes over one feature group
  each, gap bounds, template positions, window extension), checked when made.
* :mod:`~mtanno.keyframes.store` — its JSON file (:func:`load_keyframes`,
  :func:`save_keyframes`, schema ``mtanno.keyframes/1``).
* :mod:`~mtanno.keyframes.folders` — folders of query files (:func:`keyframe_files`,
  :func:`load_keyframe_folder`, :func:`load_class_keyframes` for annotate and tune).
* :mod:`~mtanno.keyframes.describe` — :func:`format_query` (``mtanno keyframes show``).
* :mod:`~mtanno.keyframes.search` — all chains of a query at once, through an index
  (:func:`search_index`) or by a direct scan of feature matrices (:func:`search_documents`);
  :class:`KeyframeHits` and candidate windows for annotation (:func:`document_windows`,
  :func:`class_windows`, :func:`class_spans` as arrays; :class:`KeyframeSet` prepares several
  classes' queries once).
* :mod:`~mtanno.keyframes.learn` — learning a query per class from positive and negative
  training clips: the genetic algorithm of [MBS09] §6 (``ga``), hard-template columns
  (``hard``, thesis) and [MR06]'s column heuristic (``heuristic``).
* :mod:`~mtanno.keyframes.run` — the whole ``mtanno learn-keyframes`` run, from file names to
  files (:func:`~mtanno.keyframes.run.learn_keyframes_to`, its options
  :class:`~mtanno.keyframes.run.KeyframeOptions`).
* :mod:`~mtanno.keyframes.query` — the whole ``mtanno query`` run (by example, query file or
  keyframe query; :func:`~mtanno.keyframes.query.query_to`, :class:`~mtanno.keyframes.query.QueryOptions`):
  here because keyframe queries rank above the index.
* :mod:`~mtanno.keyframes.ga` and :mod:`~mtanno.keyframes.fitness` — the genetic algorithm
  and its fitness (hits and misses of a candidate query on the training clips).
* ``_kernels`` — numba kernels on interval lists (private).
"""

__all__ = [
    "SCHEMA", "Extension", "Gap", "Keyframe", "KeyframeHits", "KeyframeQuery", "KeyframeSet",
    "chain_hits", "class_spans",
    "class_windows", "document_windows", "format_query", "keyframe_files", "load_class_keyframes",
    "load_keyframe_folder", "load_keyframes",
    "save_keyframes", "search_documents", "search_index", "stiffness_bounds",
]

from mtanno.keyframes.describe import format_query
from mtanno.keyframes.folders import keyframe_files, load_class_keyframes, load_keyframe_folder
from mtanno.keyframes.model import (
    SCHEMA,
    Extension,
    Gap,
    Keyframe,
    KeyframeQuery,
    stiffness_bounds,
)
from mtanno.keyframes.search import (
    KeyframeHits,
    KeyframeSet,
    chain_hits,
    class_spans,
    class_windows,
    document_windows,
    search_documents,
    search_index,
)
from mtanno.keyframes.store import load_keyframes, save_keyframes
from mtanno.util.lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)  # the modules not imported above, on first use
