"""How ``mtanno annotate`` annotates, as one value: :class:`AnnotateOptions`, the options
that :func:`mtanno.annotate.annotate_to`, :func:`mtanno.annotate.load_annotation_setup`
and :func:`mtanno.annotate.annotate_files` share (docs/architecture.md, "Options").
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from mtanno.errors import MtannoError

__all__ = ["AnnotateOptions", "MATCH_VARIANTS", "SETUP_OPTIONS"]

#: The options :func:`~mtanno.annotate.load_annotation_setup` reads (the others shape each
#: document's annotation, or where it runs).
SETUP_OPTIONS = ("config_path", "keyframes_dir", "tau", "delta")

#: The Δ̄ and matching cost variants ([MBS09] §4 as written, or the reference
#: implementation's; docs/annotation.md).
MATCH_VARIANTS = ("reference", "paper")


@dataclass(frozen=True)
class AnnotateOptions:
    """How documents are annotated (``mtanno annotate``'s options; the defaults are the
    command's).

    What :func:`~mtanno.annotate.load_annotation_setup` reads: ``config_path``, the class
    configuration (a TOML file or a configuration folder that ``mtanno tune`` writes);
    ``keyframes_dir``, a folder of keyframe queries (a class with one is matched only
    inside its candidate windows, [MBS09] §5); ``tau`` replaces the configuration's
    default τ; ``delta`` the quantization δ (None: the configuration's ``[decoder]
    delta``, else :data:`mtanno.templates.params.ANNOTATION_DELTA`).

    How each document is annotated: ``dbar_variant`` and ``match_variant``, the Δ̄ and
    matching cost variants (:data:`MATCH_VARIANTS`); ``single_label``, one label per frame
    (:func:`mtanno.annotate.single_label_segments`); ``min_confidence``, rows below it
    are dropped (a number in [0, 1]; None: the tuned minimum, 0 without one).

    Where: ``n_jobs`` worker processes, or ``scheduler``, a dask.distributed address
    (``local:N``) — the result does not depend on them."""

    config_path: str | os.PathLike | None = None
    keyframes_dir: str | os.PathLike | None = None
    tau: float | None = None
    delta: float | None = None
    dbar_variant: str = "reference"
    match_variant: str = "reference"
    single_label: bool = False
    min_confidence: float | None = None
    n_jobs: int = 1
    scheduler: str | None = None

    def __post_init__(self):
        from mtanno.confidence.model import check_min_confidence
        from mtanno.templates.params import check_tau

        for name in ("dbar_variant", "match_variant"):
            v = getattr(self, name)
            if v not in MATCH_VARIANTS:
                raise MtannoError(f"unknown {{{name}}} {v!r} (choose from "
                                  f"{', '.join(MATCH_VARIANTS)})", options=(name,))
        if self.tau is not None:
            check_tau(self.tau)
        if self.min_confidence is not None:
            check_min_confidence(self.min_confidence, what="min_confidence")
        if not isinstance(self.n_jobs, int) or isinstance(self.n_jobs, bool) \
                or self.n_jobs < 1:
            raise MtannoError(f"{{n_jobs}} must be a positive integer, got {self.n_jobs!r}",
                              options=("n_jobs",))
