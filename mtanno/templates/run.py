"""The whole ``mtanno learn-mt`` run, from file names to files ([MR06] §4.1): the training
examples named one of the three ways (:func:`mtanno.templates.training.collect_sources`),
one template per class learned (:func:`mtanno.templates.learn.learn_classes`) and written to
``OUT/CLASS.json`` under the output folder's lock. A class that fails fails alone.

:class:`LearnOptions` holds what is learned; :func:`learn_to_folder` is the run;
:class:`LearnRun` what it did.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from mtanno.errors import MtannoError
from mtanno.templates.learn import ITER_MAX, ITER_THRESH, ClassLearned, learn_classes

__all__ = ["LearnOptions", "LearnRun", "learn_to_folder"]


@dataclass(frozen=True)
class LearnOptions:
    """What :func:`learn_to_folder` learns and where it may write (the defaults are the
    command's): only ``classes``, if given (each must have examples); hard templates (thesis
    §3.3) with ``hard``, else soft ones ([MR06] §4.1); at most ``iter_max`` iterations,
    fewer when the largest normalised alignment cost falls to ``thresh``
    (:func:`mtanno.templates.learn.learn`); ``inside_input``: the output folder may be, or
    lie inside, a folder of training files."""

    classes: tuple[str, ...] = ()
    hard: bool = False
    iter_max: int = ITER_MAX
    thresh: float = ITER_THRESH
    inside_input: bool = False

    def __post_init__(self):
        object.__setattr__(self, "classes", tuple(self.classes))


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
                    truth: str | os.PathLike | None = None,
                    options: LearnOptions | None = None, wait: bool = False,
                    on_wait: Callable[[str], None] | None = None,
                    note: Callable[[str], None] | None = None,
                    on_start: Callable[[int], None] | None = None,
                    progress: Callable[[ClassLearned, str | None], None] | None = None,
                    ) -> LearnRun:
    """The whole ``mtanno learn-mt`` run: the training examples named as
    :func:`mtanno.templates.training.collect_sources` takes them (``training``,
    ``manifest``, ``features_dir``, ``split``, ``truth``; ``note`` receives its notes),
    grouped by class, every output checked against the inputs, and one template per class
    learned as ``options`` say (:class:`LearnOptions`, :func:`learn_classes`) and written to
    ``outdir/CLASS.json`` under the folder's lock (:func:`mtanno.util.locks.folder_lock`;
    ``wait``/``on_wait`` as there; a run that writes nothing leaves no new folder; an
    ``outdir`` that is or lies inside a folder of training files only with
    ``options.inside_input``). A class
    that fails fails alone, as does a training folder that gives no example
    (:attr:`LearnRun.skipped`). ``on_start(n)`` is called
    before the first of ``n`` classes, ``progress(done, error)`` after each (``error``: why
    it failed, None when it was written)."""
    from mtanno.templates.store import class_file, save_template
    from mtanno.templates.training import collect_sources, group_by_class, input_folders
    from mtanno.util.locks import folder_lock
    from mtanno.util.output import output_folder
    from mtanno.util.preflight import check_outputs

    options = options or LearnOptions()
    run = LearnRun()
    sources = collect_sources(training, manifest=manifest, features_dir=features_dir,
                              split=split, truth=truth, note=note, failures=run.skipped)
    groups = group_by_class(sources, classes=list(options.classes) or None)
    out = Path(outdir)
    check_outputs([out / f"{c}.json" for c in groups if c and "/" not in c and "\0" not in c],
                  [*(s.path for s in sources), manifest, truth], folders={out: []},
                  scanned=input_folders(training, features_dir),
                  inside_input=options.inside_input,
                  writable=False)  # a class whose file cannot be written fails alone
    t0 = time.perf_counter()
    if on_start:
        on_start(len(groups))
    with output_folder(out), folder_lock(out, wait=wait, on_wait=on_wait):
        for done in learn_classes(groups, hard=options.hard, iter_max=options.iter_max,
                                  thresh=options.thresh):
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
