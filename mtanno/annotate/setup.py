"""What shapes an annotation besides its documents, loaded once for a batch: the class
models of a template folder and of a class configuration (quantized templates with their
files), the configuration, the keyframe queries and the tuned confidence
(:class:`AnnotationSetup`, :func:`load_annotation_setup`); :meth:`AnnotationSetup.annotate`
runs :func:`mtanno.annotate.batch.annotate_files` with it.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from mtanno.annotate.batch import AnnotationBatch, _iter_annotate, annotate_files
from mtanno.annotate.config import ClassConfig, config_file, load_class_config
from mtanno.annotate.label import ClassModel
from mtanno.annotate.options import AnnotateOptions
from mtanno.errors import MtannoError
from mtanno.templates.params import ANNOTATION_DELTA, check_tau

if TYPE_CHECKING:
    from mtanno.features.store import FeatureLayout

__all__ = ["AnnotationSetup", "annotation_setup", "class_models", "load_annotation_setup",
           "load_class_models", "load_config_templates"]


def load_class_models(mt_dir: str | os.PathLike, *, delta: float = ANNOTATION_DELTA,
                      classes: Sequence[str] = ()) -> tuple[list[ClassModel], FeatureLayout]:
    """The templates of a folder (``*.json``; or one template file;
    :func:`mtanno.templates.store.load_template_folder`), quantized with ``delta``, as
    :class:`ClassModel` records (with their file and SHA-256), and the feature layout
    (set, names, rate) they all share. ``classes`` keeps only those."""
    from mtanno.templates.store import load_template_folder

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
    from mtanno.util.provenance import sha256_file

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
    from mtanno.templates.model import quantize
    from mtanno.templates.store import load_template
    from mtanno.util.provenance import sha256_file

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
        from mtanno.util.provenance import provenance

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
        """:func:`annotate_files` of ``paths`` with this setup (in ``n_jobs`` processes or
        on ``scheduler``)."""
        return annotate_files(paths, self.models, layout=self.layout, config=self.config,
                              keyframes=self.keyframes or None, confidence=self.confidence,
                              options=self.options(n_jobs=n_jobs, scheduler=scheduler),
                              progress=progress)

    def options(self, *, n_jobs: int = 1, scheduler: str | None = None) -> AnnotateOptions:
        """The :class:`AnnotateOptions` of each document's annotation with this setup (its
        variants, single label and minimum confidence), run in ``n_jobs`` processes or
        on ``scheduler``."""
        return AnnotateOptions(dbar_variant=self.dbar_variant,
                               match_variant=self.match_variant,
                               single_label=self.single_label,
                               min_confidence=self.min_confidence, n_jobs=n_jobs,
                               scheduler=scheduler)

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


def load_annotation_setup(mt_dir: str | os.PathLike,
                          options: AnnotateOptions | None = None) -> AnnotationSetup:
    """Read what ``mtanno annotate`` annotates with, as ``options`` say
    (:class:`AnnotateOptions`): the templates of ``mt_dir``, the class configuration
    (``config_path``; :func:`annotation_setup`), the keyframe queries of
    ``keyframes_dir`` for those classes. ``tau`` replaces the configuration's default τ;
    ``delta`` defaults to the configuration's ``[decoder] delta``, else
    :data:`ANNOTATION_DELTA`; ``min_confidence`` replaces the tuned minimum confidence;
    the variants and ``single_label`` are recorded in the setup (``n_jobs`` and
    ``scheduler`` are :meth:`AnnotationSetup.annotate`'s)."""
    from mtanno.templates.store import load_template_folder
    from mtanno.util.provenance import sha256_file

    o = options or AnnotateOptions()
    config_path, keyframes_dir = o.config_path, o.keyframes_dir
    setup = annotation_setup(
        load_template_folder(mt_dir),
        config=load_class_config(config_path) if config_path else None,
        config_sha256=sha256_file(config_file(config_path)) if config_path else None,
        tau=o.tau, delta=o.delta, dbar_variant=o.dbar_variant,
        match_variant=o.match_variant, single_label=o.single_label,
        where=f"the templates in {mt_dir}", min_confidence=o.min_confidence)
    if keyframes_dir:
        from mtanno.keyframes import load_class_keyframes

        (setup.keyframes, setup.keyframe_files, setup.keyframes_missing,
         setup.keyframes_extra) = load_class_keyframes(keyframes_dir, setup.classes,
                                                       feature_set=setup.layout.feature_set,
                                                       fps=setup.layout.fps)
    return setup
