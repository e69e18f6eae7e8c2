"""Bounds on the numbers a motion file declares (issue 22).

A reader refuses a value outside these bounds, naming the file and the line, instead of
allocating what an absurd header asks for or computing from values whose squares overflow
(numpy would warn and the features would be computed from ``inf``). The bounds are far
beyond any real capture (the CMU, HDM05 and Bandai files stay below 1 000 cm, 3 000° and
120 frames/s) and far below what the arithmetic of the features can take: positions up to
``MAX_LENGTH`` times the depth of the rig square and multiply without overflow.
"""

from __future__ import annotations

import numpy as np

#: Largest magnitude of an offset, a bone length or a translation value, in the rig's length
#: unit (cm for ASF/AMC, the file's unit for BVH): 100 km in centimetres.
MAX_LENGTH = 1e7

#: Largest magnitude of a rotation value, in degrees (real files unwrap the root's turn to a
#: few thousand degrees).
MAX_ANGLE_DEG = 1e6
MAX_ANGLE_RAD = MAX_ANGLE_DEG * np.pi / 180.0

#: Frame rates a file may declare: a frame every 0.1 ms up to one every 10 s.
MIN_FPS = 0.1
MAX_FPS = 10_000.0

#: Largest AMC frame number (the frame numbers of mtanno's tables are below 2³¹ too).
MAX_FRAME_NUMBER = 2**31 - 1

#: Largest ``:units length`` divisor of an ASF file and its inverse (a file unit from
#: 1/1 000 000 inch to 1 000 000 inches).
MAX_LENGTH_UNIT = 1e6


def fps_in_range(fps: float) -> bool:
    """True for a frame rate a motion file may declare (:data:`MIN_FPS` … :data:`MAX_FPS`)."""
    return MIN_FPS <= fps <= MAX_FPS


def first_beyond(values: np.ndarray, limit: float) -> int | None:
    """Flat index of the first value of ``values`` whose magnitude exceeds ``limit`` (or
    that is NaN), None when all are within: one vectorised pass, the index searched only
    when there is one."""
    if values.size == 0:
        return None
    worst = np.max(np.abs(values))
    if worst <= limit:
        return None
    flat = np.abs(values).ravel()
    return int(np.flatnonzero(~(flat <= limit))[0])
