"""The motions of the report page's player (issues 24 and 33): a reviewer sees the motion
that a row labels, not only its frames.

Per document the player shows its poses at the 30 Hz analysis frames the annotation counts
in, normalised as ``mtanno features --poses`` stores them
(:func:`mtanno.features.poses.normalize_poses`: root at x = z = 0, facing one way, in leg
lengths). From a motion file (:func:`load_motion_poses`) they are the rig's own joints and
bones (the canonical root's subtree, moved by the same per-frame turn, shift and scale that
normalise its canonical joints, :func:`rig_poses`); from the pose block of a feature file
they are the 22 canonical joints joined by :data:`BONES`.

A motion is shown only when it is the annotated one as far as the report can tell: its
frame count at 30 Hz equals the one the annotation recorded (or covers every labelled frame
when none is recorded), and, where the document's feature file is given, its SHA-256 is the
one the features were computed from (:func:`motion_mismatch`). Anything else (another
take, a shorter or longer file, another rig or frame rate) is said per document, never
played silently.

Poses and Δ curves travel to the page in compact form (:func:`encode_poses`,
:func:`encode_curves`): integers, differences along time, deflated, base 64 — about
4 KB for a 3 s clip. :mod:`mtanno.evaluation.page` puts them into the page's data files.
"""

from __future__ import annotations

import base64
import os
import zlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.io.rigs import CANONICAL_JOINTS

__all__ = ["BONES", "CURVE_QUANTUM", "POSE_QUANTUM", "EncodedPoses", "PlayerPoses",
           "canonical_player_poses",
           "decode_curves", "decode_poses", "encode_curves", "encode_poses",
           "load_motion_poses", "motion_files", "motion_mismatch", "rig_poses"]

#: Bones of the stick figure of canonical poses: pairs of canonical joints.
BONES = (("root", "lhip"), ("root", "rhip"), ("lhip", "lknee"), ("rhip", "rknee"),
         ("lknee", "lankle"), ("rknee", "rankle"), ("lankle", "ltoes"), ("rankle", "rtoes"),
         ("root", "belly"), ("belly", "chest"), ("chest", "neck"), ("neck", "head"),
         ("head", "headtop"), ("chest", "lshoulder"), ("chest", "rshoulder"),
         ("lshoulder", "lelbow"), ("rshoulder", "relbow"), ("lelbow", "lwrist"),
         ("relbow", "rwrist"), ("lwrist", "lfingers"), ("rwrist", "rfingers"))
#: Poses travel as integers in this fraction of a leg length (about a millimetre).
POSE_QUANTUM = 1e-3
#: Δ curves travel as integers in this unit; :data:`_CURVE_NONE` marks "no match".
CURVE_QUANTUM = 1e-4
_CURVE_NONE = 65535
_J = {name: i for i, name in enumerate(CANONICAL_JOINTS)}
#: The side of each canonical joint: l, r, or c (centre: root, spine, head).
_SIDES = "".join(n[0] if n != "root" and n[0] in "lr" else "c" for n in CANONICAL_JOINTS)


@dataclass
class PlayerPoses:
    """What the player draws of one document: ``positions`` (frames × joints × 3, leg
    lengths, Y up, normalised), the ``bones`` as (parent, child) joint index pairs, and per
    joint its side (``"l"``, ``"r"`` or ``"c"``, the figure's colours)."""

    positions: np.ndarray
    bones: list[tuple[int, int]]
    sides: str

    @property
    def frames(self) -> int:
        return int(self.positions.shape[0])

    def encoded(self) -> EncodedPoses:
        """The same, the positions as the page carries them (:func:`encode_poses`)."""
        return EncodedPoses(self.frames, self.bones, self.sides, encode_poses(self.positions))


@dataclass
class EncodedPoses:
    """:class:`PlayerPoses` with its positions encoded (:func:`encode_poses`): what a
    report keeps of thousands of motions (a few kilobytes each)."""

    frames: int
    bones: list[tuple[int, int]]
    sides: str
    text: str


def canonical_player_poses(poses: np.ndarray) -> PlayerPoses:
    """The player's view of canonical poses (a feature file's pose block)."""
    P = np.asarray(poses)
    if P.ndim != 3 or P.shape[1:] != (len(CANONICAL_JOINTS), 3):
        raise MtannoError(f"poses must be (frames × {len(CANONICAL_JOINTS)} × 3), got "
                          f"{P.shape}")
    return PlayerPoses(P, [(_J[a], _J[b]) for a, b in BONES], _SIDES)


def _encode_int16(q: np.ndarray) -> str:
    """Base 64 of the deflated (zlib) little-endian int16 differences along axis 0 of
    ``q`` (frames × values), stored value by value (all frames of the first value, then
    the next): smooth motion gives small differences, which deflate well. Sums wrap modulo
    2¹⁶ both ways, so every int16 comes back."""
    cols = np.ascontiguousarray(q.reshape(q.shape[0], -1).T).astype(np.int32)
    diff = np.diff(cols, axis=1, prepend=0).astype("<i2")  # wraps modulo 2^16
    return base64.b64encode(zlib.compress(diff.tobytes(), 3)).decode("ascii")


def _decode_int16(text: str, width: int) -> np.ndarray:
    diff = np.frombuffer(zlib.decompress(base64.b64decode(text)), dtype="<i2")
    cols = np.cumsum(diff.reshape(width, -1).astype(np.int64), axis=1)
    return ((cols + 32768) % 65536 - 32768).T.astype(np.int16)


def encode_poses(poses: np.ndarray) -> str:
    """(frames × joints × 3) positions in leg lengths as the page carries them: integers in
    :data:`POSE_QUANTUM` (clipped at ±32 leg lengths), differences along time, deflated,
    base 64 (the page's script inflates them with the browser's ``DecompressionStream``)."""
    P = np.asarray(poses, dtype=np.float64)
    if P.ndim != 3 or P.shape[2] != 3 or P.shape[1] == 0:
        raise MtannoError(f"poses must be (frames × joints × 3), got {P.shape}")
    return _encode_int16(np.clip(np.rint(P / POSE_QUANTUM), -32767, 32767).astype(np.int16))


def decode_poses(text: str, joints: int = len(CANONICAL_JOINTS)) -> np.ndarray:
    """The poses of :func:`encode_poses` (frames × joints × 3, leg lengths), as the page's
    script decodes them."""
    q = _decode_int16(text, joints * 3)
    return q.reshape(-1, joints, 3).astype(np.float64) * POSE_QUANTUM


def encode_curves(curves: np.ndarray) -> str:
    """(classes × frames) Δ curves as the page carries them: unsigned integers in
    :data:`CURVE_QUANTUM` up to 6.5, 65535 where a class has no match (∞ or NaN),
    differences along time, deflated, base 64."""
    C = np.asarray(curves, dtype=np.float64)
    if C.ndim != 2:
        raise MtannoError(f"curves must be (classes × frames), got {C.shape}")
    q = np.where(np.isfinite(C), np.rint(np.clip(C, 0, 6.5) / CURVE_QUANTUM), _CURVE_NONE)
    return _encode_int16(q.astype(np.uint16).view(np.int16).T)


def decode_curves(text: str, classes: int) -> np.ndarray:
    """The curves of :func:`encode_curves` (classes × frames), ∞ where there was none."""
    q = _decode_int16(text, classes).T.view(np.uint16)
    return np.where(q == _CURVE_NONE, np.inf, q * CURVE_QUANTUM)


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


def rig_poses(positions: np.ndarray, canonical: np.ndarray, parents: Sequence[int],
              root: int, side_of: dict[int, str],
              normalised: np.ndarray | None = None) -> PlayerPoses:
    """The rig's own joints normalised like its canonical joints: ``positions`` (frames ×
    nodes × 3, Y up) of every node, ``canonical`` (frames × 22 × 3) those of the canonical
    joints at the same frames. :func:`~mtanno.features.poses.normalize_poses` turns, shifts
    and scales each frame; the turn is recovered from its result by a least-squares 2-D
    rotation of the canonical joints' floor coordinates (exact: it is a rotation), so that
    every node moves as the canonical joints do. Only the canonical root (node ``root``)
    and its descendants are kept (a BVH root above the hips would add a bone to the floor);
    ``side_of`` gives the side of the nodes that are canonical joints, the others take
    their parent's. ``normalised``: ``normalize_poses(canonical)`` when already known."""
    from mtanno.features.poses import body_scale, normalize_poses

    C = np.asarray(canonical, dtype=np.float64)
    out = np.asarray(normalize_poses(C) if normalised is None else normalised, np.float64)
    scale = body_scale(C)
    a_x, a_z = C[:, :, 0] - C[:, :1, 0], C[:, :, 2] - C[:, :1, 2]
    b_x, b_z = out[:, :, 0] * scale, out[:, :, 2] * scale
    ux = (a_x * b_x + a_z * b_z).sum(axis=1)
    uz = (a_z * b_x - a_x * b_z).sum(axis=1)
    norm = np.hypot(ux, uz)
    flat = norm <= 1e-12
    norm = np.where(flat, 1.0, norm)
    ux, uz = np.where(flat, 1.0, ux / norm), np.where(flat, 0.0, uz / norm)
    keep = [root]
    for node in range(len(parents)):  # parents come before their children
        if node != root and parents[node] in keep:
            keep.append(node)
    where = {node: i for i, node in enumerate(keep)}
    P = np.asarray(positions, dtype=np.float64)[:, keep]
    x, z = P[:, :, 0] - C[:, :1, 0], P[:, :, 2] - C[:, :1, 2]
    R = np.empty_like(P)
    R[:, :, 0] = x * ux[:, None] + z * uz[:, None]
    R[:, :, 1] = P[:, :, 1]
    R[:, :, 2] = -x * uz[:, None] + z * ux[:, None]
    sides = []
    for node in keep:
        sides.append(side_of.get(node) or (sides[where[parents[node]]] if node != root
                                           else "c"))
    bones = [(where[parents[n]], where[n]) for n in keep[1:]]
    return PlayerPoses((R / scale).astype(np.float32), bones, "".join(sides))


def _read_motion_poses(path: Path, asf, sha256: bool = True
                       ) -> tuple[np.ndarray, PlayerPoses, str]:
    """One motion file at its 30 Hz analysis frames: the canonical poses as the pose block
    stores them, the rig's own (:func:`rig_poses`), and the file's SHA-256 (with
    ``sha256``, else "")."""
    from mtanno.features.extract import poses_at
    from mtanno.features.hysteresis import analysis_frames
    from mtanno.io import canonical_positions, read_motion

    motion = read_motion(path, asf=asf, sha256=sha256)
    keep = analysis_frames(motion.positions.shape[0], motion.fps)
    index = motion.smap.indices(motion.rig, CANONICAL_JOINTS)
    C = canonical_positions(motion)  # Y up, as read_motion gives it
    canonical = poses_at(C, keep)
    side_of = {int(n): side for n, side in zip(index, _SIDES) if side != "c"}
    own = rig_poses(motion.positions[keep], C[keep], motion.rig.parents.tolist(),
                    int(index[_J["root"]]), side_of, normalised=canonical)
    return canonical, own, str(motion.source_sha256 or "")


def _read_task(path: str, asf, rig: bool, encode: bool, sha256: bool) -> tuple:
    """One document's motion for :func:`load_motion_poses` (in a worker process): (poses,
    SHA-256, None) or (None, None, the error's message)."""
    try:
        canonical, own, digest = _read_motion_poses(Path(path), asf, sha256)
    except MtannoError as exc:
        return None, None, str(exc) if exc.path else f"{path}: {exc}"
    out = own if rig else canonical
    return (out.encoded() if encode and rig else out), digest, None


def load_motion_poses(files: dict[str, Path], docs: Sequence[str], *,
                      asf: str | os.PathLike | None = None,
                      failures: list[str] | None = None, rig: bool = False,
                      encode: bool = False, digests: dict[str, str] | None = None,
                      jobs: int = 1, progress: Callable[[], None] | None = None) -> dict:
    """The normalised poses at the 30 Hz analysis frames of each document of ``docs`` that
    has a motion file in ``files`` (:func:`motion_files`), as ``features --poses`` computes
    them (``asf``, else the ASF found beside or above an AMC file; skeleton map detected):
    (frames × 22 × 3) arrays, or with ``rig`` the rig's own joints and bones
    (:class:`PlayerPoses`, :func:`rig_poses`; with ``encode`` as :class:`EncodedPoses`, a
    few kilobytes each). ``digests`` (given) receives each file's SHA-256 (else none is
    computed). Files are read in
    ``jobs`` processes; ``progress()`` is called after each. A file that cannot be read is
    left out, its message appended to ``failures`` (an error without it)."""
    from mtanno.util.workers import make_pool

    todo = [d for d in docs if d in files]
    out = {}
    with make_pool(jobs=jobs, n_tasks=len(todo)) as pool:
        tasks = [(str(files[d]), None if asf is None else str(asf), rig, encode,
                  digests is not None) for d in todo]
        for d, (poses, digest, error) in zip(todo, pool.map(_read_task, tasks,
                                                             chunksize=8)):
            if progress is not None:
                progress()
            if error is not None:
                if failures is None:
                    raise MtannoError(error)
                failures.append(error)
                continue
            if digests is not None:
                digests[d] = digest
            out[d] = poses
    return out


def motion_mismatch(doc: str, motion_frames: int, *, recorded: int | None,
                    last_labelled: int, path: str | os.PathLike,
                    digest: str | None = None, features_source: str | None = None
                    ) -> str | None:
    """Why the motion of ``doc`` (``path``, ``motion_frames`` at 30 Hz) is not the one
    annotated, or None when nothing says so: the annotation ``recorded`` another frame
    count; without a recorded count, the motion ends before the last labelled frame; or its
    SHA-256 ``digest`` is not the ``features_source`` the document's feature file records
    (checked when both are known)."""
    where = f"{path}: "
    if recorded is not None and motion_frames != recorded:
        ratio = motion_frames / recorded if recorded else float("inf")
        how = ("shorter" if motion_frames < recorded else
               f"{ratio:.1f}× as long" if ratio >= 1.5 else "longer")
        return (f"{where}the motion has {motion_frames} frames at 30 Hz, the annotation of "
                f"{doc!r} {recorded} ({how}: another take, rig or frame rate?); not played")
    if recorded is None and motion_frames < last_labelled:
        return (f"{where}the motion has {motion_frames} frames at 30 Hz, the annotation of "
                f"{doc!r} labels frames up to {last_labelled}; not played")
    if digest and features_source and digest != features_source:
        return (f"{where}not the file the features of {doc!r} were computed from (another "
                "SHA-256); not played")
    return None
