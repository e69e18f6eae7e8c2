"""The annotate stage: per-frame class labels of documents from motion templates ([MBS09]
§4–5, docs/method.md §7) and the tuned methods of issue 10 (``docs/annotation.md``).

Modules, in the order the data flows through them:

* :mod:`~mtanno.annotate.config` — class configurations (per-class τ, superclasses, the
  decoder's options; TOML);
* :mod:`~mtanno.annotate.dbar` — the modified distance Δ̄ of a class (docs/method.md §7
  step 2);
* :mod:`~mtanno.annotate.label` — one document's labels and segments (docs/method.md §7
  steps 3–4; :class:`ClassModel`, :func:`annotate_document`, :func:`label_document`);
* :mod:`~mtanno.annotate.decode` — the segment decoder of tuned annotation (issue 10);
* :mod:`~mtanno.annotate.tables` — annotation tables (0-based rows, 1-based files);
* :mod:`~mtanno.annotate.options` — how documents are annotated (:class:`AnnotateOptions`,
  the options of the run, the setup and the batch);
* :mod:`~mtanno.annotate.setup` — what shapes an annotation, loaded once for a batch
  (:class:`AnnotationSetup`, :func:`load_annotation_setup`, class models);
* :mod:`~mtanno.annotate.batch` — batches of feature files (:func:`annotate_files`);
* :mod:`~mtanno.annotate.folder` — resumable annotation into a folder (``--output-dir``);
* :mod:`~mtanno.annotate.run` — the whole ``mtanno annotate`` run, from file names to
  files (:func:`annotate_to`);
* the stage's numba kernels (private), one module per family of kernels that call each
  other: ``_dbar_kernels`` (the reference Δ̄), ``_label_kernels`` (labels and runs),
  ``_decode_kernels`` (the segment decoder and its frame evidence).

The confidence of every segment (its evidence, verification, calibration and the tuned
model a configuration holds) is :mod:`mtanno.confidence`.

The public names of these modules are importable from ``mtanno.annotate`` itself.
"""

__all__ = [
    "ANNOTATION_COLUMNS", "ANNOTATION_SUFFIXES", "AnnotateOptions", "AnnotateRun",
    "DECODER_KEYS", "Annotation", "AnnotationBatch", "AnnotationSetup", "ClassConfig",
    "ClassModel", "Windows",
    "annotate_document", "annotate_files", "annotate_to", "annotation_files",
    "annotation_setup", "annotation_table", "class_config_text", "class_deltas",
    "class_models", "evidence_covered", "label_document", "label_frames",
    "load_annotation_setup", "load_class_config", "load_class_models",
    "load_config_templates", "merge_annotation_tables", "merged_spans", "modified_delta",
    "read_annotation_table", "read_annotation_tables", "read_annotations",
    "segments_from_labels", "single_label_segments", "to_segments", "write_annotations",
    "write_class_config",
]

from mtanno.annotate.batch import AnnotationBatch, annotate_files
from mtanno.annotate.config import (
    DECODER_KEYS,
    ClassConfig,
    class_config_text,
    load_class_config,
    write_class_config,
)
from mtanno.annotate.dbar import modified_delta
from mtanno.annotate.label import (
    ClassModel,
    Windows,
    annotate_document,
    class_deltas,
    evidence_covered,
    label_document,
    label_frames,
    merged_spans,
    segments_from_labels,
    single_label_segments,
)
from mtanno.annotate.options import AnnotateOptions
from mtanno.annotate.run import AnnotateRun, annotate_to
from mtanno.annotate.setup import (
    AnnotationSetup,
    annotation_setup,
    class_models,
    load_annotation_setup,
    load_class_models,
    load_config_templates,
)
from mtanno.annotate.tables import (
    ANNOTATION_COLUMNS,
    ANNOTATION_SUFFIXES,
    annotation_files,
    annotation_table,
    merge_annotation_tables,
    read_annotation_table,
    read_annotation_tables,
    read_annotations,
    write_annotations,
)
from mtanno.labels.segments import Annotation, to_segments
from mtanno.util.lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)  # the modules not imported above, on first use
