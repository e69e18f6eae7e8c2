"""mtanno: find, retrieve and annotate human motions in motion-capture archives.

The package reads the pipeline left to right: :mod:`mtanno.io` (mocap files to joint
positions), :mod:`mtanno.features` (40 boolean relational features at 30 Hz),
:mod:`mtanno.store` (Parquet feature files), :mod:`mtanno.templates`, :mod:`mtanno.index`,
:mod:`mtanno.keyframes`, :mod:`mtanno.annotate`, :mod:`mtanno.evaluation.metrics`. The command
line (:mod:`mtanno.cli`) is a thin layer over these functions.

The short way in (:mod:`mtanno.api`, loaded on first use so that ``import mtanno`` stays
light): :func:`read_motion`, :func:`compute_features`, :func:`learn_templates`,
:func:`load_templates`, :func:`annotate_documents`, :func:`evaluate_annotation`::

    import mtanno
    X = mtanno.compute_features(mtanno.read_motion("HDM_bd_squat1Reps_001_120.amc"))
    mts = mtanno.learn_templates(manifest="clips.csv", features_dir="feats/", split="train")
    result = mtanno.annotate_documents("docfeats/", mts)
    print(mtanno.evaluate_annotation(result, truth="docs/truth.csv").table())
"""

from mtanno.errors import MtannoError

__version__ = "0.1.0"

_API = ("annotate_documents", "compute_features", "evaluate_annotation", "learn_templates",
        "load_templates", "read_motion")

__all__ = ["MtannoError", "__version__", *_API]


def __getattr__(name: str):
    if name in _API:
        from mtanno import api

        return getattr(api, name)
    raise AttributeError(f"module 'mtanno' has no attribute {name!r}")
