"""Annotating batches of feature files: the class models of a template folder and a class
configuration, loaded once (:class:`AnnotationSetup`), and the documents annotated in
worker processes or on a dask cluster (:func:`annotate_files`), a failing file reported
and the batch going on.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from mtanno.annotate.config import ClassConfig, config_file, load_class_config
from mtanno.annotate.label import ClassModel, annotate_document, valid_rows, valid_windows
from mtanno.errors import MtannoError
from mtanno.labels.segments import Annotation
from mtanno.templates.params import ANNOTATION_DELTA, check_tau

if TYPE_CHECKING:
    from mtanno.features.store import FeatureLayout

__all__ = ["AnnotationBatch", "AnnotationSetup", "annotate_files", "annotation_setup",
           "class_models", "load_annotation_setup", "load_class_models",
           "load_config_templates"]


def load_class_models(mt_dir: str | os.PathLike, *, delta: float = ANNOTATION_DELTA,
                      classes: Sequence[str] = ()) -> tuple[list[ClassModel], FeatureLayout]:
    """The templates of a folder (``*.json``; or one template file;
    :func:`mtanno.templates.model.load_template_folder`), quantized with ``delta``, as
    :class:`ClassModel` records (with their file and SHA-256), and the feature layout
    (set, names, rate) they all share. ``classes`` keeps only those."""
    from mtanno.templates.model import load_template_folder

    return class_models(load_template_folder(mt_dir, classes=classes), delta=delta,
                        where=f"the templates in {mt_dir}")


def class_models(templates: dict, *, delta: float = ANNOTATION_DELTA,
                 where: str = "the templates") -> tuple[list[ClassModel], FeatureLayout]:
    """:class:`ClassModel` records of loaded templates (class name →
    :class:`mtanno.templates.model.MotionTemplate`, e.g. from ``load_template_folder`` or
    learned in memory), quantized with ``delta``, and the feature layout they share
    (``where`` names them in messages)."""
    from mtanno.features.store import check_layout
    from mtanno.templates.model import quantize
    from mtanno.util.tables import sha256_file

    if not templates:
        raise MtannoError("no class templates to annotate with")
    models: list[ClassModel] = []
    for mt in templates.values():
        q = quantize(mt, delta)
        model = ClassModel(mt.class_name, q.values, q.weights, path=mt.path,
                           sha256=sha256_file(mt.path) if mt.path else None)
        try:
            model.matcher("reference")  # refuse a template the kernel cannot use, naming it
        except MtannoError as exc:
            raise MtannoError(exc.message, path=mt.path) from None
        models.append(model)
    first = next(iter(templates.values()))
    layout = first.layout(where)
    for mt in templates.values():  # templates made in memory were not checked by a reader
        check_layout(mt.layout(), layout, path=mt.path)
    return models, layout


def load_config_templates(config: ClassConfig, layout: FeatureLayout, *,
                          delta: float = ANNOTATION_DELTA) -> list[ClassModel]:
    """The further templates of ``config.templates`` (several templates per class) as
    :class:`ClassModel` records, quantized with ``delta``: each file must hold a template
    of the class it is listed under, with the ``layout`` of the other templates."""
    from mtanno.features.store import check_layout
    from mtanno.templates.model import load_template, quantize
    from mtanno.util.tables import sha256_file

    out = []
    for cls, paths in config.template_paths().items():
        line = config.line_of("templates", cls)
        for path in paths:
            if not path.is_file():
                raise MtannoError(f"[templates] {cls}: template file {path} not found",
                                  path=config.path, line=line)
            mt = load_template(path)
            if mt.class_name != cls:
                raise MtannoError(f"[templates] {cls}: {path} holds a template of class "
                                  f"{mt.class_name!r}", path=config.path, line=line)
            check_layout(mt.layout(f"template {path}"), layout, path=str(path))
            q = quantize(mt, delta)
            model = ClassModel(cls, q.values, q.weights, path=str(path),
                               sha256=sha256_file(path), extra=True)
            try:
                model.matcher("reference")
            except MtannoError as exc:
                raise MtannoError(exc.message, path=str(path)) from None
            out.append(model)
    return out


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
    from mtanno.util.tables import utc_now

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
                   layout: FeatureLayout, config: ClassConfig | None = None,
                   dbar_variant: str = "reference", match_variant: str = "reference",
                   keyframes=None, n_jobs: int = 1,
                   progress=None, single_label: bool = False,
                   scheduler: str | None = None, confidence=None,
                   min_confidence: float | None = None) -> AnnotationBatch:
    """Annotate feature files (:func:`annotate_document`), in ``n_jobs`` processes
    (:class:`mtanno.util.workers.WorkerPool`). ``keyframes`` maps class names to keyframe
    queries (:mod:`mtanno.keyframes`), or is a :class:`mtanno.keyframes.KeyframeSet` of
    them: those classes are matched only inside their
    candidate windows in each document ([MBS09] §5), the others everywhere. A file that
    cannot be read or does not have the templates' ``layout`` is recorded in ``failed``
    and the batch goes on. ``progress`` is called once per file with its path and its
    failure message (None on success). ``single_label`` resolves overlapping segments
    (:func:`single_label_segments`). ``scheduler``: a dask.distributed cluster runs the
    documents instead of local processes (:class:`mtanno.util.workers.DaskPool`, same results).
    ``confidence``: the tuned :class:`mtanno.confidence.model.ConfidenceModel` (None: the
    uncalibrated confidence); ``min_confidence`` drops rows below it (None: the tuned
    minimum, 0 without one). Rows are sorted by document, start, end and label."""
    batch = AnnotationBatch()
    for path, result in _iter_annotate(paths, models, layout=layout,
                                       config=config or ClassConfig(),
                                       dbar_variant=dbar_variant, match_variant=match_variant,
                                       keyframes=keyframes, n_jobs=n_jobs,
                                       single_label=single_label, scheduler=scheduler,
                                       confidence=confidence,
                                       min_confidence=min_confidence):
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


@dataclass
class AnnotationSetup:
    """Everything that shapes an annotation besides its documents, loaded once for a batch
    (:func:`load_annotation_setup`): the class models (the templates of the template folder
    and of the configuration's ``[templates]``, quantized with ``delta``), their feature
    layout, the class configuration, the keyframe queries with their files, and the
    options. :meth:`provenance` is what every annotation table of the batch records, and
    :meth:`annotate` runs :func:`annotate_files` with it."""

    models: list[ClassModel]
    layout: FeatureLayout
    config: ClassConfig = field(default_factory=ClassConfig)
    delta: float = ANNOTATION_DELTA
    dbar_variant: str = "reference"
    match_variant: str = "reference"
    keyframes: dict = field(default_factory=dict)
    keyframe_files: list[dict] = field(default_factory=list)
    single_label: bool = False
    config_sha256: str | None = None
    #: classes without a keyframe query (matched everywhere), and queries without a template
    keyframes_missing: list[str] = field(default_factory=list)
    keyframes_extra: list[str] = field(default_factory=list)
    #: the configuration was tuned with other templates (:meth:`ClassConfig.template_warnings`)
    warnings: list[str] = field(default_factory=list)
    #: the tuned confidence of the configuration (None: uncalibrated), and the minimum
    #: confidence asked for (None: the tuned one)
    confidence: object = None
    min_confidence: float | None = None

    @property
    def classes(self) -> list[str]:
        return list(dict.fromkeys(m.name for m in self.models))

    def files(self) -> list[str]:
        """Every file the setup was read from: templates, class configuration, keyframe
        queries, verification bank."""
        bank = getattr(self.confidence, "bank_path", None)
        return [*(m.path for m in self.models if m.path), *([self.config.path]
                if self.config.path else []), *(f["path"] for f in self.keyframe_files),
                *([bank] if bank else [])]

    def provenance(self, *, inputs=(), documents: dict[str, int] | None = None) -> dict:
        """The provenance of an annotation table of ``inputs`` (feature file records) with
        ``documents`` (frames per document): templates with SHA-256, τ (default and per
        class), superclasses, δ, the configuration's methods, the configuration file and its
        SHA-256, variants, feature set, keyframe files, single label, the confidence
        (calibrated or not, evidence, minimum, bank) and the background tune saw."""
        from mtanno.confidence.model import confidence_record
        from mtanno.util.tables import provenance

        cfg = self.config
        return provenance(inputs=inputs, templates=[m.record() for m in self.models],
                          tau=cfg.default_tau, tau_per_class=cfg.tau or None,
                          superclasses=cfg.superclasses or None, delta=self.delta,
                          methods=cfg.methods() or None,
                          classes=({"path": cfg.path, "sha256": self.config_sha256}
                                   if cfg.path else None),
                          variant=self.dbar_variant, match=self.match_variant,
                          feature_set=self.layout.feature_set,
                          keyframes=self.keyframe_files or None,
                          single_label=self.single_label or None, documents=documents,
                          confidence=confidence_record(self.confidence, self.min_confidence),
                          background=[{"path": p, "sha256": h} for p, h in
                                      sorted(cfg.background.items())] or None)

    def annotate(self, paths: Sequence[str | os.PathLike], *, n_jobs: int = 1, progress=None,
                 scheduler: str | None = None) -> AnnotationBatch:
        """:func:`annotate_files` of ``paths`` with this setup."""
        return annotate_files(paths, self.models, layout=self.layout, config=self.config,
                              dbar_variant=self.dbar_variant, match_variant=self.match_variant,
                              keyframes=self.keyframes or None, n_jobs=n_jobs,
                              progress=progress, single_label=self.single_label,
                              scheduler=scheduler, confidence=self.confidence,
                              min_confidence=self.min_confidence)

    def iter_annotate(self, paths: Sequence[str | os.PathLike], *, n_jobs: int = 1,
                      scheduler: str | None = None,
                      outputs: Sequence[str | os.PathLike] | None = None):
        """(path, result) per document in input order as they are done (result: document,
        rows, native frames, SHA-256, seconds; or the failure's message). With ``outputs``
        (one table per path) each table is written, with this setup's provenance for its
        document, where the document was annotated (result: document, rows written,
        frames, SHA-256, seconds)."""
        return _iter_annotate(paths, self.models, layout=self.layout, config=self.config,
                              dbar_variant=self.dbar_variant, match_variant=self.match_variant,
                              keyframes=self.keyframes or None, n_jobs=n_jobs,
                              single_label=self.single_label, scheduler=scheduler,
                              confidence=self.confidence, min_confidence=self.min_confidence,
                              outputs=outputs, provenance=None if outputs is None else
                              self.provenance(inputs=[{}], documents={"": 0}))


def annotation_setup(templates: dict, *, config: ClassConfig | None = None,
                     config_sha256: str | None = None, tau: float | None = None,
                     delta: float | None = None, dbar_variant: str = "reference",
                     match_variant: str = "reference", single_label: bool = False,
                     where: str = "the templates",
                     min_confidence: float | None = None) -> AnnotationSetup:
    """The :class:`AnnotationSetup` of loaded templates (class name →
    :class:`mtanno.templates.model.MotionTemplate`) and a class configuration, applied as
    ``mtanno annotate --classes`` applies it: checked against the templates' classes, its
    δ unless ``delta`` is given (else :data:`ANNOTATION_DELTA`), its further templates, and
    :meth:`ClassConfig.template_warnings` in ``warnings``, its tuned confidence
    (its verification bank read and checked). ``tau`` replaces its default τ
    (on a copy: the object passed is not changed); ``min_confidence`` its minimum
    confidence of an output row (a number in [0, 1])."""
    from dataclasses import replace

    from mtanno.confidence.model import check_min_confidence

    config = replace(config) if config is not None else ClassConfig()
    if tau is not None:
        config.default_tau = check_tau(tau)
    if delta is None:
        delta = config.delta if config.delta is not None else ANNOTATION_DELTA
    models, layout = class_models(templates, delta=delta, where=where)
    config.check([m.name for m in models])
    warnings = config.template_warnings(models)
    models += load_config_templates(config, layout, delta=delta)
    if min_confidence is not None:
        min_confidence = check_min_confidence(min_confidence, what="min_confidence")
    return AnnotationSetup(models, layout, config, delta, dbar_variant, match_variant,
                           single_label=single_label, config_sha256=config_sha256,
                           warnings=warnings, confidence=_loaded(config.confidence),
                           min_confidence=min_confidence)


def _loaded(confidence):
    """The configuration's tuned confidence with its bank read (so that a missing or
    changed bank file is refused before any document is annotated)."""
    if confidence is not None:
        _ = confidence.bank
    return confidence


def load_annotation_setup(mt_dir: str | os.PathLike, *,
                          config_path: str | os.PathLike | None = None,
                          keyframes_dir: str | os.PathLike | None = None,
                          tau: float | None = None, delta: float | None = None,
                          dbar_variant: str = "reference", match_variant: str = "reference",
                          single_label: bool = False,
                          min_confidence: float | None = None) -> AnnotationSetup:
    """Read what ``mtanno annotate`` annotates with: the templates of ``mt_dir``, the
    class configuration (``config_path``; :func:`annotation_setup`), the keyframe queries
    of ``keyframes_dir`` for those classes. ``tau`` replaces the configuration's default
    τ; ``delta`` defaults to the configuration's ``[decoder] delta``, else
    :data:`ANNOTATION_DELTA`; ``min_confidence`` replaces the tuned minimum confidence."""
    from mtanno.templates.model import load_template_folder
    from mtanno.util.tables import sha256_file

    setup = annotation_setup(
        load_template_folder(mt_dir),
        config=load_class_config(config_path) if config_path else None,
        config_sha256=sha256_file(config_file(config_path)) if config_path else None, tau=tau,
        delta=delta, dbar_variant=dbar_variant, match_variant=match_variant,
        single_label=single_label, where=f"the templates in {mt_dir}",
        min_confidence=min_confidence)
    if keyframes_dir:
        from mtanno.keyframes import load_class_keyframes

        (setup.keyframes, setup.keyframe_files, setup.keyframes_missing,
         setup.keyframes_extra) = load_class_keyframes(keyframes_dir, setup.classes,
                                                       feature_set=setup.layout.feature_set,
                                                       fps=setup.layout.fps)
    return setup
