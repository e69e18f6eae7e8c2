"""Verification of candidate segments against examples (issue 26, part 3): how closely a
segment's motion resembles the training examples of its class, the examples of the other
classes, and background motions that belong to no class.

The motion templates of [MR06] keep, per frame, only what the class's examples share, so
a long document of unknown motions offers every template a window that fits. The examples
themselves say more: a segment is compared with each example by subsequence DTW
(:mod:`mtanno.confidence._verify_kernels`; free start and end inside the example, cost per
segment frame) on one of two representations —

* ``poses``: the normalised poses that ``mtanno features --poses`` stores (root at the
  origin of the floor plane, heading along +x, leg lengths; [MRC05] §7's pose distance),
  joints :data:`POSE_JOINTS`, local cost the mean coordinate difference (leg lengths);
* ``features``: the 40 boolean relational features, local cost the Hamming distance over
  the number of features —

at :data:`VERIFY_FPS` (every :data:`VERIFY_STEP`-th analysis frame), a long segment
sampled evenly to at most :data:`MAX_QUERY` rows.

Invariances (issue 35; :data:`INVARIANCES`, ``tune --invariance``, recorded in the bank so
that annotate verifies as tune did) make the pose comparison blind to what is not motion:

* ``retarget`` — every pose is moved onto one canonical skeleton before the comparison
  (:func:`retarget_poses`: each bone keeps its direction and takes the length of
  :data:`CANONICAL_BONES`), so that rigs whose joints sit elsewhere on the body (a head
  joint at the chin or at the crown, narrow or wide shoulders and hips) compare by how
  the body moves, not by where their joints were placed;
* ``mirror`` — a segment is also compared mirrored (left and right swapped,
  :func:`mirror_rows`), the smaller cost counting: a right kick verifies as a kick.

A :class:`Bank` holds the sequences of every training example (class, performer) and of
the background documents, and per class the typical distance of one of its examples to
those of the other performers (:attr:`Bank.scale`: leave one performer out), so that
distances compare across classes.

Frames are 0-based analysis frames (30 Hz) in every argument.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from mtanno.errors import JSONError, MtannoError, parse_json, read_input

__all__ = ["BANK_FORMAT", "CANONICAL_BONES", "INVARIANCES", "MAX_QUERY", "POSE_JOINTS",
           "REPRESENTATIONS", "VERIFY_FPS", "VERIFY_STEP", "Bank", "build_bank",
           "check_invariance", "mirror_rows", "read_bank", "retarget_poses", "sequence",
           "subsequence_costs", "write_bank"]

#: Analysis frames per verification frame (30 Hz → 5 Hz).
VERIFY_STEP = 6
#: Rate of the verification sequences (frames per second).
VERIFY_FPS = 30.0 / VERIFY_STEP
#: Longest query, in verification frames (a longer segment is sampled evenly).
MAX_QUERY = 20
#: The joints compared in the pose representation (a subset of the 22 canonical joints:
#: the body's extremities and middle, enough to tell motions apart at half the cost).
POSE_JOINTS = ("root", "lknee", "rknee", "lankle", "rankle", "chest", "head", "lelbow",
               "relbow", "lwrist", "rwrist")
#: Representations a bank can hold.
REPRESENTATIONS = ("poses", "features")
#: The ``format`` of a bank file's metadata.
BANK_FORMAT = "mtanno-verification-bank"
#: What the pose comparison can be made blind to (module docstring; poses only).
INVARIANCES = ("retarget", "mirror")
#: The canonical skeleton of ``retarget``: joint → (parent, bone length in leg lengths),
#: parents before children. Lengths: about the middle of the HDM05 (ASF), CMU (ASF) and
#: Bandai (BVH) rigs as the pose normalisation measures them (thigh + shin = 1 leg length
#: by that normalisation's definition).
CANONICAL_BONES: dict[str, tuple[str, float]] = {
    "lhip": ("root", 0.12), "rhip": ("root", 0.12),
    "lknee": ("lhip", 0.5), "rknee": ("rhip", 0.5),
    "lankle": ("lknee", 0.5), "rankle": ("rknee", 0.5),
    "ltoes": ("lankle", 0.2), "rtoes": ("rankle", 0.2),
    "belly": ("root", 0.16), "chest": ("belly", 0.14), "neck": ("chest", 0.17),
    "head": ("neck", 0.15), "headtop": ("head", 0.1),
    "lshoulder": ("chest", 0.27), "rshoulder": ("chest", 0.27),
    "lelbow": ("lshoulder", 0.32), "relbow": ("rshoulder", 0.32),
    "lwrist": ("lelbow", 0.31), "rwrist": ("relbow", 0.31),
    "lfingers": ("lwrist", 0.1), "rfingers": ("rwrist", 0.1),
}


def _pose_index() -> np.ndarray:
    from mtanno.io.rigs import CANONICAL_JOINTS

    return np.array([CANONICAL_JOINTS.index(j) for j in POSE_JOINTS], dtype=np.int64)


def check_invariance(invariance, representation: str | None = "poses") -> tuple[str, ...]:
    """The invariances ``invariance`` (names of :data:`INVARIANCES`) checked, in that
    order; they need the pose representation."""
    names = tuple(invariance or ())
    unknown = [n for n in names if n not in INVARIANCES]
    if unknown:
        raise MtannoError(f"unknown invariance {unknown[0]!r} (choose from "
                          f"{', '.join(INVARIANCES)})")
    if names and representation != "poses":
        raise MtannoError(f"the invariances {', '.join(names)} need verification by poses "
                          f"(this bank verifies by {representation or 'nothing'})")
    return tuple(n for n in INVARIANCES if n in names)


def retarget_poses(poses: np.ndarray) -> np.ndarray:
    """Poses (frames × 22 × 3, canonical joints) moved onto the canonical skeleton
    :data:`CANONICAL_BONES`: from the root (kept), every joint is placed at its parent's
    new position plus the bone's canonical length along the bone's direction in the
    pose (a bone of no length keeps no length). Float64, the input's shape."""
    from mtanno.io.rigs import CANONICAL_JOINTS

    P = np.asarray(poses, dtype=np.float64)
    if P.ndim != 3 or P.shape[1:] != (len(CANONICAL_JOINTS), 3):
        raise MtannoError(f"poses must be (frames × {len(CANONICAL_JOINTS)} × 3), got {P.shape}")
    j = {n: i for i, n in enumerate(CANONICAL_JOINTS)}
    out = P.copy()
    for child, (parent, length) in CANONICAL_BONES.items():
        bone = P[:, j[child]] - P[:, j[parent]]
        norm = np.linalg.norm(bone, axis=1, keepdims=True)
        unit = np.divide(bone, norm, out=np.zeros_like(bone), where=norm > 1e-9)
        out[:, j[child]] = out[:, j[parent]] + length * unit
    return out


#: Column pairs of :data:`POSE_JOINTS` swapped by :func:`mirror_rows` (left ↔ right).
_MIRROR = [POSE_JOINTS.index(("r" + n[1:]) if n[0] == "l" else ("l" + n[1:]))
           if n[0] in "lr" and n not in ("root",) else k for k, n in enumerate(POSE_JOINTS)]


def mirror_rows(rows: np.ndarray) -> np.ndarray:
    """Pose rows of a verification sequence (rows × 3·:data:`POSE_JOINTS`) mirrored in
    the body's sagittal plane: left and right joints swapped and x (the body's left-to-
    right axis of the normalised poses) negated — again a normalised pose."""
    R = np.asarray(rows, dtype=np.float32)
    if R.ndim != 2 or R.shape[1] != 3 * len(POSE_JOINTS):
        raise MtannoError(f"pose rows must be (rows × {3 * len(POSE_JOINTS)}), got {R.shape}")
    out = R.reshape(len(R), len(POSE_JOINTS), 3)[:, _MIRROR].copy()
    out[:, :, 0] *= -1
    return np.ascontiguousarray(out.reshape(len(R), -1))


def sequence(*, X: np.ndarray | None = None, poses: np.ndarray | None = None,
             representation: str, invariance: tuple[str, ...] = ()) -> np.ndarray:
    """The verification sequence of a stretch of motion: (rows × dims) float32 at
    :data:`VERIFY_FPS`. ``X``: (features × frames) 0/1 features; ``poses``: (frames × 22 ×
    3) normalised poses (leg lengths); the one ``representation`` names is used.
    ``invariance``: with ``"retarget"`` the poses are moved onto the canonical skeleton
    first (:func:`retarget_poses`; ``"mirror"`` acts in :meth:`Bank.nearest`)."""
    if representation == "poses":
        if poses is None:
            raise MtannoError("the pose representation needs poses (mtanno features --poses)")
        P = np.asarray(poses)
        if P.ndim != 3 or P.shape[2] != 3:
            raise MtannoError(f"poses must be (frames × joints × 3), got {P.shape}")
        P = P[::VERIFY_STEP]
        if "retarget" in invariance:
            P = retarget_poses(P)
        rows = P[:, _pose_index()].reshape(-1, 3 * len(POSE_JOINTS))
    elif representation == "features":
        if X is None:
            raise MtannoError("the feature representation needs the feature matrix")
        rows = np.asarray(X)[:, ::VERIFY_STEP].T
    else:
        raise MtannoError(f"unknown representation {representation!r} (choose from "
                          f"{', '.join(REPRESENTATIONS)})")
    return np.ascontiguousarray(rows, dtype=np.float32)


def _query(seq: np.ndarray) -> np.ndarray:
    """``seq`` sampled evenly to at most :data:`MAX_QUERY` rows (and at least one)."""
    n = seq.shape[0]
    if n <= MAX_QUERY:
        return seq
    idx = np.round(np.linspace(0, n - 1, MAX_QUERY)).astype(np.int64)
    return np.ascontiguousarray(seq[idx])


def subsequence_costs(query: np.ndarray, items: np.ndarray, offsets: np.ndarray
                      ) -> np.ndarray:
    """Subsequence DTW cost of ``query`` (rows × dims) inside each item of ``items``
    (rows ``offsets[k]:offsets[k+1]``): (items,) costs per query row, the local cost the
    mean absolute difference of two rows (∞ for an empty item;
    :mod:`mtanno.confidence._verify_kernels`)."""
    from mtanno.confidence._verify_kernels import _subsequence_costs

    Q = np.ascontiguousarray(query, dtype=np.float32)
    B = np.ascontiguousarray(items, dtype=np.float32)
    off = np.ascontiguousarray(offsets, dtype=np.int64)
    if Q.ndim != 2 or B.ndim != 2 or Q.shape[1] != B.shape[1]:
        raise MtannoError(f"query and items must be (rows × dims) with the same dims, got "
                          f"{Q.shape} and {B.shape}")
    if Q.shape[0] == 0:
        raise MtannoError("the query has no rows")
    if Q.shape[1] == 0:
        raise MtannoError("the query has no dims")
    if off.ndim != 1 or off.size < 1 or off[0] != 0 or off[-1] != B.shape[0] \
            or np.any(np.diff(off) < 0):
        raise MtannoError("offsets must rise from 0 to the number of item rows")
    if not (np.all(np.isfinite(Q)) and np.all(np.isfinite(B))):
        raise MtannoError("query and items must be finite")
    out = np.empty(off.size - 1)
    _subsequence_costs(Q, B, off, out)
    out[np.diff(off) == 0] = np.inf
    return out


@dataclass
class Bank:
    """Verification sequences (module docstring): items (rows × dims float32, one after
    another, ``offsets``), each item's class (``""`` for background) and performer, and
    per class the leave-one-performer-out scale (the median, over its examples, of the
    cost of an example inside the class's examples of other performers)."""

    representation: str
    items: np.ndarray
    offsets: np.ndarray
    labels: list[str]
    performers: list[str]
    scale: dict[str, float] = field(default_factory=dict)
    path: str | None = None
    #: what the comparison is blind to (:data:`INVARIANCES`): the bank's sequences were
    #: made so, and every query must be (:func:`sequence`)
    invariance: tuple[str, ...] = ()
    #: what :meth:`_checked` found once (None: not yet)
    _facts: tuple | None = field(default=None, repr=False, compare=False)

    @property
    def classes(self) -> list[str]:
        return sorted({c for c in self.labels if c})

    @property
    def has_background(self) -> bool:
        return "" in self.labels

    def costs(self, query: np.ndarray) -> np.ndarray:
        """Cost of a query sequence inside every item (:func:`subsequence_costs`); with
        the ``mirror`` invariance the smaller of the query's and its mirror's. The bank's
        own arrays are checked once, not with every query (a segment of a short clip cost
        as much in checks as in matching)."""
        q = _query(query)
        c = self._costs(q)
        if "mirror" in self.invariance:
            c = np.minimum(c, self._costs(mirror_rows(q)))
        return c

    def _costs(self, query: np.ndarray) -> np.ndarray:
        from mtanno.confidence._verify_kernels import _subsequence_costs

        Q = np.ascontiguousarray(query, dtype=np.float32)
        if not self._checked():
            return subsequence_costs(Q, self.items, self.offsets)
        if Q.ndim != 2 or Q.shape[0] == 0 or Q.shape[1] != self.items.shape[1] \
                or not np.all(np.isfinite(Q)):
            return subsequence_costs(Q, self.items, self.offsets)  # says what is wrong
        out = np.empty(self.offsets.size - 1)
        _subsequence_costs(Q, self.items, self.offsets, out)
        out[self._empty] = np.inf
        return out

    def _checked(self) -> bool:
        """Whether the items and offsets are what :func:`subsequence_costs` checks
        (contiguous float32, finite; int64 offsets rising from 0 to the rows), checked
        once; with it, the empty items and the label of every item by number."""
        if self._facts is None:
            items, off = self.items, self.offsets
            ok = (isinstance(items, np.ndarray) and items.dtype == np.float32
                  and items.ndim == 2 and items.flags.c_contiguous
                  and isinstance(off, np.ndarray) and off.dtype == np.int64
                  and off.ndim == 1 and off.flags.c_contiguous and off.size >= 1
                  and off[0] == 0 and off[-1] == items.shape[0]
                  and not np.any(np.diff(off) < 0) and bool(np.all(np.isfinite(items))))
            names = list(dict.fromkeys(self.labels))
            codes = np.array([names.index(lab) for lab in self.labels], dtype=np.int64)
            empty = np.diff(off) == 0 if ok else None
            self._facts = (ok, empty, names, codes)
        return self._facts[0]

    @property
    def _empty(self) -> np.ndarray:
        return self._facts[1]

    def nearest(self, query: np.ndarray) -> dict[str, float]:
        """Per class (and ``""`` for background) the smallest cost of ``query`` inside its
        items (a class whose items all cost ∞ is left out)."""
        c = self.costs(query)
        self._checked()
        _, _, names, codes = self._facts
        best = np.full(len(names), np.inf)
        np.minimum.at(best, codes, c)
        return {lab: v for lab, v in zip(names, best.tolist()) if v < np.inf}

    def metadata(self) -> dict:
        return {"format": BANK_FORMAT, "version": 1, "representation": self.representation,
                "step": VERIFY_STEP, "fps": VERIFY_FPS,
                "joints": list(POSE_JOINTS) if self.representation == "poses" else None,
                "labels": self.labels, "performers": self.performers,
                "offsets": [int(x) for x in self.offsets], "scale": self.scale,
                "invariance": list(self.invariance)}


def build_bank(examples: Sequence[tuple[str, str, np.ndarray]],
               background: Sequence[np.ndarray] = (), *, representation: str,
               invariance: Sequence[str] = ()) -> Bank:
    """A :class:`Bank` of ``examples`` ((class, performer, sequence) each; sequences of
    :func:`sequence`, made with ``invariance``) and ``background`` sequences; computes
    each class's scale (under the same invariance)."""
    if representation not in REPRESENTATIONS:
        raise MtannoError(f"unknown representation {representation!r}")
    invariance = check_invariance(invariance, representation)
    seqs = [s for _, _, s in examples] + list(background)
    seqs = [s for s in seqs if s.shape[0] > 0]
    labels = [c for c, _, s in examples if s.shape[0] > 0] + [""] * sum(
        1 for s in background if s.shape[0] > 0)
    performers = [str(p) for _, p, s in examples if s.shape[0] > 0] + [""] * (
        len(labels) - sum(1 for _, _, s in examples if s.shape[0] > 0))
    if not seqs:
        raise MtannoError("no example to verify against")
    dims = {s.shape[1] for s in seqs}
    if len(dims) != 1:
        raise MtannoError(f"the sequences have different dims: {sorted(dims)}")
    offsets = np.concatenate([[0], np.cumsum([s.shape[0] for s in seqs])]).astype(np.int64)
    bank = Bank(representation, np.ascontiguousarray(np.concatenate(seqs), dtype=np.float32),
                offsets, labels, performers, invariance=invariance)
    bank.scale = _scales(bank)
    return bank


def _scales(bank: Bank) -> dict[str, float]:
    """Per class: the median over its examples of the cost of the example inside the
    class's examples of other performers (of the other examples when it has one
    performer); 1.0 for a class with a single example."""
    out = {}
    for c in bank.classes:
        idx = [k for k, lab in enumerate(bank.labels) if lab == c]
        vals = []
        for k in idx:
            others = [j for j in idx if bank.performers[j] != bank.performers[k]] or \
                     [j for j in idx if j != k]
            if not others:
                continue
            q = bank.items[bank.offsets[k]:bank.offsets[k + 1]]
            items, offs = _gather(bank, others)
            cost = subsequence_costs(_query(q), items, offs).min()
            if "mirror" in bank.invariance:
                cost = min(cost, subsequence_costs(mirror_rows(_query(q)), items, offs).min())
            vals.append(float(cost))
        v = float(np.median(vals)) if vals else 1.0
        out[c] = v if v > 0 else 1.0
    return out


def _gather(bank: Bank, idx: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    parts = [bank.items[bank.offsets[k]:bank.offsets[k + 1]] for k in idx]
    offs = np.concatenate([[0], np.cumsum([p.shape[0] for p in parts])]).astype(np.int64)
    return np.ascontiguousarray(np.concatenate(parts)), offs


def write_bank(path: str | os.PathLike, bank: Bank) -> None:
    """Write a bank as Parquet (columns ``v0 …`` float32, one row per item row; the
    metadata key ``mtanno`` holds :meth:`Bank.metadata`), atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from mtanno.util.output import atomic_path

    cols = {f"v{d}": pa.array(bank.items[:, d]) for d in range(bank.items.shape[1])}
    table = pa.table(cols).replace_schema_metadata(
        {"mtanno": json.dumps(bank.metadata(), ensure_ascii=False)})
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)


def read_bank(path: str | os.PathLike) -> Bank:
    """Read a bank written by :func:`write_bank`; anything else is an
    :class:`MtannoError` naming the file."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    spath = str(path)
    data = read_input(path, what="verification bank")  # a regular file, never a FIFO
    try:
        table = pq.ParquetFile(pa.BufferReader(data), pre_buffer=False).read(use_threads=False)
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise MtannoError(f"not a readable verification bank: {exc}", path=spath) from None
    try:  # the one bounded JSON reader: depth, size, encoding checked (mtanno.errors)
        meta = parse_json((table.schema.metadata or {}).get(b"mtanno", b"null"), path=spath)
    except JSONError as exc:
        raise MtannoError(f"verification bank metadata is malformed ({exc.message})",
                          path=spath) from None
    if not isinstance(meta, dict) or meta.get("format") != BANK_FORMAT:
        raise MtannoError("not a verification bank (no mtanno bank metadata)", path=spath)
    if meta.get("version") != 1 or meta.get("step") != VERIFY_STEP:
        raise MtannoError(f"verification bank of another version or rate (step "
                          f"{meta.get('step')!r}, this mtanno verifies every {VERIFY_STEP}th "
                          f"frame); run mtanno tune again", path=spath)
    try:
        rep = meta["representation"]
        labels = [str(x) for x in meta["labels"]]
        performers = [str(x) for x in meta["performers"]]
        offsets = np.array(meta["offsets"], dtype=np.int64)
        scale = {str(k): float(v) for k, v in meta["scale"].items()}
        invariance = check_invariance(meta.get("invariance") or (), rep)
        items = np.column_stack([table.column(f"v{d}").to_numpy().astype(np.float32)
                                 for d in range(table.num_columns)]) if table.num_columns \
            else np.zeros((0, 0), np.float32)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise MtannoError(f"verification bank metadata is malformed ({exc})",
                          path=spath) from None
    except MtannoError as exc:
        raise MtannoError(f"verification bank metadata: {exc.message}", path=spath) from None
    if rep not in REPRESENTATIONS or len(labels) != len(performers) \
            or offsets.size != len(labels) + 1 or offsets[0] != 0 \
            or offsets[-1] != items.shape[0] or np.any(np.diff(offsets) <= 0) \
            or (rep == "poses" and items.shape[1] != 3 * len(POSE_JOINTS)) \
            or not np.all(np.isfinite(items)) \
            or not all(v > 0 and np.isfinite(v) for v in scale.values()):
        raise MtannoError("verification bank is inconsistent (items, offsets, labels or "
                          "scales do not agree)", path=spath)
    return Bank(rep, np.ascontiguousarray(items), offsets, labels, performers, scale,
                path=spath, invariance=invariance)
