"""A frame classifier as evidence (issue 35, part 3): does a classifier that looks at each
frame alone agree with a segment's label?

The templates and the verification (:mod:`mtanno.confidence.verify`) judge a segment as
a whole against the examples of its class; a motion of the class done in another style or
on another rig (a straight run against jogs in a circle) fits them worse than a foreign
motion that happens to resemble a class (raising a hand against grabbing high). A frame
classifier errs differently (issue 35: it labels Bandai's runs as jogs): the k nearest
training windows of a frame — the 40 boolean features of the frames within ±0.5 s
(:data:`FRAME_HALF`), Hamming distance, majority of :data:`FRAME_K` (the k-NN peer of
``scripts/baseline_knn.py``, issue 10) — with the background motions' frames as a class of
their own ("none"). The evidence ``classifier`` of a segment is its soft vote: over
:data:`FRAME_SAMPLES` of its frames, evenly spread, the share of their nearest training
windows whose label is the segment's (one of its member classes).

The training windows (every :data:`FRAME_STEP`-th frame of every training example, inside
the example, and of every background document) are the :class:`FrameBank`, written by
``mtanno tune`` beside the configuration (``CONFIG.frames.parquet``) so that annotate
never reads a training file. In tune's cross-validation the bank of a fold holds its
training examples and the background not held out in it, and a class left out of the
templates is left out of the votes too (:meth:`FrameBank.votes` ``exclude``): an unknown
motion meets a classifier that does not know it, as it will in an archive.

Frames are 0-based analysis frames (30 Hz) in every argument.
"""

from __future__ import annotations

import json
import os
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError

__all__ = ["BACKGROUND_LABEL", "FRAME_BANK_FORMAT", "FRAME_HALF", "FRAME_K", "FRAME_SAMPLES",
           "FRAME_STEP", "FrameBank", "build_frame_bank", "pack_windows", "read_frame_bank",
           "sample_frames", "write_frame_bank"]

#: Half window of a frame's description, frames at 30 Hz (±0.5 s).
FRAME_HALF = 15
#: Neighbours that vote.
FRAME_K = 5
#: Frames of a segment that are classified (evenly spread; all of a shorter segment).
FRAME_SAMPLES = 12
#: Every how many frames of a training example or background document a window is kept.
FRAME_STEP = 2
#: The label of background windows.
BACKGROUND_LABEL = ""
#: The ``format`` of a frame bank file's metadata.
FRAME_BANK_FORMAT = "mtanno-frame-bank"


def _words(n_features: int, half: int = FRAME_HALF) -> int:
    return (n_features * (2 * half + 1) + 63) // 64


def pack_windows(X: np.ndarray, frames: np.ndarray | None = None) -> np.ndarray:
    """(len(frames) × words) uint64: the bit-packed ±:data:`FRAME_HALF` window of each of
    ``frames`` (0-based; default every frame) of the (features × frames) 0/1 matrix
    ``X`` (:mod:`mtanno.confidence._frame_kernels`)."""
    from mtanno.confidence._frame_kernels import _pack_at

    A = np.asarray(X)
    if A.ndim != 2 or A.shape[0] == 0 or A.shape[1] == 0:
        raise MtannoError(f"features must be a non-empty (features × frames) matrix, got "
                          f"shape {A.shape}")
    L = A.shape[1]
    t = np.arange(L, dtype=np.int64) if frames is None else np.asarray(frames, dtype=np.int64)
    if t.ndim != 1 or (t.size and (t.min() < 0 or t.max() >= L)):
        raise MtannoError(f"frames must be 0-based frames of the {L} frames")
    out = np.zeros((t.size, _words(A.shape[0])), dtype=np.uint64)
    _pack_at(np.ascontiguousarray(A != 0, dtype=np.uint8), t, FRAME_HALF, out)
    return out


def sample_frames(start: int, end: int, n: int = FRAME_SAMPLES) -> np.ndarray:
    """``n`` frames of ``start`` … ``end`` (inclusive) spread evenly, both ends included
    (every frame of a segment of at most ``n`` frames)."""
    if end < start:
        raise MtannoError(f"a segment ends ({end}) before it starts ({start})")
    if end - start + 1 <= n:
        return np.arange(start, end + 1, dtype=np.int64)
    return np.unique(np.round(np.linspace(start, end, n)).astype(np.int64))


@dataclass
class FrameBank:
    """Training windows of the frame classifier (module docstring): ``windows`` (n ×
    words uint64), each one's label (an index into ``names``; :data:`BACKGROUND_LABEL`
    names the background), and the number of features per frame."""

    windows: np.ndarray
    labels: np.ndarray
    names: list[str]
    n_features: int
    path: str | None = None

    def votes(self, X: np.ndarray, frames: np.ndarray, *,
              exclude: Collection[str] = ()) -> list[str | None]:
        """The classifier's label of each of ``frames`` of the document ``X`` (its k
        nearest training windows' majority; the background's label
        :data:`BACKGROUND_LABEL`), training windows of the classes ``exclude`` left
        out; None where no training window is left."""
        from mtanno.confidence._frame_kernels import _vote

        self._check(X)
        queries = pack_windows(X, frames)
        allowed = np.array([n not in exclude for n in self.names], dtype=np.bool_)
        out = np.empty(queries.shape[0], dtype=np.int64)
        _vote(queries, self.windows, self.labels.astype(np.int64), allowed, FRAME_K,
              len(self.names), out)
        return [self.names[v] if v >= 0 else None for v in out.tolist()]

    def agreement(self, X: np.ndarray, start: int, end: int, members: Collection[str], *,
                  exclude: Collection[str] = ()) -> float:
        """The share of the nearest training windows of the segment ``start`` … ``end``'s
        sampled frames (:func:`sample_frames`; :data:`FRAME_K` each, those of the classes
        ``exclude`` left out) whose label is one of ``members``: the classifier's soft
        vote for the segment's label."""
        from mtanno.confidence._frame_kernels import _neighbours

        self._check(X)
        queries = pack_windows(X, sample_frames(start, end))
        allowed = np.array([n not in exclude for n in self.names], dtype=np.bool_)
        near = np.empty((queries.shape[0], FRAME_K), dtype=np.int64)
        _neighbours(queries, self.windows, self.labels.astype(np.int64), allowed, FRAME_K,
                    near)
        hit = np.array([n in members for n in self.names] + [False])
        return float(hit[near].mean())  # −1 (no neighbour) indexes the False at the end

    def _check(self, X) -> None:
        if np.asarray(X).shape[0] != self.n_features:
            raise MtannoError(f"the frame bank has {self.n_features} features per frame, the "
                              f"document {np.asarray(X).shape[0]}", path=self.path)

    def metadata(self) -> dict:
        return {"format": FRAME_BANK_FORMAT, "version": 1, "half": FRAME_HALF, "k": FRAME_K,
                "step": FRAME_STEP, "features": self.n_features, "names": self.names}


def build_frame_bank(examples: Sequence[tuple[str, np.ndarray]],
                     background: Sequence[np.ndarray] = ()) -> FrameBank:
    """The :class:`FrameBank` of training ``examples`` ((class, features × frames) each)
    and ``background`` documents (features × frames): the window of every
    :data:`FRAME_STEP`-th frame of each, taken inside it."""
    parts = [(c, np.asarray(X)) for c, X in examples] + \
        [(BACKGROUND_LABEL, np.asarray(X)) for X in background]
    parts = [(c, X) for c, X in parts if X.ndim == 2 and X.shape[1] > 0]
    if not parts:
        raise MtannoError("no training frames for the frame classifier")
    dims = {X.shape[0] for _, X in parts}
    if len(dims) != 1:
        raise MtannoError(f"the training frames have different numbers of features: "
                          f"{sorted(dims)}")
    names = sorted({c for c, _ in parts})
    index = {c: i for i, c in enumerate(names)}
    windows, labels = [], []
    for c, X in parts:
        w = pack_windows(X, np.arange(0, X.shape[1], FRAME_STEP))
        windows.append(w)
        labels.append(np.full(w.shape[0], index[c], dtype=np.int16))
    return FrameBank(np.ascontiguousarray(np.concatenate(windows)), np.concatenate(labels),
                     names, dims.pop())


def write_frame_bank(path: str | os.PathLike, bank: FrameBank) -> None:
    """Write a frame bank as Parquet (columns ``w0 …`` uint64, one row per training
    window, and ``label`` int16; the metadata key ``mtanno`` holds
    :meth:`FrameBank.metadata`), atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from mtanno.util.output import atomic_path

    cols = {f"w{d}": pa.array(bank.windows[:, d]) for d in range(bank.windows.shape[1])}
    cols["label"] = pa.array(bank.labels.astype(np.int16))
    table = pa.table(cols).replace_schema_metadata(
        {"mtanno": json.dumps(bank.metadata(), ensure_ascii=False)})
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)


def read_frame_bank(path: str | os.PathLike) -> FrameBank:
    """Read a frame bank written by :func:`write_frame_bank`; anything else is an
    :class:`MtannoError` naming the file."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    spath = str(path)
    if not Path(path).is_file():
        raise MtannoError("frame bank not found", path=spath)
    try:
        table = pq.read_table(path)
        meta = json.loads((table.schema.metadata or {}).get(b"mtanno", b"null"))
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise MtannoError(f"not a readable frame bank: {exc}", path=spath) from None
    if not isinstance(meta, dict) or meta.get("format") != FRAME_BANK_FORMAT:
        raise MtannoError("not a frame bank (no mtanno frame bank metadata)", path=spath)
    if (meta.get("version"), meta.get("half"), meta.get("k"), meta.get("step")) != (
            1, FRAME_HALF, FRAME_K, FRAME_STEP):
        raise MtannoError("frame bank of another version or window; run mtanno tune again",
                          path=spath)
    try:
        names = [str(x) for x in meta["names"]]
        n_features = int(meta["features"])
        words = _words(n_features)
        windows = np.column_stack([table.column(f"w{d}").to_numpy().astype(np.uint64)
                                   for d in range(words)])
        labels = table.column("label").to_numpy().astype(np.int16)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise MtannoError(f"frame bank is malformed ({exc})", path=spath) from None
    if table.num_columns != words + 1 or not names or labels.size == 0 \
            or labels.min() < 0 or labels.max() >= len(names):
        raise MtannoError("frame bank is inconsistent (windows, labels and names do not "
                          "agree)", path=spath)
    return FrameBank(np.ascontiguousarray(windows), labels, names, n_features, path=spath)
