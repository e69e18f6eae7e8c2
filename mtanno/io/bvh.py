"""BVH reader: hierarchy → :class:`~mtanno.io.skeleton.Rig`, motion → :class:`Channels`.

Spec: ``docs/method.md`` §1 (BVH: any rig, per-joint channel count and Euler order taken
from the ``CHANNELS`` line, ``Frame Time`` read, never assumed) and
``docs/method/features.md`` §0 (BVH rigs map to canonical joints through a skeleton map).
Conventions (the usual reading of BVH, and pybvh's; ``scripts/pybvh_peer.py`` checks the
two agree):

* Nodes are the ``ROOT``/``JOINT`` blocks in file order; every ``End Site`` becomes a node
  named ``<parent joint name>_End`` with its file offset and no channels.
* Positions are joint origins (``Rig.end_point = False``):
  ``P_j = P_parent + G_parent · t_j`` and ``G_j = G_parent · L_j``.
* ``L_j = R_c1(a1) · R_c2(a2) · R_c3(a3)`` with the rotation channels in the order the
  ``CHANNELS`` line lists them (``Zrotation Xrotation Yrotation`` → Z·X·Y); degrees in the
  file, radians in :class:`Channels`. Missing rotation channels are zero rotations.
* Position channels *replace* the offset: ``t_j = (Xposition, Yposition, Zposition)`` of the
  frame (a missing component keeps the offset's value). The Bandai Namco files declare
  6 channels on every joint and store the offset in the position channels of every joint
  below ``Hips``, which confirms this reading (adding them would double every bone).
* Lengths are in the file's unit (centimetres for the Bandai and CMU conversions); Y is up.

The MOTION block is parsed in one pass by the numba kernel of :mod:`mtanno.io._numparse`
(one row per line, values straight into the channel arrays); only when it finds something
irregular does a slower scan count the values on every line, to report the bad line, or
NumPy's C text parser convert numbers outside the kernel's exact range. Every problem with the file raises
:class:`~mtanno.errors.MtannoError` with the file and the 1-based line.
"""

from __future__ import annotations

import hashlib
import io
import os
import re
from dataclasses import dataclass, field
from decimal import Decimal, InvalidOperation

import numba
import numpy as np

from mtanno.errors import MtannoError, read_input
from mtanno.io import _limits, _numparse
from mtanno.io.skeleton import AXIS_CODES, Channels, Rig

__all__ = ["read_bvh", "frame_rate_from_frame_time"]

# Control bytes that never occur in a text file (tab, LF, VT, FF and CR are allowed).
_BINARY = re.compile(rb"[\x00-\x08\x0e-\x1f]")
_TEXT_BYTES = bytes(b for b in range(256) if not (b < 9 or 14 <= b < 32))
_MOTION = re.compile(rb"(?m)^[ \t]*MOTION[ \t\r]*$")
_FRAMES = re.compile(r"^\s*Frames:\s*(\S+)\s*$")
_FRAME_TIME = re.compile(r"^\s*Frame\s+Time:\s*(\S+)\s*$")
_NUMBER = re.compile(rb"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?", re.ASCII)


@dataclass
class _Node:
    name: str
    parent: int
    offset: tuple[float, float, float]
    line: int
    end_site: bool = False
    # (column kind, axis) per channel in file order; kind "pos" or "rot"
    channels: list[tuple[str, int]] = field(default_factory=list)


class _Tokens:
    """Whitespace tokens of the hierarchy with their 1-based line numbers."""

    def __init__(self, lines: list[str], path: str):
        self.path = path
        self.items: list[tuple[str, int]] = []
        for k, line in enumerate(lines, start=1):
            for tok in line.split():
                if len(tok) > 1 and ("{" in tok or "}" in tok):
                    # "{" / "}" glued to a word ("Hips{") are separate tokens
                    self.items.extend((part, k) for part in re.split(r"([{}])", tok) if part)
                else:
                    self.items.append((tok, k))
        self.pos = 0
        self.last_line = max(len(lines), 1)

    def peek(self) -> tuple[str, int] | None:
        return self.items[self.pos] if self.pos < len(self.items) else None

    def next(self, what: str) -> tuple[str, int]:
        if self.pos >= len(self.items):
            raise MtannoError(f"the hierarchy ends where {what} was expected", path=self.path,
                              line=self.last_line)
        item = self.items[self.pos]
        self.pos += 1
        return item

    def rest_of_line(self, line: int) -> list[str]:
        """Tokens remaining on ``line`` (consumed), stopping before a brace."""
        out = []
        while self.pos < len(self.items) and self.items[self.pos][1] == line \
                and self.items[self.pos][0] not in "{}":
            out.append(self.items[self.pos][0])
            self.pos += 1
        return out

    def number(self, what: str) -> float:
        tok, line = self.next(what)
        try:
            value = float(tok)
        except ValueError:
            raise MtannoError(f"expected {what}, found '{_clip(tok)}'", path=self.path,
                              line=line) from None
        if not np.isfinite(value):
            raise MtannoError(f"{what} is not a finite number ('{tok}')", path=self.path,
                              line=line)
        if abs(value) > _limits.MAX_LENGTH:  # its square would overflow further on
            raise MtannoError(f"{what} '{_clip(tok)}' is absurd (beyond "
                              f"±{_limits.MAX_LENGTH:g})", path=self.path, line=line)
        return value

    def expect(self, word: str) -> int:
        tok, line = self.next(f"'{word}'")
        if tok != word:
            raise MtannoError(f"expected '{word}', found '{_clip(tok)}'", path=self.path, line=line)
        return line


def _parse_channel(tok: str) -> tuple[str, int] | None:
    """``Xposition`` → ("pos", 0), ``Zrotation`` → ("rot", 2); None if not a channel."""
    low = tok.lower()
    if len(low) < 2 or low[0] not in AXIS_CODES:
        return None
    if low[1:] == "position":
        return "pos", AXIS_CODES[low[0]]
    if low[1:] == "rotation":
        return "rot", AXIS_CODES[low[0]]
    return None


def _parse_hierarchy(lines: list[str], path: str) -> list[_Node]:
    """Parse the HIERARCHY section (everything before the MOTION line) into nodes."""
    toks = _Tokens(lines, path)
    first = toks.peek()
    if first is None:
        raise MtannoError("no HIERARCHY section (the file is empty before MOTION)", path=path,
                          line=1)
    if first[0] != "HIERARCHY":
        raise MtannoError(f"not a BVH file: expected 'HIERARCHY', found '{first[0]}'",
                          path=path, line=first[1])
    toks.next("HIERARCHY")
    nodes: list[_Node] = []
    names: dict[str, int] = {}
    # Stack of (node index, line of its opening brace) for the open ROOT/JOINT blocks.
    stack: list[tuple[int, int]] = []

    def add(name: str, parent: int, line: int) -> int:
        if name in names:
            raise MtannoError(f"joint name '{name}' is used twice (first on line "
                              f"{nodes[names[name]].line})", path=path, line=line)
        names[name] = len(nodes)
        nodes.append(_Node(name=name, parent=parent, offset=(0.0, 0.0, 0.0), line=line))
        return len(nodes) - 1

    while True:
        item = toks.peek()
        if item is None:
            if stack:
                node = nodes[stack[-1][0]]
                raise MtannoError(f"unbalanced braces: the block of '{node.name}' (line "
                                  f"{node.line}) is never closed", path=path,
                                  line=toks.last_line)
            if not nodes:
                raise MtannoError("the hierarchy has no ROOT", path=path, line=toks.last_line)
            return nodes
        tok, line = toks.next("a keyword")
        if tok in ("ROOT", "JOINT"):
            if tok == "ROOT" and (stack or nodes):
                raise MtannoError("a second ROOT: only one skeleton per file is supported"
                                  if not stack else "ROOT inside another joint's block",
                                  path=path, line=line)
            if tok == "JOINT" and not stack:
                raise MtannoError("JOINT outside any ROOT block (unbalanced braces?)",
                                  path=path, line=line)
            name = " ".join(toks.rest_of_line(line))
            if not name:
                raise MtannoError(f"{tok} without a name", path=path, line=line)
            j = add(name, stack[-1][0] if stack else -1, line)
            stack.append((j, toks.expect("{")))
            _parse_joint_body(toks, nodes[j], path)
        elif tok == "End":
            site = toks.rest_of_line(line)
            if site != ["Site"]:
                raise MtannoError(f"expected 'End Site', found 'End {' '.join(site)}'",
                                  path=path, line=line)
            if not stack:
                raise MtannoError("End Site outside any joint block", path=path, line=line)
            parent = stack[-1][0]
            base = f"{nodes[parent].name}_End"
            name, k = base, 2
            while name in names:  # several end sites under one joint: _End, _End2, ...
                name, k = f"{base}{k}", k + 1
            e = add(name, parent, line)
            nodes[e].end_site = True
            toks.expect("{")
            tok2, line2 = toks.next("OFFSET")
            if tok2 != "OFFSET":
                raise MtannoError(f"expected OFFSET in End Site, found '{tok2}'", path=path,
                                  line=line2)
            nodes[e].offset = tuple(toks.number("an OFFSET value") for _ in range(3))
            toks.expect("}")
        elif tok == "}":
            if not stack:
                raise MtannoError("unbalanced braces: '}' without a matching '{'", path=path,
                                  line=line)
            stack.pop()
        else:
            raise MtannoError(f"unexpected '{_clip(tok)}' in the hierarchy", path=path, line=line)


def _parse_joint_body(toks: _Tokens, node: _Node, path: str) -> None:
    """Read the OFFSET and CHANNELS lines at the start of a ROOT/JOINT block."""
    seen_offset = False
    while True:
        item = toks.peek()
        if item is None or item[0] not in ("OFFSET", "CHANNELS"):
            break
        tok, line = toks.next("OFFSET or CHANNELS")
        if tok == "OFFSET":
            node.offset = tuple(toks.number("an OFFSET value") for _ in range(3))
            seen_offset = True
        else:
            count_tok, count_line = toks.next("the channel count")
            try:
                count = int(count_tok)
            except ValueError:
                raise MtannoError(f"CHANNELS count '{count_tok}' is not an integer",
                                  path=path, line=count_line) from None
            if not 0 <= count <= 6:
                raise MtannoError(f"CHANNELS count {count} is not between 0 and 6", path=path,
                                  line=count_line)
            names = toks.rest_of_line(line)
            if len(names) != count:
                raise MtannoError(f"CHANNELS declares {count} channels but lists "
                                  f"{len(names)}", path=path, line=line)
            chans = []
            for c in names:
                parsed = _parse_channel(c)
                if parsed is None:
                    raise MtannoError(f"unknown channel '{c}' (expected Xposition … "
                                      f"Zrotation)", path=path, line=line)
                if parsed in chans:
                    raise MtannoError(f"channel '{c}' listed twice", path=path, line=line)
                chans.append(parsed)
            node.channels = chans
    if not seen_offset:
        raise MtannoError(f"joint '{node.name}' has no OFFSET", path=path, line=node.line)


_HIERARCHY_CACHE: dict[bytes, list] = {}


def _cached_hierarchy(header: bytes, text: str, path: str) -> list:
    """_parse_hierarchy, remembered per header text: the clips of one dataset share a rig,
    so a batch parses it once. Errors are never cached (they name the file)."""
    nodes = _HIERARCHY_CACHE.get(header)
    if nodes is None:
        nodes = _parse_hierarchy(text.split("\n"), path)
        if len(_HIERARCHY_CACHE) > 64:
            _HIERARCHY_CACHE.clear()
        _HIERARCHY_CACHE[header] = nodes
    return nodes


def _tokens_per_line(buf):
    """Number of whitespace-separated tokens on every line of ``buf`` (uint8 array)."""
    counts = np.zeros(int(np.count_nonzero(buf == 10)) + 1, dtype=np.int64)
    _count_tokens(buf, counts)
    return counts


@numba.njit(cache=True)
def _count_tokens(buf, counts):
    line = 0
    in_tok = False
    for b in buf:
        if b == 10:
            line += 1
            in_tok = False
        elif b == 32 or b == 9 or b == 13 or b == 11 or b == 12:
            in_tok = False
        elif not in_tok:
            counts[line] += 1
            in_tok = True


def frame_rate_from_frame_time(text: str) -> float:
    """Frames per second from a ``Frame Time`` token (seconds per frame).

    ``1/Frame Time``, snapped to a clean rate R — a whole number of frames per second, or an
    NTSC rate N·1000/1001 (23.976…, 29.97…, 59.94…) — when the file's value is ``1/R``
    rounded to the digits printed (within half a unit of the last digit) and within 1e-4
    relative of it: ``0.0333333`` → 30.0, ``0.016667`` → 60.0, ``0.008333`` → 120.0,
    ``0.0333667`` → 30000/1001; ``0.0123`` stays 81.30… Raises ValueError for a value that
    is not a positive finite number.
    """
    ft = float(text)
    if not np.isfinite(ft) or ft <= 0:
        raise ValueError(text)
    try:
        exponent = Decimal(text).as_tuple().exponent
        half_ulp = 0.5 * 10.0 ** int(exponent)  # half a unit in the last printed digit
    except (InvalidOperation, TypeError, ValueError):
        half_ulp = 0.0
    tol = min(max(half_ulp * (1 + 1e-9), 1e-9 * ft), 1e-4 * ft)
    fps = 1.0 / ft
    for clean in (float(round(fps)), round(fps * 1.001) / 1.001):
        if clean > 0 and abs(1.0 / clean - ft) <= tol:
            return clean
    return fps


def _clip(text: str, n: int = 40) -> str:
    """``text`` stripped and cut to ``n`` characters for an error message."""
    text = text.strip()
    return text if len(text) <= n else text[: n - 1] + "…"


def _line_of(data: bytes, pos: int) -> int:
    return data.count(b"\n", 0, pos) + 1


def read_bvh(path: str | os.PathLike, *, sha256: bool = False) -> tuple[Rig, Channels]:
    """Read a BVH file into its rig and per-frame channels (docs/method.md §1).

    Parameters
    ----------
    path:
        The ``.bvh`` file (ASCII, UTF-8 or Latin-1; LF, CRLF or CR line ends).
    sha256:
        Also give the SHA-256 of the file's bytes as read (``channels.sha256``).

    Returns
    -------
    rig, channels:
        ``rig.kind == "bvh"``, joint-origin positions, identity ``pre``/``post``; lengths
        in the file's unit. ``channels.angles`` in radians (file: degrees) in the order
        of each joint's rotation channels, ``channels.trans`` the position channel values
        (the offset where a joint has no such channel), ``channels.fps`` = 1/``Frame Time``
        in frames per second (see :func:`frame_rate_from_frame_time`).

    Raises
    ------
    MtannoError
        ``path:line: message`` for any malformed input.
    """
    spath = str(path)
    data = read_input(path)
    digest = hashlib.sha256(data).hexdigest() if sha256 else None
    data = _checked_text(data, spath)
    m = _MOTION.search(data)
    header = data[: m.start()] if m is not None else data
    try:
        text = header.decode("utf-8")
    except UnicodeDecodeError:
        text = header.decode("latin-1")
    nodes = _cached_hierarchy(header, text, spath)
    if m is None:
        raise MtannoError("no MOTION section after the hierarchy", path=spath,
                          line=text.rstrip().count("\n") + 1)
    head = _motion_header(data, m, spath)
    layout = _ChannelLayout.of(nodes)
    block = data[head.pos:] if head.pos < len(data) else b""
    _check_frame_count(head, layout.n_channels, len(block), spath)
    angles, trans = _motion_values(block, layout, head, spath)
    _check_values(block, angles, trans, layout, head, spath)
    n_nodes = len(nodes)
    rig = Rig(
        kind="bvh",
        names=[n.name for n in nodes],
        parents=np.array([n.parent for n in nodes], dtype=np.int64),
        offsets=layout.offsets,
        axes=layout.axes,
        pre=np.tile(np.eye(3), (n_nodes, 1, 1)),
        post=np.tile(np.eye(3), (n_nodes, 1, 1)),
        end_point=False,
        source=spath,
        meta={
            "channels": {n.name: ["XYZ"[a] + ("position" if k == "pos" else "rotation")
                                  for k, a in n.channels] for n in nodes if n.channels},
            "end_sites": [n.name for n in nodes if n.end_site],
            "frame_time": float(head.frame_time),
            "n_channels": layout.n_channels,
        },
    )
    return rig, Channels(angles=angles, trans=trans, has_trans=layout.has_trans, fps=head.fps,
                         sha256=digest)


def _checked_text(data: bytes, spath: str) -> bytes:
    """The file's bytes without a UTF-8 BOM and DOS end mark, classic Mac line ends made
    LF; an error for an empty or binary file."""
    data = data.removeprefix(b"\xef\xbb\xbf").rstrip(b"\x1a")
    if not data.strip():
        raise MtannoError("the file is empty", path=spath, line=1)
    # fast test (bytes.translate deletes every text byte), regex only to locate the culprit
    bad = _BINARY.search(data) if data.translate(None, _TEXT_BYTES) else None
    if bad is not None:
        raise MtannoError(f"not a text file (byte 0x{bad.group()[0]:02x}): binary or "
                          f"corrupt", path=spath, line=_line_of(data, bad.start()))
    if b"\n" not in data and b"\r" in data:
        data = data.replace(b"\r", b"\n")
    return data


@dataclass(frozen=True)
class _MotionHeader:
    """The MOTION section's header: where its data starts (byte ``pos``), the frame count
    and rate, the Frame Time as written, and the lines of both fields."""

    pos: int
    n_frames: int
    frames_line: int
    fps: float
    frame_time: str
    frame_time_line: int


def _motion_header(data: bytes, m: re.Match, spath: str) -> _MotionHeader:
    """Parse the "Frames:" and "Frame Time:" lines after MOTION (``m`` its match)."""
    nl = data.find(b"\n", m.end())
    pos = len(data) if nl < 0 else nl + 1  # start of the line after MOTION
    line_no = _line_of(data, m.start())
    fields: list[tuple[str, int]] = []
    while len(fields) < 2:
        if pos >= len(data):
            raise MtannoError("the MOTION section ends before its 'Frames:' and "
                              "'Frame Time:' lines", path=spath, line=line_no)
        nl = data.find(b"\n", pos)
        nl = len(data) if nl < 0 else nl
        line_no += 1
        raw = data[pos:nl].decode("latin-1")
        pos = nl + 1
        if raw.strip():
            fields.append((raw, line_no))
    (frames_raw, frames_line), (ft_raw, ft_line) = fields
    count = _header_field(_FRAMES, frames_raw, "'Frames: <count>' after MOTION", spath,
                          frames_line)
    try:
        n_frames = int(count)
        if n_frames < 0:
            raise ValueError
    except ValueError:
        raise MtannoError(f"frame count '{count}' is not a whole number ≥ 0", path=spath,
                          line=frames_line) from None
    frame_time = _header_field(_FRAME_TIME, ft_raw, "'Frame Time: <seconds>' after Frames",
                               spath, ft_line)
    try:
        fps = frame_rate_from_frame_time(frame_time)
    except ValueError:
        raise MtannoError(f"Frame Time '{frame_time}' is not a positive number of seconds",
                          path=spath, line=ft_line) from None
    if not 1 / _limits.MAX_FPS <= float(frame_time) <= 1 / _limits.MIN_FPS:
        raise MtannoError(f"Frame Time '{_clip(frame_time)}' is outside "
                          f"{1 / _limits.MAX_FPS:g} … {1 / _limits.MIN_FPS:g} seconds",
                          path=spath, line=ft_line)
    return _MotionHeader(pos, n_frames, frames_line, fps, frame_time, ft_line)


def _header_field(pattern: re.Pattern, raw: str, expected: str, spath: str, line: int) -> str:
    """The value (group 1) of a MOTION header line ``raw``, refused unless ``pattern``
    matches it (``expected`` says what should stand there)."""
    m = pattern.match(raw)
    if m is None:
        raise MtannoError(f"expected {expected}, found '{_clip(raw)}'", path=spath, line=line)
    return m.group(1)


def _check_frame_count(head: _MotionHeader, n_channels: int, n_bytes: int, spath: str) -> None:
    """Refuse a ``Frames:`` count the MOTION data cannot hold before room is made for it:
    a row of ``n_channels`` values takes at least ``2 · n_channels`` bytes (a digit and a
    separator each; the last row may lack its line end)."""
    most = (n_bytes + 1) // (2 * n_channels) if n_channels else 0
    if head.n_frames > most:
        raise MtannoError(f"'Frames: {head.n_frames}' is more than the motion data can hold "
                          f"({n_bytes} bytes: at most {most} rows of {n_channels} values)",
                          path=spath, line=head.frames_line)


@dataclass(frozen=True)
class _ChannelLayout:
    """Where each channel of a frame row goes: rotation channel columns ``rot_col`` to
    (node, slot in the node's rotation order), position columns ``pos_col`` to (node,
    component); per node its offset, rotation axes (unused axes fill the remaining slots
    with zero angles) and whether it has position channels."""

    offsets: np.ndarray
    axes: np.ndarray
    has_trans: np.ndarray
    rot_col: list[int]
    rot_node: list[int]
    rot_slot: list[int]
    pos_col: list[int]
    pos_node: list[int]
    pos_comp: list[int]
    n_channels: int

    @classmethod
    def of(cls, nodes) -> _ChannelLayout:
        n_nodes = len(nodes)
        offsets = np.array([n.offset for n in nodes], dtype=np.float64).reshape(n_nodes, 3)
        axes = np.tile(np.arange(3, dtype=np.int64), (n_nodes, 1))
        has_trans = np.zeros(n_nodes, dtype=np.bool_)
        rot_col, rot_node, rot_slot, pos_col, pos_node, pos_comp = [], [], [], [], [], []
        col = 0
        for j, node in enumerate(nodes):
            rots = [a for kind, a in node.channels if kind == "rot"]
            axes[j] = rots + [a for a in range(3) if a not in rots]
            slot = 0
            for kind, a in node.channels:
                if kind == "rot":
                    rot_col.append(col)
                    rot_node.append(j)
                    rot_slot.append(slot)
                    slot += 1
                else:
                    pos_col.append(col)
                    pos_node.append(j)
                    pos_comp.append(a)
                    has_trans[j] = True
                col += 1
        return cls(offsets, axes, has_trans, rot_col, rot_node, rot_slot, pos_col, pos_node,
                   pos_comp, col)


def _motion_values(block: bytes, lay: _ChannelLayout, head: _MotionHeader, spath: str
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(angles in radians, translations) of every frame from the MOTION data ``block``.

    Fast path: a numba kernel, one row per line, bit-identical to float() (Clinger's exact
    fast path). Slow path: name the line with a wrong value count, a wrong frame count or a
    bad value; or convert numbers outside the kernel's exact range with NumPy's correctly
    rounded parser."""
    n_frames, n_channels = head.n_frames, lay.n_channels
    n_nodes = lay.offsets.shape[0]
    first_data_line = head.frame_time_line + 1
    angles = np.zeros((n_frames, n_nodes, 3), dtype=np.float64)
    trans = np.empty((n_frames, n_nodes, 3), dtype=np.float64)
    trans[:] = lay.offsets  # components without a channel keep the offset's value
    status, frames = _numparse.BAD, -1
    if n_frames and n_channels:
        dst_kind = np.full(n_channels, _numparse.TO_ANGLES, dtype=np.int64)
        dst_kind[lay.pos_col] = _numparse.TO_TRANS
        dst_node = np.zeros(n_channels, dtype=np.int64)
        dst_slot = np.zeros(n_channels, dtype=np.int64)
        dst_node[lay.rot_col], dst_slot[lay.rot_col] = lay.rot_node, lay.rot_slot
        dst_node[lay.pos_col], dst_slot[lay.pos_col] = lay.pos_node, lay.pos_comp
        dst_scale = np.full(n_channels, np.pi / 180.0)  # = np.deg2rad
        dst_scale[lay.pos_col] = 1.0
        frames, status, _ = _numparse.parse_frames(
            np.frombuffer(block, dtype=np.uint8), np.full(n_channels, _numparse.VALUE),
            np.arange(n_channels), 0, np.zeros(0, np.uint8), np.zeros(1, np.int64),
            dst_kind, dst_node, dst_slot, dst_scale, np.zeros(n_channels), angles, trans,
            _numparse.POW10, True)
    if status == _numparse.OK and frames == n_frames:
        return angles, trans
    counts = _tokens_per_line(np.frombuffer(block, dtype=np.uint8))
    rows = np.flatnonzero(counts)  # line index (within block) of every non-blank line
    wrong = np.flatnonzero(counts[rows] != n_channels)
    if wrong.size:
        k = rows[wrong[0]]
        got = int(counts[k])
        which = "few" if got < n_channels else "many"
        raise MtannoError(f"too {which} values: motion frame {wrong[0] + 1} has {got} but "
                          f"the hierarchy declares {n_channels} channels", path=spath,
                          line=first_data_line + int(k))
    if rows.size != n_frames:
        raise MtannoError(f"'Frames: {n_frames}' but the file has {rows.size} rows of "
                          f"motion data", path=spath, line=head.frames_line)
    if n_frames and n_channels:
        values = None
        if status == _numparse.INEXACT:
            try:
                values = np.loadtxt(io.BytesIO(block), dtype=np.float64, ndmin=2,
                                    comments=None, encoding="latin-1"
                                    ).reshape(n_frames, n_channels)
            except ValueError as exc:
                _locate_bad_value(block, rows, n_channels, first_data_line, spath, str(exc))
        if values is None or not np.isfinite(values).all():
            _locate_bad_value(block, rows, n_channels, first_data_line, spath, "")
        angles[:, lay.rot_node, lay.rot_slot] = np.deg2rad(values[:, lay.rot_col])
        trans[:, lay.pos_node, lay.pos_comp] = values[:, lay.pos_col]
    return angles, trans


def _check_values(block: bytes, angles: np.ndarray, trans: np.ndarray, lay: _ChannelLayout,
                  head: _MotionHeader, spath: str) -> None:
    """Refuse an absurd channel value (a rotation beyond ±10⁶°, a position beyond ±10⁷
    file units): finite, but the features would square it into ``inf``. One pass over the
    arrays; the line is looked for only when there is such a value (the first in the file
    is named)."""
    found = []
    for arr, limit, cols in ((angles, _limits.MAX_ANGLE_RAD,
                              zip(lay.rot_col, lay.rot_node, lay.rot_slot)),
                             (trans, _limits.MAX_LENGTH,
                              zip(lay.pos_col, lay.pos_node, lay.pos_comp))):
        where = {(n, s): c for c, n, s in cols}
        bad = np.abs(arr) > limit  # (only channels can be: offsets are bounded)
        if bad.any():
            frame = int(np.flatnonzero(bad.any(axis=(1, 2)))[0])
            found.extend((frame, where[int(n), int(s)]) for n, s in zip(*np.nonzero(bad[frame])))
    if not found:
        return
    frame, col = min(found)
    rows = np.flatnonzero(_tokens_per_line(np.frombuffer(block, dtype=np.uint8)))
    tok = block.split()[frame * lay.n_channels + col].decode("latin-1")
    what, bound = (("rotation", _limits.MAX_ANGLE_DEG) if col in lay.rot_col else
                   ("position", _limits.MAX_LENGTH))
    raise MtannoError(f"{what} value '{_clip(tok)}' (frame {frame + 1}, channel {col + 1}) "
                      f"is absurd (beyond ±{bound:g})", path=spath,
                      line=head.frame_time_line + 1 + int(rows[frame]))


def _locate_bad_value(block: bytes, rows: np.ndarray, n_channels: int, first_data_line: int,
                      path: str, detail: str) -> None:
    """Slow path: raise for the first token of the MOTION data that is not a finite number."""
    tokens = block.split()
    for k, tok in enumerate(tokens):
        if _NUMBER.fullmatch(tok) and np.isfinite(float(tok)):
            continue
        frame, channel = divmod(k, n_channels)
        raise MtannoError(f"value '{_clip(tok.decode('latin-1'))}' (frame {frame + 1}, channel "
                          f"{channel + 1}) is not a finite number", path=path,
                          line=first_data_line + int(rows[frame]))
    raise MtannoError(f"unreadable motion data: {detail}", path=path,  # pragma: no cover
                      line=first_data_line + int(rows[0]))
