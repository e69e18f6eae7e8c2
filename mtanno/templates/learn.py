"""Learning motion templates from example clips: soft MTs ([MR06] §4.1) and hard MTs (thesis §3.3).

Soft MT learning follows the reference implementation ("strategy 5") operation for
operation, as written down in ``docs/method/features.md`` §A, so that it reproduces the
golden templates of ``../shared/data/reference/mt/`` bit for bit:

1. Every iteration takes each example k in turn as the reference, warps every other
   example onto it with DTW (:mod:`mtanno.templates.dtw`; others in ascending order),
   averages the reference and the warped examples column by column, weighted
   (``T = Σ Wwt·Wwarp / Σ Wwt``, new weights ``Σ Wwt / N``), and *balances* the result:
   expand → contract → expand (:func:`expand`, :func:`contract`).
2. The N balanced templates are the next iteration's input (a Jacobi update). The
   alignment cost of reference k against example o, normalised by the total weight of
   k's new template, is the "spread"; the loop stops when its maximum is ≤ ``thresh``
   (0.005), when the maximum equals the previous one, or after ``iter_max`` (10)
   iterations.
3. The result is the template built with example 1 as reference in the last iteration.

Hard MTs (thesis §3.3.1, docs/method.md §3.2) use the same loop with the hard sum
(a value is kept where all inputs agree, else 0.5) in place of every weighted mean, and
the wildcard cost c_H in DTW. One change to the contraction: a light group left at the end
is merged with the whole previous output column instead of the single input column before
it (which drops inputs; see :func:`contract`). Then only the thesis' operations are used
and Claim 3.1 holds: every training example has DTW cost 0 against the hard MT.

Columns are frames at 30 Hz; a template's total weight approximates the mean training
length in frames. All sums run left to right, as in the reference implementation.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numba
import numpy as np

from mtanno._version import __version__
from mtanno.errors import MtannoError
from mtanno.templates.dtw import _all_references, _one_reference
from mtanno.templates.model import MotionTemplate
from mtanno.templates.training import TrainingExample, check_consistent

__all__ = [
    "ITER_MAX", "ITER_THRESH", "CONTRACT_MIN_WEIGHT", "ClassLearned", "LearnResult", "LearnRun",
    "average_step", "balance", "contract", "expand", "learn", "learn_classes", "learn_template",
    "learn_to_folder",
]

#: Defaults of the reference implementation (``motionTemplatePrecomputeBatch.m``).
ITER_MAX = 10
ITER_THRESH = 0.005
#: Contraction merges columns until their summed weight reaches this
#: (docs/method/features.md §A).
CONTRACT_MIN_WEIGHT = 0.75


# --------------------------------------------------------------------------- kernels


@numba.njit(cache=True)
def _round_half_away(x):
    """MATLAB ``round`` for x ≥ 0 (half away from zero; Python's round(2.5) is 2)."""
    r = math.floor(x)
    if x - r >= 0.5:
        r += 1.0
    return r


@numba.njit(cache=True)
def _expand(V, w):
    """Column i → max(1, round(w_i)) copies of weight w_i / copies."""
    p, n = V.shape
    reps = np.empty(n, dtype=np.int64)
    total = 0
    for i in range(n):
        r = int(_round_half_away(w[i]))
        if r < 1:
            r = 1
        reps[i] = r
        total += r
    V2 = np.empty((p, total))
    w2 = np.empty(total)
    t = 0
    for i in range(n):
        wi = w[i] / reps[i]
        for _ in range(reps[i]):
            for k in range(p):
                V2[k, t] = V[k, i]
            w2[t] = wi
            t += 1
    return V2, w2


@numba.njit(cache=True)
def _merge(V, w, a, b, hard, out, wout, col):
    """Columns a..b−1 of V → one column ``out[:, col]``: weighted mean (hard: hard sum),
    weight = their summed weight (left to right)."""
    s = 0.0
    for t in range(a, b):
        s += w[t]
    wout[col] = s
    for k in range(V.shape[0]):
        if hard:
            x = V[k, a]
            for t in range(a + 1, b):
                if V[k, t] != x:
                    x = 0.5
            out[k, col] = x
        else:
            acc = 0.0
            for t in range(a, b):
                acc += w[t] * V[k, t]
            out[k, col] = acc / s


@numba.njit(cache=True)
def _contract(V, w, hard, min_weight, whole_previous):
    """Left-to-right contraction (docs/method/features.md §A ``contract``).

    A light group that reaches the end is merged with the single input column before it
    and replaces the previous output column (the reference implementation; the other
    inputs of that output column are dropped), or, with ``whole_previous``, with all
    inputs of the previous output column (a merge of adjacent columns only, which hard
    MTs need for thesis Claim 3.1)."""
    p, n = V.shape
    V2 = np.empty((p, n))
    w2 = np.empty(n)
    no = 0
    i = 0
    last = 0  # first input column of the previous output column
    while i < n:
        if w[i] >= min_weight:
            for k in range(p):
                V2[k, no] = V[k, i]
            w2[no] = w[i]
            last = i
            no += 1
            i += 1
            continue
        s = w[i]
        j = i + 1
        while s < min_weight and j < n:
            s += w[j]
            j += 1
        if s >= min_weight:
            _merge(V, w, i, j, hard, V2, w2, no)
            last = i
            no += 1
            i = j
        elif no == 0:
            # everything left is lighter than min_weight and there is no column before it
            _merge(V, w, i, n, hard, V2, w2, no)
            no += 1
            i = n
        else:
            _merge(V, w, last if whole_previous else i - 1, n, hard, V2, w2, no - 1)
            i = n
    return V2[:, :no].copy(), w2[:no].copy()


@numba.njit(cache=True)
def _sum_lr(x):
    """Left-to-right sum (numpy's pairwise sum rounds differently)."""
    s = 0.0
    for v in x:
        s += v
    return s


# --------------------------------------------------------------------------- helpers


def _check_templates(templates: Sequence[np.ndarray], weights, hard: bool):
    if len(templates) == 0:
        raise MtannoError("no training examples")
    mats = []
    for n, X in enumerate(templates):
        X = np.asarray(X, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] == 0 or X.shape[0] == 0:
            raise MtannoError(f"example {n + 1} must be a non-empty (features × frames) "
                              f"matrix, got shape {X.shape}")
        if mats and X.shape[0] != mats[0].shape[0]:
            raise MtannoError(f"example {n + 1} has {X.shape[0]} features, example 1 has "
                              f"{mats[0].shape[0]}")
        if not np.isfinite(X).all() or X.min() < 0.0 or X.max() > 1.0:
            raise MtannoError(f"example {n + 1} has entries outside [0, 1] (or NaN)")
        if hard and not np.isin(X, (0.0, 0.5, 1.0)).all():
            raise MtannoError(f"example {n + 1}: hard learning needs entries 0, 0.5 or 1")
        mats.append(X)
    if weights is None:
        ws = [np.ones(X.shape[1]) for X in mats]
    else:
        if len(weights) != len(mats):
            raise MtannoError(f"{len(weights)} weight vectors for {len(mats)} examples")
        ws = []
        for n, (X, w) in enumerate(zip(mats, weights)):
            w = np.asarray(w, dtype=np.float64)
            if w.shape != (X.shape[1],) or not (np.isfinite(w).all() and (w > 0).all()):
                raise MtannoError(f"example {n + 1}: weights must be {X.shape[1]} positive "
                                  f"finite numbers")
            ws.append(w)
    return mats, ws


def _pack(mats, ws):
    off = np.zeros(len(mats) + 1, dtype=np.int64)
    off[1:] = np.cumsum([X.shape[1] for X in mats])
    vals = np.ascontiguousarray(np.concatenate(mats, axis=1))
    wts = np.ascontiguousarray(np.concatenate(ws))
    return vals, wts, off


def _buffers(p: int, maxlen: int, total: int):
    return dict(num=np.empty((p, total)), den=np.empty(total), D=np.empty((maxlen, maxlen)),
                pi=np.empty(2 * maxlen, dtype=np.int64),
                pj=np.empty(2 * maxlen, dtype=np.int64), S=np.empty((p, maxlen)),
                wd=np.empty(maxlen))


def _finish(num, den, N, hard):
    """Average → balance: ``T = num ./ den``, ``Tw = den / N``, expand-contract-expand."""
    T = np.ascontiguousarray(num if hard else num / den)
    Tw = den / N
    return _balance(T, Tw, hard)


def _balance(T, Tw, hard):
    T, Tw = _expand(T, Tw)
    T, Tw = _contract(T, Tw, hard, CONTRACT_MIN_WEIGHT, hard)
    return _expand(T, Tw)


# --------------------------------------------------------------------------- public API


def expand(values: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Expansion operator (thesis §3.3.1; docs/method/features.md §A): every column i
    becomes ``max(1, round(w_i))`` copies (rounding half away from zero) of weight
    w_i / copies."""
    V, w = _check_templates([values], [weights], False)
    return _expand(np.ascontiguousarray(V[0]), w[0])


def contract(values: np.ndarray, weights: np.ndarray, *, hard: bool = False,
             whole_previous: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Contraction operator (docs/method/features.md §A): scanning left to right, a column
    lighter than 0.75 is merged with the following ones until their weight reaches 0.75
    (weighted mean, or hard sum when ``hard``).

    A light group left at the end is merged with the input column before it and replaces
    the previous output column, dropping that column's other inputs (reference
    implementation; default for soft MTs), or, with ``whole_previous`` (default for hard
    MTs), merged with the whole previous output column — only adjacent columns are ever
    merged then, which thesis Claim 3.1 relies on.
    """
    V, w = _check_templates([values], [weights], hard)
    whole = bool(hard) if whole_previous is None else bool(whole_previous)
    return _contract(np.ascontiguousarray(V[0]), w[0], bool(hard), CONTRACT_MIN_WEIGHT, whole)


def balance(values: np.ndarray, weights: np.ndarray, *,
            hard: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """"Unwarp" a template by its weights: expand, contract, expand (thesis eq. 3.5)."""
    V, w = _check_templates([values], [weights], hard)
    return _balance(np.ascontiguousarray(V[0]), w[0], bool(hard))


def average_step(templates: Sequence[np.ndarray], *, reference: int = 0,
                 weights: Sequence[np.ndarray] | None = None,
                 hard: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One reference-based averaging step (thesis eq. 3.4–3.5; one pass of the loop body
    of docs/method/features.md §A for one reference).

    Every other template is warped onto ``templates[reference]`` (0-based), all are
    averaged (soft: weighted mean; hard: hard sum) and the result is balanced. Returns
    ``(values, weights, costs)`` with ``costs[o]`` the DTW cost of template o against the
    reference (0 for the reference itself), not normalised.
    """
    mats, ws = _check_templates(templates, weights, hard)
    N = len(mats)
    if not 0 <= reference < N:
        raise MtannoError(f"reference {reference} out of range (0..{N - 1})")
    vals, wts, off = _pack(mats, ws)
    maxlen = int(np.diff(off).max())
    buf = _buffers(vals.shape[0], maxlen, vals.shape[1])
    cost = np.zeros(N)
    _one_reference(vals, wts, off, reference, bool(hard), buf["num"], buf["den"], cost,
                   buf["D"], buf["pi"], buf["pj"], buf["S"], buf["wd"])
    a, b = off[reference], off[reference + 1]
    T, Tw = _finish(buf["num"][:, a:b], buf["den"][a:b], N, bool(hard))
    return T, Tw, cost


@dataclass
class LearnResult:
    """A learned template and how the learning went.

    Attributes
    ----------
    values:
        (features × K) template, entries in [0, 1] (hard: 0, 0.5 or 1); K columns at 30 Hz.
    weights:
        (K,) column weights; their sum approximates the mean training length in frames.
    iterations:
        Number of learning iterations run.
    cost_max, cost_mean:
        Per iteration, the maximum and mean normalised alignment cost (the "spread";
        the mean includes each reference's zero cost against itself).
    """

    values: np.ndarray
    weights: np.ndarray
    iterations: int
    cost_max: list[float] = field(default_factory=list)
    cost_mean: list[float] = field(default_factory=list)

    @property
    def final_cost(self) -> float:
        """Final maximum normalised alignment cost (0 if no iteration ran)."""
        return self.cost_max[-1] if self.cost_max else 0.0


def learn(examples: Sequence[np.ndarray], *, hard: bool = False, iter_max: int = ITER_MAX,
          thresh: float = ITER_THRESH,
          weights: Sequence[np.ndarray] | None = None) -> LearnResult:
    """Learn a motion template from N examples of one class (docs/method.md §3.1–3.2).

    Parameters
    ----------
    examples:
        (features × frames_n) matrices at 30 Hz, entries in [0, 1] (training clips: 0/1).
        Their order matters: the template learned with example 1 as reference is
        returned, and ties are broken by order.
    hard:
        Learn a hard MT (thesis §3.3.1) instead of a soft one ([MR06] §4.1).
    iter_max, thresh:
        Stop after ``iter_max`` iterations, or once the maximum normalised alignment cost
        is ≤ ``thresh`` or no longer changes.
    weights:
        Initial column weights per example (default: all 1).
    """
    if not isinstance(iter_max, int) or isinstance(iter_max, bool) or iter_max < 1:
        raise MtannoError(f"iter_max must be a positive integer, got {iter_max!r}")
    if not (isinstance(thresh, (int, float)) and math.isfinite(thresh) and thresh >= 0):
        raise MtannoError(f"thresh must be a finite number ≥ 0, got {thresh!r}")
    U, w = _check_templates(examples, weights, hard)
    hard = bool(hard)
    N = len(U)
    p = U[0].shape[0]
    it = 0
    emax = thresh + 1.0
    eprev = 0.0
    cost_max: list[float] = []
    cost_mean: list[float] = []
    while it < iter_max and emax > thresh and eprev != emax:
        eprev = emax
        it += 1
        vals, wts, off = _pack(U, w)
        maxlen = int(np.diff(off).max())
        buf = _buffers(p, maxlen, vals.shape[1])
        # per reference k the largest and the summed cost of the examples against it,
        # normalised by the weight of its new template: N values, not an N × N matrix
        cmax, csum, scale = np.empty(N), np.empty(N), np.empty(N)
        _all_references(vals, wts, off, hard, buf["num"], buf["den"], cmax, csum, buf["D"],
                        buf["pi"], buf["pj"], buf["S"], buf["wd"])
        U_new, w_new = [], []
        for k in range(N):
            a, b = off[k], off[k + 1]
            T, Tw = _finish(buf["num"][:, a:b], buf["den"][a:b], N, hard)
            scale[k] = _sum_lr(Tw)
            U_new.append(T)
            w_new.append(Tw)
        emax = float((cmax / scale).max())
        cost_max.append(emax)
        cost_mean.append(float((csum / scale).sum() / (N * N)))
        U, w = U_new, w_new
    return LearnResult(values=U[0], weights=w[0], iterations=it, cost_max=cost_max,
                       cost_mean=cost_mean)


def learn_template(examples: Sequence[TrainingExample], *, class_name: str | None = None,
                   hard: bool = False, iter_max: int = ITER_MAX,
                   thresh: float = ITER_THRESH) -> MotionTemplate:
    """Learn the motion template of one class from loaded training examples
    (:func:`mtanno.templates.training.load_examples`), in the given order.

    The class name defaults to the examples' (which must then all agree). A soft template
    is returned unquantized (``delta`` None; quantize it with
    :func:`mtanno.templates.model.quantize` for matching); a hard template is quantized by
    construction (``delta`` 0: δ = 0 quantization leaves it unchanged).
    """
    if not examples:
        raise MtannoError("no training examples")
    check_consistent(examples)
    if class_name is None:
        names = sorted({ex.class_name for ex in examples})
        if len(names) > 1:
            raise MtannoError(f"examples of several classes ({', '.join(names)}); learn "
                              f"one class at a time or give class_name")
        class_name = names[0]
    res = learn([ex.X for ex in examples], hard=hard, iter_max=iter_max, thresh=thresh)
    first = examples[0]
    params = {
        "method": "hard (thesis 3.3.1)" if hard else "soft (MR06 4.1, reference strategy 5)",
        "iter_max": iter_max,
        "iter_thresh": thresh,
        "contract_min_weight": CONTRACT_MIN_WEIGHT,
        "local_cost": ("sum of wildcard-free |x-y| (c_H) x mean column weight" if hard else
                       "mean |x-y| over features x mean column weight"),
        "reference_example": 1,
        "examples": len(examples),
        "mtanno_version": __version__,
    }
    return MotionTemplate(
        class_name=class_name, feature_names=list(first.feature_names), values=res.values,
        weights=res.weights, feature_set=first.feature_set, fps=first.fps,
        kind="hard" if hard else "soft", quantized=bool(hard), delta=0.0 if hard else None,
        training=[ex.record() for ex in examples], params=params,
        iterations=res.iterations, final_cost=res.final_cost,
        history={"max": res.cost_max, "mean": res.cost_mean})


@dataclass(frozen=True)
class ClassLearned:
    """One class of :func:`learn_classes`: its template (None when it failed, ``error``
    saying why), how many examples it was learned from, and a warning for few examples."""

    class_name: str
    template: MotionTemplate | None
    n_examples: int = 0
    error: str | None = None
    warning: str | None = None


def learn_classes(groups: dict, *, hard: bool = False, iter_max: int = ITER_MAX,
                  thresh: float = ITER_THRESH):
    """Learn every class of ``groups`` (class name → its example sources,
    :func:`mtanno.templates.training.group_by_class`), in order, yielding a
    :class:`ClassLearned` per class as it is done. A class that cannot be learned (an
    example that cannot be read, features unlike the first class's) is yielded with its
    error and the others go on: the batch of ``mtanno learn-mt`` and
    :func:`mtanno.api.learn_templates`. The examples of every class must have the layout of
    the first class learned."""
    from mtanno.templates.training import few_examples_warning, load_examples

    reference = None
    for name, sources in groups.items():
        try:
            examples = load_examples(sources)
            check_consistent(examples, like=reference)
            reference = reference or examples[0]
            mt = learn_template(examples, class_name=name, hard=hard, iter_max=iter_max,
                                thresh=thresh)
        except MtannoError as exc:
            yield ClassLearned(name, None, error=str(exc))
            continue
        yield ClassLearned(name, mt, len(examples),
                           warning=few_examples_warning(name, len(examples)))


@dataclass
class LearnRun:
    """What :func:`learn_to_folder` did: the classes written and those that failed, the
    examples the written ones were learned from, seconds of learning, and the training
    inputs that gave no example (each an error; the others were used)."""

    written: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    n_examples: int = 0
    seconds: float = 0.0
    skipped: list[MtannoError] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        """0 when every class was written from every input, else 1."""
        return 1 if self.failed or self.skipped else 0


def learn_to_folder(training: Sequence[str | os.PathLike], outdir: str | os.PathLike, *,
                    manifest: str | os.PathLike | None = None,
                    features_dir: str | os.PathLike | None = None, split: str | None = None,
                    truth: str | os.PathLike | None = None, classes: Sequence[str] = (),
                    hard: bool = False, iter_max: int = ITER_MAX, thresh: float = ITER_THRESH,
                    wait: bool = False, on_wait: Callable[[str], None] | None = None,
                    note: Callable[[str], None] | None = None,
                    on_start: Callable[[int], None] | None = None,
                    progress: Callable[[ClassLearned, str | None], None] | None = None,
                    inside_input: bool = False) -> LearnRun:
    """The whole ``mtanno learn-mt`` run: the training examples named as
    :func:`mtanno.templates.training.collect_sources` takes them (``note`` receives its
    notes), grouped by class (only ``classes``, if given), every output checked against the
    inputs, and one template per class learned (:func:`learn_classes`) and written to
    ``outdir/CLASS.json`` under the folder's lock (:func:`mtanno.util.locks.folder_lock`;
    ``wait``/``on_wait`` as there; a run that writes nothing leaves no new folder; an
    ``outdir`` that is or lies inside a folder of training files only with
    ``inside_input``). A class
    that fails fails alone, as does a training folder that gives no example
    (:attr:`LearnRun.skipped`). ``on_start(n)`` is called
    before the first of ``n`` classes, ``progress(done, error)`` after each (``error``: why
    it failed, None when it was written)."""
    import time

    from mtanno.templates.model import class_file, save_template
    from mtanno.templates.training import collect_sources, group_by_class, input_folders
    from mtanno.util.locks import folder_lock
    from mtanno.util.output import output_folder
    from mtanno.util.preflight import check_outputs

    run = LearnRun()
    sources = collect_sources(training, manifest=manifest, features_dir=features_dir,
                              split=split, truth=truth, note=note, failures=run.skipped)
    groups = group_by_class(sources, classes=list(classes) or None)
    out = Path(outdir)
    check_outputs([out / f"{c}.json" for c in groups if c and "/" not in c and "\0" not in c],
                  [*(s.path for s in sources), manifest, truth], folders={out: []},
                  scanned=input_folders(training, features_dir), inside_input=inside_input,
                  writable=False)  # a class whose file cannot be written fails alone
    t0 = time.perf_counter()
    if on_start:
        on_start(len(groups))
    with output_folder(out), folder_lock(out, wait=wait, on_wait=on_wait):
        for done in learn_classes(groups, hard=hard, iter_max=iter_max, thresh=thresh):
            try:
                if done.error is not None:
                    raise MtannoError(done.error)
                save_template(class_file(out, done.class_name), done.template)
            except MtannoError as exc:
                run.failed.append(done.class_name)
                if progress:
                    progress(done, str(exc))
                continue
            run.written.append(done.class_name)
            run.n_examples += done.n_examples
            if progress:
                progress(done, None)
    run.seconds = time.perf_counter() - t0
    return run
