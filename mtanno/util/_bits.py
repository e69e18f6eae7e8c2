"""Bit kernels shared by the stages' numba kernels (private): :func:`popcount64`.

One definition, imported by every kernel module that counts bits (templates.match,
annotate._decode_kernels, keyframes._kernels, align._kernels). numba's on-disk cache keys a
kernel on its *own* file only: measured with numba 0.6x, a kernel in ``a.py`` calling an
njit function of ``b.py`` keeps its cached machine code when only ``b.py`` changes. That
matters to a developer who edits this file (clear the ``__pycache__`` folders, or touch the
importers), never to an installation: pip writes every file anew, which invalidates every
cache entry. The function is a fixed bit trick, so the hazard is small.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["popcount64"]

_M1 = np.uint64(0x5555555555555555)
_M2 = np.uint64(0x3333333333333333)
_M4 = np.uint64(0x0F0F0F0F0F0F0F0F)
_H01 = np.uint64(0x0101010101010101)
_S1 = np.uint64(1)
_S2 = np.uint64(2)
_S4 = np.uint64(4)
_S56 = np.uint64(56)


@numba.njit(cache=True, inline="always")
def popcount64(x):
    """Number of set bits of a uint64, or of a non-negative int64 (SWAR bit trick; LLVM
    compiles it to one popcnt). The final multiply wraps around modulo 2**64 by design
    (numpy warns about it when the kernels run as plain Python with NUMBA_DISABLE_JIT=1; the
    result is still right)."""
    u = np.uint64(x)
    u = u - ((u >> _S1) & _M1)
    u = (u & _M2) + ((u >> _S2) & _M2)
    u = (u + (u >> _S4)) & _M4
    return np.int64((u * _H01) >> _S56)
