"""``mtanno tune``: the annotation parameters learned by cross-validation inside the
training data (issue 10; ``docs/annotation.md``).

For every fold (:mod:`mtanno.tuning.cv`) the templates are learned from the other folds'
examples, quantized with each δ of :data:`DELTA_GRID`, and matched against the fold's
held-out documents once; then the parameters are chosen by coordinate search, each
candidate scored by annotating all held-out documents from those cached distance
functions (:func:`mtanno.annotate.label_document` / :func:`mtanno.annotate.decode.decode_segments`,
exactly what ``annotate --classes`` does). The objective is

    J = (F1 + F2) / 2 − w · U

with F1, F2 the frame and segment F-measures over all folds ([MBS09] §7) and U the
unknown-class rate — for each class in turn left out of the templates, the fraction of
its held-out frames that another class labels — weighted by ``unknown_weight`` (w). A
class without a template in a fold (its examples all held out) is unknown there: its
frames count in U and are ignored by F1 and F2 (:func:`mtanno.tuning.score.count`).

The search, in this order, each step only over the methods switched on
(:data:`METHODS`):

1. one τ for all classes (grid :data:`TAU_GRID`), for each δ of :data:`DELTA_GRID`
   (``delta``) and with and without the segment decoder (``resolve``);
2. boundary refinement (``refine``): the decoder's slack (:data:`SLACK_GRID`), or the
   extension over unclaimed frames only;
   then, with the segment decoder, its segment cost (``segments``): λ of
   :data:`SEGMENT_COSTS` together with the one τ again (λ shifts the threshold);
3. several templates per class (``templates``): each class split into 2 or 3 groups of
   examples (:mod:`mtanno.tuning.cluster`), kept where J rises by more than :data:`EPS`;
   then time-scaled copies of the classes' templates (:mod:`mtanno.templates.tempo`: a
   faster, a slower or both of :data:`~mtanno.templates.tempo.TEMPO_SCALES`), greedily: the
   class and copies that raise J most (by more than :data:`EPS`) first, as long as all
   copies together match at most :data:`~mtanno.templates.tempo.COPY_BUDGET` times the
   templates' columns (they cost annotation time in proportion);
4. per-class τ (``tau``): τ_p scaled by :data:`TAU_STEPS`, two sweeps, a change kept
   where J rises by more than :data:`EPS`;
5. rejection (``reject``): a ceiling ρ_p = m·τ_p (m in :data:`REJECT_STEPS`) per class,
   kept where J rises by more than :data:`EPS`;
6. frame-wise tie-breaking (``frames``): the evidence weight (:data:`FRAME_WEIGHTS`), kept
   where J rises by more than :data:`EPS` (the evidence costs annotation time);
7. all τ and ρ scaled together once more (:data:`SCALE_STEPS`).

Everything is deterministic for a seed (fold composition, grouping, learning, search
order); ``n_jobs`` only spreads the learning, the matching and the scoring of each step's
candidates over processes. A step scores every candidate's runs with all classes first
and its runs with a class left out only while the candidate can still win
(:meth:`Tuner._best`): the same choice for a fraction of the work.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from mtanno.annotate import ClassConfig, label_document
from mtanno.annotate.decode import DEFAULT_SLACK, decode_segments, fold_label, relative_evidence
from mtanno.errors import MtannoError
from mtanno.templates.params import ANNOTATION_DELTA, ANNOTATION_TAU
from mtanno.templates.tempo import COPY_BUDGET, TEMPO_SCALES
from mtanno.tuning.cv import Fold
from mtanno.tuning.folddata import (
    _FoldData,
    _sub_arrays,
    fold_data,
    prepare_fold_class,
)
from mtanno.tuning.score import (  # unchecked: own segments
    Counts,
    _count,
    _cover,
    _covered_fraction,
)

__all__ = ["DELTA_GRID", "EPS", "FRAME_WEIGHTS", "METHODS", "REJECT_STEPS", "SCALE_SETS",
           "SCALE_STEPS", "SEGMENT_COSTS", "SLACK_GRID", "TAU_GRID", "TAU_STEPS",
           "UNKNOWN_WEIGHT", "Evaluation", "Params", "Tuner", "prepare_fold_class"]

#: The methods ``tune`` can switch on (all by default); ``--disable`` names them.
METHODS = ("tau", "reject", "refine", "resolve", "segments", "templates", "frames", "delta")
#: Quantization δ tried ([MBS09] uses 0.05; examples of varied styles want a larger one).
DELTA_GRID = (0.05, 0.15, 0.25, 0.35)
#: One τ for all classes, tried first.
TAU_GRID = (0.03, 0.04, 0.05, 0.065, 0.08, 0.1, 0.13, 0.16, 0.2, 0.25, 0.3, 0.4, 0.5)
#: Slack of the decoder's segment starts (frames at 30 Hz).
SLACK_GRID = (0, 1, 2, 3, 5, 8)
#: Segment costs λ of the decoder tried (in frames: a match must save λ unlabelled frames).
SEGMENT_COSTS = (0.0, 2.0, 4.0, 6.0, 10.0, 15.0)
#: Factors tried on a class's τ.
TAU_STEPS = (0.6, 0.8, 1.25, 1.6)
#: Rejection ceilings tried, as fractions of the class's τ.
REJECT_STEPS = (0.3, 0.45, 0.6, 0.8)
#: Weights of the frame-wise evidence tried.
FRAME_WEIGHTS = (0.0, 0.1, 0.3, 1.0)
#: Group counts tried for several templates per class.
GROUPS = (2, 3)
#: Sets of tempo factors tried for a class's time-scaled templates (each alone, then all).
SCALE_SETS = (*((f,) for f in TEMPO_SCALES), tuple(TEMPO_SCALES))
#: Factors on all τ and ρ tried at the end.
SCALE_STEPS = (0.8, 0.9, 1.1, 1.25)
#: Smallest rise of J for which a per-class change is kept (guards against noise).
EPS = 0.002
#: Default weight of the unknown-class rate in the objective.
UNKNOWN_WEIGHT = 0.02
#: Runs with a class left out remembered (a few steps' worth; oldest dropped first).
HIDDEN_CACHE = 4096


@dataclass
class Params:
    """A point of the search: δ, decoder, refinement, and per class τ, ρ, the number of
    template groups (1: the class's template only) and the tempo factors of its
    time-scaled templates."""

    delta: float = ANNOTATION_DELTA
    resolve: bool = False
    refine: bool = False
    slack: int = DEFAULT_SLACK
    tau: dict[str, float] = field(default_factory=dict)
    reject: dict[str, float] = field(default_factory=dict)
    groups: dict[str, int] = field(default_factory=dict)
    scales: dict[str, tuple[float, ...]] = field(default_factory=dict)
    frame_weight: float = 0.0
    segment_cost: float = 0.0

    def copy(self, **changes) -> Params:
        out = replace(self, tau=dict(self.tau), reject=dict(self.reject),
                      groups=dict(self.groups), scales=dict(self.scales))
        for k, v in changes.items():
            setattr(out, k, v)
        return out

    def config(self, *, default_tau: float | None = None) -> ClassConfig:
        """The class configuration of these parameters (τ equal to ``default_tau`` are
        left to ``[tau] default``)."""
        taus = list(self.tau.values())
        default = default_tau if default_tau is not None else \
            (max(set(taus), key=taus.count) if taus else ANNOTATION_TAU)
        return ClassConfig(default_tau=default,
                           tau={c: t for c, t in self.tau.items() if t != default},
                           resolve=self.resolve, refine=self.refine, slack=self.slack,
                           frame_weight=self.frame_weight, segment_cost=self.segment_cost,
                           delta=self.delta,
                           reject={c: r for c, r in self.reject.items() if r != math.inf})


@dataclass
class Evaluation:
    """Scores of one parameter point over all folds: J, the pooled counts, the unknown
    rate U (and its frames), per-class counts and per-class unknown rates."""

    J: float
    counts: Counts
    unknown: float
    unknown_frames: tuple[int, int]
    per_class: dict[str, Counts] = field(default_factory=dict)
    per_class_unknown: dict[str, tuple[int, int]] = field(default_factory=dict)

    def summary(self) -> str:
        p1, r1, f1 = self.counts.frame()
        p2, r2, f2 = self.counts.segment()
        return (f"P1 {p1:.3f} R1 {r1:.3f} F1 {f1:.3f} P2 {p2:.3f} R2 {r2:.3f} F2 {f2:.3f} "
                f"unknown {self.unknown:.3f} J {self.J:.4f}")


@dataclass
class _Part:
    """The scores of a parameter point's runs with every class (:meth:`Tuner._main_part`):
    pooled counts, the unknown-class counts so far (hit, frames), per class."""

    total: Counts
    unk: list[int]
    per: dict[str, Counts]
    per_unk: dict[str, tuple[int, int]]


def _groups_text(split: dict[str, int]) -> str:
    """The classes with several templates, for the search log: ``squat 2, kick 3 (others
    one)``, or ``one per class``."""
    if not split:
        return "one per class"
    return ", ".join(f"{c} {k}" for c, k in split.items()) + " (others one)"


def _scales_text(scaled: dict[str, Sequence[float]]) -> str:
    """The tempo factors of the classes' time-scaled templates, for the search log:
    ``lieDownFloor ×0.6, squat ×0.6 ×1.6``, or ``none``."""
    if not scaled:
        return "none"
    return ", ".join(f"{c} " + " ".join(f"×{f:g}" for f in fs) for c, fs in scaled.items())

class Tuner:
    """Scores parameter points on cached fold data and searches them (module docstring)."""

    def __init__(self, folds: Sequence[Fold], prepared: dict[tuple[str, str], dict], *,
                 classes: Sequence[str], methods: Sequence[str] = METHODS,
                 unknown_weight: float = UNKNOWN_WEIGHT, log: Callable[[str], None] | None = None,
                 columns: dict | None = None,
                 fetch: Callable[[float], dict] | None = None, jobs: int = 1):
        """``prepared``: (fold, class) → ``{"groups": …, "match": …}`` as
        :func:`prepare_fold_class` returns it. ``columns``: the matching columns
        (:func:`mtanno.templates.tempo.matched_columns`) of each class's template (key:
        class) and of its time-scaled copies (key: (class, factor)), for the copies'
        budget; None: no budget.

        ``fetch``: when given, ``prepared`` holds only template (1, 0) of every class (what
        the search's first step needs, at every δ), and ``fetch(δ)`` gives, in the same
        form, the matches of all templates with their evidence at δ; it is called the
        first time a point at δ needs them (issue 34: only the δ the search chose is kept
        whole). ``jobs`` > 1: the candidates of a search step are scored in that many
        worker processes (forked: they share the cached fold data)."""
        self._fetch = fetch
        self._whole: set[float] = set()
        #: (fold, class left out, the other classes' parameters) → its unknown-class
        #: counts: the candidates of a per-class step share the run without their class
        self._hidden: dict[tuple, tuple[int, int]] = {}
        self.jobs = int(jobs)
        self._pool = None
        self.classes = list(classes)
        self.columns = columns
        self.methods = set(methods)
        self.unknown_weight = float(unknown_weight)
        self.log = log or (lambda msg: None)
        names = list(self.classes)
        for f in folds:
            for c, _, _ in f.held_out.truth:
                if c not in names:
                    names.append(c)
        self.names = names
        self.ids = {c: i for i, c in enumerate(names)}
        self.folds: list[_FoldData] = [fold_data(f, prepared, self.classes, self.ids)
                                       for f in folds]
        self.evaluations = 0
        #: frames of all runs with a class left out (the unknown rate's denominator, less
        #: the classes absent from a fold): the same for every parameter point
        self._left_out_frames = sum(b - a + 1 for fd in self.folds
                                    for c, sub in fd.hidden.items()
                                    for a, b in sub.truth_by_class[c])

    # ------------------------------------------------------------------ fold data

    def _need(self, params: Params) -> None:
        """Fetch the matches of all templates at ``params.delta`` if ``params`` needs more
        than template (1, 0) without evidence and they are not here yet."""
        if self._fetch is None or params.delta in self._whole:
            return
        if not (params.frame_weight > 0 or any(k > 1 for k in params.groups.values())
                or any(params.scales.values())):
            return
        got = self._fetch(params.delta)
        for fd in self.folds:
            for c in fd.classes:
                for (delta, k, i), v in got[(fd.name, c)]["match"].items():
                    fd.match[(delta, c, k, i)] = v
        self._whole.add(params.delta)
        self._close_pool()  # its workers hold the fold data as it was

    def _close_pool(self, *, error: bool = False) -> None:
        pool, self._pool = self._pool, None
        if pool is not None:
            if error:
                pool.stop()
            else:
                pool.__exit__(None, None, None)

    # ------------------------------------------------------------------ scoring

    def _templates(self, fd: _FoldData, c: str, params: Params) -> list[tuple[int, int]]:
        k = params.groups.get(c, 1)
        n = fd.groups.get((c, k), 1) if k > 1 else 1
        return ([(1, 0)] + ([(n, i) for i in range(n)] if n > 1 else [])
                + [(0, f) for f in params.scales.get(c, ())])

    def decoder_arrays(self, fd: _FoldData, params: Params):
        """Δ/τ (ρ applied), starts and frame evidence per class of the fold (segment
        decoder), as :func:`mtanno.annotate.label_document` builds them."""
        L = fd.n_frames
        P = len(fd.classes)
        mat = np.full((P, L), np.inf)
        st = np.full((P, L), -1, dtype=np.int64)
        ev = np.full((P, L), np.inf) if params.frame_weight > 0 else None
        for p, c in enumerate(fd.classes):
            tau, rho = params.tau[c], params.reject.get(c, math.inf)
            for k, i in self._templates(fd, c, params):
                d, s, e = fd.match[(params.delta, c, k, i)]
                fold_label(mat[p], st[p], d, s, tau=tau, reject=rho)
                if ev is not None and e is not None:  # a time-scaled copy's equals (1, 0)'s
                    np.minimum(ev[p], e, out=ev[p])
        return mat, st, ev

    def fold_segments(self, fd: _FoldData, params: Params, classes: Sequence[str], arrays=None):
        """Output segments (label id, first, last) of one fold with ``classes`` only
        (``arrays``: :meth:`decoder_arrays` of the fold, for the segment decoder)."""
        if params.resolve:
            mat, st, ev = arrays if arrays is not None else self.decoder_arrays(fd, params)
            rows = [fd.classes.index(c) for c in classes]
            if len(rows) < len(fd.classes):
                mat, st = mat[rows], st[rows]
                ev = None if ev is None else ev[rows]
            dec = decode_segments(mat, st, tau=np.ones(len(rows)), slack=params.slack
                                  if params.refine else 0, evidence=None if ev is None
                                  else relative_evidence(ev), weight=params.frame_weight,
                                  segment_cost=params.segment_cost,
                                  boundaries=fd.offsets[1:-1])
            return [(self.ids[classes[d.label]], d.start, d.end) for d in dec]
        return self._reference_segments(fd, params, classes)

    def _reference_segments(self, fd: _FoldData, params: Params, classes: Sequence[str]):
        """The reference decoder (Δ̄, labels, extension) on all held-out documents at once:
        one frame of Δ = ∞ between documents keeps runs and extensions inside them (Δ̄
        picks never cross documents: their spans come from per-document matching); frames
        are mapped back afterwards. Equal to :func:`label_document` per document."""
        cfg = ClassConfig(tau=dict(params.tau), reject=dict(params.reject),
                          refine=params.refine)
        cuts = fd.offsets[1:-1]
        shift = np.arange(1, len(cuts) + 1)
        names, arrays = [], []
        for c in classes:
            for k, i in self._templates(fd, c, params):
                d, s, _ = fd.match[(params.delta, c, k, i)]
                s = np.where(s >= 0, s + np.searchsorted(cuts, s, side="right"), -1)
                names.append(c)
                arrays.append((c, np.insert(d, cuts, np.inf), np.insert(s, cuts, -1), None))
        L = fd.n_frames + len(cuts)
        rows, _, _ = label_document("d", names, iter(arrays), L, config=cfg)
        sep = np.zeros(L, dtype=bool)
        sep[cuts + shift - 1] = True
        back = np.arange(L) - np.cumsum(sep)  # frame of the concatenation without separators
        return [(self.ids[r.label], int(back[r.start]), int(back[r.end])) for r in rows]

    def _without(self, params: Params, c: str) -> tuple:
        """What the run with class ``c`` left out depends on: ``params`` but ``c``'s own."""
        return (params.delta, params.resolve, params.refine, params.slack,
                params.frame_weight, params.segment_cost,
                tuple((x, params.tau.get(x), params.reject.get(x), params.groups.get(x, 1),
                       tuple(params.scales.get(x, ()))) for x in self.classes if x != c))

    def evaluate(self, params: Params, *, per_class: bool = False) -> Evaluation:
        """J and the counts of ``params`` over all folds (unknown rate with each class left
        out in turn)."""
        part, arrays = self._main_part(params, per_class=per_class, keep=True)
        return self._left_out_part(params, part, arrays, per_class=per_class)

    def _main_part(self, params: Params, *, per_class: bool = False,
                   keep: bool = False) -> tuple[_Part, list | None]:
        """The part of :meth:`evaluate` with every class: the pooled counts (per class
        with ``per_class``) and the unknown-class counts of the classes absent from a
        fold; with ``keep`` also every fold's :meth:`decoder_arrays` (the segment decoder's)."""
        self._need(params)
        self.evaluations += 1
        total = Counts.zero()
        unk = [0, 0]
        per: dict[str, Counts] = {}
        per_unk: dict[str, tuple[int, int]] = {}
        kept = [] if keep else None
        for fd in self.folds:
            arrays = self.decoder_arrays(fd, params) if params.resolve else None
            if kept is not None:
                kept.append(arrays)
            segs = self.fold_segments(fd, params, fd.classes, arrays)
            if fd.truth_cover is None:
                fd.truth_cover = _cover(fd.truth, len(self.names), fd.n_frames)
            total += _count(fd.truth, segs, len(self.names), fd.n_frames, fd.ignore,
                            fd.truth_cover)
            if per_class:
                for c in self.classes:
                    cid = self.ids[c]
                    got = _count([t for t in fd.truth if t[0] == cid],
                                 [s for s in segs if s[0] == cid], len(self.names), fd.n_frames,
                                 fd.ignore)
                    per.setdefault(c, Counts.zero())
                    per[c] += got
            for c, spans in fd.absent.items():  # unknown here, whatever the weight
                hit, n = _covered_fraction(spans, segs, fd.n_frames)
                unk[0] += hit
                unk[1] += n
                h0, n0 = per_unk.get(c, (0, 0))
                per_unk[c] = (h0 + hit, n0 + n)
        return _Part(total, unk, per, per_unk), kept

    def _left_out_part(self, params: Params, part: _Part, arrays: list | None = None, *,
                       per_class: bool = False, beat: tuple | None = None,
                       ) -> Evaluation | None:
        """:meth:`evaluate` from its :meth:`_main_part`: the runs with each class left out
        added to the unknown-class counts (``arrays``: the folds' kept arrays; else made
        again where a run needs them). ``beat`` = (J, inclusive): give up, returning None,
        as soon as J can no longer exceed that value (or equal it, when ``inclusive`` is
        false) — the unknown-class counts only grow, so J only falls as runs are added."""
        total = part.total
        unk = list(part.unk)
        per_unk = dict(part.per_unk)
        F = (total.frame()[2] + total.segment()[2]) / 2
        w = self.unknown_weight
        if w > 0 or per_class:
            N = unk[1] + self._left_out_frames
            for j, fd in enumerate(self.folds):
                fold_arrays = arrays[j] if arrays is not None else None
                for c, sub in fd.hidden.items():
                    if beat is not None:
                        J_up = F - w * (unk[0] / N if N else 0.0)
                        if J_up < beat[0] or (J_up == beat[0] and not beat[1]):
                            return None
                    key = (fd.name, c, self._without(params, c))
                    got = self._hidden.get(key)
                    if got is None:
                        if params.resolve and fold_arrays is None:
                            fold_arrays = self.decoder_arrays(fd, params)
                        rest = [x for x in fd.classes if x != c]
                        sub_arrays = fold_arrays if sub is fd or fold_arrays is None else \
                            _sub_arrays(sub, fold_arrays)
                        got = _covered_fraction(sub.truth_by_class[c], self.fold_segments(
                            sub, params, rest, sub_arrays) if rest else [], sub.n_frames)
                        if len(self._hidden) >= HIDDEN_CACHE:
                            del self._hidden[next(iter(self._hidden))]
                        self._hidden[key] = got
                    hit, n = got
                    unk[0] += hit
                    unk[1] += n
                    h0, n0 = per_unk.get(c, (0, 0))
                    per_unk[c] = (h0 + hit, n0 + n)
        U = unk[0] / unk[1] if unk[1] else 0.0
        J = (total.frame()[2] + total.segment()[2]) / 2 - w * U
        if beat is not None and (J < beat[0] or (J == beat[0] and not beat[1])):
            return None
        return Evaluation(J, total, U, (unk[0], unk[1]), part.per, per_unk)

    # ------------------------------------------------------------------ search

    def _best(self, candidates: Sequence[Params], current: Evaluation | None = None,
              eps: float = 0.0) -> tuple[Params | None, Evaluation | None]:
        """The candidate of highest J (the first of equals), if it beats ``current`` by
        more than ``eps``.

        Exactly that, with less work (issue 34): every candidate's run with all classes
        first — J is at most its F-measure part less w times the unknown-class rate of the
        classes absent from a fold — then, from the highest such bound down, the runs with
        a class left out, each candidate given up as soon as its J can no longer beat the
        best so far (nor ``current`` by ``eps``). With ``jobs`` > 1 both stages run in the
        workers, the second a worker-sized wave at a time."""
        candidates = list(candidates)
        if not candidates:
            return None, None
        floor = current.J + eps if current is not None else None
        parts = self._map(_main_shared, [(c,) for c in candidates])
        w = self.unknown_weight
        ups = []
        for part in parts:
            N = part.unk[1] + (self._left_out_frames if w > 0 else 0)
            F = (part.total.frame()[2] + part.total.segment()[2]) / 2
            ups.append(F - w * (part.unk[0] / N if N else 0.0))
        order = sorted(range(len(candidates)), key=lambda i: (-ups[i], i))
        best_i, best_ev = None, None

        def beat(i: int) -> tuple[float, bool] | None:
            """What candidate i must beat: (J, equal is enough), or None (nothing yet)."""
            rules = []
            if floor is not None:
                rules.append((floor, False))
            if best_ev is not None:
                rules.append((best_ev.J, i < best_i))
            if not rules:
                return None
            return max(rules, key=lambda r: (r[0], not r[1]))

        def hopeless(i: int) -> bool:
            b = beat(i)
            return b is not None and (ups[i] < b[0] or (ups[i] == b[0] and not b[1]))

        pending = list(order)
        while pending:
            wave, rest = [], []
            for i in pending:
                if hopeless(i):
                    continue
                (wave if len(wave) < max(1, self.jobs) else rest).append(i)
            if not wave:
                break
            got = self._map(_left_out_shared, [(candidates[i], parts[i], beat(i))
                                                for i in wave])
            for i, ev in zip(wave, got):
                if ev is not None and (best_ev is None or ev.J > best_ev.J
                                       or (ev.J == best_ev.J and i < best_i)):
                    best_i, best_ev = i, ev
            pending = rest
        if best_ev is None or (floor is not None and best_ev.J <= floor):
            return None, None
        return candidates[best_i], best_ev

    def _map(self, fn, args: list[tuple]) -> list:
        """``fn(self, *a)`` of every ``a``, in order: in the worker processes when ``jobs``
        > 1 (the fold data each candidate needs fetched first)."""
        for a in args:
            self._need(a[0])
        if self.jobs < 2 or len(args) < 2:
            return [fn(*a, tuner=self) for a in args]
        if self._pool is None:
            from mtanno.util.workers import WorkerPool

            self._pool = WorkerPool(self.jobs, shared=self)
        return list(self._pool.map(fn, args))

    def with_tau(self, p: Params, tau: float) -> Params:
        return p.copy(tau={c: tau for c in self.classes}, reject={})

    def search(self, *, delta: float = ANNOTATION_DELTA, methods: Sequence[str] | None = None,
               ) -> tuple[Params, Evaluation, list[str]]:
        """The coordinate search of the module docstring over ``methods`` (default: the
        tuner's); returns the best parameters, their evaluation and a log of the steps
        (one line each, with J)."""
        try:
            got = self._search(delta=delta, methods=methods)
        except BaseException:
            self._close_pool(error=True)
            raise
        self._close_pool()
        return got

    def _search(self, *, delta: float, methods: Sequence[str] | None,
                ) -> tuple[Params, Evaluation, list[str]]:
        on = set(self.methods if methods is None else methods)
        steps: list[str] = []

        def note(what: str, ev: Evaluation) -> None:
            line = f"{what}: {ev.summary()}"
            steps.append(line)
            self.log(line)

        base = Params(delta=delta, resolve="resolve" in on, refine="refine" in on,
                      slack=DEFAULT_SLACK, groups={c: 1 for c in self.classes})
        ref_ev = self.evaluate(self.with_tau(base.copy(resolve=False, refine=False),
                                              ANNOTATION_TAU))
        note(f"reference (tau {ANNOTATION_TAU}, delta {delta})", ref_ev)
        # 1. one τ, per δ and decoder
        deltas = [float(d) for d in DELTA_GRID] if "delta" in on else [float(delta)]
        decoders = [True, False] if "resolve" in on else [False]
        cur, cur_ev = self._best([self.with_tau(base.copy(delta=dl, resolve=res,
                                                         refine=base.refine), t)
                                  for dl in deltas for res in decoders for t in TAU_GRID])
        note(f"one tau {cur.tau[self.classes[0]]:g}, delta {cur.delta:g}, "
             f"{'segment decoder' if cur.resolve else 'reference decoder'}", cur_ev)
        # 2. boundary refinement
        if "refine" in on:
            cands = ([cur.copy(slack=s, refine=s > 0) for s in SLACK_GRID] if cur.resolve
                     else [cur.copy(refine=r) for r in (False, True)])
            got, ev = self._best(cands)
            if ev.J > cur_ev.J:
                cur, cur_ev = got, ev
            what = (f"slack {cur.slack}" if cur.resolve and cur.refine else
                    "extension over unclaimed frames" if cur.refine else "off")
            note(f"refine: {what}", cur_ev)
        if "segments" in on and cur.resolve:
            got, ev = self._best([self.with_tau(cur.copy(segment_cost=lam), t)
                                  for lam in SEGMENT_COSTS[1:] for t in TAU_GRID], cur_ev, EPS)
            if got is not None:
                cur, cur_ev = got, ev
            note(f"segment cost {cur.segment_cost:g}, one tau {cur.tau[self.classes[0]]:g}",
                 cur_ev)
        # 3. several templates per class
        if "templates" in on:
            for c in self.classes:
                got, ev = self._best([cur.copy(groups={**cur.groups, c: k}) for k in GROUPS],
                                     cur_ev, EPS)
                if got is not None:
                    cur, cur_ev = got, ev
            split = {c: k for c, k in cur.groups.items() if k > 1}
            note(f"templates {_groups_text(split)}", cur_ev)
            cur, cur_ev, used = self._copies(cur, cur_ev)
            scaled = {c: fs for c, fs in cur.scales.items() if fs}
            budget = "" if self.columns is None else \
                f" ({used} of {self._budget()} columns)"
            note(f"time-scaled templates {_scales_text(scaled)}{budget}", cur_ev)
        # 4. per-class τ
        if "tau" in on:
            for _ in range(2):
                changed = False
                for c in self.classes:
                    got, ev = self._best([cur.copy(tau={**cur.tau, c: _round(cur.tau[c] * f)})
                                          for f in TAU_STEPS], cur_ev, EPS)
                    if got is not None:
                        cur, cur_ev, changed = got, ev, True
                if not changed:
                    break
            note("per-class tau", cur_ev)
        # 5. rejection ceilings
        if "reject" in on:
            for c in self.classes:
                got, ev = self._best([cur.copy(reject={**cur.reject, c: _round(cur.tau[c] * m)})
                                      for m in REJECT_STEPS], cur_ev, EPS)
                if got is not None:
                    cur, cur_ev = got, ev
            note(f"reject {len(cur.reject)} classes", cur_ev)
        # 6. frame-wise tie-breaking
        if "frames" in on and cur.resolve:  # evidence costs time: kept only where it pays
            got, ev = self._best([cur.copy(frame_weight=w) for w in FRAME_WEIGHTS[1:]],
                                 cur_ev, EPS)
            if got is not None:
                cur, cur_ev = got, ev
            note(f"frame weight {cur.frame_weight:g}", cur_ev)
        # 7. all thresholds scaled together
        got, ev = self._best([cur.copy(tau={c: _round(t * s) for c, t in cur.tau.items()},
                                       reject={c: _round(r * s) for c, r in cur.reject.items()})
                              for s in SCALE_STEPS], cur_ev, EPS)
        if got is not None:
            cur, cur_ev = got, ev
        note("final", cur_ev)
        return cur, self.evaluate(cur, per_class=True), steps


    def _budget(self) -> int:
        """Columns all time-scaled copies together may have."""
        return int(COPY_BUDGET * sum(self.columns[c] for c in self.classes))

    def _copies(self, cur: Params, cur_ev: Evaluation) -> tuple[Params, Evaluation, int]:
        """Step 3's time-scaled copies: repeatedly, of every class without copies yet and
        every set of :data:`SCALE_SETS` that fits into the budget, the one of highest J
        (the first of equals) is kept if it raises J by more than :data:`EPS`. Returns the
        parameters, their evaluation and the columns the copies use."""
        used = 0
        while True:
            cands, costs = [], []
            for c in self.classes:
                if cur.scales.get(c):
                    continue
                for fs in SCALE_SETS:
                    cost = 0 if self.columns is None else \
                        sum(self.columns[(c, f)] for f in fs)
                    if self.columns is not None and used + cost > self._budget():
                        continue
                    cands.append(cur.copy(scales={**cur.scales, c: fs}))
                    costs.append(cost)
            got, ev = self._best(cands, cur_ev, EPS)
            if got is None:
                return cur, cur_ev, used
            used += costs[cands.index(got)]
            cur, cur_ev = got, ev


def _main_shared(params: Params, *, tuner: Tuner | None = None) -> _Part:
    """:meth:`Tuner._main_part` (in a worker of the tuner's pool: ``tuner`` None)."""
    if tuner is None:
        from mtanno.util.workers import shared

        tuner = shared()
    return tuner._main_part(params)[0]


def _left_out_shared(params: Params, part: _Part, beat, *,
                     tuner: Tuner | None = None) -> Evaluation | None:
    """:meth:`Tuner._left_out_part` (in a worker of the tuner's pool: ``tuner`` None)."""
    if tuner is None:
        from mtanno.util.workers import shared

        tuner = shared()
    return tuner._left_out_part(params, part, beat=beat)


def _round(x: float) -> float:
    """A threshold to 4 significant digits: the configuration reads 0.1248, not
    0.12480000000000001 (and holds exactly the value that was scored)."""
    return float(f"{x:.4g}")


def check_methods(methods: Sequence[str]) -> list[str]:
    """``methods`` checked against :data:`METHODS`."""
    bad = [m for m in methods if m not in METHODS]
    if bad:
        raise MtannoError(f"unknown method(s) {', '.join(bad)} (choose from {', '.join(METHODS)})")
    return [m for m in METHODS if m in methods]
