"""Command modules of the ``mtanno`` command line, one per pipeline stage.

Each module defines its Click commands and lists them in ``COMMANDS``; :mod:`mtanno.cli`
adds every module found here to the ``mtanno`` group. Commands stay thin: they parse
options, call the stage's Python API and report.

Modules, in pipeline order: ``features`` (features, info), ``show`` (show), ``templates``
(learn-mt, mt …), ``keyframes`` (learn-keyframes, keyframes show), ``index`` (index …,
query), ``retrieve`` (retrieve), ``annotate`` (annotate), ``tune`` (tune), ``evaluation``
(evaluate, evaluate-retrieval, compose, truth, report), ``align`` (align), ``skeleton``
(skeleton guess: a BVH rig's generated skeleton map), ``markers`` (markers guess: a marker
set for a C3D file's labels); ``_common``
holds what they share (error reporting, common options, progress bars).
"""

__all__ = ["align", "annotate", "evaluation", "features", "index", "keyframes", "retrieve",
           "markers", "show", "skeleton", "templates", "tune"]
