"""The confidence that ``mtanno tune`` learns (issue 26): the evidence of every segment the
tuned annotation outputs on the held-out documents of the cross-validation — segments of
known classes, segments over a class left out of the templates (each class in turn: its
motions are unknown there), segments on the background documents — with whether its label
is right (a truth segment of its label overlaps it with IoU ≥ :data:`RIGHT_IOU`), a
calibrator fitted on them (:func:`mtanno.confidence.calibration.fit_calibrated`, grouped by
held-out document), and the minimum confidence of an output row chosen on the calibrator's
out-of-fold probabilities by the tuning objective J = (F1 + F2)/2 − w·U, every label on a
background document a false positive, the background weighted as half of the archive
(:data:`BACKGROUND_SHARE`).

The evidence and its inputs are built as ``mtanno annotate`` builds them
(:func:`mtanno.confidence.evidence.label_facts`, :func:`~mtanno.confidence.evidence.
document_evidence`), so that the calibrator is applied to what it was fitted on.

The verification bank of a fold (:mod:`mtanno.confidence.verify`) holds the fold's training
examples and the background documents that are not held out in it, so that no segment is
verified against its own motion.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from mtanno.confidence.evidence import BANK_EVIDENCE, EVIDENCE, document_evidence, label_facts
from mtanno.evaluation.calibration import segment_right
from mtanno.labels.segments import Annotation
from mtanno.tuning.score import Counts, _count, _covered_fraction

__all__ = ["BACKGROUND_SHARE", "MIN_CONFIDENCE_GRID", "ConfidenceFit", "bank_of",
           "learn_confidence"]

#: Minimum confidences tried for the output rows.
MIN_CONFIDENCE_GRID = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8)


@dataclass
class ConfidenceFit:
    """What :func:`learn_confidence` found: the evidence names, the calibrator, the chosen
    minimum confidence, the out-of-fold probabilities and rightness of the segments (and
    where they came from: ``kinds`` "known", "unknown" or "background"), the score of each
    minimum tried (J, F1, F2, U, fraction of background frames labelled), and the
    representation verified on."""

    evidence: tuple[str, ...]
    calibrator: object
    min_confidence: float
    oof: np.ndarray
    right: np.ndarray
    kinds: list[str]
    table: list[dict] = field(default_factory=list)
    representation: str | None = None


@dataclass
class _Run:
    """The segments of one fold (or one class-left-out run of it) with what scoring and
    the evidence need."""

    fold: int
    segs: list[tuple[int, int, int]]
    costs: list[float]              # Δ/τ at the segment's end (∞: unknown)
    frame_of: np.ndarray | None     # run frame → frame of the fold's held-out documents
    hidden: str | None = None       # the class left out (None: all classes)
    scored: list[bool] = field(default_factory=list)  # per segment: has evidence (in a
    # left-out run only those over the left-out class; the others are the fold's own)


def learn_confidence(tuner, params, folds, *, templates: dict, background_seqs=None,
                     representation: str | None, unknown_weight: float, seed: int = 0,
                     log: Callable[[str], None] | None = None) -> ConfidenceFit:
    """Fit the confidence of ``params`` on ``tuner``'s folds (module docstring).

    ``folds``: the :class:`mtanno.tuning.cv.Fold` records the tuner was built from (same
    order); ``templates``: class → template (their lengths); ``background_seqs``: the
    verification sequence of every background document (indexed as
    :attr:`mtanno.tuning.cv.Fold.background`); ``representation``: what the bank holds
    (None: no bank, evidence ``cost`` and ``length`` only)."""
    from mtanno.confidence.calibration import fit_calibrated

    names = tuple(n for n in EVIDENCE if (representation is not None or n not in BANK_EVIDENCE)
                  and (n != "background" or background_seqs))
    if not params.resolve:
        names = tuple(n for n in names if n != "cost")
    taus = dict(params.tau)
    facts = label_facts({c: mt.values.shape[1] for c, mt in templates.items()},
                        tau_for=lambda c: taus.get(c, math.nan))
    rows_E, right, kinds, groups, runs, owners = [], [], [], [], [], []
    for j, (f, fd) in enumerate(zip(folds, tuner.folds)):
        bank = _fold_bank(f, background_seqs, representation) if representation else None
        for run in _runs(tuner, fd, params, j):
            runs.append(run)
            E, ok, kind, doc = _run_evidence(run, f, fd, tuner, bank, names, facts)
            rows_E.append(E)
            right.extend(ok)
            kinds.extend(kind)
            groups.extend(f"{j}:{d}" for d in doc)
            owners.extend([len(runs) - 1] * len(ok))
    E = np.concatenate(rows_E) if rows_E else np.zeros((0, len(names)))
    y = np.array(right, dtype=np.float64)
    if log and (len(y) < 10 or y.min(initial=0) == y.max(initial=0)):
        log(f"confidence: warning: {len(y)} held-out segments, {int(y.sum())} right: too few "
            "to learn from; the confidence is about constant")
    fit = fit_calibrated(E, y, names=names, rng=seed, groups=np.array(groups))
    table = _thresholds(tuner, folds, runs, np.array(owners), fit.oof, unknown_weight)
    best = max(table, key=lambda t: (round(t["J"], 9), -t["min_confidence"]))
    if log:
        for t in table:
            log(f"confidence >= {t['min_confidence']:g}: F1 {t['F1']:.3f} F2 {t['F2']:.3f} "
                f"unknown {t['U']:.3f} background labelled {t['background']:.3f} "
                f"J {t['J']:.4f}")
    return ConfidenceFit(names, fit.calibrator, float(best["min_confidence"]), fit.oof, y,
                         kinds, table, representation)


def bank_of(examples, background_seqs, representation: str):
    """The verification bank of training ``examples`` (their performer, else their
    document, as the performer) and the background sequences ``background_seqs``."""
    from mtanno.confidence.verify import build_bank, sequence

    items = [(e.class_name, str(e.performer if e.performer is not None else e.document),
              sequence(X=e.X, poses=e.poses, representation=representation))
             for e in examples]
    return build_bank(items, list(background_seqs or []), representation=representation)


def _fold_bank(fold, background_seqs, representation):
    """The verification bank of one fold: its training examples and the background
    documents not held out in it."""
    held = set(fold.background)
    return bank_of(fold.train, [s for k, s in enumerate(background_seqs or [])
                                if k not in held], representation)


def _runs(tuner, fd, params, j: int):
    """The fold's output segments with all its classes, and per class left out those over
    the documents holding it."""
    arrays = tuner.decoder_arrays(fd, params) if params.resolve else None
    segs = tuner.fold_segments(fd, params, fd.classes, arrays)
    yield _Run(j, segs, _costs(tuner, fd, segs, arrays), None, scored=[True] * len(segs))
    for c, sub in fd.hidden.items():
        rest = [x for x in fd.classes if x != c]
        if not rest:
            continue
        sub_arrays = arrays if sub is fd else (tuner.decoder_arrays(sub, params) if params.resolve
                                               else None)
        s2 = tuner.fold_segments(sub, params, rest, sub_arrays)
        frame_of = None if sub is fd else _frames_of(fd, sub, c)
        yield _Run(j, s2, _costs(tuner, sub, s2, sub_arrays), frame_of, c,
                   [_over(sub.truth_by_class[c], a, b) for _, a, b in s2])


def _frames_of(fd, sub, c: str) -> np.ndarray:
    """Frame of ``fd`` of every frame of its subset ``sub`` (the documents holding c)."""
    docs = sorted({int(np.searchsorted(fd.offsets, a, side="right")) - 1
                   for a, _ in fd.truth_by_class.get(c, [])})
    return np.concatenate([np.arange(fd.offsets[d], fd.offsets[d + 1]) for d in docs])


def _costs(tuner, fd, segs, arrays) -> list[float]:
    if arrays is None:
        return [math.nan] * len(segs)
    mat = arrays[0]
    rows = {tuner.ids[c]: k for k, c in enumerate(fd.classes)}
    return [float(mat[rows[p], b]) for p, _, b in segs]


def _run_evidence(run: _Run, fold, fd, tuner, bank, names, facts):
    """Evidence rows, rightness, kind and document of every segment of a run (frames of
    the fold's held-out documents, which the rows index as annotate's index a document)."""
    sub = fd if run.hidden is None else fd.hidden[run.hidden]
    truth = sub.truth if run.hidden is None else []  # over a left-out class: all wrong
    ho = fold.held_out
    n_known = len(ho.offsets) - 1 - len(fold.background)
    rows, ok, kind, doc = [], [], [], []
    for (p, a, b), cost, scored in zip(run.segs, run.costs, run.scored):
        if not scored:
            continue  # a known class's segment: scored in the fold's own run
        A, B = (a, b) if run.frame_of is None else (int(run.frame_of[a]), int(run.frame_of[b]))
        d = int(np.searchsorted(ho.offsets, A, side="right")) - 1
        label = tuner.names[p]
        rows.append(Annotation(str(d), A, B, label, cost * facts.taus.get(label, 1.0)))
        is_bg = d >= n_known
        ok.append((not is_bg) and run.hidden is None and segment_right((p, a, b), truth))
        kind.append("background" if is_bg else "unknown" if run.hidden else "known")
        doc.append(d)
    E = document_evidence(rows, facts, X=ho.X, poses=ho.poses, bank=bank, names=names)
    return E, ok, kind, doc


def _over(spans, a: int, b: int) -> bool:
    """Whether frames a..b lie mostly over ``spans`` (the left-out class's truth)."""
    hit = sum(max(0, min(b, e) - max(a, s) + 1) for s, e in spans)
    return hit * 2 >= b - a + 1


def _thresholds(tuner, folds, runs, owners, prob, unknown_weight: float) -> list[dict]:
    """J, F1, F2, U and the fraction of background frames labelled for each minimum of
    :data:`MIN_CONFIDENCE_GRID`, the segments below it dropped.

    Every label on a background frame is a false positive; the background's frames and
    segments are weighted so that it counts as much as the held-out documents of known
    classes (:data:`BACKGROUND_SHARE`: an archive at least half of whose motions belong
    to no class), whatever the number of background files given."""
    out = []
    for m in MIN_CONFIDENCE_GRID:
        known, unk, bg, bg_segs = Counts.zero(), [0, 0], [0, 0], 0
        for r_i, run in enumerate(runs):
            idx = np.flatnonzero(owners == r_i)
            keep = iter(prob[idx] >= m)  # segments without evidence are kept
            fd = tuner.folds[run.fold]
            sub = fd if run.hidden is None else fd.hidden[run.hidden]
            kept = [s for s, scored in zip(run.segs, run.scored) if not scored or next(keep)]
            if run.hidden is None:
                known += _count(fd.truth, kept, len(tuner.names), fd.n_frames, fd.ignore)
                for spans in fd.absent.values():
                    h, n = _covered_fraction(spans, kept, fd.n_frames)
                    unk[0] += h
                    unk[1] += n
                spans = _background_spans(fd)
                h, n = _covered_fraction(spans, kept, fd.n_frames)
                bg[0] += h
                bg[1] += n
                if spans:
                    bg_segs += sum(1 for _, a, _ in kept if a >= spans[0][0])
            else:
                h, n = _covered_fraction(sub.truth_by_class[run.hidden], kept, sub.n_frames)
                unk[0] += h
                unk[1] += n
        U = unk[0] / unk[1] if unk[1] else 0.0
        f1, f2 = _weighted_f(known, bg[0], bg_segs, _background_weight(tuner, bg[1]))
        out.append({"min_confidence": m, "J": (f1 + f2) / 2 - unknown_weight * U, "F1": f1,
                    "F2": f2, "U": U, "background": bg[0] / bg[1] if bg[1] else 0.0})
    return out


#: The share of an archive that the background is weighted to when the minimum confidence
#: is chosen (the rest: the held-out documents of known classes).
BACKGROUND_SHARE = 0.5


def _background_weight(tuner, bg_frames: int) -> float:
    """The weight of one background frame (or segment): the background weighs
    :data:`BACKGROUND_SHARE` of all held-out frames."""
    if not bg_frames:
        return 0.0
    known = sum(fd.n_frames for fd in tuner.folds) - bg_frames
    return known / bg_frames * BACKGROUND_SHARE / (1 - BACKGROUND_SHARE)


def _weighted_f(known: Counts, bg_frames: int, bg_segments: int, weight: float):
    """(F1, F2) of the known documents' counts with the background's labelled frames and
    segments added, weighted, to the predictions."""
    from mtanno.evaluation.metrics import f_measure, ratio

    p1 = ratio(known.frame_correct, known.frame_predicted + weight * bg_frames)
    r1 = ratio(known.frame_correct, known.frame_support)
    p2 = ratio(known.seg_correct, known.seg_predicted + weight * bg_segments)
    r2 = ratio(known.seg_found, known.seg_support)
    return f_measure(p1, r1), f_measure(p2, r2)


def _background_spans(fd) -> list[tuple[int, int]]:
    """The frames of the fold's background documents (the last of its held-out
    documents), as (first, last) spans."""
    n_bg = fd.n_background
    if not n_bg:
        return []
    off = fd.offsets
    return [(int(off[k]), int(off[k + 1]) - 1) for k in range(len(off) - 1 - n_bg, len(off) - 1)]
