"""Annotating batches of feature files: the documents annotated in worker processes or on
a dask cluster (:func:`annotate_files`) with what :mod:`mtanno.annotate.setup` loaded
once, many short documents per task, a failing file reported and the batch going on.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from mtanno.annotate.config import ClassConfig
from mtanno.annotate.label import ClassModel, annotate_document, valid_rows, valid_windows
from mtanno.annotate.options import SETUP_OPTIONS, AnnotateOptions
from mtanno.errors import MtannoError
from mtanno.labels.segments import Annotation

if TYPE_CHECKING:
    from mtanno.features.store import FeatureLayout

__all__ = ["AnnotationBatch", "annotate_files"]


@dataclass
class AnnotationBatch:
    """What :func:`annotate_files` did: the segments of every document annotated, each
    document's native frames and frame count, the files read (path, SHA-256) and the
    failures (one message per file that could not be annotated); ``seconds`` is the time
    spent annotating (keyframe search, matching, labels; not reading), summed over the
    documents."""

    rows: list[Annotation] = field(default_factory=list)
    native: dict[str, np.ndarray] = field(default_factory=dict)
    frames: dict[str, int] = field(default_factory=dict)
    files: list[dict] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def to_arrow(self):
        """The annotation table of the batch as a :class:`pyarrow.Table`, the table
        ``mtanno annotate -o`` writes (:func:`mtanno.annotate.tables.annotation_table`):
        doc, start, end (1-based inclusive 30 Hz frames, as in every file; ``rows`` are
        0-based), label, cost, and start_native, end_native (1-based native frames) when
        the batch knows every document's native frames."""
        from mtanno.annotate.tables import annotation_table

        known = all(r.doc in self.native for r in self.rows)
        return annotation_table(self.rows, self.native if known else None)

    def to_pandas(self):
        """:meth:`to_arrow` as a :class:`pandas.DataFrame` (1-based frames); pandas is not
        a dependency of mtanno, so without it this is an :class:`MtannoError` saying so."""
        try:
            import pandas  # noqa: F401
        except ImportError:
            raise MtannoError("AnnotationBatch.to_pandas needs pandas (pip install 'mtanno[pandas]'); "
                              "to_arrow() gives the same table without it") from None
        return self.to_arrow().to_pandas()


def _annotate_file(path, models, layout, config, dbar_variant, match_variant, keyframes,
                   single_label=False, confidence=None, min_confidence=None):
    """One document of a batch: (document, rows, native frames, sha256, seconds) or the
    message of its failure (a worker sends it back as text). Every row gets its
    confidence (:func:`mtanno.confidence.score.score_document`); rows below the
    minimum confidence (``min_confidence``, else the tuned one) are dropped."""
    import time

    from mtanno.confidence.score import score_document, single_label_by_confidence
    from mtanno.features.store import check_layout, read_features
    from mtanno.templates.match import pack_document

    bank = confidence.bank if confidence is not None else None
    need_poses = (bank is not None and bank.representation == "poses") or bool(config.poses)
    try:
        ff = read_features(path, sha256=True, poses=need_poses)
        check_layout(ff, layout)
        if need_poses and ff.poses is None:
            raise MtannoError("the class configuration needs poses in the feature files (its "
                              "[inputs]), but this one has none: run mtanno features --poses "
                              f"(or features --classes {config.path})", path=ff.path)
        t0 = time.perf_counter()
        windows = None
        packed = pack_document(ff.X, ff.X.shape[0])  # once, for keyframes and templates
        if keyframes:
            from mtanno.keyframes import class_spans

            try:
                windows = class_spans(ff.X, ff.names, keyframes,
                                      feature_set=layout.feature_set, packed=packed)
            except MtannoError as exc:
                raise MtannoError(exc.message, path=ff.path) from None
        # frames without evidence (a marker file's lost joints) are never labelled
        windows = valid_windows(windows, [m.name for m in models], ff.valid)
        # a tuned confidence decides overlaps itself (the reference path's single label)
        by_confidence = single_label and confidence is not None and not config.resolve
        rows, _, _ = annotate_document(ff.document, ff.X, models, config=config,
                                       windows=windows, dbar_variant=dbar_variant,
                                       match_variant=match_variant,
                                       single_label=single_label and not by_confidence,
                                       packed=packed, matrix=False)
        try:
            rows = score_document(rows, X=ff.X, poses=ff.poses,
                                  models=models, config=config, confidence=confidence)
        except MtannoError as exc:
            raise MtannoError(exc.message, path=exc.path or ff.path) from None
        rows = valid_rows(rows, ff.valid)
        if by_confidence:
            rows = single_label_by_confidence(rows)
        least = min_confidence if min_confidence is not None else (
            confidence.min_confidence if confidence is not None else 0.0)
        if least > 0:
            rows = [r for r in rows if r.confidence >= least]
    except MtannoError as exc:
        return str(exc)
    return ff.document, rows, ff.native_frames, ff.sha256, time.perf_counter() - t0


#: Documents per task of a worker pool at most (a task carries file names only: the setup
#: reaches every worker once, :func:`mtanno.util.workers.shared`).
MAX_CHUNK = 16
#: Tasks per worker at least, where there are enough documents (for an even load).
CHUNKS_PER_JOB = 4


def _chunks(paths: list, n_jobs: int) -> list[list]:
    """``paths`` in consecutive tasks of up to :data:`MAX_CHUNK` documents, at least
    :data:`CHUNKS_PER_JOB` tasks per worker where there are enough (one document per task
    without a pool: the results come as the documents are done)."""
    if n_jobs < 2:
        return [[p] for p in paths]
    size = max(1, min(MAX_CHUNK, -(-len(paths) // (n_jobs * CHUNKS_PER_JOB))))
    return [paths[i:i + size] for i in range(0, len(paths), size)]


def _annotate_chunk(items: list[tuple[str, str | None]]) -> list:
    """Every document of a task, with the batch's setup that every worker got once
    (:func:`mtanno.util.workers.shared`): :func:`_annotate_file`, or, with an output
    table, :func:`_annotate_into` it."""
    from mtanno.util.workers import shared

    setup, base = shared()
    return [_annotate_file(p, *setup) if dst is None else _annotate_into(p, dst, setup, base)
            for p, dst in items]


def _annotate_into(path: str, dst: str, setup: tuple, base: dict):
    """One document annotated and its table written to ``dst`` (format by suffix) with the
    provenance ``base`` of the batch for this one document (its feature file, frames and
    time of writing; issue 34: written where it was computed, in the worker, instead of
    one after another by the parent): ``(document, rows written, frames, sha256,
    seconds)``, or the message of its failure."""
    from mtanno.annotate.tables import write_annotations
    from mtanno.util.provenance import utc_now

    got = _annotate_file(path, *setup)
    if isinstance(got, str):
        return got
    doc, rows, native, digest, seconds = got
    prov = dict(base)  # the keys in the order AnnotationSetup.provenance gives them
    prov["created"] = utc_now()
    prov["inputs"] = [{"path": str(path), "sha256": digest}]
    prov["documents"] = {doc: int(native.shape[0])}
    try:
        write_annotations(dst, rows, {doc: native}, provenance=prov)
    except MtannoError as exc:
        return str(exc)
    return doc, len(rows), int(native.shape[0]), digest, seconds


def _iter_annotate(paths: Sequence[str | os.PathLike], models: Sequence[ClassModel], *,
                   layout: FeatureLayout, config: ClassConfig, dbar_variant: str,
                   match_variant: str, keyframes, n_jobs: int,
                   single_label: bool, scheduler: str | None, confidence=None,
                   min_confidence: float | None = None,
                   outputs: Sequence[str | os.PathLike] | None = None,
                   provenance: dict | None = None):
    """(path, result) for every document of a batch in input order, as the pool delivers
    them: result is ``(document, rows, native frames, sha256, seconds)`` or the message
    of the document's failure. With ``outputs`` (one table per path) each document's
    table is written where it is annotated, with ``provenance`` (the batch's, with
    placeholders for the document's own entries; :func:`_annotate_into`), and result is
    ``(document, rows written, frames, sha256, seconds)``.

    Issue 34 (many short files as cheap as one long document): the setup (models,
    configuration, keyframe queries, confidence with its verification bank) reaches each
    worker once — forked with the pool, or scattered to a dask cluster — and a task
    carries the names of several documents (:func:`_chunks`). With local workers the
    first document is annotated here before the pool starts, so that the workers are
    forked with every kernel it needs already loaded."""
    from mtanno.keyframes import KeyframeSet
    from mtanno.util.workers import make_pool

    if keyframes and not isinstance(keyframes, KeyframeSet):
        # prepared once for the batch; if that fails, each document says why
        try:
            keyframes = KeyframeSet(keyframes, layout.names, feature_set=layout.feature_set)
        except MtannoError:
            pass
    setup = (models, layout, config, dbar_variant, match_variant, keyframes, single_label,
             confidence, min_confidence)
    items = list(zip([str(p) for p in paths], [None] * len(paths) if outputs is None
                     else [str(o) for o in outputs]))
    if n_jobs > 1 and scheduler is None and len(items) > 1:
        # the first document here: the workers are forked with its kernels loaded
        (path, dst), items = items[0], items[1:]
        yield path, (_annotate_file(path, *setup) if dst is None else
                     _annotate_into(path, dst, setup, provenance))
    chunks = _chunks(items, n_jobs if scheduler is None else max(n_jobs, 2))
    with make_pool(jobs=n_jobs, scheduler=scheduler, n_tasks=len(chunks),
                   shared=(setup, provenance)) as pool:
        for chunk, results in zip(chunks, pool.map(_annotate_chunk, [(c,) for c in chunks])):
            yield from ((p, r) for (p, _), r in zip(chunk, results))


def annotate_files(paths: Sequence[str | os.PathLike], models: Sequence[ClassModel], *,
                   layout: FeatureLayout, config: ClassConfig | None = None, keyframes=None,
                   confidence=None, options: AnnotateOptions | None = None,
                   progress=None) -> AnnotationBatch:
    """Annotate feature files (:func:`annotate_document`) with the class ``models`` as
    ``options`` say (:class:`~mtanno.annotate.options.AnnotateOptions`: the variants,
    ``single_label``, ``min_confidence``, ``n_jobs`` processes of a
    :class:`mtanno.util.workers.WorkerPool` or a dask.distributed ``scheduler``
    (:class:`mtanno.util.workers.DaskPool`, same results); what
    :func:`~mtanno.annotate.load_annotation_setup` reads — ``config_path``,
    ``keyframes_dir``, ``tau``, ``delta`` — is given loaded here, and is an error in
    ``options``). ``config``: the class configuration (None: the reference annotation).
    ``keyframes`` maps class names to keyframe queries (:mod:`mtanno.keyframes`), or is a
    :class:`mtanno.keyframes.KeyframeSet` of them: those classes are matched only inside
    their candidate windows in each document ([MBS09] §5), the others everywhere.
    ``confidence``: the tuned :class:`mtanno.confidence.model.ConfidenceModel` (None: the
    uncalibrated confidence); ``options.min_confidence`` drops rows below it (None: the
    tuned minimum, 0 without one). A file that cannot be read or does not have the
    templates' ``layout`` is recorded in ``failed`` and the batch goes on. ``progress`` is
    called once per file with its path and its failure message (None on success). Rows
    are sorted by document, start, end and label."""
    o = options or AnnotateOptions()
    given = [name for name in SETUP_OPTIONS if getattr(o, name) is not None]
    if given:
        names = [f"{{{n}}}" for n in given]
        what = (", ".join(names[:-1]) + " and " if len(names) > 1 else "") + names[-1]
        raise MtannoError(f"{what} go{'' if len(given) > 1 else 'es'} with "
                          "load_annotation_setup: annotate_files takes the templates, the "
                          "configuration and the keyframe queries loaded",
                          options=tuple(given))
    batch = AnnotationBatch()
    for path, result in _iter_annotate(paths, models, layout=layout,
                                       config=config or ClassConfig(),
                                       dbar_variant=o.dbar_variant,
                                       match_variant=o.match_variant, keyframes=keyframes,
                                       n_jobs=o.n_jobs, single_label=o.single_label,
                                       scheduler=o.scheduler, confidence=confidence,
                                       min_confidence=o.min_confidence):
        if isinstance(result, str):
            batch.failed.append(result)
            if progress:
                progress(path, result)
            continue
        doc, rows, native, digest, seconds = result
        batch.seconds += seconds
        batch.rows.extend(rows)
        batch.native[doc] = native
        batch.frames[doc] = int(native.shape[0])
        batch.files.append({"path": str(path), "sha256": digest})
        if progress:
            progress(path, None)
    batch.rows.sort(key=lambda r: (r.doc, r.start, r.end, r.label))
    return batch
