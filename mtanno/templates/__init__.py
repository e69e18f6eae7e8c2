"""Motion templates (MTs): learning, storage, quantization and mirroring (docs/method.md §3).

* :mod:`~mtanno.templates.model` — :class:`MotionTemplate`, :func:`quantize`
  (docs/method.md §3.3) and :func:`mirror` ([MR06] §5.4).
* :mod:`~mtanno.templates.store` — its JSON file (:func:`save_template`,
  :func:`load_template`) and folders of template files.
* :mod:`~mtanno.templates.learn` — soft MT learning ([MR06] §4.1, exactly as the reference
  implementation, docs/method/features.md §A) and hard MTs (thesis §3.3):
  :func:`mtanno.templates.learn.learn` on matrices, :func:`learn_template` on training
  examples (the function ``learn`` is not re-exported here, so that
  ``mtanno.templates.learn`` stays the module).
* :mod:`~mtanno.templates.run` — the whole ``mtanno learn-mt`` run, from file names to
  files (:func:`learn_to_folder`, its options :class:`LearnOptions`).
* :mod:`~mtanno.templates.dtw` — the DTW alignment and warping used by learning.
* :mod:`~mtanno.templates.training` — gathering training examples from a folder tree, a
  manifest CSV or annotated documents.
* :mod:`~mtanno.templates.match` — matching a template over documents: the streaming
  masked subsequence DTW of docs/method.md §3.4 (:func:`match_template`,
  :class:`PreparedTemplate`).
* :mod:`~mtanno.templates.params` — the published τ and δ of retrieval and annotation,
  one name each, and :func:`~mtanno.templates.params.check_tau`, the one rule for τ.
* :mod:`~mtanno.templates.describe` — a template as text for a person (``mtanno mt show``).
* :mod:`~mtanno.templates.transform` — a template file in, a template file out (the runs
  of ``mt mirror``, ``mt scale``, ``mt quantize``).
* :mod:`~mtanno.templates.tempo` — time-scaled copies of a template (faster or slower
  performers; ``mtanno mt scale``, and several templates per class in ``tune``).

Typical use by a later stage::

    from mtanno.templates import load_template, quantize
    mt = quantize(load_template("mts/squat1Reps.json"), 0.05)
    mt.values   # (features × K) with 0, 1, 0.5 (wildcard)
    mt.weights  # (K,)
"""

__all__ = [
    "SCHEMA", "ExampleSource", "LearnOptions", "LearnResult", "LearnRun", "MotionTemplate",
    "TrainingExample",
    "group_by_class", "learn_template", "learn_to_folder", "load_examples", "load_template", "mirror",
    "quantize", "save_template", "sources_from_manifest", "sources_from_tree",
    "sources_from_truth",
]

from mtanno.templates.learn import LearnResult, learn_template
from mtanno.templates.model import SCHEMA, MotionTemplate, mirror, quantize
from mtanno.templates.run import LearnOptions, LearnRun, learn_to_folder
from mtanno.templates.store import load_template, save_template
from mtanno.templates.training import (
    ExampleSource,
    TrainingExample,
    group_by_class,
    load_examples,
    sources_from_manifest,
    sources_from_tree,
    sources_from_truth,
)
from mtanno.util.lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)  # the modules not imported above, on first use
