"""The whole ``mtanno tune`` run: read the training inputs, build the folds, learn and match
per fold and class (in worker processes), search (:class:`mtanno.tuning.search.Tuner`),
learn the final extra templates, and write the class configuration.

Files read: the templates folder (classes, layout, learning parameters), the keyframe
folder if given, and the training examples' feature files — nothing else (a test watches
every file the run opens).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mtanno.annotate.decode import EVIDENCE_MARGIN
from mtanno.errors import MtannoError
from mtanno.templates.params import ANNOTATION_TAU
from mtanno.templates.tempo import TEMPO_SCALES, matched_columns, time_scaled
from mtanno.templates.training import ExampleSource, TrainingExample
from mtanno.tuning.cv import DOCUMENT_MODES, MAX_EXAMPLES, learning_subset, make_folds
from mtanno.tuning.folddata import learn_fold_class, match_fold_class
from mtanno.tuning.search import (
    GROUPS,
    METHODS,
    UNKNOWN_WEIGHT,
    Evaluation,
    Params,
    Tuner,
    check_methods,
)
from mtanno.tuning.write import (
    bank_path_of,
    check_tuned_output,
    frame_bank_path_of,
    template_folder_of,
    tuned_paths,
    write_tuned,
)

__all__ = ["VERIFY_MODES", "TuneOptions", "TuneResult", "bank_path_of", "frame_bank_path_of",
           "template_folder_of", "tune", "tune_files", "write_tuned"]  # the paths and
# write_tuned from mtanno.tuning.write, for callers


#: How ``tune`` verifies segments for their confidence (:attr:`TuneOptions.verify`).
VERIFY_MODES = ("auto", "poses", "features", "none")


@dataclass(frozen=True)
class TuneOptions:
    """What :func:`tune` (and :func:`tune_files`) learns and how (``mtanno tune``'s
    options; the defaults are the command's).

    ``keyframes_dir``: keyframe queries (``learn-keyframes``); the held-out documents are
    then matched only inside their candidate windows, as ``annotate --keyframes`` does (the
    queries were learned on all training examples, so the cross-validated scores are a
    little optimistic). ``methods``: those of :data:`METHODS` to tune (the others stay as
    in the reference annotation; kept in :data:`METHODS` order). ``documents``: how
    held-out clips become documents (:data:`mtanno.tuning.cv.DOCUMENT_MODES`), composed in
    an order seeded by ``seed``. ``unknown_weight``: w of the objective (a finite number ≥
    0). ``ablation``: also search once with each method left out and once with none
    (:attr:`TuneResult.ablation`). ``n_jobs`` local processes, or a dask.distributed
    ``scheduler``, run the per fold and class tasks — with the same result.

    Issue 26: ``background`` — feature files (or folders of them) of motions of none of
    the classes, held out with the folds (every label on them counts as wrong).
    ``confidence``: learn each segment's confidence and the minimum confidence of an
    output row (:mod:`mtanno.tuning.confidence`), verifying segments against the examples
    by ``verify`` (:data:`VERIFY_MODES`: ``"poses"``, ``"features"``, ``"none"`` — the
    evidence of cost and length only — or ``"auto"``: poses when every training and
    background file has them). ``invariance`` (issue 35): what the pose verification is
    blind to (:data:`mtanno.confidence.verify.INVARIANCES`; needs verification by poses).
    ``evidence``: the kinds of evidence the confidence may use (:data:`mtanno.confidence.
    evidence.EVIDENCE`; None: all that the inputs allow). Issue 34: ``max_examples`` —
    every template learned is learned from at most that many of the class's examples
    (:func:`mtanno.tuning.cv.learning_subset`; None or 0: all), as learning costs the
    square of the examples."""

    keyframes_dir: str | os.PathLike | None = None
    seed: int = 0
    n_jobs: int = 1
    methods: tuple[str, ...] = METHODS
    documents: str = "composed"
    unknown_weight: float = UNKNOWN_WEIGHT
    ablation: bool = False
    scheduler: str | None = None
    background: tuple[str | os.PathLike, ...] = ()
    verify: str = "auto"
    confidence: bool = True
    invariance: tuple[str, ...] = ()
    evidence: tuple[str, ...] | None = None
    max_examples: int | None = MAX_EXAMPLES

    def __post_init__(self):
        for name in ("methods", "background", "invariance",
                     *(("evidence",) if self.evidence is not None else ())):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        methods = _check_options(self.methods, self.documents, self.unknown_weight,
                                 self.verify, self.evidence)
        object.__setattr__(self, "methods", tuple(methods))  # in METHODS order
        for name, least in (("seed", 0), ("n_jobs", 1)):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < least:
                raise MtannoError(f"{{{name}}} must be an integer ≥ {least}, got {v!r}",
                                  options=(name,))


@dataclass
class TuneResult:
    """What :func:`tune` found: the parameters, their cross-validated evaluation (pooled
    over folds, per class), the search log, the extra templates per class (several
    templates per class), the reference annotation's evaluation on the same folds, and
    what was read (``inputs``: files with SHA-256; ``folds``: held-out performer → number
    of held-out examples)."""

    params: Params
    evaluation: Evaluation
    reference: Evaluation
    steps: list[str]
    classes: list[str]
    extra_templates: dict[str, list] = field(default_factory=dict)
    inputs: list[dict] = field(default_factory=list)
    folds: dict[str, int] = field(default_factory=dict)
    seed: int = 0
    methods: list[str] = field(default_factory=list)
    documents: str = "composed"
    unknown_weight: float = UNKNOWN_WEIGHT
    seconds: float = 0.0
    ablation: dict[str, TuneResult] = field(default_factory=dict)
    #: class → SHA-256 of the template file tuned with (``[tuned_with]`` of the config)
    template_sha256: dict[str, str] = field(default_factory=dict)
    #: the background documents tuned with (path, SHA-256 each; ``[background]``)
    background: list[dict] = field(default_factory=list)
    #: the learned confidence (:class:`mtanno.tuning.confidence.ConfidenceFit`; None: none)
    confidence: object = None
    #: the verification bank of all training examples and background documents (None:
    #: no verification)
    bank: object = None
    #: the frame classifier's bank of the same (None: the confidence does not use it)
    frame_bank: object = None
    #: the most examples a template was learned from (None: all; issue 34)
    max_examples: int | None = None
    #: the templates' feature set (what the documents' feature files must hold)
    feature_set: str | None = None
    #: where :func:`tune_files` wrote the extra templates (None: it wrote none, or
    #: :func:`tune` alone)
    extra_folder: Path | None = None

    @property
    def not_validated(self) -> list[str]:
        """Classes that no fold could score: all their examples come from one performer,
        so no fold has both their template and held-out examples of them (their
        thresholds are learned only from the motions they must not label)."""
        return [c for c in self.classes
                if c not in self.evaluation.per_class
                or not self.evaluation.per_class[c].frame_support]


def _learn_params(mt) -> dict:
    p = mt.params or {}
    out = {"hard": mt.kind == "hard"}
    if isinstance(p.get("iter_max"), int) and p["iter_max"] >= 1:
        out["iter_max"] = int(p["iter_max"])
    if isinstance(p.get("iter_thresh"), (int, float)) and p["iter_thresh"] >= 0:
        out["thresh"] = float(p["iter_thresh"])
    return out


def _spans(windows_per_doc: list[list[tuple[int, int]]], offsets: np.ndarray, margin: int = 0):
    """Absolute merged spans of per-document windows, widened by ``margin`` within each
    document (as annotate widens a document's windows for the frame evidence)."""
    from mtanno.annotate import merged_spans

    starts, ends = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for (a, b), wins in zip(zip(offsets[:-1], offsets[1:]), windows_per_doc):
        s, e = merged_spans([(s - margin, e + margin) for s, e in wins], int(b - a))
        starts.append(s + a)
        ends.append(e + a)
    return np.concatenate(starts), np.concatenate(ends)


def _final_groups(cls: str, examples: list[TrainingExample], k: int, learn: dict) -> list:
    """The group templates of a class learned from its training examples (all of them, or
    the :func:`mtanno.tuning.cv.learning_subset` the caller drew)."""
    from mtanno.templates.learn import learn_template
    from mtanno.tuning.cluster import example_distances, group_examples

    lab = group_examples(example_distances(examples), k)
    n = int(lab.max()) + 1
    if n < 2:
        return []
    return [learn_template([e for e, g in zip(examples, lab) if g == i], class_name=cls,
                           **learn) for i in range(n)]


def tune(sources: Sequence[ExampleSource], mt_dir: str | os.PathLike,
         options: TuneOptions | None = None, *,
         log: Callable[[str], None] | None = None) -> TuneResult:
    """Learn the annotation parameters of the classes in ``mt_dir`` by cross-validation
    inside the training examples ``sources`` (:func:`mtanno.templates.training.
    collect_sources`) as ``options`` say (:class:`TuneOptions`): see
    :mod:`mtanno.tuning.search` for the search and :mod:`mtanno.tuning.cv` for the folds.
    ``log`` receives one line per search step.

    With ``options.ablation``, ``TuneResult.ablation`` maps ``"without-METHOD"`` and
    ``"none"`` to the searches with each method of ``methods`` left out and with none of
    them (one τ for all classes), on the same folds. With a ``scheduler`` the examples and
    held-out documents are sent to the cluster once, the tasks carry indices
    (:func:`mtanno.util.workers.make_pool`). Issue 34: the search keeps template (1, 0)'s
    distance functions at every δ and the others' only at the δ it chose (memory linear
    in training frames).
    """
    o = options or TuneOptions()
    keyframes_dir, seed, n_jobs, documents = o.keyframes_dir, o.seed, o.n_jobs, o.documents
    unknown_weight, scheduler, verify, confidence = (o.unknown_weight, o.scheduler, o.verify,
                                                     o.confidence)
    evidence, max_examples = o.evidence, o.max_examples
    t0 = time.perf_counter()
    methods = list(o.methods)
    templates, layout, examples, queries = _tune_inputs(sources, mt_dir, keyframes_dir,
                                                        poses=verify in ("auto", "poses"))
    bg_docs, bg_records = _background_inputs(o.background, layout, examples,
                                             poses=verify in ("auto", "poses"))
    representation = _representation(verify, examples, bg_docs) if confidence else None
    classes = list(templates)
    folds = make_folds(examples, documents=documents, seed=seed,
                       read_document=_read_document if any(
                           s.start is not None for s in sources) else None,
                       background=bg_docs)
    if representation == "poses" and any(f.held_out.poses is None for f in folds):
        if verify == "poses":
            raise MtannoError("{verify} poses needs poses in every held-out document (run "
                              "mtanno features --poses)", options=("verify",))
        representation = "features"  # auto: a document without poses
    invariance = _invariance(o.invariance, representation) if confidence else ()
    learn = {c: _learn_params(templates[c]) for c in classes}
    shared = {"examples": examples,
              "held": {f.name: (f.held_out.X, f.held_out.offsets) for f in folds}}
    tuner = _tuner(folds, examples, templates, queries, layout, methods, learn, shared,
                   n_jobs=n_jobs, scheduler=scheduler, max_examples=max_examples, seed=seed,
                   unknown_weight=unknown_weight, log=log)
    delta0 = _deltas(methods, templates)[0]
    params, evaluation, steps = tuner.search(delta=delta0)
    reference = tuner.evaluate(tuner.with_tau(Params(delta=delta0), ANNOTATION_TAU), per_class=True)
    variants = {}
    if o.ablation:
        for name, subset in [*((f"without-{m}", [x for x in methods if x != m])
                               for m in methods), ("none", [])]:
            if log:
                log(f"ablation {name}:")
            variants[name] = tuner.search(delta=delta0, methods=subset)
    extra_of = _further_templates([params, *(v[0] for v in variants.values())], examples,
                                  templates, learn, n_jobs=n_jobs, scheduler=scheduler,
                                  shared=shared, max_examples=max_examples, seed=seed)
    fit, bank, frame_bank = _learn_confidence(
        tuner, params, folds, templates, examples, bg_docs, representation, unknown_weight,
        seed, log, tuple(invariance), evidence) if confidence else (None, None, None)
    inputs, shas = _input_records(mt_dir, templates, keyframes_dir, examples)
    folds_held = {f.name: len(f.held_examples) for f in folds}
    seconds = time.perf_counter() - t0
    result = TuneResult(params, evaluation, reference, steps, classes, extra_of(params), inputs,
                        folds_held, seed, methods, documents, unknown_weight, seconds,
                        template_sha256=shas, background=bg_records, confidence=fit,
                        bank=bank, frame_bank=frame_bank, max_examples=max_examples or None,
                        feature_set=layout.feature_set)
    for name, (p, ev, st) in variants.items():
        subset = [x for x in methods if f"without-{x}" != name] if name != "none" else []
        result.ablation[name] = TuneResult(p, ev, reference, st, classes, extra_of(p), inputs,
                                           folds_held, seed, subset, documents, unknown_weight,
                                           seconds, template_sha256=shas,
                                           max_examples=max_examples or None,
                                           feature_set=layout.feature_set)
    return result


def tune_files(training: Sequence[str | os.PathLike], mt_dir: str | os.PathLike,
               output: str | os.PathLike, options: TuneOptions | None = None, *,
               manifest: str | os.PathLike | None = None,
               features_dir: str | os.PathLike | None = None, split: str | None = None,
               truth: str | os.PathLike | None = None,
               ablation_dir: str | os.PathLike | None = None, inside_input: bool = False,
               log: Callable[[str], None] | None = None, command: Sequence[str] = (),
               failures: list[MtannoError] | None = None) -> TuneResult:
    """The whole ``mtanno tune`` run: the training examples named as
    :func:`mtanno.templates.training.collect_sources` takes them, every output checked
    against the inputs before any work (:func:`mtanno.util.preflight.check_outputs`),
    :func:`tune` as ``options`` say (:class:`TuneOptions`), and the configuration written
    to ``output`` by :func:`mtanno.tuning.write.write_tuned` (a configuration folder, or a
    ``.toml`` file with its bank and extra templates beside it; the result's
    :attr:`~TuneResult.extra_folder` names where the extra templates went); with
    ``ablation_dir`` the ablation is run (whatever ``options.ablation`` says) and written
    as ``without-METHOD.toml`` and ``none.toml`` there (a folder that is,
    or lies inside, a folder of the inputs only with ``inside_input``). ``log`` receives
    the notes on the inputs and the search log, a line each; ``failures`` receives the
    training folders that give no example (the others are used; without it such a folder is
    an error)."""
    from dataclasses import replace

    from mtanno.keyframes import keyframe_files
    from mtanno.templates.store import template_files
    from mtanno.templates.training import collect_sources, input_folders
    from mtanno.util.output import make_folder
    from mtanno.util.preflight import check_outputs

    o = options or TuneOptions()
    keyframes_dir = o.keyframes_dir
    sources = collect_sources(training, manifest=manifest, features_dir=features_dir,
                              split=split, truth=truth, note=log, failures=failures)
    ablations = [*(f"without-{m}" for m in METHODS), "none"] if ablation_dir else []
    check_tuned_output(output)
    planned = [tuned_paths(output)[0],
               *([bank_path_of(output)] if o.confidence else []),
               *([frame_bank_path_of(output)] if o.confidence
                 and "classifier" in (o.evidence or ()) else []),
               *(Path(ablation_dir) / f"{n}.toml" for n in ablations)]
    scanned = input_folders(training, features_dir, also=[mt_dir, keyframes_dir])
    check_outputs(planned, [mt_dir, *template_files(mt_dir), manifest, truth,
                            *(s.path for s in sources), *o.background,
                            *(keyframe_files(keyframes_dir) if keyframes_dir else [])],
                  folders={ablation_dir: []} if ablation_dir else None, scanned=scanned,
                  inside_input=inside_input)
    if log:
        files = {s.path for s in sources}
        log(f"training inputs: {len(sources)} examples in {len(files)} feature files"
            + (f" (manifest {manifest}, split {split or 'all'})" if manifest
               else f" (truth {truth})" if truth else ""))
    if ablation_dir is not None and not o.ablation:
        o = replace(o, ablation=True)
    result = tune(sources, mt_dir, o, log=log)
    write_tuned(output, result, command=command)
    if result.extra_templates:
        result.extra_folder = template_folder_of(output)
    if ablation_dir is not None:
        make_folder(ablation_dir)
        for name, variant in result.ablation.items():
            write_tuned(Path(ablation_dir) / f"{name}.toml", variant, command=command)
    return result


def _invariance(invariance, representation) -> tuple[str, ...]:
    """``tune``'s invariances checked against the bank's representation."""
    from mtanno.confidence.verify import check_invariance

    try:
        return check_invariance(invariance, representation)
    except MtannoError as exc:
        raise MtannoError(f"{{invariance}}: {exc.message}", options=("invariance",)) from None


def _check_options(methods, documents, unknown_weight, verify, evidence=None) -> list[str]:
    """:func:`tune`'s options checked; returns the methods in :data:`METHODS` order."""
    if evidence is not None:
        from mtanno.confidence.evidence import EVIDENCE

        unknown = [e for e in evidence if e not in EVIDENCE]
        if unknown or not evidence:
            raise MtannoError(f"{{evidence}} must name some of {', '.join(EVIDENCE)}, got "
                              f"{', '.join(evidence) or 'none'}", options=("evidence",))
    methods = check_methods(methods)
    if documents not in DOCUMENT_MODES:
        raise MtannoError(f"unknown {{documents}} {documents!r} (choose from "
                          f"{', '.join(DOCUMENT_MODES)})", options=("documents",))
    if not (unknown_weight >= 0 and math.isfinite(unknown_weight)):
        raise MtannoError(f"unknown weight must be a finite number ≥ 0, got {unknown_weight!r}")
    if verify not in VERIFY_MODES:
        raise MtannoError(f"unknown {{verify}} {verify!r} (choose from "
                          f"{', '.join(VERIFY_MODES)})", options=("verify",))
    return methods


def _read_document(path):
    """The features and poses (None without) of a whole training document (examples cut
    from annotated ones)."""
    from mtanno.features.store import read_features

    ff = read_features(path, poses=True)
    return ff.X, ff.poses


def _representation(verify: str, examples, bg_docs) -> str | None:
    """The bank's representation for ``verify`` (None: no bank)."""
    if verify == "none":
        return None
    posed = all(e.poses is not None for e in examples) and all(
        p is not None for _, _, p in bg_docs)
    if verify == "poses" and not posed:
        raise MtannoError("{verify} poses needs poses in every training and background "
                          "feature file (run mtanno features --poses)", options=("verify",))
    return "poses" if verify == "poses" or (verify == "auto" and posed) else "features"


def _background_inputs(background, layout, examples, *, poses: bool):
    """The background documents ((name, features, poses or None) each) of the feature
    files named by ``background`` (files, or folders searched for them) and their records
    (path, SHA-256). Each must have the templates' ``layout`` and must not be a training
    file."""
    if not background:
        return [], []
    from mtanno.features.inputs import feature_files
    from mtanno.features.store import check_layout, read_features

    training = {e.sha256: e.file for e in examples}
    docs, records = [], []
    for path in feature_files(background):
        ff = read_features(path, sha256=True, poses=poses)
        check_layout(ff, layout, path=str(path))
        if ff.sha256 in training:
            raise MtannoError(f"background file is also a training file ({training[ff.sha256]}"
                              "): background motions must hold none of the classes",
                              path=str(path))
        if ff.X.shape[1] == 0:
            raise MtannoError("background feature file has no frames", path=str(path))
        docs.append((ff.document, ff.X, ff.poses))
        records.append({"path": str(path), "sha256": ff.sha256})
    return docs, records


def _learn_confidence(tuner, params, folds, templates, examples, bg_docs, representation,
                      unknown_weight, seed, log, invariance=(), evidence=None):
    """The confidence fitted on the folds, the verification bank of everything and the
    frame classifier's bank (None unless the confidence uses it)."""
    from mtanno.confidence.evidence import FRAME_EVIDENCE
    from mtanno.confidence.verify import sequence
    from mtanno.tuning.confidence import bank_of, frame_bank_of, learn_confidence

    seqs = None
    if representation is not None:
        seqs = [sequence(X=X, poses=P, representation=representation, invariance=invariance)
                for _, X, P in bg_docs]
    if log:
        log(f"confidence: verifying by {representation or 'nothing'}"
            + (f" ({', '.join(invariance)})" if invariance else "")
            + f"; {len(bg_docs)} background documents")
    fit = learn_confidence(tuner, params, folds, templates=templates, background_seqs=seqs,
                           representation=representation, unknown_weight=unknown_weight,
                           seed=seed, log=log, invariance=invariance, evidence=evidence,
                           background_X=[X for _, X, _ in bg_docs])
    bank = bank_of(examples, seqs, representation, invariance) \
        if representation is not None else None
    frames = None
    if any(n in FRAME_EVIDENCE for n in fit.evidence):
        frames = frame_bank_of(examples, [X for _, X, _ in bg_docs])
    return fit, bank, frames


def _tune_inputs(sources, mt_dir, keyframes_dir, *, poses: bool = False):
    """The templates of ``mt_dir``, their feature layout, the training examples (each of
    that layout; every class must have some) and the keyframe queries of
    ``keyframes_dir`` (empty without)."""
    from mtanno.features.store import check_layout
    from mtanno.templates.store import load_template_folder
    from mtanno.templates.training import group_by_class, load_examples

    templates = load_template_folder(mt_dir)
    classes = list(templates)
    first = next(iter(templates.values()))
    layout = first.layout(f"the templates in {mt_dir}")
    groups = group_by_class(sources)
    examples = [e for c in groups for e in load_examples(groups[c], poses=poses)]
    for ex in examples:
        check_layout(ex.layout(), layout, path=ex.file)
    no_examples = [c for c in classes if c not in groups]
    if no_examples:
        raise MtannoError(f"no training examples of class(es) {', '.join(no_examples)} "
                          f"(templates in {mt_dir}); tune needs examples of every class")
    queries = {}
    if keyframes_dir is not None:
        from mtanno.keyframes import load_class_keyframes

        queries, _, _, _ = load_class_keyframes(keyframes_dir, classes,
                                                feature_set=layout.feature_set, fps=layout.fps)
    return templates, layout, examples, queries


def _tuner(folds, examples, templates, queries, layout, methods, learn, shared, *, n_jobs,
           scheduler, max_examples, seed, unknown_weight, log) -> Tuner:
    """The :class:`mtanno.tuning.search.Tuner` of the folds: per fold and class its
    templates learned and template (1, 0) matched at every δ in the workers
    (:func:`_fold_tasks`), the others matched when the search asks
    (:func:`_fetch_matches`)."""
    classes = list(templates)
    tasks = _fold_tasks(folds, examples, templates, queries, layout, methods, learn,
                        max_examples=max_examples, seed=seed)
    prepared = dict(zip([t[0] for t in tasks], _run_tasks(tasks, n_jobs, _fold_class_task,
                                                          scheduler=scheduler, shared=shared)))
    columns = {c: matched_columns(templates[c].weights) for c in classes}
    columns.update({(c, float(f)): matched_columns(time_scaled(templates[c], f).weights)
                    for c in classes for f in TEMPO_SCALES})
    fetch = _fetch_matches(tasks, prepared, n_jobs=n_jobs, scheduler=scheduler, shared=shared)
    return Tuner(folds, prepared, classes=classes, methods=methods,
                 unknown_weight=unknown_weight, log=log, columns=columns, fetch=fetch,
                 jobs=n_jobs if scheduler is None else 1)


def _fold_tasks(folds, examples, templates, queries, layout, methods, learn, *,
                max_examples: int | None = None, seed: int = 0) -> list:
    """One task per fold and class with training examples in it (:func:`_fold_class_task`):
    the class's templates learned on the fold's training examples (at most
    ``max_examples`` of them, :func:`mtanno.tuning.cv.learning_subset`), matched over its
    held-out documents (inside the keyframe windows where the class has a query). The
    tasks come largest first (examples × frames², what learning costs), for an even load
    of the workers."""
    index = {id(e): i for i, e in enumerate(examples)}
    tasks, cost = [], []
    for f in folds:
        windows = None
        if queries:
            from mtanno.keyframes import class_windows

            windows = [class_windows(X, list(layout.names), queries,
                                     feature_set=layout.feature_set)
                       for _, X in f.held_out.documents()]
        for c in templates:
            train = [e for e in f.train if e.class_name == c]
            if not train:
                continue
            train = [train[i] for i in learning_subset(train, max_examples, seed=seed)]
            spans = ev_spans = None
            if windows is not None and c in queries:
                wins = [w.get(c, []) for w in windows]
                spans = _spans(wins, f.held_out.offsets)
                ev_spans = _spans(wins, f.held_out.offsets, EVIDENCE_MARGIN)
            tasks.append(((f.name, c), (c, [index[id(e)] for e in train], f.name), {
                "deltas": _deltas(methods, templates), "groups": GROUPS
                if "templates" in methods else (), "learn": learn[c], "spans": spans,
                "evidence": "frames" in methods and "resolve" in methods,
                "evidence_spans": ev_spans,
                "scales": TEMPO_SCALES if "templates" in methods else ()}))
            cost.append(sum(e.X.shape[1] for e in train))  # √ of the learning's cost
    order = sorted(range(len(tasks)), key=lambda j: -cost[j])
    return [tasks[j] for j in order]


def _further_templates(chosen: Sequence[Params], examples, templates, learn, *, n_jobs,
                       scheduler, shared, max_examples: int | None = None,
                       seed: int = 0) -> Callable[[Params], dict]:
    """``extra_of(params)``: per class its further templates under ``params`` (one of
    ``chosen``): the groups' templates, learned here from the class's training examples
    (at most ``max_examples``, :func:`mtanno.tuning.cv.learning_subset`) for every group
    count that ``chosen`` uses, then the time-scaled copies of its template."""
    classes = list(templates)
    by_class = {}
    for c in classes:
        idx = [i for i, e in enumerate(examples) if e.class_name == c]
        by_class[c] = [idx[j] for j in learning_subset([examples[i] for i in idx], max_examples,
                                                       seed=seed)]
    wanted = sorted({(c, p.groups[c]) for p in chosen for c in classes
                     if p.groups.get(c, 1) > 1})
    got = _run_tasks([(key, (key[0], by_class[key[0]], key[1], learn[key[0]]), {})
                      for key in wanted], n_jobs, _final_groups_task, scheduler=scheduler,
                     shared=shared) if wanted else []
    learned = {key: g for key, g in zip(wanted, got) if g}

    def extra_of(p: Params) -> dict:
        out = {}
        for c in classes:
            mts = [*learned.get((c, p.groups.get(c, 1)), []),
                   *(time_scaled(templates[c], f) for f in p.scales.get(c, ()))]
            if mts:
                out[c] = mts
        return out

    return extra_of


def _input_records(mt_dir, templates, keyframes_dir, examples) -> tuple[list[dict], dict]:
    """The inputs of a tune run (template files, keyframe files, training feature files,
    each with SHA-256) for the provenance, and the SHA-256 of each class's template (the
    configuration's ``[tuned_with]``)."""
    from mtanno.templates.store import template_files
    from mtanno.util.provenance import sha256_file

    inputs = [{"path": str(p), "sha256": sha256_file(p)} for p in template_files(mt_dir)]
    shas = {i["path"]: i["sha256"] for i in inputs}
    shas = {c: shas[mt.path] for c, mt in templates.items()}
    if keyframes_dir is not None:
        from mtanno.keyframes import keyframe_files

        inputs += [{"path": str(p), "sha256": sha256_file(p)}
                   for p in keyframe_files(keyframes_dir)]
    seen = set()
    for ex in examples:
        if ex.file not in seen:
            seen.add(ex.file)
            inputs.append({"path": ex.file, "sha256": ex.sha256})
    return inputs, shas


def _deltas(methods: Sequence[str], templates) -> list[float]:
    from mtanno.templates.params import ANNOTATION_DELTA
    from mtanno.tuning.search import DELTA_GRID

    return [float(d) for d in DELTA_GRID] if "delta" in methods else [ANNOTATION_DELTA]


def _run_tasks(tasks: list, n_jobs: int, fn, *, scheduler: str | None = None,
               shared=None) -> list:
    """``fn(*args, **kwargs)`` of every (key, args, kwargs) task, in order, in the executor
    of :func:`mtanno.util.workers.make_pool` (``n_jobs`` processes, or a dask cluster), with
    ``shared`` readable through :func:`mtanno.util.workers.shared`."""
    from mtanno.util.workers import make_pool

    with make_pool(jobs=n_jobs, scheduler=scheduler, shared=shared,
                   n_tasks=len(tasks)) as pool:
        return list(pool.map(_call, [(fn, args, kwargs) for _, args, kwargs in tasks]))


def _call(fn, args, kwargs):
    return fn(*args, **kwargs)


def _fold_class_task(cls: str, train: list[int], fold: str, *, deltas, groups, learn, spans,
                     evidence, evidence_spans, scales) -> dict:
    """The templates of one fold and class (:func:`mtanno.tuning.search.learn_fold_class`)
    from the shared examples (by index), and the matches of template (1, 0) on the fold's
    held-out documents at every δ, without evidence (:func:`mtanno.tuning.search.
    match_fold_class`): what the search's first step needs. The other templates are
    matched later at the δ the search chose (:func:`_match_task`)."""
    from mtanno.util.workers import shared

    data = shared()
    held_X, offsets = data["held"][fold]
    mts, made = learn_fold_class(cls, [data["examples"][i] for i in train], groups=groups,
                                 learn=learn, scales=scales)
    match = match_fold_class({(1, 0): mts[(1, 0)]}, held_X, offsets, deltas=deltas,
                             spans=spans, evidence=False)
    return {"groups": made, "templates": mts, "match": match}


def _match_task(templates: dict, fold: str, delta: float, *, spans, evidence,
                evidence_spans) -> dict:
    """All templates of one fold and class matched at ``delta``, with their evidence."""
    from mtanno.util.workers import shared

    held_X, offsets = shared()["held"][fold]
    return {"match": match_fold_class(templates, held_X, offsets, deltas=[delta], spans=spans,
                                      evidence=evidence, evidence_spans=evidence_spans)}


def _fetch_matches(tasks, prepared, *, n_jobs, scheduler, shared):
    """``fetch(δ)`` of :class:`mtanno.tuning.search.Tuner`: every fold and class's templates
    matched at δ, in the workers (:func:`_match_task`)."""

    def fetch(delta: float) -> dict:
        jobs = [(key, (prepared[key]["templates"], key[0], float(delta)),
                 {k: kwargs[k] for k in ("spans", "evidence", "evidence_spans")})
                for key, _, kwargs in tasks]
        return dict(zip([t[0] for t in jobs], _run_tasks(jobs, n_jobs, _match_task,
                                                         scheduler=scheduler, shared=shared)))

    return fetch


def _final_groups_task(cls: str, idx: list[int], k: int, learn: dict) -> list:
    from mtanno.util.workers import shared

    return _final_groups(cls, [shared()["examples"][i] for i in idx], k, learn)
