"""Retrieval hits from the distance function Δ of a motion template ([MR06] §5.4).

:func:`extract_hits` turns one document's Δ and start frames (from
:func:`mtanno.templates.match.match_template`) into hits; :func:`retrieve` matches a template
against several documents and ranks all hits by cost. Two extraction rules, both greedy
(repeatedly the smallest remaining Δ(ℓ) ≤ τ, ties to the lowest frame), as in the reference
implementation (``../shared/data/reference/retrieval/README.md``; docs/method.md §3.5):

``"retrieval"`` (``motionTemplateDTWRetrievalWeighted``)
    A minimum at end frame e with start s (hit length len = e − s + 1) is recorded only if
    s is not covered by the start zone [s' − ⌈b_s·len'⌉, s' + ⌈f_s·len'⌉] of an earlier
    recorded hit (``start_excl`` = (b_s, f_s), default (0.1, 0.5)). Either way the end
    frames [e − ⌈b_e·len⌉, e + ⌈f_e·len⌉] are blanked (``end_excl`` = (b_e, f_e), default
    (0.5, 0.1)) — for a dropped candidate with len = the length of the recorded hit whose
    start zone covers s (the latest one where zones overlap), as the reference code does.
``"classification"`` (``…ForClassification``, used for annotation)
    Every minimum is recorded and blanks exactly its own frames [s, e]; no start check.

:func:`retrieve_to` is the whole ``mtanno retrieve`` run, from file names to the hit table.

Extraction stops after ``max_hits`` recorded hits; the result then says whether the cap cut
off further hits (:attr:`HitList.truncated`). Frames are 0-based here (30 Hz frames); the
command line writes them 1-based.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mtanno.errors import MtannoError
from mtanno.templates.match import DEFAULT_STEP_WEIGHTS, DEFAULT_STEPS, PreparedTemplate
from mtanno.templates.params import RETRIEVAL_DELTA, RETRIEVAL_TAU, check_tau

__all__ = ["DEFAULT_MAX_HITS", "HIT_MODES", "Hit", "HitList",
           "RetrievalBatch", "RetrieveRun", "extract_hits", "hit_table", "retrieve",
           "retrieve_files", "retrieve_files_classes", "retrieve_to", "write_hits"]

#: How hits are picked from Δ (:func:`extract_hits`).
HIT_MODES = ("retrieval", "classification")
#: Hit cap per document.
DEFAULT_MAX_HITS = 1000


@dataclass(frozen=True)
class Hit:
    """One retrieval hit: document frames ``start``..``end`` (0-based, inclusive, 30 Hz).

    ``cost`` is Δ(end). ``doc`` is the document's name (or whatever label the caller gave)
    and ``doc_index`` its position in the input sequence.
    """

    doc: str | int
    start: int
    end: int
    cost: float
    doc_index: int = 0

    @property
    def length(self) -> int:
        """Number of frames of the hit."""
        return self.end - self.start + 1


class HitList(list):
    """A list of :class:`Hit` in rank order (increasing cost).

    ``truncated`` is True when the hit cap stopped the extraction while at least one more
    hit would have been recorded without it; ``cap`` is the cap that was applied.
    """

    def __init__(self, hits: Iterable[Hit] = (), *, truncated: bool = False, cap: int | None = None):
        super().__init__(hits)
        self.truncated = truncated
        self.cap = cap


def _check_fraction_pair(value, name: str) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise MtannoError(f"{name} must be a pair of numbers (backward, forward), got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b)) or a < 0 or b < 0:
        raise MtannoError(f"{name} must be finite and non-negative, got {value!r}")
    return a, b


def _check_options(tau, mode, max_hits) -> float:

    tau = check_tau(tau)
    if mode not in HIT_MODES:
        raise MtannoError(f"unknown hit mode {mode!r} (choose from {', '.join(HIT_MODES)})")
    if isinstance(max_hits, bool) or not isinstance(max_hits, (int, np.integer)) or max_hits < 1:
        raise MtannoError(f"max_hits must be a positive integer, got {max_hits!r}")
    return tau


def extract_hits(delta: np.ndarray, start: np.ndarray, *, tau: float, mode: str = "retrieval",
                 max_hits: int = DEFAULT_MAX_HITS,
                 end_excl: tuple[float, float] = (0.5, 0.1),
                 start_excl: tuple[float, float] = (0.1, 0.5),
                 doc: str | int = 0, doc_index: int = 0) -> HitList:
    """Greedy hits of one document's Δ below ``tau`` ([MR06] §5.4, docs/method.md §3.5).

    Parameters
    ----------
    delta:
        (L,) Δ per document frame; ``inf`` or NaN where no match ends.
    start:
        (L,) 0-based start frame of the optimal match ending at each frame.
    tau:
        Quality threshold: candidates have Δ ≤ tau. The reference drivers use 0.175
        (retrieval) and 0.13 (classification); [MR06] recommends 0.06.
    mode:
        ``"retrieval"`` or ``"classification"`` (module docstring).
    max_hits:
        Stop after this many recorded hits (the reference used 100 for retrieval and 2000 for
        classification); ``truncated`` on the result says whether it cut anything off.
    end_excl, start_excl:
        (backward, forward) exclusion fractions of the hit length for end frames and start
        frames; retrieval mode only.
    doc, doc_index:
        Copied into every :class:`Hit`.

    Returns
    -------
    HitList
        Hits in the order found (non-decreasing cost; equal costs by increasing end frame).
    """
    tau = _check_options(tau, mode, max_hits)
    eb, ef = _check_fraction_pair(end_excl, "end_excl")
    sb, sf = _check_fraction_pair(start_excl, "start_excl")
    d = np.asarray(delta, dtype=np.float64)
    a = np.asarray(start)
    if d.ndim != 1 or a.shape != d.shape:
        raise MtannoError(f"delta and start must be 1-D arrays of equal length, got shapes "
                          f"{d.shape} and {a.shape}")
    n = d.shape[0]
    cand = np.flatnonzero(np.isfinite(d) & (d <= tau))  # NaN and inf never qualify
    if cand.size and not np.issubdtype(a.dtype, np.integer):
        raise MtannoError(f"start must hold integer frame indices, got dtype {a.dtype}")
    s_c = a[cand]
    if np.any((s_c < 0) | (s_c > cand)):
        raise MtannoError("start frames must lie in 0..end for every frame where delta is finite")
    order = cand[np.argsort(d[cand], kind="stable")]  # by cost, ties by frame
    retrieval = mode == "retrieval"
    blanked = np.zeros(n, dtype=bool)
    # zone_len[t] > 0: start frame t lies in the start zone of a recorded hit of that length
    # (the latest recorded hit wins where zones overlap)
    zone_len = np.zeros(n, dtype=np.int64) if retrieval else None
    hits = HitList(cap=int(max_hits))
    for e in order.tolist():
        if blanked[e]:
            continue
        s = int(a[e])
        length = e - s + 1
        if retrieval:
            record = zone_len[s] == 0
            if not record:
                # as the reference does: a dropped candidate's end zone is measured with the
                # length of the recorded hit whose start zone covers its start
                length = int(zone_len[s])
            lo, hi = e - math.ceil(eb * length), e + math.ceil(ef * length)
        else:
            record = True
            lo, hi = s, e
        if record and len(hits) >= max_hits:
            hits.truncated = True
            break
        blanked[max(0, lo):hi + 1] = True
        if record:
            hits.append(Hit(doc=doc, start=s, end=e, cost=float(d[e]), doc_index=doc_index))
            if retrieval:
                zone_len[max(0, s - math.ceil(sb * length)):s + math.ceil(sf * length) + 1] = length
    return hits


def retrieve(template_values: np.ndarray, weights: np.ndarray,
             documents: Iterable[tuple[str, np.ndarray]], *, tau: float,
             mode: str = "retrieval", max_hits: int = DEFAULT_MAX_HITS,
             variant: str = "reference",
             steps: Sequence[tuple[int, int]] = DEFAULT_STEPS,
             step_weights: Sequence[float] = DEFAULT_STEP_WEIGHTS,
             end_excl: tuple[float, float] = (0.5, 0.1),
             start_excl: tuple[float, float] = (0.1, 0.5)) -> HitList:
    """Match a quantized template against documents and rank all hits by cost ([MR06] §5.4).

    ``documents`` yields ``(name, X)`` pairs, X (f × L) 0/1 features at 30 Hz; each is
    matched on its own (:func:`mtanno.templates.match.match_template`, paths never cross
    documents) and its hits extracted with :func:`extract_hits`, one document at a time so
    only one Δ is held. The hits of all documents are then merged by cost (ties: earlier
    document, then the order within the document — the same result as one greedy pass over
    all documents with separators) and cut to ``max_hits``; ``truncated`` is set when that
    or a per-document cap cut hits off.
    """
    tau = _check_options(tau, mode, max_hits)
    prep = PreparedTemplate(template_values, weights, variant=variant, steps=steps,
                            step_weights=step_weights)
    per_doc: list[HitList] = []
    for i, item in enumerate(documents):
        if not isinstance(item, (tuple, list)) or len(item) != 2:
            raise MtannoError(f"documents must be (name, features) pairs, got {type(item).__name__} "
                              f"as item {i + 1}")
        name, X = item
        delta, start = prep.match(X)
        per_doc.append(extract_hits(delta, start, tau=tau, mode=mode, max_hits=max_hits,
                                    end_excl=end_excl, start_excl=start_excl, doc=name,
                                    doc_index=i))
    ranked = sorted(((h.cost, h.doc_index, r, h) for hl in per_doc for r, h in enumerate(hl)),
                    key=lambda t: t[:3])
    out = HitList((t[3] for t in ranked[:max_hits]), cap=int(max_hits),
                  truncated=len(ranked) > max_hits or any(hl.truncated for hl in per_doc))
    return out


HIT_COLUMNS = ("doc", "start", "end", "start_native", "end_native", "cost", "rank")


def hit_table(hits: Sequence[Hit] | Mapping[str, Sequence[Hit]], native: Sequence[np.ndarray]):
    """The hit table (``docs/retrieval.md``) as a :class:`pyarrow.Table`: doc, start, end
    (1-based inclusive 30 Hz frames), start_native, end_native (frames of the source motion
    file, from each document's ``native`` frame column, indexed by ``Hit.doc_index``),
    cost, rank (1 = cheapest). ``hits`` may map class names to their hits (``retrieve
    --mt`` with a folder of templates): then a first column ``class`` names each hit's
    class, the classes follow each other in the mapping's order and ranks count per class."""
    import pyarrow as pa

    from mtanno.util.tables import arrow_table

    by_class = hits if isinstance(hits, Mapping) else None
    groups = by_class.items() if by_class is not None else [(None, hits)]
    names = (("class",) if by_class is not None else ()) + HIT_COLUMNS
    cols: dict[str, list] = {c: [] for c in names}
    for cls, class_hits in groups:
        for rank, h in enumerate(class_hits, 1):
            nat = native[h.doc_index]
            row = (str(h.doc), h.start + 1, h.end + 1, int(nat[h.start]), int(nat[h.end]),
                   float(h.cost), rank)
            for c, v in zip(names, ((cls,) if by_class is not None else ()) + row):
                cols[c].append(v)
    types = {"class": pa.string(), "doc": pa.string(), "cost": pa.float64()}
    return arrow_table(cols, {c: t for c, t in types.items() if c in cols})


def write_hits(path: str | os.PathLike, hits: Sequence[Hit] | Mapping[str, Sequence[Hit]],
               native: Sequence[np.ndarray], *, provenance: dict | None = None) -> None:
    """Write the hit table (:func:`hit_table`; one class's hits, or class → hits) in the
    format of ``path``'s suffix (``-``: CSV on standard output), atomically and with its
    provenance (:mod:`mtanno.util.tables`)."""
    from mtanno.util.tables import write_table

    write_table(path, hit_table(hits, native), provenance=provenance)


@dataclass
class RetrievalBatch:
    """What :func:`retrieve_files` found: the ranked hits, each good document's native
    frame column (by ``Hit.doc_index``), the files read (path, SHA-256) and one message per
    file that could not be used."""

    hits: HitList
    native: list[np.ndarray] = field(default_factory=list)
    files: list[dict] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    by_class: dict[str, HitList] = field(default_factory=dict)


def _documents(paths: Sequence[str | os.PathLike], layout, batch: RetrievalBatch,
               progress: Callable[[str, str | None], None] | None):
    """Yield (document name, features) of each feature file that can be read and fits
    ``layout``; record its native frames and file in ``batch``, a failure in
    ``batch.failed``, and call ``progress`` once per file."""
    from mtanno.features.store import check_layout, read_features

    for p in paths:
        try:
            ff = read_features(p, sha256=True)
            check_layout(ff, layout)
        except MtannoError as exc:
            batch.failed.append(str(exc))
            if progress:
                progress(str(p), str(exc))
            continue
        batch.native.append(ff.native_frames)
        batch.files.append({"path": str(p), "sha256": ff.sha256})
        yield ff.document, ff.X
        if progress:
            progress(str(p), None)


def retrieve_files(template_values: np.ndarray, weights: np.ndarray,
                   paths: Sequence[str | os.PathLike], *, layout, tau: float,
                   max_hits: int = DEFAULT_MAX_HITS, variant: str = "reference",
                   progress: Callable[[str, str | None], None] | None = None) -> RetrievalBatch:
    """:func:`retrieve` over feature files: each is read (:func:`mtanno.features.store.read_features`)
    and checked against the template's ``layout`` (:func:`mtanno.features.store.check_layout`); a
    file that fails is recorded in ``failed`` and the others are still searched.
    ``progress`` is called once per file with its path and its failure (None on success)."""
    batch = RetrievalBatch(HitList())
    batch.hits = retrieve(template_values, weights, _documents(paths, layout, batch, progress),
                          tau=tau, max_hits=max_hits, variant=variant)
    return batch


def retrieve_files_classes(templates: Mapping[str, tuple[np.ndarray, np.ndarray]],
                           paths: Sequence[str | os.PathLike], *, layout, tau: float,
                           max_hits: int = DEFAULT_MAX_HITS, variant: str = "reference",
                           progress: Callable[[str, str | None], None] | None = None
                           ) -> RetrievalBatch:
    """:func:`retrieve_files` for several classes at once (``retrieve --mt FOLDER``, the
    folders ``annotate --mt`` takes): ``templates`` maps class names to (quantized values,
    weights) of one feature ``layout``; each feature file is read and checked once, then
    every class is retrieved on the good ones. ``by_class`` holds each class's ranked hits
    (``hits`` those of all classes, in class order); ``max_hits`` applies per class."""
    batch = RetrievalBatch(HitList())
    docs = list(_documents(paths, layout, batch, progress))
    for cls, (values, weights) in templates.items():
        batch.by_class[cls] = retrieve(values, weights, docs, tau=tau, max_hits=max_hits,
                                       variant=variant)
    batch.hits = HitList((h for hl in batch.by_class.values() for h in hl),
                         truncated=any(hl.truncated for hl in batch.by_class.values()),
                         cap=int(max_hits))
    return batch


def retrieval_template(mt, *, delta: float | None = None):
    """The template as retrieval uses it ([MR06] §5.4): quantized with ``delta``, else with
    its own δ, else :data:`RETRIEVAL_DELTA`; a template quantized already keeps its δ (a
    ``delta`` that differs is an error: its values cannot be quantized again)."""
    from mtanno.templates.model import quantize

    if mt.quantized:
        if delta is not None and delta != mt.delta:
            raise MtannoError(f"template is already quantized with delta {mt.delta:g}; "
                              "{delta} only applies to unquantized templates", path=mt.path,
                              options=("delta",))
        return mt
    return quantize(mt, delta if delta is not None else (mt.delta if mt.delta is not None
                                                          else RETRIEVAL_DELTA))



@dataclass
class RetrieveRun:
    """What :func:`retrieve_to` did: the classes retrieved, the hits written (all classes),
    the documents searched, one message per feature file that could not be used
    (``failed``) and per input that named none (``missing``), whether the hit cap cut hits
    off, and τ."""

    classes: list[str]
    hits: int
    documents: int
    failed: list[str]
    missing: list[str]
    truncated: bool
    tau: float

    @property
    def exit_code(self) -> int:
        """0 when every input was searched, else 1."""
        return 1 if self.failed or self.missing else 0


def retrieve_to(features: Sequence[str | os.PathLike], mt_path: str | os.PathLike,
                output: str | os.PathLike = "-", *, tau: float = RETRIEVAL_TAU,
                delta: float | None = None, max_hits: int = DEFAULT_MAX_HITS,
                variant: str = "reference",
                on_start: Callable[[list[str], int], None] | None = None,
                progress: Callable[[str, str | None], None] | None = None) -> RetrieveRun:
    """The whole ``mtanno retrieve`` run ([MR06] §5.4): the feature files ``features``
    names (files, folders searched recursively) searched for the class of the template
    ``mt_path`` (made a retrieval template with ``delta``, :func:`retrieval_template`) or,
    for a folder of templates, for each of its classes (:func:`retrieve_files_classes`:
    ranks and ``max_hits`` per class); the hits with cost ≤ ``tau`` written to ``output``
    (suffix picks the format, ``-`` is CSV on standard output; docs/formats.md) with their
    provenance (inputs, templates, τ, δ, variant). Every output is checked against the
    inputs first.

    ``on_start(missing, n)`` is called before the first of ``n`` feature files, with the
    messages of the inputs that named no feature file; ``progress(path, error)`` after each
    file (``error``: why it could not be used, None when it was searched)."""
    from mtanno.features.inputs import feature_files
    from mtanno.templates.store import load_template, load_template_folder, template_files
    from mtanno.util.preflight import check_outputs
    from mtanno.util.provenance import file_record, provenance
    from mtanno.util.tables import output_files, table_format

    table_format(output)
    tau = check_tau(tau)
    missing: list[str] = []  # inputs naming no feature file: reported, the batch goes on
    files = feature_files(features, failures=missing)
    check_outputs(output_files(output), [mt_path, *template_files(mt_path), *files],
                  scanned={f: (".parquet",) for f in features if Path(f).is_dir()})
    found = (load_template_folder(mt_path) if Path(mt_path).is_dir() else
             {"": load_template(mt_path)})
    mts = {m.class_name: retrieval_template(m, delta=delta) for m in found.values()}
    mt = next(iter(mts.values()))
    several = len(mts) > 1
    layout = mt.layout(f"template {mt.path}")
    if on_start:
        on_start(missing, len(files))
    if several:
        batch = retrieve_files_classes({c: (m.values, m.weights) for c, m in mts.items()},
                                       files, layout=layout, tau=tau, max_hits=max_hits,
                                       variant=variant, progress=progress)
    else:
        batch = retrieve_files(mt.values, mt.weights, files, layout=layout, tau=tau,
                               max_hits=max_hits, variant=variant, progress=progress)
    hits = batch.hits
    deltas = sorted({m.delta for m in mts.values()})
    write_hits(output, batch.by_class if several else hits, batch.native,
               provenance=provenance(
                   inputs=batch.files, templates=[{"class": c, **file_record(m.path)}
                                                  for c, m in mts.items()],
                   tau=tau, delta=deltas[0] if len(deltas) == 1 else deltas, variant=variant,
                   max_hits=max_hits, feature_set=mt.feature_set, truncated=hits.truncated))
    return RetrieveRun(list(mts), len(hits), len(files) - len(batch.failed), batch.failed,
                       missing, hits.truncated, tau)
