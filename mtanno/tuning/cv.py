"""Cross-validation data of ``mtanno tune``: folds of the training examples, held-out
documents with their truth, the templates learned without each fold, and the distance
functions of those templates on the held-out documents.

Folds leave one *performer* out (a manifest's ``actor`` column, a truth segment's
document: :attr:`mtanno.templates.training.ExampleSource.performer`); with fewer than two
performers the examples are split into :data:`FALLBACK_FOLDS` seeded folds. Held-out
documents are built from the held-out examples only:

* ``composed`` (clips): the held-out clips' feature matrices are concatenated, in
  :data:`REPEATS` seeded random orders, into documents of at most :data:`CLIPS_PER_DOC`
  clips, with their exact truth — the feature-level counterpart of ``mtanno compose``
  (which needs the motion files; features at the seams then differ slightly from a
  recomposed motion's, about 1.6 % of the bits);
* ``separate`` (clips): every held-out clip is a document of its own;
* examples cut from annotated documents (``--truth``): the held-out performer's documents
  themselves, with every truth segment they hold.

Issue 34 (training sets of real size): learning a template aligns every pair of its
examples in every iteration ([MR06] §4.1, the reference's "strategy 5"), so its cost grows
with the square of the examples; each template ``tune`` learns in a fold (and each of the
final group templates) is learned from at most ``max_examples`` of the class's examples
(:func:`learning_subset`: a seeded draw spread evenly over the performers), which bounds
the learning whatever the size of the training set.

Nothing outside the training examples is read: the documents are made of their feature
matrices, and a document's truth is the training truth. Background documents (``tune
--background``, issue 26) are spread over the folds in turn (the k-th to fold k mod the
number of folds) and appended to the fold's held-out documents without truth: every label
there is wrong.
"""

from __future__ import annotations

import hashlib
import random
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from mtanno.errors import MtannoError
from mtanno.templates.training import TrainingExample

__all__ = ["CLIPS_PER_DOC", "DOCUMENT_MODES", "FALLBACK_FOLDS", "MAX_EXAMPLES", "REPEATS",
           "Fold", "HeldOut", "learning_subset", "make_folds"]

#: How held-out clips become documents.
DOCUMENT_MODES = ("composed", "separate")
#: Clips per composed held-out document.
CLIPS_PER_DOC = 20
#: Seeded orders in which the held-out clips are composed (each clip appears once per order).
REPEATS = 2
#: Folds when the examples name fewer than two performers.
FALLBACK_FOLDS = 3
#: Examples a template of ``tune`` is learned from at most (per class and fold; ``tune
#: --max-examples``): the learning's cost grows with their square (module docstring).
#: Measured on the Bandai leave-one-style-out folds (docs/benchmarks.md, "Training sets
#: and archives of lab size"): 24 annotates the held-out styles as well as 48 (mean frame F1
#: 0.641 against 0.628, the folds scattering ±0.2 either way) and tunes 600 clips in 75 s
#: instead of 277 s.
MAX_EXAMPLES = 24


@dataclass
class HeldOut:
    """The held-out documents of a fold, concatenated: features (f × L), document
    boundaries ``offsets`` (n + 1 frame indices), document names, and the truth as
    (class, first, last) 0-based inclusive frames of the concatenation; ``poses`` (L × 22
    × 3, leg lengths) when every part has them, else None."""

    X: np.ndarray
    offsets: np.ndarray
    names: list[str]
    truth: list[tuple[str, int, int]]
    poses: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        return int(self.X.shape[1])

    def documents(self):
        """(name, features) of every held-out document."""
        for name, a, b in zip(self.names, self.offsets[:-1], self.offsets[1:]):
            yield name, self.X[:, a:b]


@dataclass
class Fold:
    """One cross-validation fold: its name (the held-out performer, or ``fold-k``), the
    training examples of the other folds, the held-out documents, and the indices of the
    background documents held out in it (the others may serve as its background)."""

    name: str
    train: list[TrainingExample]
    held_out: HeldOut
    held_examples: list[TrainingExample] = field(default_factory=list)
    background: list[int] = field(default_factory=list)


def _fold_keys(examples: Sequence[TrainingExample], seed: int) -> list[str]:
    performers = [ex.performer for ex in examples]
    if None not in performers and len(set(performers)) >= 2:
        return [str(p) for p in performers]
    # no performers: seeded folds that keep every class spread over all folds
    rng = random.Random(f"{seed}:folds")
    keys = [""] * len(examples)
    by_class: dict[str, list[int]] = {}
    for i, ex in enumerate(examples):
        by_class.setdefault(ex.class_name, []).append(i)
    for cls in sorted(by_class):
        idx = by_class[cls]
        rng.shuffle(idx)
        for j, i in enumerate(idx):
            keys[i] = f"fold-{j % FALLBACK_FOLDS + 1}"
    return keys


def _poses_of(examples: Sequence[TrainingExample], order: Sequence[int]):
    """The examples' poses concatenated in ``order`` (None unless every one has them)."""
    got = [examples[i].poses for i in order]
    if not got or any(p is None for p in got):
        return None
    return np.ascontiguousarray(np.concatenate(got), dtype=np.float32)


def _composed(examples: Sequence[TrainingExample], *, name: str, seed: int) -> HeldOut:
    rng = random.Random(f"{seed}:{name}")
    parts, offsets, names, truth, used = [], [0], [], [], []
    order_no = 0
    for _ in range(REPEATS):
        order = list(range(len(examples)))
        rng.shuffle(order)
        for d in range(0, len(order), CLIPS_PER_DOC):
            order_no += 1
            start = offsets[-1]
            for i in order[d:d + CLIPS_PER_DOC]:
                X = examples[i].X
                truth.append((examples[i].class_name, start, start + X.shape[1] - 1))
                parts.append(X)
                used.append(i)
                start += X.shape[1]
            offsets.append(start)
            names.append(f"{name}-doc{order_no:02d}")
    return HeldOut(np.ascontiguousarray(np.concatenate(parts, axis=1)),
                   np.array(offsets, np.int64), names, truth, _poses_of(examples, used))


def _separate(examples: Sequence[TrainingExample], *, name: str) -> HeldOut:
    parts, offsets, names, truth = [], [0], [], []
    for i, ex in enumerate(examples):
        start = offsets[-1]
        truth.append((ex.class_name, start, start + ex.X.shape[1] - 1))
        parts.append(ex.X)
        offsets.append(start + ex.X.shape[1])
        names.append(f"{name}-clip{i + 1:03d}")
    return HeldOut(np.ascontiguousarray(np.concatenate(parts, axis=1)),
                   np.array(offsets, np.int64), names, truth,
                   _poses_of(examples, range(len(examples))))


def _documents(examples: Sequence[TrainingExample], read_document) -> HeldOut:
    """The documents the held-out segments were cut from, whole, with all their segments."""
    by_file: dict[str, list[TrainingExample]] = {}
    for ex in examples:
        by_file.setdefault(ex.file, []).append(ex)
    parts, offsets, names, truth, poses = [], [0], [], [], []
    for file in sorted(by_file):
        X = read_document(file)
        P = None
        if isinstance(X, tuple):  # (features, poses or None)
            X, P = X
        poses.append(P)
        start = offsets[-1]
        for ex in by_file[file]:
            truth.append((ex.class_name, start + ex.start - 1, start + ex.end - 1))
        parts.append(X)
        offsets.append(start + X.shape[1])
        names.append(by_file[file][0].document)
    P = None if any(p is None for p in poses) else np.ascontiguousarray(
        np.concatenate(poses), dtype=np.float32)
    return HeldOut(np.ascontiguousarray(np.concatenate(parts, axis=1)),
                   np.array(offsets, np.int64), names, truth, P)


def _with_background(ho: HeldOut, background: Sequence, idx: Sequence[int]) -> HeldOut:
    """``ho`` with the background documents ``idx`` of ``background`` ((name, X, poses or
    None) each) appended, without truth."""
    if not idx:
        return ho
    parts, poses = [ho.X], [ho.poses]
    offsets, names = list(ho.offsets), list(ho.names)
    for k in idx:
        bname, X, P = background[k]
        parts.append(X)
        poses.append(P)
        offsets.append(offsets[-1] + X.shape[1])
        names.append(f"background:{bname}")
    P = None if any(p is None for p in poses) else np.ascontiguousarray(
        np.concatenate(poses), dtype=np.float32)
    return HeldOut(np.ascontiguousarray(np.concatenate(parts, axis=1)),
                   np.array(offsets, np.int64), names, list(ho.truth), P)


def learning_subset(examples: Sequence[TrainingExample], limit: int | None, *,
                    seed: int = 0) -> list[int]:
    """Indices, ascending, of at most ``limit`` of ``examples`` (all of them when there are
    no more, or ``limit`` is None or 0): the performers (:attr:`TrainingExample.performer`,
    else the document) take turns in the order they first appear, each giving its
    examples in a seeded order — a hash of the seed, the class and the example's content
    and frames, so that the draw is the same in every fold and wherever the files lie."""
    n = len(examples)
    if not limit or n <= limit:
        return list(range(n))
    if limit < 0:
        raise MtannoError(f"max examples must be ≥ 0 (0: all), got {limit!r}")

    def order(i: int) -> tuple[bytes, int]:
        e = examples[i]
        key = f"{seed}:{e.class_name}:{e.sha256}:{e.start}:{e.end}".encode()
        return hashlib.sha256(key).digest(), i

    queues: dict[str, list[int]] = {}
    for i, e in enumerate(examples):
        queues.setdefault(str(e.performer if e.performer is not None else e.document),
                          []).append(i)
    lists = [sorted(q, key=order) for q in queues.values()]
    picked: list[int] = []
    depth = 0
    while len(picked) < limit:
        for q in lists:
            if depth < len(q) and len(picked) < limit:
                picked.append(q[depth])
        depth += 1
    return sorted(picked)


def make_folds(examples: Sequence[TrainingExample], *, documents: str = "composed",
               seed: int = 0, read_document=None, background: Sequence = ()) -> list[Fold]:
    """The cross-validation folds of ``examples`` (module docstring).

    ``documents`` says how held-out clips become documents (:data:`DOCUMENT_MODES`).
    Examples cut from annotated documents (``--truth``) give the documents themselves
    instead: pass ``read_document(path) -> features`` (or ``(features, poses or None)``)
    to read the examples' own feature files whole. ``background``: (name, features, poses
    or None) of documents that hold no class, spread over the folds (module docstring).
    Folds come in
    the order of their names; a fold without training examples of a class leaves that
    class out of the fold's templates.
    """
    if documents not in DOCUMENT_MODES:
        raise MtannoError(f"unknown held-out document mode {documents!r} (choose from "
                          f"{', '.join(DOCUMENT_MODES)})")
    if not examples:
        raise MtannoError("no training examples to cross-validate")
    keys = _fold_keys(examples, seed)
    names = sorted(set(keys))
    if len(names) < 2:
        raise MtannoError("cross-validation needs examples of at least two performers "
                          "(or of several examples per class)")
    folds = []
    for j, name in enumerate(names):
        held = [ex for ex, k in zip(examples, keys) if k == name]
        train = [ex for ex, k in zip(examples, keys) if k != name]
        if read_document is not None:
            ho = _documents(held, read_document)
        elif documents == "separate":
            ho = _separate(held, name=name)
        else:
            ho = _composed(held, name=name, seed=seed)
        bg = [k for k in range(len(background)) if k % len(names) == j]
        folds.append(Fold(name, train, _with_background(ho, background, bg), held, bg))
    return folds

