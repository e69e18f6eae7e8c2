"""AMC motion reader (Acclaim motion capture data).

Spec: ``docs/method.md`` §1, ``docs/method/features.md`` §1.1 and §1.3. Each frame is a
frame number followed by one line per bone: the bone name and its values in the order of
the bone's ASF ``dof`` line (the root's in the order of ``:root order``). The rate is
``:SAMPLES-PER-SECOND`` when the header has it, else 120 frames/s.

Parsing splits the whole file into tokens once and checks the layout of every frame against
the first one with array operations (the fast path); any irregularity sends the file through
a line-by-line parser whose only job is to name the first bad line.
"""

from __future__ import annotations

import hashlib
import os

import numpy as np

from mtanno.errors import MtannoError, read_text_input
from mtanno.io import _limits
from mtanno.io import _numparse as _np
from mtanno.io.asf import AsfSkeleton
from mtanno.io.skeleton import AXIS_CODES, Channels

DEFAULT_AMC_FPS = 120.0


def _dof_count(skel: AsfSkeleton, name: str) -> int | None:
    if name == "root":
        return len(skel.root_order)
    d = skel.dofs.get(name)
    return None if d is None else len(d)


def _is_int(tok: bytes) -> bool:
    return tok.isdigit()


def _header(raw: bytes, path: str) -> tuple[int, int, float]:
    """(byte offset of the body, number of header lines, frame rate)."""
    fps = DEFAULT_AMC_FPS
    pos = 0
    nlines = 0
    while pos < len(raw):
        end = raw.find(b"\n", pos)
        end = len(raw) if end < 0 else end + 1
        line = raw[pos:end].strip()
        if line and not (line.startswith(b"#") or line.startswith(b":")):
            break
        if line.upper().startswith(b":SAMPLES-PER-SECOND"):
            parts = line.split()
            try:
                fps = float(parts[1])
                if not (fps > 0 and np.isfinite(fps)):
                    raise ValueError
            except (IndexError, ValueError):
                raise MtannoError("bad :SAMPLES-PER-SECOND value", path=path,
                                  line=nlines + 1) from None
            if not _limits.fps_in_range(fps):
                raise MtannoError(f":SAMPLES-PER-SECOND {parts[1].decode('latin-1')[:20]} is "
                                  f"outside {_limits.MIN_FPS:g} … {_limits.MAX_FPS:g} frames "
                                  f"per second", path=path, line=nlines + 1)
        pos = end
        nlines += 1
    return pos, nlines, fps


def read_amc(path: str | os.PathLike, skel: AsfSkeleton, *, sha256: bool = False) -> Channels:
    """Read an AMC file against its ASF skeleton into :class:`Channels` (cm, radians);
    with ``sha256`` the channels carry the SHA-256 of the bytes parsed."""
    spath = str(path)
    raw = read_text_input(path)
    body_at, header_lines, fps = _header(raw, spath)
    fast = _fast_parse(raw[body_at:], skel, fps)
    if fast is None:
        layout, values = _slow_parse(raw.decode("latin-1").splitlines(), header_lines, skel,
                                     spath)
        ch = _to_channels(layout, values, skel, fps)
    else:
        ch, layout = fast
    _check_values(ch, skel, raw, header_lines, spath)
    given = {name for name, _ in layout}
    ch.absent = {b: header_lines + 1 for b, dof in skel.dofs.items()
                 if b not in given and any(d[0] == "r" for d in dof)}
    if sha256:
        ch.sha256 = hashlib.sha256(raw).hexdigest()
    return ch


def read_amc_values(path: str | os.PathLike, skel: AsfSkeleton,
                    ) -> tuple[list[str], list[tuple[str, int]], np.ndarray, float]:
    """The raw AMC content: (header lines, layout [(bone, value count)], values as written
    in the file (frames × values, file units and degrees), frame rate). For tools that
    rewrite AMC files (:mod:`mtanno.evaluation.compose`); checks the file like :func:`read_amc`."""
    spath = str(path)
    read_amc(path, skel)  # validates, with path:line errors
    raw = read_text_input(path)
    body_at, header_lines, fps = _header(raw, spath)
    lines = raw.decode("latin-1").splitlines()
    first = _first_layout(raw[body_at:], skel)
    result = None if first is None else _tokenised_parse(raw[body_at:], first[1])
    if result is None:
        result = _slow_parse(lines, header_lines, skel, spath)
    layout, values = result
    return lines[:header_lines], layout, values, fps


def write_amc(path: str | os.PathLike, header: list[str], layout: list[tuple[str, int]],
              values: np.ndarray) -> None:
    """Write AMC frames (numbered from 1) with the given header lines, atomically."""
    from mtanno.util.output import atomic_path

    names = [name for name, _ in layout]
    counts = [n for _, n in layout]
    with atomic_path(path) as tmp, open(tmp, "w", encoding="latin-1", newline="\n") as fh:
        for line in header:
            fh.write(line + "\n")
        for f, row in enumerate(values, 1):
            fh.write(f"{f}\n")
            col = 0
            for name, n in zip(names, counts):
                fh.write(name)
                for v in row[col:col + n]:
                    fh.write(f" {v:.9g}")
                fh.write("\n")
                col += n


def _first_layout(body: bytes, skel: AsfSkeleton):
    """(first frame number, [(bone, value count)]) from the first frame, or None."""
    head = body[:8192]
    tokens = head.split()
    if len(head) == len(body) or len(tokens) < 2:
        tokens = body.split()
    if not tokens or not _is_int(tokens[0]) or int(tokens[0]) > _limits.MAX_FRAME_NUMBER:
        return None  # (the slow parse names the problem)
    counts = _dof_counts(skel)
    layout: list[tuple[str, int]] = []
    i = 1
    n_tokens = len(tokens)
    while i < n_tokens and not tokens[i].isdigit():
        name = tokens[i]
        n = counts.get(name)
        if n is None:
            return None
        layout.append((name.decode("latin-1"), n))
        i += 1 + n
    if not layout or i > n_tokens:
        return None
    return int(tokens[0]), layout


def _dof_counts(skel: AsfSkeleton) -> dict[bytes, int]:
    """:func:`_dof_count` of every bone, by its name as bytes (cached on the skeleton)."""
    counts = skel.__dict__.get("_dof_counts")
    if counts is None:
        counts = {}
        for name in ["root", *skel.dofs]:
            n = _dof_count(skel, name)
            try:
                key = name.encode("latin-1")  # as the file's tokens are decoded
            except UnicodeEncodeError:  # no token of an AMC file can name it
                continue
            if n is not None:
                counts.setdefault(key, n)
        skel.__dict__["_dof_counts"] = counts
    return counts


def _destinations(layout, skel: AsfSkeleton):
    """Per value column: (kind 0 angle / 1 root translation / 2 ignored, node, slot,
    scale, add) — where :func:`_to_channels` and the parse kernel put each value.
    Cached on the skeleton per layout (a batch has one layout per ASF)."""
    key = tuple(layout)
    cache = skel.__dict__.setdefault("_dest_cache", {})
    if key not in cache:
        cache[key] = _destinations_uncached(layout, skel)
    return cache[key]


def _destinations_uncached(layout, skel: AsfSkeleton):
    rig = skel.rig
    kind, node, slot, scale, add = [], [], [], [], []
    for name, _ in layout:
        j = rig.index(name)
        dof = [t.lower() for t in skel.root_order] if name == "root" else skel.dofs[name]
        for d in dof:
            if d[0] == "r":
                kind.append(0)
                slot.append(list(rig.axes[j]).index(AXIS_CODES[d[1]]))
                scale.append(skel.angle_scale)
                add.append(0.0)
            elif d[0] == "t" and name == "root":
                kind.append(1)
                slot.append(AXIS_CODES[d[1]])
                scale.append(skel.length_scale)
                add.append(float(rig.offsets[0, AXIS_CODES[d[1]]]))
            else:
                kind.append(2)
                slot.append(0)
                scale.append(0.0)
                add.append(0.0)
            node.append(j)
    return (np.array(kind, dtype=np.int64), np.array(node, dtype=np.int64),
            np.array(slot, dtype=np.int64), np.array(scale), np.array(add))


def _empty_channels(n_frames: int, skel: AsfSkeleton, fps: float, *,
                    fill_offset: bool = True) -> Channels:
    rig = skel.rig
    trans = np.zeros((n_frames, rig.n_nodes, 3))
    if fill_offset:
        trans[:, 0, :] = rig.offsets[0]
    has_trans = np.zeros(rig.n_nodes, dtype=bool)
    has_trans[0] = True
    return Channels(angles=np.zeros((n_frames, rig.n_nodes, 3)), trans=trans,
                    has_trans=has_trans, fps=fps)


def _program(layout) -> tuple[np.ndarray, np.ndarray]:
    """Token program of one AMC frame: frame number, then per bone its name and values."""
    kind, arg = [_np.FRAME_NO], [0]
    col = 0
    for b, (_, n) in enumerate(layout):
        kind.append(_np.NAME)
        arg.append(b)
        for _ in range(n):
            kind.append(_np.VALUE)
            arg.append(col)
            col += 1
    return np.array(kind, dtype=np.int64), np.array(arg, dtype=np.int64)


def _fast_parse(body: bytes, skel: AsfSkeleton, fps: float):
    """Parse every frame in a numba kernel: (channels, layout of a frame), None if anything
    is irregular."""
    first = _first_layout(body, skel)
    if first is None:
        return None
    first_no, layout = first
    plan = _kernel_plan(layout, skel)
    names, offs, program, tokens_per_frame, dest, missing, seen = plan
    # Room for the frames: the upper bound is that every frame has at least two bytes per
    # token, several times the real count (np.zeros maps its pages lazily, but a fresh
    # mapping of that size costs more than the parse of a short clip). So first room for
    # what the shortest frames of this layout seen so far (``seen``, bytes per frame) give,
    # with a margin; a file with more frames than that is read again with the bound.
    bound = len(body) // (2 * tokens_per_frame) + 2
    guess = min(bound, int(len(body) / (0.75 * seen[0])) + 2) if seen[0] else bound
    data = np.frombuffer(body, dtype=np.uint8)
    for room in (guess, bound) if guess < bound else (bound,):
        ch = _empty_channels(room, skel, fps, fill_offset=False)
        frames, status, _ = _np.parse_frames(data, *program, first_no, names, offs, *dest,
                                             ch.angles, ch.trans, _np.POW10, False)
        if not (status == _np.BAD and frames == room):  # not stopped for want of room
            break
    if status == _np.OK and frames:
        per_frame = len(body) / frames
        seen[0] = min(seen[0], per_frame) if seen[0] else per_frame
    if status == _np.INEXACT:
        layout_values = _tokenised_parse(body, layout)
        return None if layout_values is None else (_to_channels(*layout_values, skel, fps),
                                                   layout)
    if status != _np.OK or frames == 0:
        return None
    ch.angles = ch.angles[:frames]
    ch.trans = ch.trans[:frames]
    ch.trans[:, 0, missing] = skel.rig.offsets[0, missing]
    return ch, layout


def _kernel_plan(layout, skel: AsfSkeleton):
    """What the parse kernel needs for frames of this layout: (bone names as bytes, their
    offsets, token program, tokens per frame, value destinations, root translation axes
    without a channel, [fewest bytes per frame seen so far]). Cached on the skeleton per
    layout, as :func:`_destinations`: a batch of files of one ASF builds it once."""
    key = tuple(layout)
    cache = skel.__dict__.setdefault("_plan_cache", {})
    if key not in cache:
        encoded = [name.encode("latin-1") for name, _ in layout]
        offs = np.cumsum([0] + [len(e) for e in encoded]).astype(np.int64)
        dest = _destinations(layout, skel)
        missing = sorted({0, 1, 2} - set(dest[2][dest[0] == _np.TO_TRANS].tolist()))
        cache[key] = (np.frombuffer(b"".join(encoded), np.uint8), offs, _program(layout),
                      1 + sum(1 + n for _, n in layout), dest, missing, [0.0])
    return cache[key]


def _tokenised_parse(body: bytes, layout):
    """Exact but slower path for numbers outside the kernel's exact range."""
    tokens = body.split()
    width = 1 + sum(1 + n for _, n in layout)
    if len(tokens) % width:
        return None
    table = np.array(tokens, dtype=object).reshape(-1, width)
    value_cols = np.ones(width, dtype=bool)
    value_cols[0] = False
    c = 1
    for name, n in layout:
        if not (table[:, c] == name.encode("latin-1")).all():
            return None
        value_cols[c] = False
        c += 1 + n
    try:
        values = table[:, value_cols].astype(np.bytes_).astype(np.float64)
    except ValueError:
        return None
    if not np.isfinite(values).all():
        return None
    return layout, values


def _slow_parse(lines: list[str], header_lines: int, skel: AsfSkeleton, path: str):
    """Line-by-line parse that raises at the first bad line (used when the fast path fails)."""
    layout: list[tuple[str, int]] | None = None
    frames: list[list[float]] = []
    current: dict[str, list[float]] | None = None
    frame_line = 0
    expected_no = None

    def close_frame(at_line: int) -> None:
        nonlocal layout
        assert current is not None
        if layout is None:
            if not current:
                raise MtannoError("frame has no bone values", path=path, line=frame_line)
            layout = [(n, len(v)) for n, v in current.items()]
        else:
            missing = [n for n, _ in layout if n not in current]
            if missing:
                raise MtannoError(f"frame {expected_no - 1} ends without values for bone "
                                  f"'{missing[0]}' (truncated file?)", path=path, line=at_line)
            extra = [n for n in current if n not in dict(layout)]
            if extra:
                raise MtannoError(f"bone '{extra[0]}' appears in frame {expected_no - 1} but "
                                  "not in the first frame", path=path, line=frame_line)
        frames.append([v for n, _ in layout for v in current[n]])

    for lineno in range(header_lines + 1, len(lines) + 1):
        line = lines[lineno - 1].strip()
        if not line:
            continue
        tok = line.split()
        if len(tok) == 1 and tok[0].isdigit():
            if current is not None:
                close_frame(lineno - 1)
            no = int(tok[0])
            if no > _limits.MAX_FRAME_NUMBER:
                raise MtannoError(f"frame number {_clip_number(tok[0])} is beyond "
                                  f"{_limits.MAX_FRAME_NUMBER}", path=path, line=lineno)
            if expected_no is not None and no != expected_no:
                raise MtannoError(f"frame number {no} where {expected_no} was expected",
                                  path=path, line=lineno)
            expected_no = no + 1
            current = {}
            frame_line = lineno
            continue
        if current is None:
            raise MtannoError(f"expected a frame number, found '{tok[0]}'", path=path,
                              line=lineno)
        name = tok[0]
        n = _dof_count(skel, name)
        if n is None:
            raise MtannoError(f"unknown bone '{name}' (not in the ASF {skel.rig.source})",
                              path=path, line=lineno)
        if name in current:
            raise MtannoError(f"bone '{name}' appears twice in one frame", path=path,
                              line=lineno)
        if len(tok) - 1 != n:
            many = "too many" if len(tok) - 1 > n else "too few"
            raise MtannoError(f"{many} values for bone '{name}': {len(tok) - 1}, its dof "
                              f"line has {n}", path=path, line=lineno)
        try:
            vals = [float(t) for t in tok[1:]]
        except ValueError:
            raise MtannoError(f"value for bone '{name}' is not a number", path=path,
                              line=lineno) from None
        if not all(np.isfinite(vals)):
            raise MtannoError(f"NaN or infinite value for bone '{name}'", path=path,
                              line=lineno)
        current[name] = vals
    if current is None:
        raise MtannoError("no frames in file", path=path, line=len(lines))
    close_frame(len(lines))
    return layout, np.asarray(frames, dtype=np.float64).reshape(len(frames), -1)


def _clip_number(text: str) -> str:
    return text if len(text) <= 20 else text[:19] + "…"


def _check_values(ch: Channels, skel: AsfSkeleton, raw: bytes, header_lines: int,
                  path: str) -> None:
    """Refuse an absurd value (a rotation beyond ±10⁶°, a root translation beyond ±10⁷ cm):
    finite, but the features would square it into ``inf``. One pass over the arrays; the
    line is looked for only when there is such a value."""
    for arr, limit, what in ((ch.angles, _limits.MAX_ANGLE_RAD, "rotation"),
                             (ch.trans[:, :1], _limits.MAX_LENGTH, "translation")):
        k = _limits.first_beyond(arr, limit)
        if k is None:
            continue
        frame, node, _ = np.unravel_index(k, arr.shape)
        bone = skel.rig.names[int(node)]
        line = _line_of_bone(raw.decode("latin-1").splitlines(), header_lines, int(frame), bone)
        bound = (f"±{_limits.MAX_ANGLE_DEG:g} degrees" if what == "rotation" else
                 f"±{_limits.MAX_LENGTH:g} cm")
        raise MtannoError(f"absurd {what} value for bone '{bone}' in frame {frame + 1} "
                          f"(beyond {bound})", path=path, line=line)


def _line_of_bone(lines: list[str], header_lines: int, frame: int, bone: str) -> int | None:
    """1-based line of ``bone``'s values in the ``frame``-th frame (0-based) of an AMC
    file that parsed, or None."""
    seen = -1
    for lineno in range(header_lines + 1, len(lines) + 1):
        tok = lines[lineno - 1].split()
        if len(tok) == 1 and tok[0].isdigit():
            seen += 1
        elif seen == frame and tok and tok[0] == bone:
            return lineno
        if seen > frame:
            break
    return None


def _to_channels(layout, values: np.ndarray, skel: AsfSkeleton, fps: float) -> Channels:
    """Scatter value columns into per-node angle slots (radians) and the root translation."""
    kind, node, slot, scale, add = _destinations(layout, skel)
    ch = _empty_channels(values.shape[0], skel, fps)
    a = kind == 0
    ch.angles[:, node[a], slot[a]] = values[:, a] * scale[a]
    t = kind == 1
    ch.trans[:, node[t], slot[t]] = add[t] + values[:, t] * scale[t]
    return ch
