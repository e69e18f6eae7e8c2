"""Body units and velocity windows shared by the feature kernel (docs/method/features.md
§2–3).

The measures themselves are evaluated by the numba kernel in
:mod:`mtanno.features._kernels`; ``tests/naive_features.py`` holds readable numpy versions of
every measure that the tests hold the kernel to.
"""

from __future__ import annotations

import math
from fractions import Fraction
from functools import lru_cache

import numpy as np

from mtanno.io.rigs import CANONICAL_JOINTS

_J = {name: k for k, name in enumerate(CANONICAL_JOINTS)}


def body_units(J: np.ndarray) -> dict[str, float]:
    """Body measures from frame 1 (docs/method/features.md §2,
    docs/method/features31.md §2), in the positions' length unit.

    ``hl`` right humerus, ``hlL`` left humerus, ``sw`` shoulder width, ``hw`` hip width,
    ``cl`` chest–neck length, ``BL`` body length (sum of seven segments), ``femR``/``femL``
    right/left femur (hip–knee).
    """

    def d(a: str, b: str) -> float:
        v = J[0, _J[a]] - J[0, _J[b]]
        return float(np.sqrt(v @ v))

    return {
        "hl": d("relbow", "rshoulder"),
        "hlL": d("lshoulder", "lelbow"),
        "sw": d("rshoulder", "lshoulder"),
        "hw": d("rhip", "lhip"),
        "cl": d("chest", "neck"),
        "BL": (d("rankle", "rknee") + d("rknee", "rhip") + d("root", "belly")
               + d("belly", "chest") + d("chest", "neck") + d("neck", "head")
               + d("head", "headtop")),
        "femR": d("rknee", "rhip"),
        "femL": d("lknee", "lhip"),
    }


@lru_cache(maxsize=256)
def window_samples(window_ms: float, fps: float) -> int:
    """Moving-average length ``ceil(window_ms/1000 · fps)``, at least 1, in exact arithmetic.

    (In floats 0.1·120 = 12.000000000000002, whose ceiling would be 13.)
    """
    if window_ms <= 0:
        return 1
    exact = Fraction(window_ms) * Fraction(fps).limit_denominator(10**6) / 1000
    return max(1, math.ceil(exact))
