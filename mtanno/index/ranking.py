"""Hits of an index query ranked and written: finer ranking by a motion template on the
hits' frames only ([MRC05] §6.2, :func:`rank_by_template`) and the query hit table
(:func:`write_query_hits`, ``docs/index.md``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from mtanno.errors import MtannoError
from mtanno.index.core import Index
from mtanno.index.query import Hits

__all__ = ["QUERY_HIT_COLUMNS", "hit_table", "rank_by_template", "rank_by_template_file",
           "write_query_hits"]


def rank_by_template(index: Index, hits: Hits, values: np.ndarray, weights: np.ndarray,
                     features: Sequence[str]) -> Hits:
    """Re-rank hits by the cost of a quantized motion template on each hit's frames only
    ([MRC05] §6.2, "finer ranking … on the few hits"; docs/method.md §3.4): cost = min Δ
    over the hit, with Δ computed on the hit's frames; ∞ where the hit is too short for the
    template (such hits are ranked last; :attr:`Hits.unfit` counts them). ``values``
    (f × K, 0/1/0.5), ``weights`` (K,), ``features`` the template's feature names (rebuilt
    from the index's groups)."""
    from mtanno.templates.match import match_documents

    _check_hits(index, hits)
    names = list(features)
    cache: dict[int, np.ndarray] = {}
    docs = []
    for d, s, e in zip(hits.doc, hits.start, hits.end):
        d = int(d)
        if d not in cache:
            cache[d] = index.feature_matrix(d, names)
        docs.append(cache[d][:, int(s):int(e) + 1])
    costs = np.full(len(hits), np.inf)
    if docs:
        for i, (delta, _) in enumerate(match_documents(values, weights, docs)):
            if len(delta) and np.isfinite(delta).any():
                costs[i] = float(np.min(delta))
    hits = replace(hits, cost=costs)
    order = np.lexsort((hits.start, hits.doc, costs))
    return hits.take(order)


def _check_hits(index: Index, hits: Hits) -> None:
    """Hits of ``index``: one document number and frame range per hit, inside it."""
    doc, start, end = (np.asarray(a) for a in (hits.doc, hits.start, hits.end))
    if doc.ndim != 1 or start.shape != doc.shape or end.shape != doc.shape:
        raise MtannoError("hits need one document number, start and end per hit")
    if not len(doc):
        return
    if doc.min() < 0 or doc.max() >= len(index.documents):
        raise MtannoError(f"hit document numbers must lie in 0..{len(index.documents) - 1}")
    frames = np.array([d.frames for d in index.documents], np.int64)[doc]
    if np.any(start < 0) or np.any(end < start) or np.any(end >= frames):
        raise MtannoError("hit frames must lie inside their document (0 ≤ start ≤ end < "
                          "frames)")


def rank_by_template_file(index: Index, hits: Hits, path: str | os.PathLike
                          ) -> tuple[Hits, int]:
    """:func:`rank_by_template` with a motion-template JSON file (``query --rank-mt``):
    read with :func:`mtanno.templates.store.load_template`, checked against the index's
    feature set, quantized with the retrieval δ (:data:`mtanno.templates.params.RETRIEVAL_DELTA`,
    [MR06] §5.2) unless it already is. Returns (ranked hits, the template's columns)."""
    from mtanno.templates.model import quantize
    from mtanno.templates.params import RETRIEVAL_DELTA
    from mtanno.templates.store import load_template

    mt = load_template(path)
    if mt.feature_set != index.feature_set:
        raise MtannoError(f"template is for feature set '{mt.feature_set}' but the index holds "
                          f"'{index.feature_set}'", path=str(path))
    missing = [n for n in mt.feature_names if n not in index.features]
    if missing:
        raise MtannoError(f"template feature '{missing[0]}' is not in the index's feature set",
                          path=str(path))
    if not mt.quantized:
        mt = quantize(mt, RETRIEVAL_DELTA)
    ranked = rank_by_template(index, hits, mt.values, mt.weights, list(mt.feature_names))
    return ranked, int(mt.values.shape[1])


def write_query_hits(path: str | os.PathLike, index: Index, hits: Hits, *,
                     top: int | None = None, inputs: Sequence[str | os.PathLike] = (),
                     ranked_by: str | os.PathLike | None = None, **record) -> None:
    """Write the hit table of ``hits`` (:meth:`Hits.rows`, the best ``top`` only) atomically
    in the format of ``path``'s suffix (``-``: CSV on standard output), with its provenance:
    the query's ``inputs`` and the index generation, the ranking template ``ranked_by``
    (its cost column is written when the hits were ranked), ``top`` and ``record``."""
    from mtanno.util.provenance import file_record, provenance
    from mtanno.util.tables import write_table

    rows = hits.rows(index)
    if top is not None:
        rows = rows[:top]
    write_table(path, hit_table(rows, with_mt=hits.cost is not None,
                                with_span=hits.span_start is not None), provenance=provenance(
        inputs=[file_record(i) for i in inputs] + [{"path": str(index.root / "manifest.json"),
                                                    "generation": index.generation}],
        templates=[file_record(ranked_by)] if ranked_by else (), top=top,
        feature_set=index.feature_set, **record))


QUERY_HIT_COLUMNS = ("doc", "start", "end", "rank", "score", "mt_cost", "span_start",
                     "span_end", "boundaries")


def hit_table(rows: Sequence[dict], *, with_mt: bool = False, with_span: bool = False):
    """The query hit table (``docs/index.md``) of :meth:`Hits.rows` as a
    :class:`pyarrow.Table`: doc, start, end, rank, score (an integer column when every
    score is whole), mt_cost (only ``with_mt``; null where the template cannot fit),
    span_start, span_end (only ``with_span``: untrimmed frames), boundaries."""
    import pyarrow as pa

    from mtanno.util.tables import arrow_table

    optional = {"mt_cost": with_mt, "span_start": with_span, "span_end": with_span}
    cols = [c for c in QUERY_HIT_COLUMNS if optional.get(c, True)]
    scores = [r.get("score") for r in rows]
    whole = all(s is None or float(s).is_integer() for s in scores)
    types = {"doc": pa.string(), "boundaries": pa.string(), "mt_cost": pa.float64(),
             "score": pa.int64() if whole else pa.float64()}
    data = {}
    for c in cols:
        values = [r.get(c) for r in rows]
        if c == "score" and whole:
            values = [None if v is None else int(v) for v in values]
        data[c] = values
    return arrow_table(data, types)  # (names of non-UTF-8 files written as text)
