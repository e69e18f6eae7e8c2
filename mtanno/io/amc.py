"""AMC motion reader (Acclaim motion capture data).

Spec: ``algorithms.md`` §1, ``features.md`` §1.1 and §1.3. Each frame is a frame number
followed by one line per bone: the bone name and its values in the order of the bone's ASF
``dof`` line (the root's in the order of ``:root order``). The rate is
``:SAMPLES-PER-SECOND`` when the header has it, else 120 frames/s.

Parsing splits the whole file into tokens once and checks the layout of every frame against
the first one with array operations (the fast path); any irregularity sends the file through
a line-by-line parser whose only job is to name the first bad line.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
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
        pos = end
        nlines += 1
    return pos, nlines, fps


def read_amc(path: str | os.PathLike, skel: AsfSkeleton) -> Channels:
    """Read an AMC file against its ASF skeleton into :class:`Channels` (cm, radians)."""
    spath = str(path)
    try:
        raw = Path(path).read_bytes()
    except FileNotFoundError:
        raise MtannoError("file not found", path=spath) from None
    except OSError as exc:
        raise MtannoError(f"cannot read file: {exc.strerror}", path=spath) from None
    if not raw.strip():
        raise MtannoError("file is empty", path=spath, line=1)
    if b"\x00" in raw:
        line = raw[: raw.index(b"\x00")].count(b"\n") + 1
        raise MtannoError("binary data (NUL byte) in a text file", path=spath, line=line)
    body_at, header_lines, fps = _header(raw, spath)
    layout, values = _fast_parse(raw[body_at:], skel)
    if layout is None:
        layout, values = _slow_parse(raw.decode("latin-1").splitlines(), header_lines, skel,
                                     spath)
    return _to_channels(layout, values, skel, fps)


def _fast_parse(body: bytes, skel: AsfSkeleton):
    """Tokenise at once; (layout, values) or (None, None) when anything is irregular."""
    tokens = body.split()
    if not tokens or not _is_int(tokens[0]):
        return None, None
    layout: list[tuple[str, int]] = []
    i = 1
    while i < len(tokens) and not _is_int(tokens[i]):
        name = tokens[i].decode("latin-1")
        n = _dof_count(skel, name)
        if n is None:
            return None, None
        layout.append((name, n))
        i += 1 + n
    width = i
    if not layout or len(tokens) % width:
        return None, None
    table = np.array(tokens, dtype=object).reshape(-1, width)
    name_cols = []
    c = 1
    for _, n in layout:
        name_cols.append(c)
        c += 1 + n
    first = table[0]
    for col in name_cols:
        if not (table[:, col] == first[col]).all():
            return None, None
    try:
        frame_no = table[:, 0].astype(np.bytes_).astype(np.int64)
    except ValueError:
        return None, None
    if not np.array_equal(frame_no, np.arange(frame_no[0], frame_no[0] + len(frame_no))):
        return None, None
    value_cols = np.ones(width, dtype=bool)
    value_cols[0] = False
    value_cols[name_cols] = False
    try:
        values = table[:, value_cols].astype(np.bytes_).astype(np.float64)
    except ValueError:
        return None, None
    if not np.isfinite(values).all():
        return None, None
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


def _to_channels(layout, values: np.ndarray, skel: AsfSkeleton, fps: float) -> Channels:
    rig = skel.rig
    n_frames = values.shape[0]
    angles = np.zeros((n_frames, rig.n_nodes, 3))
    trans = np.zeros((n_frames, rig.n_nodes, 3))
    has_trans = np.zeros(rig.n_nodes, dtype=bool)
    has_trans[0] = True
    trans[:, 0, :] = rig.offsets[0]
    col = 0
    for name, n in layout:
        node = rig.index(name)
        dof = [t.lower() for t in skel.root_order] if name == "root" else skel.dofs[name]
        for d in dof:
            if d[0] == "r":
                slot = int(np.flatnonzero(rig.axes[node] == AXIS_CODES[d[1]])[0])
                angles[:, node, slot] = values[:, col] * skel.angle_scale
            elif d[0] == "t" and name == "root":
                trans[:, 0, AXIS_CODES[d[1]]] += values[:, col] * skel.length_scale
            col += 1
    return Channels(angles=angles, trans=trans, has_trans=has_trans, fps=fps)
