"""Labelled intervals of documents: the input format a user gives (truth tables of ground
truth or reviewed annotations) and the one interval type, kept below every stage that
reads them (learning from annotated documents, annotation, tuning, evaluation).

* :mod:`~mtanno.labels.segments` — :class:`Segment` (1-based, what files hold),
  :class:`Annotation` (0-based, with cost and confidence, what the code makes) and the one
  conversion between them;
* :mod:`~mtanno.labels.truth` — truth tables read and written (rate conversion to 30 Hz,
  frames checked against documents), the CMU mocap6 converter.
"""

from mtanno.util.lazy import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "segments": ("Annotation", "Segment", "by_document", "to_segments"),
    "truth": ("MAX_FRAME", "check_within", "read_truth", "to_analysis_frame",
              "truth_from_mocap6", "truth_table", "write_truth"),
})


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
