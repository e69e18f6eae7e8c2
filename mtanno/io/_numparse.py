"""Numba kernel that reads motion data (AMC frames, BVH MOTION rows) straight from bytes.

A frame is described by a small *token program*: frame number, bone name, or value (with
the place it goes). One loop walks the bytes and the program together, so the per-number
work is a few integer operations (a separate number parser, even inlined by numba, made
the kernel 1.65× slower, so the number parsing lives in the loop).

A number is parsed as an integer mantissa and a power of ten. When the mantissa is at most
2^53 and the power is within ±22, ``m·10^e`` or ``m/10^−e`` of two exactly representable
doubles is the correctly rounded value (Clinger's fast path), so the result is
bit-identical to ``float(text)``. Anything else is reported back (status INEXACT) so the
caller can use an exact parser; anything irregular (status BAD) sends the caller to a
line-by-line parser that names the problem.
"""

from __future__ import annotations

import numba
import numpy as np

# status codes
OK = 0
BAD = 1       # irregular input
INEXACT = 2   # a number outside the exact fast path: use an exact parser

# token program codes
FRAME_NO = 0  # the frame number (first_no + frame)
NAME = 1      # a bone name: arg = index into name_off
VALUE = 2     # a number: arg = value column (dst_* arrays)

# value destinations
TO_ANGLES = 0  # angles[f, node, slot] = v * scale
TO_TRANS = 1   # trans[f, node, slot] = add + v * scale
SKIP = 2

POW10 = np.array([10.0 ** k for k in range(23)])
_EXACT = 2**53


@numba.njit(cache=True)
def parse_frames(buf, prog_kind, prog_arg, first_no, names, name_off, dst_kind, dst_node,
                 dst_slot, dst_scale, dst_add, angles, trans, pow10, rows):
    """Read frames of tokens laid out by the program into ``angles`` / ``trans``.

    With ``rows`` every frame must be exactly one line (BVH). Returns ``(frames read,
    status, byte position of the problem)``; reading stops with BAD when a frame would
    exceed ``angles.shape[0]``.
    """
    # one kernel: the token loop and its dispatch stay in one function, so that the
    # parser's state stays in registers instead of passing through a call per token
    n = buf.shape[0]
    plen = prog_kind.shape[0]
    pos = 0
    frame = 0
    while True:
        for step in range(plen):
            # skip white space
            newline = False
            while pos < n:
                c = buf[pos]
                if c == 32 or c == 13 or c == 9 or c == 11 or c == 12:
                    pos += 1
                elif c == 10:
                    newline = True
                    pos += 1
                else:
                    break
            if rows and pos < n and newline != (step == 0 and frame > 0):
                return frame, BAD, pos
            if pos >= n:
                if step == 0:
                    return frame, OK, pos
                return frame, BAD, pos
            if step == 0 and frame >= angles.shape[0]:
                return frame, BAD, pos
            kind = prog_kind[step]
            start = pos
            if kind == NAME:
                b = prog_arg[step]
                a0 = name_off[b]
                a1 = name_off[b + 1]
                if pos + (a1 - a0) > n:
                    return frame, BAD, start
                for k in range(a1 - a0):
                    if buf[pos + k] != names[a0 + k]:
                        return frame, BAD, start
                pos += a1 - a0
            elif kind == FRAME_NO:
                no = 0
                # numba twin of the exponent's digit loop below (the same capped integer):
                # an inlined helper for the two made the kernel 3 % slower (see the mantissa)
                while pos < n:
                    d = np.int64(buf[pos]) - 48
                    if d < 0 or d > 9:
                        break
                    if no < 10**12:
                        no = no * 10 + d
                    pos += 1
                if pos == start or no != first_no + frame:
                    return frame, BAD, start
            else:
                neg = False
                c = buf[pos]
                if c == 45 or c == 43:
                    neg = c == 45
                    pos += 1
                mant = 0
                exp10 = 0
                nd = 0
                d0 = pos
                # numba twin of the fraction's digit loop below (and of the frame number's
                # and the exponent's): each digit loop stays written out in the token loop.
                # Measured on the 10 MB of cmu_02's AMC files (numba 0.68), 20.1 ms written
                # out; one inlined helper for mantissa and fraction: 33.3 ms (1.65×); one for
                # frame number and exponent: 20.7 ms (3 % slower)
                while pos < n:
                    d = np.int64(buf[pos]) - 48
                    if d < 0 or d > 9:
                        break
                    if nd < 18:
                        mant = mant * 10 + d
                        if mant:
                            nd += 1
                    else:
                        exp10 += 1
                    pos += 1
                digits = pos - d0
                if pos < n and buf[pos] == 46:
                    pos += 1
                    d1 = pos
                    # numba twin of the mantissa's digit loop above: written out in the
                    # token loop for speed (the figures are there)
                    while pos < n:
                        d = np.int64(buf[pos]) - 48
                        if d < 0 or d > 9:
                            break
                        if nd < 18:
                            mant = mant * 10 + d
                            exp10 -= 1
                            if mant:
                                nd += 1
                        pos += 1
                    digits += pos - d1
                if digits == 0:
                    return frame, BAD, start
                if pos < n and (buf[pos] == 101 or buf[pos] == 69):
                    pos += 1
                    eneg = False
                    if pos < n and (buf[pos] == 45 or buf[pos] == 43):
                        eneg = buf[pos] == 45
                        pos += 1
                    e = 0
                    e0 = pos
                    # numba twin of the frame number's digit loop above (the same capped
                    # integer): written out for speed (the figures are at the mantissa)
                    while pos < n:
                        d = np.int64(buf[pos]) - 48
                        if d < 0 or d > 9:
                            break
                        if e < 100000:
                            e = e * 10 + d
                        pos += 1
                    if pos == e0:
                        return frame, BAD, start
                    exp10 += -e if eneg else e
                if nd >= 18 or mant > _EXACT or exp10 > 22 or exp10 < -22:
                    return frame, INEXACT, start
                v = float(mant)
                if exp10 >= 0:
                    v = v * pow10[exp10]
                else:
                    v = v / pow10[-exp10]
                if neg:
                    v = -v
                col = prog_arg[step]
                dk = dst_kind[col]
                if dk == TO_ANGLES:
                    angles[frame, dst_node[col], dst_slot[col]] = v * dst_scale[col]
                elif dk == TO_TRANS:
                    trans[frame, dst_node[col], dst_slot[col]] = dst_add[col] + v * dst_scale[col]
            # a token must end at white space
            if pos < n:
                c = buf[pos]
                if not (c == 32 or c == 10 or c == 13 or c == 9 or c == 11 or c == 12):
                    return frame, BAD, start
        frame += 1
