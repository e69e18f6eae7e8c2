"""Two-threshold (hysteresis) quantisation and reduction to the 30 Hz analysis rate.

Spec: ``docs/method/features.md`` §4 (the toolbox's ``features_combine_robust``) and
``docs/method/features.md`` §6, ``docs/method.md`` §1–2.
"""

from __future__ import annotations

from fractions import Fraction
from functools import lru_cache

import numba
import numpy as np

from mtanno.util.units import ANALYSIS_FPS  # (re-exported: the features' rate)


@numba.njit(cache=True)
def _hysteresis_kernel(on, off, out):
    """Rows are features, columns frames; streaming, one state bit per row."""
    n_rows, n = on.shape
    for r in range(n_rows):
        s = False
        prev_on = False
        prev_off = False
        for t in range(n):
            rise = on[r, t] and not prev_on
            fall = t >= 1 and prev_off and not off[r, t]
            s = (not fall) and (s or rise)
            out[r, t] = s
            prev_on = on[r, t]
            prev_off = off[r, t]


def hysteresis(on: np.ndarray, off: np.ndarray) -> np.ndarray:
    """Combine a strict test ``on`` and a lenient test ``off`` (docs/method/features.md §4).

    The state starts OFF; it switches on where ``on`` rises (``on`` true at frame 1 counts
    as a rise) and off where ``off`` falls; a rise and a fall in the same frame leave it off.
    For nested tests (``on ⇒ off``) this is ordinary hysteresis. Accepts (frames,) or
    (rows × frames) boolean arrays and returns uint8 of the same shape.
    """
    on = np.asarray(on, dtype=np.bool_)
    off = np.asarray(off, dtype=np.bool_)
    if on.shape != off.shape:
        raise ValueError("on and off must have the same shape")
    squeeze = on.ndim == 1
    on2 = np.ascontiguousarray(on.reshape(1, -1) if squeeze else on)
    off2 = np.ascontiguousarray(off.reshape(1, -1) if squeeze else off)
    out = np.empty(on2.shape, dtype=np.bool_)
    _hysteresis_kernel(on2, off2, out)
    out = out.view(np.uint8)
    return out[0] if squeeze else out


@lru_cache(maxsize=64)
def _rate_ratio(fps: float, target_fps: float) -> Fraction:
    """fps / target_fps as an exact fraction (each rate to within 1e-6, as written)."""
    return Fraction(fps).limit_denominator(10**6) / Fraction(target_fps).limit_denominator(10**6)


def analysis_frames(n_native: int, fps: float, target_fps: float = ANALYSIS_FPS) -> np.ndarray:
    """0-based native frame kept for each analysis frame (docs/method/features.md §6).

    Analysis frame k (time k/target_fps) takes the nearest native frame,
    ``floor(k·fps/target_fps + 1/2)``, computed exactly; at 120 Hz that keeps native frames
    1, 5, 9, … (1-based) and gives ceil(N/4) frames, as the reference implementation does.
    """
    if n_native <= 0:
        return np.zeros(0, dtype=np.int64)
    ratio = _rate_ratio(fps, target_fps)
    count = int((n_native - 1) / ratio) + 1  # k with k·ratio ≤ N − 1
    k = np.arange(count, dtype=np.int64)
    idx = (2 * k * ratio.numerator + ratio.denominator) // (2 * ratio.denominator)
    return np.minimum(idx, n_native - 1)
