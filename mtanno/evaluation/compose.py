"""Compose long evaluation documents from labelled clips, with an exact ground truth.

A composed document is a seeded random sequence of clips of one actor (one ASF skeleton),
written as one AMC file that ``mtanno features`` reads. At every seam the next clip's root
is re-anchored: turned about the vertical axis so that its heading at its first frame equals
the previous clip's heading at its last frame, and moved on the floor so that its root
starts where the previous clip's root ended. The root height is kept. Optional pauses
repeat the last pose for a number of native frames and are left unlabelled.

The ground truth lists every clip as a segment of 30 Hz frames: exactly the analysis frames
(docs/method/features.md §6) whose native frame belongs to the clip.
"""

from __future__ import annotations

import json
import math
import os
import random
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.features.hysteresis import analysis_frames
from mtanno.io.amc import read_amc_values, write_amc
from mtanno.io.asf import AsfSkeleton, read_asf
from mtanno.io.skeleton import euler_matrix
from mtanno.labels.segments import Segment
from mtanno.labels.truth import write_truth
from mtanno.util.output import atomic_path


@dataclass(frozen=True)
class Clip:
    """A labelled clip: AMC path, class label, actor."""

    path: Path
    label: str
    actor: str


def read_clips(path: str | os.PathLike, *, root: str | os.PathLike | None = None,
                  actor: str | None = None, split: str | None = None) -> list[Clip]:
    """Clips of a manifest (:func:`mtanno.util.clips.read_clip_manifest`: columns
    ``file,class[,actor,split]``, file relative to ``root``, by default the manifest's
    folder), filtered by actor and split. Every clip file must exist."""
    from mtanno.util.clips import read_clip_manifest as read_rows

    table, rows = read_rows(path)
    root = Path(root) if root is not None else Path(path).parent
    out = []
    for row in rows:
        if actor is not None and row.actor != actor:
            continue
        if split is not None and row.split != split:
            continue
        clip = root / row.file
        if not clip.is_file():
            raise MtannoError(f"clip file {clip} not found", path=table.path, line=row.line)
        out.append(Clip(clip, row.label, row.actor))
    if not out:
        raise MtannoError(f"no clips in the manifest for actor={actor} split={split}",
                          path=table.path)
    return out


def _root_columns(skel: AsfSkeleton, layout) -> dict[str, int]:
    col = 0
    for name, n in layout:
        if name == "root":
            return {tok.upper(): col + i for i, tok in enumerate(skel.root_order)}
        col += n
    raise MtannoError("AMC has no root line")


def _root_matrix(rx: float, ry: float, rz: float) -> np.ndarray:
    return euler_matrix(2, rz) @ euler_matrix(1, ry) @ euler_matrix(0, rx)


def _zyx_angles(m: np.ndarray) -> tuple[float, float, float]:
    """(rx, ry, rz) with m = Rz(rz)·Ry(ry)·Rx(rx)."""
    ry = -math.asin(max(-1.0, min(1.0, m[2, 0])))
    rx = math.atan2(m[2, 1], m[2, 2])
    rz = math.atan2(m[1, 0], m[0, 0])
    return rx, ry, rz


def _yaw(m: np.ndarray) -> float:
    """Heading angle about Y of the root's local X axis (the axis F40 measures)."""
    h = m @ np.array([1.0, 0.0, 0.0])
    return math.atan2(-h[2], h[0])


def reanchor(values: np.ndarray, cols: dict[str, int], *, angle_scale: float,
             anchor_xz: tuple[float, float] | None, anchor_yaw: float | None) -> np.ndarray:
    """Turn and move a clip's root so its first frame has the given floor position and
    heading (file units and degrees in, out). With ``anchor_xz`` None the clip is kept."""
    out = values.copy()
    if anchor_xz is None:
        return out
    tx, ty, tz = (values[:, cols[k]] for k in ("TX", "TY", "TZ"))
    rx, ry, rz = (values[:, cols[k]] * angle_scale for k in ("RX", "RY", "RZ"))
    first = _root_matrix(rx[0], ry[0], rz[0])
    phi = anchor_yaw - _yaw(first)
    turn = euler_matrix(1, phi)
    c, s = math.cos(phi), math.sin(phi)
    dx, dz = tx - tx[0], tz - tz[0]
    out[:, cols["TX"]] = anchor_xz[0] + c * dx + s * dz
    out[:, cols["TZ"]] = anchor_xz[1] - s * dx + c * dz
    out[:, cols["TY"]] = ty
    for f in range(values.shape[0]):
        a = _zyx_angles(turn @ _root_matrix(rx[f], ry[f], rz[f]))
        out[f, cols["RX"]], out[f, cols["RY"]], out[f, cols["RZ"]] = (v / angle_scale for v in a)
    return out


def _chain(order: Sequence[Clip], loaded: dict, skel: AsfSkeleton, layout0, pause: int,
           ) -> tuple[list[np.ndarray], list[tuple[int, int, str]], int]:
    """The clips of one document one after the other, each turned and moved to start where
    and facing how the previous one ended, ``pause`` still frames between them: the parts
    to concatenate, each clip's span (first, last native frame 0-based, label) and the
    document's native frame count."""
    cols = _root_columns(skel, layout0)
    anchor_xz = anchor_yaw = None
    offset = 0
    parts, spans = [], []
    for clip in order:
        header, layout, values, fps = loaded[clip.path]
        v = reanchor(values, cols, angle_scale=skel.angle_scale, anchor_xz=anchor_xz,
                     anchor_yaw=anchor_yaw)
        parts.append(v)
        spans.append((offset, offset + len(v) - 1, clip.label))
        offset += len(v)
        last = v[-1]
        anchor_xz = (last[cols["TX"]], last[cols["TZ"]])
        anchor_yaw = _yaw(_root_matrix(*(last[cols[k]] * skel.angle_scale
                                         for k in ("RX", "RY", "RZ"))))
        if pause > 0:
            parts.append(np.repeat(last[None, :], pause, axis=0))
            offset += pause
    return parts, spans, offset


def _steps(progress: Callable[[int, int], None] | None, total: int) -> Callable[[], None]:
    """A function to call after each of ``total`` steps: ``progress(done, total)``."""
    done = 0

    def step() -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total)

    return step


#: Documents ``compose`` makes unless told.
DEFAULT_DOCS = 10


def compose_documents(clips: list[Clip], out_dir: str | os.PathLike, *, n_docs: int = DEFAULT_DOCS,
                      clips_per_doc: int | None = None, seed: int = 0, pause: int = 0,
                      asf: str | os.PathLike | None = None, prefix: str | None = None,
                      shuffle: bool = True, inputs: Sequence[str | os.PathLike] = (),
                      progress: Callable[[int, int], None] | None = None,
                      inside_input: bool = False,
                      ) -> tuple[list[Path], list[Segment]]:
    """Write ``n_docs`` composed AMC documents, their ASF and ``truth.csv`` into ``out_dir``.

    Each document takes ``clips_per_doc`` clips (default: all) in a random order drawn from
    ``random.Random(seed)``, so the same seed gives the same documents. ``pause`` native
    frames of stillness separate the clips. ``shuffle=False`` keeps the clips in the given
    order (the first ``clips_per_doc`` of them). Returns the document paths and the truth.
    Every clip is read and checked before anything is written; no output may be one of the
    clips, the ASF or the further ``inputs`` (the manifest, say), and ``out_dir`` may be, or
    lie inside, a folder holding clips only with ``inside_input``: composed documents among
    the clips would be read as clips by the next ``features`` run over it.
    ``progress(done, total)`` is called after each clip read and each document written.
    """
    if not clips:
        raise MtannoError("no clips to compose")
    from mtanno.io import find_asf
    from mtanno.util.output import make_folder
    from mtanno.util.preflight import check_outputs

    # everything is read and checked before the first byte is written: a bad clip leaves
    # no partial output folder
    asf_path = Path(asf) if asf is not None else find_asf(clips[0].path)
    skel = read_asf(asf_path)
    if list(skel.rig.axes[0]) != [2, 1, 0] or skel.rig.pre[0].tolist() != np.eye(3).tolist():
        raise MtannoError("compose needs an ASF root with axis XYZ and zero orientation",
                          path=str(asf_path))
    for c in clips:
        if not c.label:
            raise MtannoError("a clip without a class label", path=str(c.path))
    out_dir = Path(out_dir)
    prefix = prefix or asf_path.stem
    planned = [out_dir / f"{prefix}_doc{d:02d}.amc" for d in range(1, n_docs + 1)]
    planned += [out_dir / asf_path.name, out_dir / "truth.csv", out_dir / "truth.csv.meta.json",
                out_dir / "compose.json"]
    check_outputs(planned, [asf_path, *(c.path for c in clips), *inputs],
                  folders={out_dir: []}, scanned={c.path.parent: () for c in clips},
                  inside_input=inside_input)
    rng = random.Random(seed)
    loaded = {}
    step = _steps(progress, len(clips) + n_docs)
    for c in clips:
        loaded[c.path] = read_amc_values(c.path, skel)
        step()
    first = loaded[clips[0].path]
    for c in clips:
        if loaded[c.path][1] != first[1] or loaded[c.path][3] != first[3]:
            raise MtannoError("clips must share bone layout and frame rate (this one differs "
                              f"from {clips[0].path})", path=str(c.path))
    make_folder(out_dir)
    with atomic_path(out_dir / asf_path.name) as tmp:
        shutil.copyfile(asf_path, tmp)
    k = len(clips) if clips_per_doc is None else min(clips_per_doc, len(clips))
    docs, truth, plan = [], [], []
    for d in range(1, n_docs + 1):
        order = rng.sample(range(len(clips)), k) if shuffle else list(range(k))
        name = f"{prefix}_doc{d:02d}"
        layout0 = loaded[clips[order[0]].path][1]
        fps0 = loaded[clips[order[0]].path][3]
        parts, spans, offset = _chain([clips[i] for i in order], loaded, skel, layout0, pause)
        # exact 30 Hz truth: the analysis frames whose native frame lies in the clip
        kept = analysis_frames(offset, fps0)
        for first, last, label in spans:
            a = int(np.searchsorted(kept, first, side="left"))
            b = int(np.searchsorted(kept, last, side="right")) - 1
            if b >= a:
                truth.append(Segment(name, a + 1, b + 1, label))
        path = out_dir / f"{name}.amc"
        header = [f"# composed by mtanno compose (seed {seed}, document {d})",
                  f"#!OML:ASF {asf_path.name}", ":FULLY-SPECIFIED",
                  ":DEGREES" if skel.angle_scale != 1.0 else ":RADIANS"]
        if fps0 != 120.0:
            header.append(f":SAMPLES-PER-SECOND {fps0:g}")
        write_amc(path, header, layout0, np.concatenate(parts))
        docs.append(path)
        plan.append({"document": name, "clips": [str(clips[i].path) for i in order]})
        step()
    from mtanno.util.provenance import provenance

    write_truth(out_dir / "truth.csv", truth, provenance=provenance(
        inputs=[asf_path, *inputs], seed=seed, pause=pause, documents=plan))
    with atomic_path(out_dir / "compose.json") as tmp:
        tmp.write_text(json.dumps({"seed": seed, "pause": pause, "asf": str(asf_path),
                                   "documents": plan}, indent=1))
    return docs, truth


@dataclass(frozen=True)
class ComposeOptions:
    """How :func:`compose_to` composes (the defaults are the command's; those of
    :func:`compose_documents`): ``n_docs`` documents of ``clips_per_doc`` clips each
    (default: all), drawn in an order seeded by ``seed`` (``shuffle=False``: the given
    order), ``pause`` native frames of stillness between clips."""

    n_docs: int = DEFAULT_DOCS
    clips_per_doc: int | None = None
    seed: int = 0
    pause: int = 0
    shuffle: bool = True


def compose_to(manifest: str | os.PathLike, out_dir: str | os.PathLike, *,
               root: str | os.PathLike | None = None, actor: str | None = None,
               split: str | None = None, asf: str | os.PathLike | None = None,
               options: ComposeOptions | None = None, inside_input: bool = False,
               progress: Callable[[int, int], None] | None = None,
               ) -> tuple[list[Path], list[Segment]]:
    """The whole ``mtanno compose`` run: the clips of ``manifest`` (:func:`read_clips`:
    ``root``, ``actor``, ``split``) composed into documents in ``out_dir`` as ``options``
    say (:class:`ComposeOptions`, :func:`compose_documents`: ``asf``, ``inside_input``,
    ``progress``; the manifest is never an output). Returns the document paths and the
    truth."""
    o = options or ComposeOptions()
    clips = read_clips(manifest, root=root, actor=actor, split=split)
    return compose_documents(clips, out_dir, n_docs=o.n_docs, clips_per_doc=o.clips_per_doc,
                             seed=o.seed, pause=o.pause, asf=asf, shuffle=o.shuffle,
                             inputs=[manifest], progress=progress, inside_input=inside_input)
