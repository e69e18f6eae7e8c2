"""The stick-figure player of the report page (issue 24): a reviewer sees the motion that
a row labels, not only its frames.

Per document the page embeds its poses at the 30 Hz analysis frames the annotation
counts in: the 22 canonical joints (:data:`mtanno.io.rigs.CANONICAL_JOINTS`) normalised as
``mtanno features --poses`` stores them (:func:`mtanno.features.poses.normalize_poses`:
root at x = z = 0, facing one way, in leg lengths), from the documents' motion files
(:func:`load_motion_poses`) or from the pose blocks of their feature files. They are
quantised to thousandths of a leg length (about a millimetre) as little-endian int16 and
embedded in base 64 (:func:`encode_poses`): 10 documents of 60 s take about 3 MB.

The page's script (``player.js``, package data, inlined) draws each document's poses as a
stick figure on a canvas, its annotation as a timeline with a cursor under it, plays and
pauses, seeks where the timeline is clicked, and plays a review row's segment when the row
is clicked. Every player element has ``data-mtanno-player``, ``data-doc``, ``data-frames``
(its document's frames at 30 Hz) and ``data-frame`` (the frame shown, 1-based like every
file); the page opened with ``#autoplay`` starts every player. The review list's controls
(accept, reject, relabel, boundaries) and its "Download truth" button are the same script.
"""

from __future__ import annotations

import base64
import json
import os
from collections.abc import Iterable, Sequence
from importlib import resources
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.io.rigs import CANONICAL_JOINTS

__all__ = ["BONES", "POSE_QUANTUM", "decode_poses", "encode_poses", "load_motion_poses",
           "motion_files", "player_script", "players_data", "players_html", "review_html"]

#: Bones of the stick figure: pairs of canonical joints.
BONES = (("root", "lhip"), ("root", "rhip"), ("lhip", "lknee"), ("rhip", "rknee"),
         ("lknee", "lankle"), ("rknee", "rankle"), ("lankle", "ltoes"), ("rankle", "rtoes"),
         ("root", "belly"), ("belly", "chest"), ("chest", "neck"), ("neck", "head"),
         ("head", "headtop"), ("chest", "lshoulder"), ("chest", "rshoulder"),
         ("lshoulder", "lelbow"), ("rshoulder", "relbow"), ("lelbow", "lwrist"),
         ("relbow", "rwrist"), ("lwrist", "lfingers"), ("rwrist", "rfingers"))
#: Embedded poses are integers in this fraction of a leg length.
POSE_QUANTUM = 1e-3


def encode_poses(poses: np.ndarray) -> str:
    """Base 64 of (frames × 22 × 3) poses in leg lengths as little-endian int16 in units of
    :data:`POSE_QUANTUM` (values beyond ±32 leg lengths are clipped)."""
    P = np.asarray(poses, dtype=np.float64)
    if P.ndim != 3 or P.shape[1:] != (len(CANONICAL_JOINTS), 3):
        raise MtannoError(f"poses must be (frames × {len(CANONICAL_JOINTS)} × 3), got "
                          f"{P.shape}")
    q = np.clip(np.rint(P / POSE_QUANTUM), -32767, 32767).astype("<i2")
    return base64.b64encode(q.tobytes()).decode("ascii")


def decode_poses(text: str) -> np.ndarray:
    """The poses of :func:`encode_poses` (frames × 22 × 3, leg lengths), as the page's
    script decodes them."""
    q = np.frombuffer(base64.b64decode(text), dtype="<i2")
    return q.reshape(-1, len(CANONICAL_JOINTS), 3).astype(np.float64) * POSE_QUANTUM


def motion_files(inputs: Iterable[str | os.PathLike],
                 docs: Iterable[str] | None = None) -> dict[str, Path]:
    """Document name (file stem) → motion file, of files and folders (searched
    recursively for motion files, :data:`mtanno.io.formats.SUFFIXES`); with ``docs``, of
    those documents only. An
    empty name, a missing input, a file that is not a motion file, or two files of one
    document (of ``docs``) are errors naming them."""
    from mtanno.io.formats import expected, is_motion_path

    wanted = None if docs is None else set(docs)
    out: dict[str, Path] = {}
    for item in inputs:
        if not str(item).strip():
            raise MtannoError("an empty motion path (name a file or a folder; '.' for this "
                              "one)")
        p = Path(item)
        if p.is_dir():
            found = sorted(f for f in p.rglob("*") if is_motion_path(f) and f.is_file())
        elif p.exists():
            if not is_motion_path(p):
                raise MtannoError(f"not a motion file ({expected()})", path=str(p))
            found = [p]
        else:
            raise MtannoError("motion file or folder not found", path=str(p))
        for f in found:
            if wanted is not None and f.stem not in wanted:
                continue
            if f.stem in out and out[f.stem] != f:
                raise MtannoError(f"two motion files of document {f.stem!r}: {out[f.stem]} "
                                  f"and {f}")
            out[f.stem] = f
    return out


def load_motion_poses(files: dict[str, Path], docs: Sequence[str], *,
                      asf: str | os.PathLike | None = None,
                      failures: list[str] | None = None) -> dict[str, np.ndarray]:
    """The normalised poses at the 30 Hz analysis frames of each document of ``docs`` that
    has a motion file in ``files`` (:func:`motion_files`), as ``features --poses`` computes
    them (``asf``, else the ASF found beside or above an AMC file; skeleton map detected). A
    file that cannot be read is left out, its message appended to ``failures`` (an error
    without it)."""
    from mtanno.features.extract import poses_at
    from mtanno.features.hysteresis import analysis_frames
    from mtanno.io import canonical_positions, read_motion

    out = {}
    for d in docs:
        if d not in files:
            continue
        try:
            motion = read_motion(files[d], asf=asf)
            P = canonical_positions(motion)  # (Y up, as read_motion gives it)
            out[d] = poses_at(P, analysis_frames(P.shape[0], motion.fps))
        except MtannoError as exc:
            if failures is None:
                raise
            failures.append(str(exc) if exc.path else f"{files[d]}: {exc}")
    return out


def players_data(poses: dict[str, np.ndarray], annotation, frames: dict[str, int],
                 colours: dict[str, str]) -> dict:
    """What the page's script reads: the bones (joint index pairs), per document with poses
    its frames, encoded poses and annotation segments (1-based start, end, label), and
    each label's colour (``#rrggbb``)."""
    index = {name: i for i, name in enumerate(CANONICAL_JOINTS)}
    rows: dict[str, list] = {}  # the segments of each document, grouped once
    for a in annotation:
        if a.doc in poses:
            rows.setdefault(a.doc, []).append((a.start + 1, a.end + 1, a.label))
    docs = {}
    for d, P in sorted(poses.items()):
        segs = sorted(rows.get(d, []))
        docs[d] = {"frames": int(frames.get(d, P.shape[0])), "poses": encode_poses(P),
                   "posed": int(P.shape[0]), "segments": [list(s) for s in segs]}
    return {"bones": [[index[a], index[b]] for a, b in BONES], "quantum": POSE_QUANTUM,
            "joints": len(CANONICAL_JOINTS), "names": list(CANONICAL_JOINTS),
            "colours": colours, "documents": docs}


def player_script(data: dict) -> str:
    """The page's data (:func:`players_data`, JSON in a ``<script type=application/json>``
    element) and the player's script, inline: no file and no network needed."""
    js = (resources.files("mtanno.evaluation") / "player.js").read_text(encoding="utf-8")
    text = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    return (f"<script type='application/json' id='mtanno-data'>{text}</script>\n"
            f"<script>\n{js}</script>")


def players_html(data: dict, missing: Sequence[str] = ()) -> str:
    """The page's section of players (one per document with poses), ``missing`` naming
    the documents without a motion."""
    import html

    parts = ["<h2>Motions</h2><p>The documents' poses as stick figures (left side blue, "
             "right side red), the annotation under each; click the timeline to seek, a row "
             "of the review list to play its segment.</p>"]
    for d, doc in data["documents"].items():
        parts.append(
            f"<div class='player' data-mtanno-player data-doc='{html.escape(d)}' "
            f"data-frames='{doc['frames']}' data-frame='1'><b>{html.escape(d)}</b> "
            "<button class='play' type='button'>play</button> <span class='where'></span>"
            "<canvas class='figure' width='360' height='300'></canvas>"
            "<canvas class='timeline' width='1100' height='16'></canvas></div>")
    if missing:
        parts.append(f"<p>No motion for {len(missing)} document(s): "
                     f"{html.escape(', '.join(missing))}.</p>")
    return "\n".join(parts)


def review_html(rows: Sequence[dict], classes: Sequence[str], playable: set[str]) -> str:
    """The review list (:func:`mtanno.evaluation.report.review_rows`) with a reviewer's
    controls per row: decision (accept, reject), label (a class, or any name: a relabel)
    and boundaries (1-based frames at 30 Hz); editing a row accepts it. "Download truth"
    writes the accepted rows as a truth CSV (``doc,start,end,label,fps``) that
    ``learn-mt --truth``, ``tune --truth`` and ``evaluate --truth`` read. A row of a
    document with a player plays its segment when clicked."""
    import html

    def num(v):
        return "–" if v is None else f"{v:.3f}"

    options = "".join(f"<option value='{html.escape(c)}'>" for c in classes)
    out = ["<h2>Review list</h2><p>Every row, the least confident first. Accept or reject a "
           "row, correct its label or its frames (an edited row is accepted), then "
           "<button id='download-truth' type='button'>Download truth</button> (truth.csv of "
           "the accepted rows; <button id='accept-rest' type='button'>accept the rest</button>"
           ") <span id='truth-count'></span>.</p>",
           f"<datalist id='mtanno-classes'>{options}</datalist>",
           "<table class='review'><tr><th>doc</th><th>start</th><th>end</th><th>label</th>"
           "<th>seconds</th><th>cost</th><th>confidence</th><th>decision</th></tr>"]
    for r in rows:
        doc = html.escape(r["doc"])
        play = " class='review playable'" if r["doc"] in playable else " class='review'"
        out.append(
            f"<tr{play} data-doc='{doc}'><td>{doc}</td>"
            f"<td><input class='start' type='number' min='1' value='{r['start']}'></td>"
            f"<td><input class='end' type='number' min='1' value='{r['end']}'></td>"
            f"<td><input class='label' list='mtanno-classes' value='{html.escape(r['label'])}'>"
            f"</td><td>{r['seconds']:.2f}</td><td>{num(r['cost'])}</td>"
            f"<td>{num(r['confidence'])}</td><td><select class='decision'>"
            "<option value=''>–</option><option value='accept'>accept</option>"
            "<option value='reject'>reject</option></select></td></tr>")
    out.append("</table>")
    return "\n".join(out)
