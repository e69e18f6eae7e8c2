"""Frame-wise annotation of documents with motion classes (MBS09 §4–5, algorithms.md §7).

For every class template the matching distance Δ_p (algorithms.md §3.4) is computed over
the document, optionally only inside candidate windows (from a keyframe stage), turned into
the *modified distance* Δ̄_p that spreads each match's cost over the frames it covers, and
the label of a frame is the class with the smallest Δ̄ there. Maximal runs of one label are
then extended while Δ̄ keeps falling towards them, which gives the output segments (they may
overlap segments of other labels).

Frames are 0-based inside this module and 1-based inclusive in the tables it writes.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numba
import numpy as np

from mtanno.errors import MtannoError, read_input

if TYPE_CHECKING:
    from mtanno.store import FeatureLayout

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: Annotation threshold τ of MBS09 (used for every class without its own τ).
DEFAULT_TAU = 0.13
#: Quantization δ of the templates for annotation (MBS09).
DEFAULT_DELTA = 0.05


@dataclass
class ClassConfig:
    """Per-class thresholds and superclasses (a TOML file, see ``docs/annotation.md``).

    ``tau`` maps class (or superclass) names to τ; ``superclasses`` maps a superclass
    name to the classes it joins (its Δ̄ is the frame-wise minimum over them).
    """

    default_tau: float = DEFAULT_TAU
    tau: dict[str, float] = field(default_factory=dict)
    superclasses: dict[str, list[str]] = field(default_factory=dict)
    path: str | None = None

    def tau_for(self, name: str) -> float:
        return self.tau.get(name, self.default_tau)

    def check(self, classes: Sequence[str]) -> None:
        """Refuse what would be silently ignored or give nonsense: a τ that is not a
        number ≥ 0 (NaN labels nothing), and names in ``[tau]`` or ``[superclasses]`` that
        are none of ``classes`` (the templates' classes) or of the superclasses."""
        for name, value in [("default", self.default_tau), *self.tau.items()]:
            check_tau(value, what=f"tau of {name}" if name != "default" else "tau",
                      path=self.path)
        known = set(classes)
        labels = known | set(self.superclasses)
        for sup, members in self.superclasses.items():
            unknown = [m for m in members if m not in known]
            if unknown:
                raise MtannoError(f"superclass {sup!r} names class(es) without a template: "
                                  f"{', '.join(unknown)} (classes: {', '.join(sorted(known))})",
                                  path=self.path)
        unknown = sorted(n for n in self.tau if n not in labels)
        if unknown:
            raise MtannoError(f"[tau] names unknown class(es) {', '.join(unknown)} (classes "
                              f"and superclasses: {', '.join(sorted(labels))})", path=self.path)


def check_tau(tau, *, what: str = "tau", path: str | None = None) -> float:
    """τ as a float; NaN, a negative value or a non-number is an :class:`MtannoError`
    (∞ is allowed: every match counts)."""
    try:
        value = float(tau)
    except (TypeError, ValueError):
        raise MtannoError(f"{what} must be a number ≥ 0, got {tau!r}", path=path) from None
    if not value >= 0:
        raise MtannoError(f"{what} must be a number ≥ 0, got {tau!r}", path=path)
    return value


def load_class_config(path: str | os.PathLike) -> ClassConfig:
    """Read a class configuration::

        [tau]
        default = 0.13
        lieDownFloor = 0.06

        [superclasses]
        kick = ["kickLFront1Reps", "kickRFront1Reps"]
    """
    spath = str(path)
    try:
        data = tomllib.loads(read_input(path, what="class configuration").decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise MtannoError(f"not a valid TOML class configuration: {exc}", path=spath) from None
    cfg = ClassConfig(path=spath)
    taus = data.get("tau", {})
    if not isinstance(taus, dict):
        raise MtannoError("[tau] must be a table of class = number", path=spath)
    taus = dict(taus)
    cfg.default_tau = check_tau(taus.pop("default", DEFAULT_TAU), what="[tau] default",
                                path=spath)
    cfg.tau = {str(k): check_tau(v, what=f"[tau] {k}", path=spath) for k, v in taus.items()}
    sup = data.get("superclasses", {})
    if not isinstance(sup, dict) or not all(isinstance(v, list) and v for v in sup.values()):
        raise MtannoError("[superclasses] must map names to non-empty lists of classes",
                          path=spath)
    cfg.superclasses = {str(k): [str(c) for c in v] for k, v in sup.items()}
    unknown = sorted(set(data) - {"tau", "superclasses"})
    if unknown:
        raise MtannoError(f"unknown section(s) {', '.join(unknown)} (known: tau, superclasses)",
                          path=spath)
    return cfg


@numba.njit(cache=True)
def _fill_from_minima(delta, start, order, tau, max_hits, dbar):
    """Reference Δ̄: take Δ's minima in increasing order while ≤ τ; each fills the still-empty
    frames of its span [start, end] with its cost and blocks ends inside that span."""
    blocked = np.zeros(delta.shape[0], dtype=np.bool_)
    hits = 0
    for i in range(order.shape[0]):
        end = order[i]
        d = delta[end]
        if not d <= tau:
            break
        if blocked[end]:
            continue
        s = start[end]
        for k in range(s, end + 1):
            blocked[k] = True
            if dbar[k] == np.inf:
                dbar[k] = d
        hits += 1
        if hits >= max_hits:
            break
    return hits


def modified_delta(delta: np.ndarray, start: np.ndarray, *, tau: float = DEFAULT_TAU,
                   variant: str = "reference", max_hits: int | None = None,
                   out: np.ndarray | None = None) -> np.ndarray:
    """Δ̄ from a distance curve Δ and start frames (algorithms.md §7 step 2; MBS09 §4).

    ``variant="reference"`` (default, what the reference implementation does): repeatedly
    take the smallest remaining Δ(ℓ) ≤ τ (ties: earliest frame), fill the frames of
    [a_ℓ, ℓ] that are still ∞ with Δ(ℓ), and exclude that range from further picks;
    ``max_hits`` caps the picks (the reference used 2000). ``variant="paper"`` (MBS09 as
    written): for every local minimum ℓ of Δ below τ, Δ̄(k) = min(Δ̄(k), Δ(ℓ)) on [a_ℓ, ℓ].
    Frames are 0-based; Δ = ∞ where no match ends. ``out`` (float64, Δ's length) receives
    Δ̄ instead of a new array (a batch reuses one buffer).
    """
    delta = np.ascontiguousarray(delta, dtype=np.float64)
    start = np.ascontiguousarray(start, dtype=np.int64)
    if delta.shape != start.shape or delta.ndim != 1:
        raise MtannoError("delta and start must be 1-D arrays of the same length")
    tau = check_tau(tau)
    if out is None:
        dbar = np.full(delta.shape[0], np.inf)
    else:
        if out.shape != delta.shape or out.dtype != np.float64:
            raise MtannoError("out must be a float64 array of Δ's length")
        dbar = out
        dbar.fill(np.inf)
    if variant == "reference":
        finite = np.flatnonzero(np.isfinite(delta) & (delta <= tau))
        order = finite[np.argsort(delta[finite], kind="stable")]
        cap = np.iinfo(np.int64).max if max_hits is None else int(max_hits)
        _fill_from_minima(delta, start, order, float(tau), cap, dbar)
        return dbar
    if variant == "paper":
        d = np.where(np.isfinite(delta), delta, np.inf)
        left = np.concatenate(([np.inf], d[:-1]))
        right = np.concatenate((d[1:], [np.inf]))
        minima = np.flatnonzero((d <= tau) & (d < left) & (d <= right))
        for end in minima:
            s = start[end]
            np.minimum(dbar[s:end + 1], d[end], out=dbar[s:end + 1])
        return dbar
    raise MtannoError(f"unknown Δ̄ variant '{variant}' (reference or paper)")


@numba.njit(cache=True)
def _extend(dbar, s, t):
    """Walk outward from [s, t] while Δ̄ does not rise (algorithms.md §7 step 4)."""
    n = dbar.shape[0]
    r = s
    while r > 0 and dbar[r - 1] <= dbar[r]:
        r -= 1
    u = t
    while u + 1 < n and dbar[u + 1] <= dbar[u]:
        u += 1
    return r, u


class Annotation(NamedTuple):
    """One output segment: 0-based inclusive frames at 30 Hz (a named tuple: documents of
    hours give thousands, made in a few microseconds each)."""

    doc: str
    start: int
    end: int
    label: str
    cost: float


def label_frames(dbars: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(label index per frame, −1 where every Δ̄ is ∞; Δ_min per frame). Ties → smallest
    class index (algorithms.md §7 step 3)."""
    dmin = dbars.min(axis=0)
    labels = np.argmin(dbars, axis=0).astype(np.int64)
    labels[~np.isfinite(dmin)] = -1
    return labels, dmin


@numba.njit(cache=True)
def _label_runs(dbars, extend, out_p, out_s, out_t, out_cost):
    """Segments of a Δ̄ matrix (labels × frames): each frame's label is the smallest Δ̄
    (ties → smaller label, none where all are ∞); maximal runs of one label, extended
    while Δ̄ of the label does not rise (when ``extend``), merged per label where they
    overlap, with the smallest Δ̄ inside. Writes (label, start, end, cost) sorted by label
    and start; returns their number."""
    P, L = dbars.shape
    n = 0
    prev = -2
    s0 = 0
    for j in range(L + 1):
        lab = -1
        if j < L:
            best = np.inf
            for p in range(P):
                if dbars[p, j] < best:
                    best = dbars[p, j]
                    lab = p
        if j == L or lab != prev:
            if j > 0 and prev >= 0:
                s, t = s0, j - 1
                if extend:
                    s, t = _extend(dbars[prev], s, t)
                out_p[n] = prev
                out_s[n] = s
                out_t[n] = t
                n += 1
            prev = lab
            s0 = j
    order = np.argsort(out_p[:n] * (L + 1) + out_s[:n])
    sp = out_p[:n][order]
    ss = out_s[:n][order]
    st = out_t[:n][order]
    m = 0
    for i in range(n):
        if m > 0 and out_p[m - 1] == sp[i] and ss[i] <= out_t[m - 1]:  # overlapping: merge
            if st[i] > out_t[m - 1]:
                out_t[m - 1] = st[i]
        else:
            out_p[m] = sp[i]
            out_s[m] = ss[i]
            out_t[m] = st[i]
            m += 1
    for i in range(m):
        c = np.inf
        for j in range(out_s[i], out_t[i] + 1):
            if dbars[out_p[i], j] < c:
                c = dbars[out_p[i], j]
        out_cost[i] = c
    return m


def segments_from_labels(doc: str, names: Sequence[str], dbars: np.ndarray, *,
                         extend: bool = True) -> list[Annotation]:
    """Maximal runs of one label, extended (optional) and merged per label (§7 step 4)."""
    dbars = np.ascontiguousarray(dbars, dtype=np.float64)
    L = dbars.shape[1]
    out_p = np.empty(L + 1, np.int64)
    out_s = np.empty(L + 1, np.int64)
    out_t = np.empty(L + 1, np.int64)
    cost = np.empty(L + 1)
    m = _label_runs(dbars, bool(extend), out_p, out_s, out_t, cost)
    out = [Annotation(doc, s, t, names[p], c) for p, s, t, c in
           zip(out_p[:m].tolist(), out_s[:m].tolist(), out_t[:m].tolist(), cost[:m].tolist())]
    out.sort(key=lambda a: (a.start, a.end, a.label))
    return out


def single_label_segments(doc: str, names: Sequence[str], dbars: np.ndarray,
                          rows: Sequence[Annotation]) -> list[Annotation]:
    """Resolve overlapping segments into a partition (``annotate --single-label``).

    Every frame covered by one or more of ``rows`` (the segments of one document, possibly
    overlapping after the extension of algorithms.md §7 step 4) keeps the label, among the
    segments covering it, with the smallest Δ̄ there (ties → the smaller label index, as in
    step 3); frames no segment covers stay unlabelled. The result is the maximal runs of
    one label: no two segments share a frame. ``cost`` is the smallest Δ̄ of the label
    inside its run. Frames are 0-based at 30 Hz.
    """
    dbars = np.asarray(dbars, dtype=np.float64)
    P, L = dbars.shape
    index = {n: k for k, n in enumerate(names)}
    cover = np.zeros((P, L), dtype=bool)
    for r in rows:
        cover[index[r.label], r.start:r.end + 1] = True
    # covered frames rank by Δ̄ (∞ after every finite value), uncovered ones never win
    key = np.where(cover, np.nan_to_num(dbars, posinf=np.finfo(np.float64).max), np.inf)
    label = np.argmin(key, axis=0)
    label[~cover.any(axis=0)] = -1
    out: list[Annotation] = []
    change = np.flatnonzero(np.diff(label)) + 1
    for s, e in zip(np.r_[0, change], np.r_[change, L]):
        p = int(label[s])
        if p >= 0:
            out.append(Annotation(doc, int(s), int(e) - 1, names[p],
                                  float(dbars[p, s:e].min())))
    return out


@dataclass
class ClassModel:
    """A class as the annotator needs it: name, quantized template values and weights.

    :meth:`matcher` packs the template for the matching kernel once and keeps it, so a
    batch of documents does not repeat that work per document."""

    name: str
    values: np.ndarray
    weights: np.ndarray
    path: str | None = None
    sha256: str | None = None
    _prepared: dict = field(default_factory=dict, repr=False, compare=False)

    def record(self) -> dict:
        """The provenance record of the class's template: class, file, SHA-256."""
        return {"class": self.name, "path": self.path, "sha256": self.sha256}

    def matcher(self, variant: str = "reference"):
        from mtanno.templates.match import PreparedTemplate

        if variant not in self._prepared:
            self._prepared[variant] = PreparedTemplate(self.values, self.weights,
                                                       variant=variant)
        return self._prepared[variant]


def class_deltas(X: np.ndarray, classes: Sequence[ClassModel], *,
                 windows: dict[str, list[tuple[int, int]]] | None = None,
                 match_variant: str = "reference") -> list[tuple[np.ndarray, np.ndarray]]:
    """Δ_p and start frames of every class over one document (X: features × frames).

    ``windows`` (from a keyframe stage) restricts a class to candidate windows
    [first, last] (0-based inclusive; clipped to the document, overlapping ones merged):
    Δ_p is computed inside each window (windows are matched as separate documents) and is
    ∞ elsewhere (MBS09 §5). Classes without an entry are matched everywhere. The document
    is bit-packed once for all classes.
    """
    from mtanno.templates.match import pack_document

    L = X.shape[1]
    out = []
    packed = pack_document(X, X.shape[0]) if classes else None
    for c in classes:
        delta, start = np.empty(L), np.empty(L, np.int64)
        _class_delta(X, packed, c, windows, match_variant, delta, start)
        out.append((delta, start))
    return out


def _class_delta(X, packed, c: ClassModel, windows, match_variant, delta, start) -> None:
    """Δ and starts of one class into ``delta``/``start`` (in its windows, if it has)."""
    matcher = c.matcher(match_variant)
    if matcher.f != X.shape[0]:
        raise MtannoError(f"document has {X.shape[0]} features but template '{c.name}' "
                          f"{matcher.f}")
    L = X.shape[1]
    if windows is not None and c.name in windows:
        starts, ends = _merged_spans(windows[c.name], L)
        matcher.match_spans(packed, starts, ends, out=(delta, start))
    else:
        matcher.run(packed, np.array([0, L], dtype=np.int64), out=(delta, start))


def _merged_spans(spans, L: int) -> tuple[np.ndarray, np.ndarray]:
    """Windows clipped to [0, L − 1], sorted, overlapping ones merged."""
    merged: list[list[int]] = []
    for a, b in sorted((max(0, int(a)), min(L - 1, int(b))) for a, b in spans):
        if b < a:
            continue
        if merged and a <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    arr = np.array(merged, dtype=np.int64).reshape(-1, 2)
    return arr[:, 0], arr[:, 1]


def annotate_document(doc: str, X: np.ndarray, classes: Sequence[ClassModel], *,
                      config: ClassConfig | None = None,
                      windows: dict[str, list[tuple[int, int]]] | None = None,
                      dbar_variant: str = "reference", match_variant: str = "reference",
                      max_hits: int | None = None, extend: bool = True,
                      single_label: bool = False,
                      ) -> tuple[list[Annotation], list[str], np.ndarray]:
    """Annotate one document (MBS09 §4–5): returns (segments, label names, Δ̄ matrix).

    Labels are the classes, or the superclasses of ``config`` joining them (classes not in
    a superclass keep their name); Δ̄ of a label is the frame-wise minimum of its classes'.
    Segments of different labels may overlap (the reference output); with
    ``single_label`` overlaps are resolved frame by frame to the label with the smallest
    Δ̄ (:func:`single_label_segments`), so the segments form a partition of the labelled
    frames.
    """
    config = config or ClassConfig()
    if not classes:
        raise MtannoError("no class templates to annotate with")
    names = [c.name for c in classes]
    member_of = {m: s for s, ms in config.superclasses.items() for m in ms}
    labels: list[str] = []
    for n in names:
        lab = member_of.get(n, n)
        if lab not in labels:
            labels.append(lab)
    from mtanno.templates.match import pack_document

    L = X.shape[1]
    dbars = np.full((len(labels), L), np.inf)
    packed = pack_document(X, X.shape[0])
    # one Δ and one Δ̄ buffer for all classes: documents can be hours long
    delta, start, tmp = np.empty(L), np.empty(L, np.int64), np.empty(L)
    alone = {lab: sum(member_of.get(n, n) == lab for n in names) == 1 for lab in labels}
    for c in classes:
        _class_delta(X, packed, c, windows, match_variant, delta, start)
        lab = member_of.get(c.name, c.name)
        tau = config.tau.get(c.name, config.tau_for(lab))
        k = labels.index(lab)
        if alone[lab]:
            modified_delta(delta, start, tau=tau, variant=dbar_variant, max_hits=max_hits,
                           out=dbars[k])
        else:
            modified_delta(delta, start, tau=tau, variant=dbar_variant, max_hits=max_hits,
                           out=tmp)
            np.minimum(dbars[k], tmp, out=dbars[k])
    rows = segments_from_labels(doc, labels, dbars, extend=extend)
    if single_label:
        rows = single_label_segments(doc, labels, dbars, rows)
    return rows, labels, dbars


ANNOTATION_COLUMNS = ("doc", "start", "end", "label", "cost", "start_native", "end_native")


def annotation_table(rows: Sequence[Annotation], native: dict[str, np.ndarray] | None = None):
    """The annotation table of ``rows`` as a :class:`pyarrow.Table`: doc, start, end
    (1-based inclusive 30 Hz frames), label, cost (null where infinite), and start_native,
    end_native (1-based native frames) when ``native`` maps each document to its feature
    file's native_frame column."""
    import pyarrow as pa

    cols: dict[str, list] = {"doc": [], "start": [], "end": [], "label": [], "cost": []}
    if native is not None:
        cols["start_native"], cols["end_native"] = [], []
    for r in rows:
        cols["doc"].append(r.doc)
        cols["start"].append(r.start + 1)
        cols["end"].append(r.end + 1)
        cols["label"].append(r.label)
        cols["cost"].append(r.cost if math.isfinite(r.cost) else None)
        if native is not None:
            nf = native[r.doc]
            cols["start_native"].append(int(nf[r.start]))
            cols["end_native"].append(int(nf[r.end]))
    types = {"doc": pa.string(), "label": pa.string(), "cost": pa.float64()}
    return pa.table({k: pa.array(v, type=types.get(k, pa.int64())) for k, v in cols.items()})


def write_annotations(path: str | os.PathLike, rows: Sequence[Annotation],
                      native: dict[str, np.ndarray] | None = None, *,
                      provenance: dict | None = None) -> None:
    """Write an annotation table (:func:`annotation_table`) atomically, in the format of
    its suffix (``.csv``, ``.parquet``, ``.jsonl``; ``-`` for standard output), with its
    provenance (:mod:`mtanno.tables`)."""
    from mtanno.tables import write_table

    write_table(path, annotation_table(rows, native), provenance=provenance)


def read_annotations(path: str | os.PathLike) -> list[Annotation]:
    """Read an annotation table written by :func:`write_annotations` (frames → 0-based).

    Every row is checked: a doc and a label, integer frames 1 ≤ start ≤ end, a cost that is
    a number or empty; a bad row is an error naming its line."""
    return read_annotation_table(path)[0]


def read_annotation_table(path: str | os.PathLike) -> tuple[list[Annotation], dict | None]:
    """:func:`read_annotations` and the table's provenance (None when it has none)."""
    from mtanno.tables import parse_int, parse_text, read_table
    from mtanno.truth import MAX_FRAME

    table = read_table(path, what="annotation table")
    table.require(["doc", "start", "end", "label"])
    out = []
    for i, row in enumerate(table.rows):
        doc, label = parse_text(table, i, "doc"), parse_text(table, i, "label")
        start = parse_int(table, i, "start", minimum=1, maximum=MAX_FRAME)
        end = parse_int(table, i, "end", minimum=1, maximum=MAX_FRAME)
        if end < start:
            raise table.error(i, f"start {start} is after end {end}")
        cost = row.get("cost")
        if cost is None:
            cost = float("inf")
        else:
            try:
                cost = float(cost)
            except (TypeError, ValueError):
                raise table.error(i, f"cost must be a number, got {cost!r}") from None
            if math.isnan(cost):
                raise table.error(i, "cost is NaN")
        out.append(Annotation(doc, start - 1, end - 1, label, cost))
    return out, table.provenance


def read_annotation_tables(paths: Sequence[str | os.PathLike]
                           ) -> tuple[list[Annotation], dict[str, int], list[dict]]:
    """The rows of several annotation tables (a run split over machines, say), each
    document in one of them only (else an error naming both files); the documents' frame
    counts their provenance records (``annotate`` records them) and the provenances."""
    rows: list[Annotation] = []
    frames: dict[str, int] = {}
    provs: list[dict] = []
    where: dict[str, str] = {}
    for path in paths:
        part, prov = read_annotation_table(path)
        for d in sorted({a.doc for a in part}):
            if d in where:
                raise MtannoError(f"document {d!r} is annotated in {where[d]} too; give each "
                                  "document's annotation once", path=str(path))
            where[d] = str(path)
        rows.extend(part)
        provs.append(prov or {})
        recorded = (prov or {}).get("documents")
        if isinstance(recorded, dict):
            frames.update({str(k): int(v) for k, v in recorded.items()
                           if isinstance(v, int) and not isinstance(v, bool)})
    return rows, frames, provs


# --------------------------------------------------------------------------- batches


def load_class_models(mt_dir: str | os.PathLike, *, delta: float = DEFAULT_DELTA,
                      classes: Sequence[str] = ()) -> tuple[list[ClassModel], FeatureLayout]:
    """The templates of a folder (``*.json``; or one template file;
    :func:`mtanno.templates.model.load_template_folder`), quantized with ``delta``, as
    :class:`ClassModel` records (with their file and SHA-256), and the feature layout
    (set, names, rate) they all share. ``classes`` keeps only those."""
    from mtanno.templates.model import load_template_folder

    return class_models(load_template_folder(mt_dir, classes=classes), delta=delta,
                        where=f"the templates in {mt_dir}")


def class_models(templates: dict, *, delta: float = DEFAULT_DELTA,
                 where: str = "the templates") -> tuple[list[ClassModel], FeatureLayout]:
    """:class:`ClassModel` records of loaded templates (class name →
    :class:`mtanno.templates.model.MotionTemplate`, e.g. from ``load_template_folder`` or
    learned in memory), quantized with ``delta``, and the feature layout they share
    (``where`` names them in messages)."""
    from mtanno.store import FeatureLayout, check_layout, sha256_file
    from mtanno.templates.model import quantize

    if not templates:
        raise MtannoError("no class templates to annotate with")
    models: list[ClassModel] = []
    for mt in templates.values():
        q = quantize(mt, delta)
        model = ClassModel(mt.class_name, q.values, q.weights, path=mt.path,
                           sha256=sha256_file(mt.path) if mt.path else None)
        try:
            model.matcher("reference")  # refuse a template the kernel cannot use, naming it
        except MtannoError as exc:
            raise MtannoError(exc.message, path=mt.path) from None
        models.append(model)
    first = next(iter(templates.values()))
    layout = FeatureLayout(first.feature_set, tuple(first.feature_names), float(first.fps), where)
    for mt in templates.values():  # templates made in memory were not checked by a reader
        check_layout(FeatureLayout(mt.feature_set, tuple(mt.feature_names), float(mt.fps),
                                   f"template {mt.class_name}"), layout, path=mt.path)
    return models, layout


@dataclass
class AnnotationBatch:
    """What :func:`annotate_files` did: the segments of every document annotated, each
    document's native frames and frame count, the files read (path, SHA-256) and the
    failures (one message per file that could not be annotated); ``seconds`` is the time
    spent annotating (keyframe search, matching, labels; not reading), summed over the
    documents."""

    rows: list[Annotation] = field(default_factory=list)
    native: dict[str, np.ndarray] = field(default_factory=dict)
    frames: dict[str, int] = field(default_factory=dict)
    files: list[dict] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    seconds: float = 0.0


def _annotate_file(path, models, layout, config, dbar_variant, match_variant, keyframes,
                   single_label=False):
    """One document of a batch: (document, rows, native frames, sha256) or the message of
    its failure (a worker sends it back as text)."""
    import time

    from mtanno.store import check_layout, read_features

    try:
        ff = read_features(path, sha256=True)
        check_layout(ff, layout)
        t0 = time.perf_counter()
        windows = None
        if keyframes:
            from mtanno.keyframes import class_windows

            try:
                windows = class_windows(ff.X, ff.names, keyframes, feature_set=layout.feature_set)
            except MtannoError as exc:
                raise MtannoError(exc.message, path=ff.path) from None
        rows, _, _ = annotate_document(ff.document, ff.X, models, config=config,
                                       windows=windows, dbar_variant=dbar_variant,
                                       match_variant=match_variant, single_label=single_label)
    except MtannoError as exc:
        return str(exc)
    return ff.document, rows, ff.native_frames, ff.sha256, time.perf_counter() - t0


def annotate_files(paths: Sequence[str | os.PathLike], models: Sequence[ClassModel], *,
                   layout: FeatureLayout, config: ClassConfig | None = None,
                   dbar_variant: str = "reference", match_variant: str = "reference",
                   keyframes: dict | None = None, n_jobs: int = 1,
                   progress=None, single_label: bool = False,
                   scheduler: str | None = None) -> AnnotationBatch:
    """Annotate feature files (:func:`annotate_document`), in ``n_jobs`` processes
    (:class:`mtanno.workers.WorkerPool`). ``keyframes`` maps class names to keyframe
    queries (:mod:`mtanno.keyframes`): those classes are matched only inside their
    candidate windows in each document (MBS09 §5), the others everywhere. A file that
    cannot be read or does not have the templates' ``layout`` is recorded in ``failed``
    and the batch goes on. ``progress`` is called once per file with its path and its
    failure message (None on success). ``single_label`` resolves overlapping segments
    (:func:`single_label_segments`). ``scheduler``: a dask.distributed cluster runs the
    documents instead of local processes (:class:`mtanno.workers.DaskPool`, same results).
    Rows are sorted by document, start, end and label."""
    from mtanno.workers import make_pool

    config = config or ClassConfig()
    batch = AnnotationBatch()
    args = [(str(p), models, layout, config, dbar_variant, match_variant, keyframes,
             single_label) for p in paths]

    def collect(path, result):
        if isinstance(result, str):
            batch.failed.append(result)
            if progress:
                progress(path, result)
            return
        doc, rows, native, digest, seconds = result
        batch.seconds += seconds
        batch.rows.extend(rows)
        batch.native[doc] = native
        batch.frames[doc] = int(native.shape[0])
        batch.files.append({"path": str(path), "sha256": digest})
        if progress:
            progress(path, None)

    with make_pool(jobs=n_jobs, scheduler=scheduler, n_tasks=len(args)) as pool:
        for a, result in zip(args, pool.map(_annotate_file, args)):
            collect(a[0], result)
    batch.rows.sort(key=lambda r: (r.doc, r.start, r.end, r.label))
    return batch
