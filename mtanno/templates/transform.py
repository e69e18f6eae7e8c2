"""A template file in, a template file out: the runs of ``mtanno mt mirror``, ``mt scale``
and ``mt quantize`` (the output checked against the input first, written atomically).
The transformations themselves are :func:`mtanno.templates.model.mirror` ([MR06] §5.4),
:func:`mtanno.templates.tempo.time_scaled` and :func:`mtanno.templates.model.quantize`
([MR06] §5.2).
"""

from __future__ import annotations

import os

from mtanno.templates.model import MotionTemplate

__all__ = ["mirror_file", "quantize_file", "scale_file"]

PathLike = str | os.PathLike


def _load(template: PathLike, output: PathLike) -> MotionTemplate:
    from mtanno.templates.store import load_template
    from mtanno.util.preflight import check_outputs

    check_outputs([output], [template])
    return load_template(template)


def _save(output: PathLike, mt: MotionTemplate) -> MotionTemplate:
    from mtanno.templates.store import save_template

    save_template(output, mt)
    return mt


def mirror_file(template: PathLike, output: PathLike, *, name: str | None = None,
                ) -> MotionTemplate:
    """Write the template of file ``template`` with left and right swapped to ``output``
    (:func:`~mtanno.templates.model.mirror`; ``name``: the copy's class name) and return
    the copy."""
    from mtanno.templates.model import mirror

    return _save(output, mirror(_load(template, output), name=name))


def scale_file(template: PathLike, output: PathLike, *, factor: float,
               ) -> tuple[MotionTemplate, MotionTemplate]:
    """Write the copy of the template of file ``template`` time-scaled by ``factor``
    (:func:`~mtanno.templates.tempo.time_scaled`) to ``output``; return the template and
    its copy."""
    from mtanno.templates.tempo import time_scaled

    mt = _load(template, output)
    return mt, _save(output, time_scaled(mt, factor))


def quantize_file(template: PathLike, output: PathLike, *, delta: float) -> MotionTemplate:
    """Write the template of file ``template`` quantized with ``delta``
    (:func:`~mtanno.templates.model.quantize`) to ``output`` and return it."""
    from mtanno.templates.model import quantize

    return _save(output, quantize(_load(template, output), delta))
