"""mtanno: find, retrieve and annotate human motions in motion-capture archives.

The package reads the pipeline left to right: :mod:`mtanno.io` (mocap files to joint
positions), :mod:`mtanno.features` (40 boolean relational features at 30 Hz, stored as
Parquet feature files by :mod:`mtanno.features.store`), :mod:`mtanno.templates` (motion
templates), :mod:`mtanno.index` (relational index and queries), :mod:`mtanno.keyframes`,
:mod:`mtanno.annotate`, :mod:`mtanno.tuning` and :mod:`mtanno.evaluation`;
:mod:`mtanno.align` and :mod:`mtanno.retrieve` beside them, the plumbing in
:mod:`mtanno.util`. The command line (:mod:`mtanno.cli`, :mod:`mtanno.commands`) is a thin
layer over these functions.

The short way in (:mod:`mtanno.api`, loaded on first use so that ``import mtanno`` stays
light): :func:`read_motion`, :func:`compute_features`, :func:`learn_templates`,
:func:`load_templates`, :func:`annotate_documents`, :func:`evaluate_annotation`::

    import mtanno
    X = mtanno.compute_features(mtanno.read_motion("HDM_bd_squat1Reps_001_120.amc"))
    mts = mtanno.learn_templates(manifest="clips.csv", features_dir="feats/", split="train")
    result = mtanno.annotate_documents("docfeats/", mts)
    print(mtanno.evaluate_annotation(result, truth="docs/truth.csv").table())
"""

from mtanno._version import __version__
from mtanno.errors import MtannoError
from mtanno.util.lazy import submodule_getattr

_API = ("annotate_documents", "compute_features", "evaluate_annotation", "learn_templates",
        "load_templates", "read_motion")

__all__ = ["MtannoError", "__version__", *_API]


def _api(name: str):
    if name in _API:
        from mtanno import api

        return getattr(api, name)
    raise AttributeError(name)


# the facade's names, then the subpackages on first use (mtanno.annotate.load_class_config)
__getattr__ = submodule_getattr(__name__, _api)


def __dir__() -> list[str]:
    """The module's names with the facade's (loaded lazily, so not yet in the module's
    namespace): a notebook's completion offers ``mtanno.annotate_documents`` at once."""
    return sorted(set(globals()) | set(__all__))
