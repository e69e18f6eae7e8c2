"""Learning a keyframe query per class (docs/method.md §6): the genetic algorithm of [MBS09]
§6 (``ga``), columns of the hard template (``hard``, thesis ch. 6) and [MR06]'s column
heuristic (``heuristic``, [MR06] §5.4).

:func:`learn_keyframes` works on a :class:`~mtanno.keyframes.fitness.TrainingSet` (the
training clips of all classes) and the class's motion template;
:func:`keyframe_training_set` builds the training set from loaded training examples
(:func:`mtanno.templates.load_examples`). Every method records in the query's provenance
how it was made and its precision, recall and F_β on the training clips.

GA runs are independent: run k of class C uses the seed sequence (seed, crc32(C), k), so
the result does not depend on how runs are spread over processes (``jobs``). The winner is
the run result whose keyframes occur most often among all winners ([MBS09] §6): each
winner scores the mean, over its keyframes, of the number of winners that contain that
keyframe (same position, group and vector); ties go to the higher fitness, then fewer
keyframes, then the lower run number.
"""

from __future__ import annotations

import math
import zlib
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from mtanno._version import __version__
from mtanno.errors import MtannoError
from mtanno.keyframes.fitness import JITTER, Gene, Score, TrainingSet, keyframe_tolerance
from mtanno.keyframes.ga import GAParams, GARun, Problem, run_ga
from mtanno.keyframes.model import (
    ANNOTATION_EXTENSION,
    Extension,
    Gap,
    Keyframe,
    KeyframeQuery,
)

__all__ = ["DEFAULT_RUNS", "METHODS", "GAParams", "keyframe_training_set", "learn_keyframes",
           "query_score", "run_seeds"]

METHODS = ("ga", "hard", "heuristic")
#: Independent GA runs per class ([MBS09]: 100–500).
DEFAULT_RUNS = 100
#: Keyframe columns chosen by the hard and heuristic methods.
DEFAULT_COLUMNS = 3
#: Fraction of template columns ignored at each end by the column methods.
BORDER = 0.125
#: Gap stiffness of the heuristic method.
HEURISTIC_STIFFNESS = 0.5
#: Quantization δ of the heuristic method ([MR06] retrieval).
HEURISTIC_DELTA = 0.1


def keyframe_training_set(examples, *, feature_set: str | None = None,
                          groups: dict[str, Sequence[str]] | None = None,
                          jitter: int = JITTER, seed: int = 0) -> TrainingSet:
    """A :class:`TrainingSet` of loaded training examples (all classes), each example one
    clip, plus ``jitter`` copies of each with feature switches moved by a frame
    (:func:`~mtanno.keyframes.fitness.jitter_edges`); groups default to the feature set's
    index groups."""
    from mtanno.keyframes.model import feature_groups_of

    if not examples:
        raise MtannoError("no training examples")
    ex0 = examples[0]
    feature_set = feature_set or ex0.feature_set
    if groups is None:
        groups = feature_groups_of(feature_set)
    names = [f"{i:05d}:{ex.document}:{ex.start}-{ex.end}" for i, ex in enumerate(examples)]
    ts = TrainingSet([ex.X for ex in examples], [ex.class_name for ex in examples],
                     ex0.feature_names, groups, clip_names=names, feature_set=feature_set,
                     performers=[getattr(ex, "performer", None) for ex in examples],
                     jitter=jitter, seed=seed)
    ts.records = {n: {"class": ex.class_name, **ex.record()} for n, ex in zip(names, examples)}
    return ts


@dataclass
class _Context:
    """What every method needs: training set, class positives, template (soft values,
    weights), group rows."""

    training: TrainingSet
    class_name: str
    positives: np.ndarray
    soft: np.ndarray
    group_rows: list[np.ndarray]
    feature_set: str
    fps: float


def _context(training: TrainingSet, class_name: str, template, ) -> _Context:
    pos = training.positives(class_name)
    if not pos.any():
        raise MtannoError(f"class '{class_name}' has no training clips")
    names = list(template.feature_names)
    if names != training.names:
        raise MtannoError(f"template of class '{class_name}' has other features than the "
                          "training clips")
    rows = {n: i for i, n in enumerate(names)}
    group_rows = [np.array([rows[f] for f in training.groups[g]], np.int64)
                  for g in training.group_names]
    return _Context(training, class_name, pos, np.asarray(template.values, float), group_rows,
                    template.feature_set, float(template.fps))


def _query(ctx: _Context, genes: Sequence[Gene], gaps: Sequence[Gap], K: int,
           provenance: dict, mismatches: int = 0,
           extension: Extension = ANNOTATION_EXTENSION) -> KeyframeQuery:
    ts = ctx.training
    kfs = []
    for q, g, mask, value in genes:
        width = len(ts.groups[ts.group_names[g]])
        vec = "".join("*" if not mask >> k & 1 else str(value >> k & 1) for k in range(width))
        kfs.append(Keyframe(ts.group_names[g], vec, int(q), keyframe_tolerance(mask, mismatches)))
    return KeyframeQuery(ctx.class_name, ctx.feature_set, dict(ts.groups), kfs, list(gaps), K,
                         extension, ctx.fps, provenance)


def _score_dict(ctx: _Context, genes, gaps, beta: float, mismatches: int = 0) -> dict:
    """The query's score on the training clips themselves (jittered copies left out)."""
    ts = ctx.training
    bounds = [(g.dmin, g.dmax) for g in gaps]
    orig = np.arange(ts.n_clips) < ts.n_original
    s = ts.score(genes, bounds, ctx.positives, beta, within=orig, mismatches=mismatches)
    return {**s.as_dict(beta), "negative_clips": int((~ctx.positives & orig).sum())}


def _provenance(ctx: _Context, method: str, template_info: dict, extra: dict) -> dict:
    ts = ctx.training
    recs = getattr(ts, "records", {})
    m = ts.n_original  # jittered copies follow the originals and are not listed
    training = [recs.get(n, {"clip": n, "class": str(c)})
                for n, c in zip(ts.clip_names[:m], ts.labels[:m])]
    return {"method": method, **extra, "template": template_info,
            "mtanno_version": __version__, "training": training}


# --------------------------------------------------------------------------- GA

#: Folds of held-out validation.
FOLDS = 3


def validation_folds(training: TrainingSet, positives: np.ndarray, *, folds: int = FOLDS,
                     ) -> tuple[np.ndarray, list[int], str]:
    """(fold of each clip, usable folds, how folds were made) for validating GA runs on
    held-out clips. With performers known for every clip (a manifest's actor column, truth
    documents) and at least two of them, performers are dealt to folds in name order
    (three actors, three folds: leave one actor out); otherwise clips are dealt to folds
    class by class in order. A fold is usable if the class has positives both in it and
    outside it."""
    perf = training.performers
    n = training.n_clips
    fold = np.zeros(n, np.int64)
    names = sorted({p for p in perf if p is not None})
    if all(p is not None for p in perf) and len(names) >= 2:
        k = min(folds, len(names))
        of = {p: i % k for i, p in enumerate(names)}
        fold[:] = [of[p] for p in perf]
        how = f"performers ({len(names)}) in {k} folds"
    else:
        k = folds
        seen: dict[str, int] = {}
        m = training.n_original
        for i in range(n):  # a jittered copy goes with its original
            c = training.labels[i]
            if i < m:
                fold[i] = seen.get(c, 0) % k
                seen[c] = seen.get(c, 0) + 1
            else:
                fold[i] = fold[i % m]
        how = f"clips in {k} folds, class by class"
    usable = [f for f in range(k) if (positives & (fold == f)).any()
              and (positives & (fold != f)).any() and (~positives & (fold != f)).any()]
    return fold, usable, how


def _ga_run(k: int, seed_seq) -> tuple[int, GARun, Score | None]:
    """GA run k in a worker (the problem, parameters and folds are the pool's shared data,
    :func:`mtanno.util.workers.shared`); with usable folds, it learns without fold
    ``usable[k % len]`` and is scored on that fold."""
    from mtanno.util.workers import shared

    pb, params, fold, usable = shared()
    held = None
    if usable:
        held = fold == usable[k % len(usable)]
        pb = Problem(pb.strict, pb.soft, pb.group_rows, pb.training, pb.positives, ~held)
    res = run_ga(pb, rng=np.random.default_rng(seed_seq), params=params)
    val = None
    if held is not None:
        val = pb.training.score(res.genes, res.gaps, pb.positives, params.beta, within=held,
                                mismatches=params.mismatches)
    return k, res, val


def run_seeds(class_name: str, seed: int, runs: int) -> list[np.random.SeedSequence]:
    """The seed sequence of every run: (seed, crc32(class name), run number)."""
    crc = zlib.crc32(class_name.encode("utf-8"))
    return [np.random.SeedSequence([int(seed), crc, k]) for k in range(runs)]


def _choose(results: list[GARun], full: list[Score], val: list[Score | None],
            ) -> tuple[int, float]:
    """Index of the winner to keep and its keyframe frequency (module docstring): the best
    validation F_β on its held-out fold, then keyframes occurring most often among all
    winners, then the fitness on all training clips, then fewer keyframes, then the lower
    run number."""
    count = Counter(g for r in results for g in set(r.genes))
    best, key, best_freq = 0, None, 0.0
    for i, r in enumerate(results):
        freq = sum(count[g] for g in r.genes) / len(r.genes)
        v = val[i].F if val[i] is not None else full[i].F
        k = (-v, -freq, -full[i].F, len(r.genes), i)
        if key is None or k < key:
            best, key, best_freq = i, k, freq
    return best, best_freq


def _learn_ga(ctx: _Context, template, *, runs: int, seed: int, jobs: int, params: GAParams,
              validate: bool, scheduler: str | None,
              progress: Callable[[int], None] | None) -> KeyframeQuery:
    from mtanno.templates.model import quantize
    from mtanno.util.workers import make_pool

    strict = quantize(template, 0.0).values
    problem = Problem(strict, ctx.soft, ctx.group_rows, ctx.training, ctx.positives)
    fold, usable, how = validation_folds(ctx.training, ctx.positives) if validate else \
        (None, [], "none")
    seeds = run_seeds(ctx.class_name, seed, runs)
    results: list[GARun | None] = [None] * runs
    val: list[Score | None] = [None] * runs
    with make_pool(jobs=jobs, scheduler=scheduler, n_tasks=runs,
                   shared=(problem, params, fold, usable)) as pool:
        for k, res, v in pool.map(_ga_run, list(enumerate(seeds)),
                                  chunksize=max(1, runs // (4 * jobs))):
            results[k], val[k] = res, v
            if progress:
                progress(1)
    full = [ctx.training.score(r.genes, r.gaps, ctx.positives, params.beta,
                               mismatches=params.mismatches) for r in results]
    win, freq = _choose(results, full, val)
    r = results[win]
    gaps = [Gap(lo, hi) for lo, hi in r.gaps]
    extension = _extension(ctx, r.genes, r.gaps, template.length, params.mismatches)
    fits = [x.F for x in full]
    vf = [v.F for v in val if v is not None]
    extra = {
        "seed": int(seed), "runs": runs, "params": params.as_dict(),
        "validation": {"folds": how, "usable_folds": len(usable),
                       "winner": None if val[win] is None else val[win].as_dict(params.beta),
                       "median_F": float(np.median(vf)) if vf else None},
        "winner_run": win, "winner_frequency": freq,
        "fitness": _score_dict(ctx, r.genes, gaps, params.beta, params.mismatches),
        "runs_fitness": {"best": max(fits), "median": float(np.median(fits)),
                         "min": min(fits)},
        "history_of_winner": {k: [round(x, 6) for x in v] for k, v in r.history.items()},
    }
    info = {"length": template.length, "quantized_for_init": 0.0}
    return _query(ctx, r.genes, gaps, template.length,
                  _provenance(ctx, "ga (MBS09 §6)", _template_info(template, info), extra),
                  params.mismatches, extension)


#: Margin on the widest reach seen in training (data-driven window extension).
EXTENSION_MARGIN = 1.5


def _extension(ctx: _Context, genes, gaps, K: int, mismatches: int) -> Extension:
    """Window widths for a learned query: the farthest a positive training clip reaches
    before its first and after its last hit frame, times EXTENSION_MARGIN, never wider
    than [MBS09]'s 2·(q1 − 1) and 2·(K − qn)."""
    lo, hi = ctx.training.margins(genes, gaps, ctx.positives, mismatches=mismatches)
    left = 2 * (genes[0][0] - 1)
    right = 2 * max(0, K - genes[-1][0])
    if len(lo):
        left = min(left, math.ceil(EXTENSION_MARGIN * int(lo.max())))
        right = min(right, math.ceil(EXTENSION_MARGIN * int(hi.max())))
    return Extension(0, 0, left, right)


def _template_info(template, extra: dict) -> dict:
    return {"class": template.class_name, "kind": template.kind,
            "training_examples": len(template.training), **extra}


# --------------------------------------------------------------------------- columns

def _pick_columns(score: np.ndarray, n: int) -> list[int]:
    """Up to ``n`` columns (0-based) with the highest scores, ignoring BORDER of the
    columns at each end and keeping picks at least K/(2n) apart (spread over the
    template); ties go to the earlier column."""
    K = len(score)
    margin = math.ceil(BORDER * K)
    cand = [q for q in range(margin, K - margin)] or list(range(K))
    order = sorted(cand, key=lambda q: (-score[q], q))
    spacing = max(1, K // (2 * n))
    picked: list[int] = []
    for q in order:
        if len(picked) == n:
            break
        if all(abs(q - p) >= spacing for p in picked):
            picked.append(q)
    return sorted(picked)


def _column_genes(ctx: _Context, values: np.ndarray, q: int) -> list[Gene]:
    """Keyframes of column q (0-based) of a quantized template: one per group that fixes
    some feature there, all at position q + 1."""
    out = []
    for g, rows in enumerate(ctx.group_rows):
        mask = value = 0
        for k, v in enumerate(values[rows, q]):
            if v != 0.5:
                mask |= 1 << k
                value |= int(v == 1.0) << k
        if mask:
            out.append((q + 1, g, mask, value))
    return out


def _gaps_between(genes: Sequence[Gene], between: Callable[[int, int], Gap]) -> list[Gap]:
    out = []
    for a, b in zip(genes[:-1], genes[1:]):
        out.append(Gap(0, 0) if a[0] == b[0] else between(a[0], b[0]))
    return out


def _learn_hard(ctx: _Context, template, examples, *, columns: int, beta: float,
                ) -> KeyframeQuery:
    """Thesis ch. 6: columns of the hard template occur in every training motion in order
    (Claim 3.1). Gap bounds are the smallest and largest distances between the first
    frames each training clip's hard-DTW alignment matches to the chosen columns, so
    every training clip of the class is retrieved."""
    from mtanno.templates.dtw import dtw
    from mtanno.templates.learn import learn

    mats = [ex.X.astype(float) for ex in examples]
    res = learn(mats, hard=True)
    H = res.values
    score = (H != 0.5).sum(axis=0).astype(float)
    cols = _pick_columns(score, columns)
    genes = [g for q in cols for g in _column_genes(ctx, H, q)]
    if not genes:
        raise MtannoError(f"class '{ctx.class_name}': the hard template fixes no feature in "
                          "any usable column (the examples agree on nothing)")
    firsts = []  # per example: first frame matched to each chosen column
    for X in mats:
        _, path = dtw(H, X, weights_v=res.weights, hard=True)
        first = {}
        for i, j in path:
            first.setdefault(int(i), int(j))
        firsts.append(first)
    lo: dict[tuple[int, int], int] = {}
    hi: dict[tuple[int, int], int] = {}
    for first in firsts:
        for a, b in zip(cols[:-1], cols[1:]):
            d = first[b] - first[a]
            lo[a, b] = min(lo.get((a, b), d), d)
            hi[a, b] = max(hi.get((a, b), d), d)
    gaps = _gaps_between(genes, lambda p, q: Gap(max(0, lo[p - 1, q - 1]), hi[p - 1, q - 1]))
    extra = {"columns": [q + 1 for q in cols], "border": BORDER,
             "hard_template": {"length": H.shape[1], "iterations": res.iterations,
                               "final_cost": res.final_cost},
             "fitness": _score_dict(ctx, genes, gaps, beta),
             "note": "positions are columns of the hard template (its length is "
                     "template_length)"}
    ext = _extension(ctx, genes, [(g.dmin, g.dmax) for g in gaps], H.shape[1], 0)
    return _query(ctx, genes, gaps, H.shape[1],
                  _provenance(ctx, "hard (thesis ch. 6: hard-template columns)",
                              _template_info(template, {"length": template.length}), extra),
                  0, ext)


def _learn_heuristic(ctx: _Context, template, *, columns: int, beta: float) -> KeyframeQuery:
    """[MR06] §5.4: columns of the quantized template (δ = 0.1) with many ones ("white",
    consistent action) and few wildcards ("gray"), away from the borders; gap bounds from
    the column distances with stiffness 0.5."""
    from mtanno.templates.model import quantize

    Q = quantize(template, HEURISTIC_DELTA).values
    score = (Q == 1.0).sum(axis=0) - (Q == 0.5).sum(axis=0)
    cols = _pick_columns(score.astype(float), columns)
    genes = [g for q in cols for g in _column_genes(ctx, Q, q)]
    if not genes:
        raise MtannoError(f"class '{ctx.class_name}': the quantized template fixes no "
                          "feature in any usable column")
    gaps = _gaps_between(genes, lambda p, q: Gap.from_stiffness(q - p, HEURISTIC_STIFFNESS))
    extra = {"columns": [q + 1 for q in cols], "border": BORDER, "delta": HEURISTIC_DELTA,
             "stiffness": HEURISTIC_STIFFNESS,
             "fitness": _score_dict(ctx, genes, gaps, beta)}
    ext = _extension(ctx, genes, [(g.dmin, g.dmax) for g in gaps], template.length, 0)
    return _query(ctx, genes, gaps, template.length,
                  _provenance(ctx, "heuristic (MR06 §5.4: quantized-template columns)",
                              _template_info(template, {"length": template.length}), extra),
                  0, ext)


# --------------------------------------------------------------------------- public

def learn_keyframes(training: TrainingSet, class_name: str, template, *, method: str = "ga",
                    examples=None, runs: int = DEFAULT_RUNS, seed: int = 0, jobs: int = 1,
                    params: GAParams | None = None, columns: int = DEFAULT_COLUMNS,
                    validate: bool = True, scheduler: str | None = None,
                    progress: Callable[[int], None] | None = None) -> KeyframeQuery:
    """Learn the keyframe query of ``class_name`` (docs/method.md §6).

    Parameters
    ----------
    training:
        Training clips of all classes (positives: this class; negatives: the others).
    template:
        The class's soft motion template (:class:`mtanno.templates.MotionTemplate`);
        positions refer to its columns (``hard``: to the hard template's).
    method:
        ``"ga"`` ([MBS09] §6), ``"hard"`` (thesis ch. 6) or ``"heuristic"`` ([MR06]).
    examples:
        The class's training examples (``hard`` learns its template from them).
    runs, seed, jobs, params, scheduler:
        GA: independent runs, the seed they derive from, worker processes (or a
        dask.distributed scheduler address, ``local:N``), GA parameters.
    columns:
        ``hard``/``heuristic``: number of template columns to take.
    validate:
        GA: learn each run without one fold of the training clips (held-out performers
        where known, :func:`validation_folds`) and keep the winner that scores best on
        its held-out fold; False: every run learns from all clips.
    progress:
        Called with 1 after each GA run.
    """
    if method not in METHODS:
        raise MtannoError(f"unknown keyframe method '{method}' (one of {', '.join(METHODS)})")
    for name, v in (("runs", runs), ("jobs", jobs), ("columns", columns)):
        if not isinstance(v, int) or isinstance(v, bool) or v < 1:
            raise MtannoError(f"{name} must be a positive integer, got {v!r}")
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise MtannoError(f"seed must be an integer ≥ 0, got {seed!r}")
    params = params or GAParams()
    ctx = _context(training, class_name, template)
    if method == "ga":
        if len(training.classes()) < 2:
            raise MtannoError("the genetic algorithm needs training clips of at least two "
                              "classes (the other classes are its negatives)")
        return _learn_ga(ctx, template, runs=runs, seed=seed, jobs=jobs, params=params,
                         validate=validate, scheduler=scheduler, progress=progress)
    if method == "hard":
        if not examples:
            raise MtannoError("the hard method needs the class's training examples")
        return _learn_hard(ctx, template, examples, columns=columns, beta=params.beta)
    return _learn_heuristic(ctx, template, columns=columns, beta=params.beta)


def query_score(training: TrainingSet, query: KeyframeQuery, *, beta: float = 2.0) -> Score:
    """P, R, F_β of any keyframe query (e.g. a hand-made one) on the training clips of its
    class (:meth:`TrainingSet.score_query`)."""
    return training.score_query(query, beta)
