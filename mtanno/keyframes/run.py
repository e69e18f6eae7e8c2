"""The whole ``mtanno learn-keyframes`` run, from file names to files ([MBS09] §6,
docs/method.md §6): the training clips of every class read once (each class's clips are the
negatives of the others), checked against the templates, and one keyframe query per class
learned (:func:`mtanno.keyframes.learn.learn_keyframes`) and written to ``OUT/CLASS.json``
under the output folder's lock. A class that fails fails alone.

:class:`KeyframeOptions` holds what is learned and how (method, classes, GA runs and
parameters, workers); :func:`learn_keyframes_to` is the run; :class:`KeyframesRun` what it
did.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from mtanno.errors import MtannoError
from mtanno.keyframes.ga import GAParams
from mtanno.keyframes.learn import DEFAULT_COLUMNS, DEFAULT_RUNS, METHODS
from mtanno.keyframes.model import KeyframeQuery

__all__ = ["KeyframeOptions", "KeyframesRun", "learn_keyframes_to"]


@dataclass(frozen=True)
class KeyframeOptions:
    """What :func:`learn_keyframes_to` learns and how (the defaults are the command's).

    ``method``: ``"ga"`` ([MBS09] §6), ``"hard"`` or ``"heuristic"``
    (:func:`mtanno.keyframes.learn.learn_keyframes`); ``classes``: learn only these (each
    must have training clips; default: every class with a template); ``runs``, ``seed``,
    ``ga``: the GA's independent runs per class, the seed they derive from and the
    parameters of one run (:class:`~mtanno.keyframes.ga.GAParams`); ``columns``: the
    template columns ``hard`` and ``heuristic`` take; ``jobs``, ``scheduler``: worker
    processes (or a dask.distributed address, ``local:N``) the GA runs are spread over —
    the result does not depend on them; ``inside_input``: the output folder may be, or lie
    inside, a folder of training clips or of the templates."""

    method: str = "ga"
    classes: tuple[str, ...] = ()
    runs: int = DEFAULT_RUNS
    seed: int = 0
    ga: GAParams = field(default_factory=GAParams)
    columns: int = DEFAULT_COLUMNS
    jobs: int = 1
    scheduler: str | None = None
    inside_input: bool = False

    def __post_init__(self):
        if self.method not in METHODS:
            raise MtannoError(f"unknown keyframe method '{self.method}' (one of "
                              f"{', '.join(METHODS)})", options=("method",))
        object.__setattr__(self, "classes", tuple(self.classes))
        for name in ("runs", "jobs", "columns"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise MtannoError(f"{{{name}}} must be a positive integer, got {v!r}",
                                  options=(name,))
        if not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed < 0:
            raise MtannoError(f"{{seed}} must be an integer ≥ 0, got {self.seed!r}",
                              options=("seed",))


@dataclass
class KeyframesRun:
    """What :func:`learn_keyframes_to` did: the queries written (class, query, in class
    order) and the classes that failed; the classes with training clips but no template,
    left out (only without ``classes``); the training inputs that gave no example (each an
    error; the others were used); the method; seconds of learning."""

    method: str
    written: list[tuple[str, KeyframeQuery]] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    without_template: list[str] = field(default_factory=list)
    skipped: list[MtannoError] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def exit_code(self) -> int:
        """0 when every class was written from every input, else 1."""
        return 1 if self.failed or self.skipped else 0


def learn_keyframes_to(training: Sequence[str | os.PathLike], mt_dir: str | os.PathLike,
                       outdir: str | os.PathLike, *,
                       manifest: str | os.PathLike | None = None,
                       features_dir: str | os.PathLike | None = None, split: str | None = None,
                       truth: str | os.PathLike | None = None,
                       options: KeyframeOptions | None = None, wait: bool = False,
                       on_wait: Callable[[str], None] | None = None,
                       note: Callable[[str], None] | None = None,
                       on_start: Callable[[int, list[MtannoError]], None] | None = None,
                       progress: Callable[[str, int, str | None], None] | None = None,
                       ) -> KeyframesRun:
    """The whole ``mtanno learn-keyframes`` run (module docstring).

    The training clips are named as :func:`mtanno.templates.training.collect_sources`
    takes them (``training``, ``manifest``, ``features_dir``, ``split``, ``truth``;
    ``note`` receives its notes); the templates of ``mt_dir`` give the keyframe positions;
    ``options`` (:class:`KeyframeOptions`) what is learned. Every output is checked against
    the inputs first; the queries are written to ``outdir/CLASS.json`` under the folder's
    lock (:func:`mtanno.util.locks.folder_lock`; ``wait``/``on_wait`` as there; a run that
    writes nothing leaves no new folder).

    ``on_start(n, skipped)`` is called before the first class, with ``n`` the steps to come
    (GA runs with ``method="ga"``, else classes) and the training inputs that gave no
    example; ``progress(class_name, steps, error)`` when a class starts (0 steps), after
    each GA run (1 step), and when a class has failed (``error``, its message) or, with
    the column methods, is done (1 step)."""
    from mtanno.keyframes.learn import keyframe_training_set, learn_keyframes
    from mtanno.keyframes.store import save_keyframes
    from mtanno.templates.store import class_file, load_template_folder
    from mtanno.templates.training import (
        collect_sources,
        group_by_class,
        input_folders,
        load_examples,
    )
    from mtanno.util.locks import folder_lock
    from mtanno.util.output import output_folder
    from mtanno.util.preflight import check_outputs

    options = options or KeyframeOptions()
    method, classes = options.method, options.classes
    run = KeyframesRun(method)
    sources = collect_sources(training, manifest=manifest, features_dir=features_dir,
                              split=split, truth=truth, failures=run.skipped, note=note)
    groups = group_by_class(sources, classes=list(classes) or None)
    templates = load_template_folder(mt_dir)
    all_groups = group_by_class(sources)
    examples = [ex for c in all_groups for ex in load_examples(all_groups[c])]
    by_class: dict[str, list] = {}
    for ex in examples:
        by_class.setdefault(ex.class_name, []).append(ex)
    mt0 = next(iter(templates.values()))
    if examples[0].feature_names != list(mt0.feature_names):
        raise MtannoError("training clips have other features than the templates "
                          f"(feature set {examples[0].feature_set} vs {mt0.feature_set})",
                          path=examples[0].file)
    if method == "ga" and len(by_class) < 2:
        raise MtannoError(f"the genetic algorithm needs training clips of at least two classes "
                          f"(only {', '.join(by_class)} found): the other classes are its "
                          "negatives")
    ts = keyframe_training_set(examples)
    out = Path(outdir)
    todo = [c for c in groups if c in templates or classes]
    run.without_template = sorted(set(groups) - set(todo))
    check_outputs([out / f"{c}.json" for c in todo if c and "/" not in c and "\0" not in c],
                  [*(s.path for s in sources), manifest, truth,
                   *(t.path for t in templates.values())], folders={out: []},
                  scanned=input_folders(training, features_dir, also=[mt_dir]),
                  inside_input=options.inside_input,
                  writable=False)  # a class whose file cannot be written fails alone
    ga = method == "ga"
    if on_start:
        on_start(len(todo) * (options.runs if ga else 1), run.skipped)
    with output_folder(out), folder_lock(out, wait=wait, on_wait=on_wait):
        t0 = time.perf_counter()
        for cls in todo:
            if progress:
                progress(cls, 0, None)
            error = None
            try:
                if cls not in templates:
                    raise MtannoError(f"no template for class '{cls}' in {mt_dir}")
                target = class_file(out, cls)
                q = learn_keyframes(
                    ts, cls, templates[cls], method=method, runs=options.runs,
                    seed=options.seed, jobs=options.jobs, scheduler=options.scheduler,
                    params=options.ga, columns=options.columns, examples=by_class.get(cls),
                    progress=(lambda n, c=cls: progress(c, n, None)) if ga and progress
                    else None)
                save_keyframes(target, q)
                run.written.append((cls, q))
            except MtannoError as exc:
                run.failed.append(cls)
                error = str(exc)
            if progress and (error is not None or not ga):
                progress(cls, 0 if ga else 1, error)
        run.seconds = time.perf_counter() - t0
    return run
