"""Keyframe queries: search and learning ([MBS09] §5–6, thesis ch. 4 and 6, docs/method.md
§5–6) — the preselection stage in front of template matching.

* :mod:`~mtanno.keyframes.model` — :class:`KeyframeQuery` (keyframes over one feature group
  each, gap bounds, template positions, window extension), its JSON file
  (:func:`load_keyframes`, :func:`save_keyframes`, schema ``mtanno.keyframes/1``) and
  :func:`format_query` (``mtanno keyframes show``).
* :mod:`~mtanno.keyframes.search` — all chains of a query at once, through an index
  (:func:`search_index`) or by a direct scan of feature matrices (:func:`search_documents`);
  :class:`KeyframeHits` and candidate windows for annotation (:func:`document_windows`,
  :func:`class_windows`, :func:`class_spans` as arrays; :class:`KeyframeSet` prepares several
  classes' queries once).
* :mod:`~mtanno.keyframes.learn` — learning a query per class from positive and negative
  training clips: the genetic algorithm of [MBS09] §6 (``ga``), hard-template columns
  (``hard``, thesis) and [MR06]'s column heuristic (``heuristic``).
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

from mtanno.keyframes.model import (
    SCHEMA,
    Extension,
    Gap,
    Keyframe,
    KeyframeQuery,
    format_query,
    keyframe_files,
    load_class_keyframes,
    load_keyframe_folder,
    load_keyframes,
    save_keyframes,
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
from mtanno.util.lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)  # the modules not imported above, on first use
