"""Time-scaled templates: a class's template resampled to a faster or slower tempo, matched
as a further template of the class (issue 10, several templates per class).

The matching's DTW steps (1,1), (1,2), (2,1) let a match be at most twice as long or half
as long as the template, so a performance much faster or slower than the training examples
cannot match at all. A copy of the template with ``round(K·f)`` columns — column j is the
template's column ``floor((j + ½)·K / (K·f))``, i.e. the nearest one in time, with its
weight — covers performances about ``f`` times as long. Every column of the copy is a
column of the template, so its frame-wise evidence (:func:`mtanno.annotate.decode.frame_evidence`,
the best column anywhere in the template) is never lower than the template's own: taking
the minimum over the class's templates, the copy leaves the evidence unchanged.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from mtanno.errors import MtannoError
from mtanno.templates.model import MotionTemplate

__all__ = ["COPY_BUDGET", "TEMPO_SCALES", "matched_columns", "scale_columns", "time_scaled"]

#: Tempo factors tried for a class's time-scaled templates (template length × f).
TEMPO_SCALES = (0.6, 1.6)
#: The columns all time-scaled copies together may have, as a fraction of the columns of
#: the classes' templates: matching takes most of an annotation's time and grows with the
#: columns matched, and a tuned annotation should take at most about 1.2 times as long as
#: the untuned one.
COPY_BUDGET = 0.15


def scale_columns(n: int, factor: float) -> np.ndarray:
    """Indices of the columns of an ``n``-column template that its copy at ``factor`` times
    the length keeps (in order; at least 2 columns)."""
    if n < 1 or not (factor > 0 and np.isfinite(factor)):
        raise MtannoError(f"time scaling needs a template and a factor > 0, got {n} columns "
                          f"and factor {factor!r}")
    m = max(2, int(round(n * factor)))
    return np.minimum(n - 1, np.floor((np.arange(m) + 0.5) * n / m).astype(np.int64))


def matched_columns(weights: np.ndarray) -> int:
    """The columns a template of these column weights is matched with
    (:func:`mtanno.templates.match.column_repeats`): what its matching costs per document
    frame."""
    from mtanno.templates.match import column_repeats

    return int(column_repeats(weights).sum())


def time_scaled(mt: MotionTemplate, factor: float) -> MotionTemplate:
    """A copy of ``mt`` for performances ``factor`` times as long (module docstring); its
    ``params`` record the factor as ``time_scale``."""
    idx = scale_columns(mt.length, factor)
    return replace(mt, values=mt.values[:, idx].copy(), weights=mt.weights[idx].copy(),
                   training=[dict(t) for t in mt.training],
                   params={**mt.params, "time_scale": float(factor)},
                   history={k: list(v) for k, v in mt.history.items()}, path=None)
