"""Tuning the annotation (issue 10): ``mtanno tune`` learns the parameters of
``annotate --classes`` by cross-validation inside the training data.

* :mod:`~mtanno.tuning.cv` — folds (one performer held out), held-out documents built
  from the held-out examples only, the examples a template is learned from (at most N).
* :mod:`~mtanno.tuning.cluster` — several templates per class: groups of similar examples.
* :mod:`~mtanno.tuning.score` — the evaluation counts of [MBS09] §7 on frame arrays.
* :mod:`~mtanno.tuning.folddata` — learning and matching per fold and class, the fold
  data the search keeps (issue 34: the runs with a class left out read it, no copies).
* :mod:`~mtanno.tuning.search` — the objective and the coordinate search.
* :mod:`~mtanno.tuning.confidence` — the confidence of the segments (issue 26): evidence
  of the held-out segments, calibration, the minimum confidence of an output row.
* :mod:`~mtanno.tuning.run` — :func:`tune` (the whole run, as :class:`TuneOptions` say),
  :func:`tune_files` (the run as the command does it, from file names to files).
* :mod:`~mtanno.tuning.write` — :func:`write_tuned`: the configuration, its extra templates
  and its verification bank, as a configuration folder (``tune -o DIR/``, issue 34) or a
  ``.toml`` file with its side files.

The methods it tunes are applied by :func:`mtanno.annotate.label_document` and
:mod:`mtanno.annotate.decode`.
"""

__all__ = ["METHODS", "UNKNOWN_WEIGHT", "Params", "TuneOptions", "TuneResult",
           "template_folder_of", "tune", "tune_files", "write_tuned"]

from mtanno.tuning.run import TuneOptions, TuneResult, tune, tune_files
from mtanno.tuning.search import METHODS, UNKNOWN_WEIGHT, Params
from mtanno.tuning.write import template_folder_of, write_tuned
from mtanno.util.lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)  # the modules not imported above, on first use
