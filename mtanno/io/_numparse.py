"""Numba kernels that read decimal numbers straight from file bytes.

A number is parsed as an integer mantissa and a power of ten. When the mantissa is at most
2^53 and the power is within ±22, ``m·10^e`` or ``m/10^−e`` of two exactly
representable doubles is the correctly rounded value (Clinger's fast path), so the result is
bit-identical to ``float(text)``. Anything else is reported back so the caller can use a
slower exact path.
"""

from __future__ import annotations

import numba
import numpy as np

# token status codes
OK = 0
BAD = 1       # not a number
INEXACT = 2   # a number outside the exact fast path: use the slow parser

_POW10 = np.array([10.0 ** k for k in range(23)])
_BIG = np.uint64(10**17)       # stop accumulating digits beyond this
_EXACT = np.uint64(2**53)      # mantissas up to this are exact doubles


@numba.njit(cache=True, inline="always")
def _is_space(c):
    return c == 32 or c == 9 or c == 10 or c == 13 or c == 11 or c == 12


@numba.njit(cache=True, inline="always")
def skip_space(buf, pos):
    n = buf.shape[0]
    while pos < n and _is_space(buf[pos]):
        pos += 1
    return pos


@numba.njit(cache=True, inline="always")
def parse_number(buf, pos, pow10):
    """Parse one number token at ``pos``: (value, position after it, status)."""
    n = buf.shape[0]
    neg = False
    if pos < n and (buf[pos] == 45 or buf[pos] == 43):  # - +
        neg = buf[pos] == 45
        pos += 1
    mant = np.uint64(0)
    exp10 = 0
    start = pos
    inexact = False
    while pos < n:
        d = np.uint64(buf[pos] - 48)
        if d > 9:
            break
        if mant < _BIG:
            mant = mant * np.uint64(10) + d
        else:
            exp10 += 1
            inexact |= d != 0
        pos += 1
    seen = pos > start
    if pos < n and buf[pos] == 46:  # .
        pos += 1
        start = pos
        while pos < n:
            d = np.uint64(buf[pos] - 48)
            if d > 9:
                break
            if mant < _BIG:
                mant = mant * np.uint64(10) + d
                exp10 -= 1
            else:
                inexact |= d != 0
            pos += 1
        seen = seen or pos > start
    if not seen:
        return 0.0, pos, BAD
    if pos < n and (buf[pos] == 101 or buf[pos] == 69):  # e E
        pos += 1
        eneg = False
        if pos < n and (buf[pos] == 45 or buf[pos] == 43):
            eneg = buf[pos] == 45
            pos += 1
        e = 0
        start = pos
        while pos < n and 48 <= buf[pos] <= 57:
            if e < 100000:
                e = e * 10 + (buf[pos] - 48)
            pos += 1
        if pos == start:
            return 0.0, pos, BAD
        exp10 += -e if eneg else e
    if pos < n and not _is_space(buf[pos]):
        return 0.0, pos, BAD
    if inexact or mant > _EXACT or exp10 > 22 or exp10 < -22:
        return 0.0, pos, INEXACT
    v = float(mant)
    if exp10 >= 0:
        v = v * pow10[exp10]
    else:
        v = v / pow10[-exp10]
    return (-v if neg else v), pos, OK


@numba.njit(cache=True)
def parse_amc_body(buf, first_no, names, name_off, counts, dst_kind, dst_node, dst_slot,
                   dst_scale, dst_add, angles, trans, pow10):
    """Read AMC frames laid out like the first one straight into ``angles`` and ``trans``.

    Each frame: its number (``first_no``, ``first_no + 1``, …), then per bone its name (bytes
    ``names[name_off[b]:name_off[b+1]]``) and ``counts[b]`` numbers. Value column i goes to
    ``angles[f, dst_node[i], dst_slot[i]] = v·dst_scale[i]`` (kind 0), to
    ``trans[f, dst_node[i], dst_slot[i]] = dst_add[i] + v·dst_scale[i]`` (kind 1), or nowhere
    (kind 2). Returns ``(frames read, status, byte position)``; status OK, BAD (irregular:
    the caller's line-by-line parser names the problem) or INEXACT (use an exact parser).
    """
    n = buf.shape[0]
    n_bones = counts.shape[0]
    pos = skip_space(buf, 0)
    frame = 0
    while pos < n:
        if frame >= angles.shape[0]:
            return frame, BAD, pos
        no = 0
        start = pos
        while pos < n and 48 <= buf[pos] <= 57:
            no = no * 10 + (buf[pos] - 48)
            pos += 1
        if pos == start or (pos < n and not _is_space(buf[pos])) or no != first_no + frame:
            return frame, BAD, start
        col = 0
        for b in range(n_bones):
            pos = skip_space(buf, pos)
            a0 = name_off[b]
            a1 = name_off[b + 1]
            if pos + (a1 - a0) > n:
                return frame, BAD, pos
            for k in range(a1 - a0):
                if buf[pos + k] != names[a0 + k]:
                    return frame, BAD, pos
            pos += a1 - a0
            if pos < n and not _is_space(buf[pos]):
                return frame, BAD, pos
            for _ in range(counts[b]):
                pos = skip_space(buf, pos)
                v, pos2, st = parse_number(buf, pos, pow10)
                if st != OK:
                    return frame, st, pos
                kind = dst_kind[col]
                if kind == 0:
                    angles[frame, dst_node[col], dst_slot[col]] = v * dst_scale[col]
                elif kind == 1:
                    trans[frame, dst_node[col], dst_slot[col]] = dst_add[col] + v * dst_scale[col]
                col += 1
                pos = pos2
        frame += 1
        pos = skip_space(buf, pos)
    return frame, OK, pos
