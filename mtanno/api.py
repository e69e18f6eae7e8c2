"""The short way in: six functions for a notebook, re-exported by :mod:`mtanno`.

Each is a thin wrapper over the stage's own API (named in its docstring), with the
defaults of the command line::

    import mtanno
    X = mtanno.compute_features(mtanno.read_motion("HDM_bd_squat1Reps_001_120.amc"))
    mts = mtanno.learn_templates(manifest="clips.csv", features_dir="feats/", split="train")
    result = mtanno.annotate_documents("docfeats/", mts)          # or mtanno.load_templates("mts/")
    print(mtanno.evaluate_annotation(result, truth="docs/truth.csv").table())
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

from mtanno.errors import MtannoError

if TYPE_CHECKING:
    import numpy as np

    from mtanno.annotate import AnnotationBatch, ClassConfig
    from mtanno.evaluation.metrics import Report
    from mtanno.io.skeleton import Motion
    from mtanno.labels.segments import Segment
    from mtanno.templates.model import MotionTemplate

__all__ = ["annotate_documents", "compute_features", "evaluate_annotation", "learn_templates",
           "load_templates", "read_motion"]

PathLike = str | os.PathLike


def read_motion(path: PathLike, *, asf: PathLike | None = None,
                skeleton: PathLike | None = None, markers: PathLike | None = None,
                up: str | None = None) -> Motion:
    """A motion file (ASF/AMC, BVH or C3D) with world positions of every node, Y up
    (:func:`mtanno.io.read_motion`; docs/method.md §1). An AMC file's ASF is found beside
    it unless ``asf`` is given; a C3D file's joints come from the marker set ``markers``
    (default: the built-in set that fits); ``up``: the file's up axis ("y" or "z"; default
    Y for ASF/AMC and BVH, the file's for C3D)."""
    from mtanno.io import read_motion as _read

    return _read(path, asf=asf, skeleton=skeleton, markers=markers, up=up)


def compute_features(motion: Motion | PathLike, *, feature_set: str = "ak40",
                     up: str | None = None) -> np.ndarray:
    """The (features × frames) 0/1 matrix (uint8) of a motion at 30 Hz: the 40 relational
    features of [MR06] Table 6 + F40 (``feature_set="ak40"``) or the 31 of [MRC05]
    (``"mrc05"``); row names in :func:`mtanno.features.get_feature_set`. ``motion`` is a
    :class:`~mtanno.io.skeleton.Motion` or a motion file; ``up`` its up axis ("y" or "z";
    for a file as :func:`read_motion` takes it, for a Motion default "y").
    (:func:`mtanno.features.extract.features_from_motion`.)"""
    from mtanno.features.extract import features_from_motion

    if not hasattr(motion, "positions"):
        motion, up = read_motion(motion, up=up), "y"  # (read turned to Y up)
    X, _ = features_from_motion(motion, feature_set=feature_set, up=up or "y")
    return X


def learn_templates(training: Sequence[PathLike] = (), *, manifest: PathLike | None = None,
                    features_dir: PathLike | None = None, split: str | None = None,
                    truth: PathLike | None = None, classes: Sequence[str] | None = None,
                    hard: bool = False) -> dict[str, MotionTemplate]:
    """One motion template per class ([MR06] §4.1; ``hard``: thesis §3.3), from training
    examples named as ``mtanno learn-mt`` takes them: class folders ``training``, a
    ``manifest`` with ``features_dir`` (and ``split``), or a ``truth`` table with the
    documents' feature files ``training``. Returns class name → template, unquantized
    (soft), in memory; :func:`mtanno.templates.save_template` writes one.
    (:func:`mtanno.templates.training.collect_sources`,
    :func:`mtanno.templates.learn.learn_template`.)"""
    from mtanno.templates.learn import learn_classes
    from mtanno.templates.training import collect_sources, group_by_class

    sources = collect_sources(training, manifest=manifest, features_dir=features_dir,
                              split=split, truth=truth)
    out: dict[str, MotionTemplate] = {}
    for done in learn_classes(group_by_class(sources, classes=classes), hard=hard):
        if done.error is not None:
            raise MtannoError(f"class {done.class_name}: {done.error}")
        out[done.class_name] = done.template
    return out


def load_templates(folder: PathLike, *, classes: Sequence[str] = ()) -> dict[str, MotionTemplate]:
    """Class name → template of every ``*.json`` in a folder written by ``learn-mt``
    (:func:`mtanno.templates.store.load_template_folder`)."""
    from mtanno.templates.store import load_template_folder

    return load_template_folder(folder, classes=classes)


def annotate_documents(features: PathLike | Iterable[PathLike],
             templates: PathLike | dict[str, MotionTemplate], *, tau: float | None = None,
             delta: float | None = None, config: ClassConfig | None = None,
             single_label: bool = False, n_jobs: int = 1) -> AnnotationBatch:
    """Label every frame of feature files (files or folders) with the classes of
    ``templates`` (a template folder or class name → template), [MBS09] §4: τ = 0.13 and
    δ = 0.05 unless given. ``config`` (e.g. ``load_class_config("tuned.toml")``, what
    ``mtanno tune`` writes) is applied as ``mtanno annotate --classes`` applies it: its δ
    unless ``delta`` is given, its further templates, and a :class:`UserWarning` when the
    templates are not those it was tuned with; ``tau`` replaces its default τ (the
    object passed is not changed). Returns the :class:`~mtanno.annotate.AnnotationBatch`:
    its ``rows`` are the segments (0-based frames at 30 Hz), ``failed`` the files that
    could not be used. (:func:`mtanno.annotate.annotate_files`.)"""
    import warnings

    from mtanno.annotate import annotation_setup
    from mtanno.features.inputs import document_files

    paths = document_files([features] if isinstance(features, (str, os.PathLike)) else features)
    if isinstance(templates, (str, os.PathLike)):
        templates = load_templates(templates)
    setup = annotation_setup(dict(templates), config=config, tau=tau, delta=delta,
                             single_label=single_label)
    for message in setup.warnings:
        warnings.warn(message, UserWarning, stacklevel=2)
    return setup.annotate(paths, n_jobs=n_jobs)


def evaluate_annotation(annotations: AnnotationBatch | Sequence | PathLike,
             truth: PathLike | Sequence[Segment], *,
             documents: Iterable[str] | None = None) -> Report:
    """Frame- and segment-level precision, recall and F of annotations (an
    :func:`annotate_documents` result, its rows, or an annotation table file) against ground truth (a
    truth table file or its segments), [MBS09] §7, with frame accuracy, Edit and F1@{10,25,50}
    (Lea et al. 2017; on the documents' recorded lengths when the batch or table has them);
    by default over the annotated documents. ``Report.table()`` prints it, and
    ``Report.warnings`` says when truth and annotation share no label.
    (:func:`mtanno.evaluation.metrics.evaluate_annotations`.)"""
    from mtanno.annotate import read_annotation_tables, to_segments
    from mtanno.evaluation.metrics import documents_evaluated, evaluate_annotations
    from mtanno.labels.truth import check_within, read_truth

    frames = getattr(annotations, "frames", None)  # documents' lengths, for frame accuracy
    if isinstance(annotations, (str, os.PathLike)):
        annotations, frames, _ = read_annotation_tables([annotations])
    rows = getattr(annotations, "rows", annotations)
    try:
        output = to_segments(rows)
    except AttributeError:
        raise MtannoError("annotations must be an annotate_documents() result, its rows or an "
                          "annotation table file") from None
    if isinstance(truth, (str, os.PathLike)):
        path = str(truth)
        truth = read_truth(truth)
        check_within(truth, frames or {}, path=path)
    truth = list(truth)
    if documents is None:
        documents = documents_evaluated(truth, output, frames)
    return evaluate_annotations(truth, output, documents=documents, frames=frames)
