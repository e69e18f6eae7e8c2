"""``mtanno report``: an annotation run as a page for people and tables for papers.

From annotation tables and, when there is one, the ground truth (and optionally the
templates, the documents' feature files and their motions) :func:`write_report` writes into
one folder:

* ``index.html`` — the page (:mod:`mtanno.evaluation.page`): an archive view of every
  document (a compact row each, its timeline drawn in the browser, filter, sort, counts per
  class), one player beside it for the selected document (stick figure, timeline, Δ curves
  with ``--mt`` and ``--features``), review at the keyboard into a truth CSV, then the
  tables and figures below behind a table of contents;
* ``data/*.js`` — the documents' poses and Δ curves, loaded by the page when a document of
  theirs is selected (the page needs its folder);
* ``per_class.csv`` / ``.md`` / ``.tex`` — per-class P/R/F at frame and segment level with
  their support ([MBS09] §7), frame accuracy, Edit and F1@{10,25,50} (the rows of ``mtanno
  evaluate``, "–" where undefined), CSV with provenance;
* ``confusion.csv`` and ``confusion.png``/``.svg`` — the frame-level confusion matrix,
  truth × annotation, with a "none" row and column (frames without a label);
* ``reliability.png``/``.svg`` — the confidence against the truth;
* without truth ``summary.csv``/``.md``; always ``review.csv`` (every row, the least
  confident first);
* with templates ``template_<class>.png``/``.svg`` (heat maps, [MR06] Fig. 4);
* ``figures.json`` — what each figure was drawn from: a rerun whose inputs did not change
  draws none again.

A confusion matrix needs one label per frame. Annotations from ``annotate
--single-label`` are a partition; the default output may overlap, and then each frame is
counted for the covering segment with the smallest cost (the smallest Δ̄ in the segment,
which approximates the per-frame Δ̄ that ``--single-label`` uses); the page says so.
"""

from __future__ import annotations

import html
import math
import os
from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mtanno.errors import MtannoError
from mtanno.evaluation.metrics import Report, evaluate_annotations
from mtanno.evaluation.page import FORMATS
from mtanno.evaluation.report_tables import (
    html_table,
    latex_table,
    markdown_table,
    plain_markdown,
)
from mtanno.labels.segments import Segment

if TYPE_CHECKING:
    from mtanno.evaluation.page import Figures
    from mtanno.labels.segments import Annotation

NONE = "none"
#: Title of a report page.
REPORT_TITLE = "mtanno annotation report"
#: Every name :func:`write_report` may write in its folder (glob patterns for those named
#: after classes), for :func:`mtanno.util.preflight.check_outputs`; in the folder ``data/``
#: it writes (and removes) only its data files (``HASH.js``).
REPORT_FILES = ("index.html", "per_class.csv", "per_class.csv.meta.json", "per_class.md",
                "per_class.tex", "confusion.csv", "confusion.csv.meta.json", "summary.csv",
                "summary.csv.meta.json", "summary.md", "review.csv", "review.csv.meta.json",
                "figures.json", *(f"{stem}.{fmt}" for stem in ("confusion", "reliability",
                                                              "template_*") for fmt in FORMATS))


@dataclass(frozen=True)
class ReportOptions:
    """How :func:`write_report` draws the report (the defaults are the command's): the Δ
    curves of templates quantized with ``delta`` (None: 0.05) as the annotation did, with
    the threshold ``tau`` (None: the annotation default) and each class's τ of
    ``tau_per_class`` drawn; ``extra_templates`` names the classes the annotation also
    matched further templates for (a tuned configuration's ``[templates]``): their curves,
    of the class's own template only, are not the annotation's Δ, and the page says so.
    ``title``: the page's; ``chunk_bytes``: the size of the data files the poses and
    curves go into (None: :data:`~mtanno.evaluation.page.CHUNK_BYTES`; 0: one file per
    document). :func:`report_files` fills ``tau``, ``tau_per_class``, ``delta`` and
    ``extra_templates`` from what the annotation recorded where they are None (``tau``
    given: its ``tau_per_class`` only)."""

    tau: float | None = None
    tau_per_class: Mapping[str, float] | None = None
    delta: float | None = None
    extra_templates: tuple[str, ...] | None = None
    title: str = REPORT_TITLE
    chunk_bytes: int | None = None

    def __post_init__(self):
        if self.extra_templates is not None:
            object.__setattr__(self, "extra_templates", tuple(self.extra_templates))


@dataclass
class ReportResult:
    """What :func:`write_report` wrote: the folder, the HTML page, every file, the
    evaluation, the confusion matrix with its labels, notes shown on the page, per
    document why its motion is not shown (a motion that is not the annotated one), the
    number of figures drawn (not reused), and the page's summary line (documents, those
    with rows, rows, classes, frame F1: the command prints it)."""

    folder: Path
    page: Path
    files: list[Path] = field(default_factory=list)
    evaluation: Report | None = None
    labels: list[str] = field(default_factory=list)
    confusion: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)
    motion_notes: dict[str, str] = field(default_factory=dict)
    figures_drawn: int = 0
    summary: str = ""


def _by_doc(items, key=lambda x: x.doc) -> dict[str, list]:
    out: dict[str, list] = defaultdict(list)
    for x in items:
        out[key(x)].append(x)
    return out


def _frame_labels(segs: Sequence, n: int, rank: dict[str, int]) -> tuple[np.ndarray, bool]:
    """(label index per frame (−1 none), whether segments overlapped): 0-based inclusive
    (start, end, label, cost) tuples; overlaps go to the smallest cost."""
    out = np.full(n, -1)
    covered = np.zeros(n, bool)
    overlap = False
    for s, e, lab, _ in sorted(segs, key=lambda x: (x[3], rank[x[2]])):
        s, e = max(s, 0), min(e, n - 1)
        if e < s:
            continue
        if covered[s:e + 1].any():
            overlap = True
        free = ~covered[s:e + 1]
        out[s:e + 1][free] = rank[lab]
        covered[s:e + 1] = True
    return out, overlap


def confusion_matrix(truth: Sequence[Segment], annotation: Sequence[Annotation],
                     frames: dict[str, int]) -> tuple[np.ndarray, list[str], bool]:
    """Frame-level confusion matrix over the documents of ``frames`` (document → number of
    frames): rows truth labels, columns annotation labels, both sorted with "none" last.
    Returns (matrix, labels, whether the annotation overlapped)."""
    labels = sorted({s.label for s in truth} | {a.label for a in annotation}) + [NONE]
    rank = {lab: i for i, lab in enumerate(labels)}
    M = np.zeros((len(labels), len(labels)), np.int64)
    overlapped = False
    truth_of, rows_of = _by_doc(truth), _by_doc(annotation)
    for doc, n in frames.items():
        t, _ = _frame_labels([(s.start - 1, s.end - 1, s.label, 0.0)
                              for s in truth_of.get(doc, ())], n, rank)
        a, ov = _frame_labels([(r.start, r.end, r.label, r.cost)
                               for r in rows_of.get(doc, ())], n, rank)
        overlapped |= ov
        t[t < 0] = rank[NONE]
        a[a < 0] = rank[NONE]
        np.add.at(M, (t, a), 1)
    return M, labels, overlapped


def annotation_parameters(provenances: Sequence[dict]) -> dict:
    """What annotation tables' provenance records (``mtanno.annotate.read_annotation_tables``)
    say the annotation used, for :func:`write_report`: ``tau`` (default τ), ``tau_per_class``,
    ``delta`` (None where unrecorded) and ``extra_templates`` (classes matched with further
    templates); each from the first table that records it."""
    def first(key, kind):
        return next((p[key] for p in provenances if isinstance(p.get(key), kind)
                     and not isinstance(p.get(key), bool)), None)

    per_class = first("tau_per_class", dict) or {}
    methods = first("methods", dict) or {}
    extra = methods.get("templates")
    return {"tau": first("tau", (int, float)),
            "tau_per_class": {str(k): float(v) for k, v in per_class.items()
                              if isinstance(v, (int, float)) and not isinstance(v, bool)},
            "delta": first("delta", (int, float)),
            "extra_templates": sorted(extra) if isinstance(extra, dict) else []}


def write_report(out_dir: str | os.PathLike, truth: Sequence[Segment] | None,
                 annotation: Sequence[Annotation], *, frames: dict[str, int] | None = None,
                 templates: dict | None = None, features: dict[str, np.ndarray] | None = None,
                 poses: dict | None = None, pose_sources: dict[str, str] | None = None,
                 motion_notes: dict[str, str] | None = None, provenance: dict | None = None,
                 options: ReportOptions | None = None,
                 progress: Callable[[int, int], None] | None = None) -> ReportResult:
    """Write the report of ``annotation`` (rows of one or more annotation tables, 0-based
    frames) against ``truth`` into ``out_dir`` (module docstring). ``frames`` gives each
    document's length as the annotation recorded it (default: the last labelled frame of
    truth or annotation); documents are those annotated. ``templates`` (class →
    :class:`~mtanno.templates.model.MotionTemplate`) adds heat maps and, with ``features``
    (document → features × frames matrix), the Δ curves of every class in the player, as
    ``options`` say (:class:`ReportOptions`: τ, δ, the classes with further templates,
    the title, the size of the data files). ``progress(done, total)`` is called after each
    document and figure.

    Without ``truth`` (None; an archive nobody has labelled) the page has, instead of the
    scores and the confusion matrix, per class the number of segments, their duration and
    share of the archive (``summary.csv``). Either way ``review.csv`` holds every row, the
    least confident first, and the page reviews them into a truth CSV.

    ``poses`` (document → (frames × 22 × 3) normalised canonical poses at the 30 Hz frames,
    or :class:`~mtanno.evaluation.player.PlayerPoses`) gives the player its motions
    (``pose_sources``: document → the file they came from, for messages); one whose frame
    count is not the annotation's is not shown, and ``ReportResult.motion_notes`` and the
    page say why (:func:`~mtanno.evaluation.player.motion_mismatch`; ``motion_notes``:
    those the caller found so already, document → why). They go into data
    files of about ``options.chunk_bytes`` bytes."""
    from mtanno.evaluation.page import (
        CHUNK_BYTES,
        Figures,
        curve_entries,
        page_data,
        pose_entries,
        write_chunks,
    )
    from mtanno.plot import require_matplotlib
    from mtanno.util.output import make_folder

    require_matplotlib()
    if not annotation:
        raise MtannoError("the annotation has no rows to report on")
    o = options or ReportOptions()
    folder = make_folder(out_dir)
    result = ReportResult(folder, folder / "index.html")
    result.motion_notes.update(motion_notes or {})
    recorded = dict(frames or {})
    scored = truth is not None
    truth = list(truth or [])
    n_with_rows, docs, last = _documents(annotation, truth, recorded)
    frames = {d: max(recorded.get(d, 0), last[d]) for d in docs}
    prov = dict(provenance or {})
    step = _counter(progress, len(docs) + len(templates or {}) + (2 if scored else 0))
    figs = Figures(folder, result, step)
    sections: list[tuple[str, str, str]] = []
    if scored:
        _scores(figs, truth, annotation, docs, frames, prov, sections)
    else:
        _summary(figs, annotation, frames, prov, sections)
    _review_table(folder, result, annotation, prov)
    labels = sorted({a.label for a in annotation} | {s.label for s in truth}
                    | set(templates or ()))
    colours = _hex_colours(labels)
    if templates:
        _template_figures(figs, templates, sections)
    entries, rigs, rig_list = pose_entries(poses, docs, recorded, last, frames,
                                           pose_sources or {}, result, step)
    curves = None
    if templates and features:
        curves = curve_entries(entries, templates, features, docs, o.tau,
                               dict(o.tau_per_class or {}), o.delta)
    if curves and o.extra_templates:
        result.notes.append(
            "the annotation also matched further templates of "
            f"{', '.join(sorted(o.extra_templates))} (its class configuration's [templates]); "
            "their Δ curves here are those of the class's own template only")
    chunks, where = write_chunks(folder, entries, docs, chunk_bytes=CHUNK_BYTES
                                 if o.chunk_bytes is None else o.chunk_bytes)
    result.files += [folder / "data" / f"{c}.js" for c in chunks]
    _motion_notes(result, docs, poses, entries)
    data = page_data(docs, frames, annotation, truth=truth if scored else None,
                     colours=colours, notes=result.motion_notes, chunks=chunks, where=where,
                     rigs=rigs, rig_list=rig_list, curves=curves, title=o.title)
    data["motions"] = poses is not None
    sections += _closing_sections(result, prov, scored)
    figs.close()
    _write_page(result, o.title, data, sections, n_with_rows, annotation)
    return result


def _counter(progress: Callable[[int, int], None] | None, total: int) -> Callable[[], None]:
    """A step of ``progress(done, total)``, counted."""
    done = [0]

    def step() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], max(total, done[0]))

    return step


def _documents(annotation, truth, recorded) -> tuple[int, list[str], dict[str, int]]:
    """The number of documents with rows; the documents: those with rows and those
    recorded as annotated without any (their truth counts); per document its last
    labelled frame (1-based) in annotation or truth."""
    last: dict[str, int] = dict.fromkeys(recorded, 0)
    for a in annotation:
        last[a.doc] = max(last.get(a.doc, 0), a.end + 1)
    n_with_rows = len({a.doc for a in annotation})
    for t in truth:
        if t.doc in last:
            last[t.doc] = max(last[t.doc], t.end)
    return n_with_rows, sorted(last), last


def _write_page(result: ReportResult, title: str, data: dict, sections, n_with_rows: int,
                annotation) -> None:
    from mtanno.evaluation.page import page_html
    from mtanno.util.output import write_text

    result.summary = (
        f"{len(data['docs']['name'])} documents ({n_with_rows} with rows), {len(annotation)} "
        f"rows, {len({a.label for a in annotation})} classes"
        + (f"; frame F1 {result.evaluation.frame.F:.3f}" if result.evaluation
           else "; no truth given: no scores"))
    summary = result.summary + "; frames at 30 Hz"
    write_text(result.page, page_html(title=title, summary=html.escape(summary),
                                      notes=result.notes, sections=sections, data=data))
    result.files.append(result.page)


def _hex_colours(labels: Sequence[str]) -> dict[str, str]:
    from matplotlib.colors import to_hex

    from mtanno.plot import label_colours

    colours = label_colours(labels)
    return {lab: to_hex(colours.get(lab, "#888888")) for lab in labels}


def _summary(figs: Figures, annotation, frames, prov, sections) -> None:
    """Without truth: per class segments, duration and share (summary.csv, .md, page)."""
    import pyarrow as pa

    from mtanno.util.tables import write_table

    rows = summary_rows(annotation, frames)
    folder, result = figs.folder, figs.result
    write_table(folder / "summary.csv", pa.Table.from_pylist(rows), provenance=prov)
    _text(result, folder / "summary.md", plain_markdown(rows))
    result.files += [folder / "summary.csv", folder / "summary.csv.meta.json"]
    sections.append(("summary", "Classes in the annotation", html_table(rows)))


def _text(result: ReportResult, path: Path, text: str) -> None:
    from mtanno.util.output import write_text

    write_text(path, text)
    result.files.append(path)


def _review_table(folder: Path, result: ReportResult, annotation, prov) -> None:
    import pyarrow as pa

    from mtanno.util.tables import write_table

    write_table(folder / "review.csv", pa.Table.from_pylist(review_rows(annotation)),
                provenance=prov)
    result.files += [folder / "review.csv", folder / "review.csv.meta.json"]


def _template_figures(figs: Figures, templates: dict, sections) -> None:
    from mtanno.evaluation.page import file_stems
    from mtanno.plot import plot_template

    stems = file_stems(sorted(templates))
    for name, mt in sorted(templates.items()):
        figs.figure(lambda mt=mt: plot_template(mt), f"template_{stems[name]}", "templates",
                    f"template {name}", name, list(mt.feature_names), mt.values, mt.weights,
                    mt.kind, mt.quantized, mt.delta)
    sections.append(("templates", "Templates", figs.html("templates")))


def _motion_notes(result: ReportResult, docs, poses, entries) -> None:
    """The page's notes on motions: documents without one, those not played."""
    if poses is None:
        return
    missing = [d for d in docs if d not in poses]
    if missing:
        result.notes.append(f"no motion for {len(missing)} of {len(docs)} document(s): "
                            + ", ".join(missing[:20]) + (", …" if len(missing) > 20 else ""))
    if result.motion_notes:
        bad = sorted(result.motion_notes)
        result.notes.append(
            f"the motion of {len(bad)} document(s) is not the annotated one and is not played "
            "(each says why in the archive; filter note:): " + ", ".join(bad[:20])
            + (", …" if len(bad) > 20 else ""))


def _closing_sections(result: ReportResult, prov: dict, scored: bool) -> list:
    files = ("per_class.csv/.md/.tex, confusion.csv" if scored else "summary.csv/.md")
    listing = (f"<p>Beside this page: {files}, review.csv (every row, the least confident "
               "first), every figure as PNG and SVG, figures.json (what each was drawn from: "
               "a rerun draws again only what changed), and data/ (the documents' poses and "
               "Δ curves, loaded when a document is selected: move the folder, not the page "
               "alone).</p>")
    text = "\n".join(f"{k}: {v}" for k, v in prov.items() if k != "inputs")
    return [("files", "Files", listing),
            ("provenance", "Provenance", f"<pre>{html.escape(text)}</pre>")]


def _scores(figs: Figures, truth, annotation, docs, frames, prov, sections) -> None:
    """The evaluation against ``truth``: the per-class table (CSV, Markdown, LaTeX), the
    confusion matrix (table and figure) and the reliability of the confidence."""
    import pyarrow as pa

    from mtanno.labels.segments import to_segments
    from mtanno.plot import plot_confusion
    from mtanno.util.tables import write_table

    result, folder = figs.result, figs.folder
    ev = evaluate_annotations(truth, to_segments(annotation), documents=docs, frames=frames)
    result.evaluation = ev
    result.notes.extend(ev.warnings)  # e.g. truth and annotation without a common label
    rows = ev.rows()
    write_table(folder / "per_class.csv", pa.Table.from_pylist(rows), provenance=prov)
    result.files += [folder / "per_class.csv", folder / "per_class.csv.meta.json"]
    _text(result, folder / "per_class.md", markdown_table(rows))
    _text(result, folder / "per_class.tex", latex_table(rows))
    sections.append(("scores", "Precision, recall, F per class", html_table(rows)))
    M, labels, overlapped = confusion_matrix(truth, annotation, frames)
    result.confusion, result.labels = M, labels
    if overlapped:
        result.notes.append("the annotation's segments overlap; in the confusion matrix "
                            "each frame counts for the covering segment with the smallest "
                            "cost (use `mtanno annotate --single-label` for an exact "
                            "partition by Δ̄); the Acc column, like `mtanno evaluate`, gives "
                            "each frame to the covering segment that starts last")
    table = {"truth": labels, **{lab: M[:, j].tolist() for j, lab in enumerate(labels)}}
    write_table(folder / "confusion.csv", pa.table(table), provenance=prov)
    result.files += [folder / "confusion.csv", folder / "confusion.csv.meta.json"]
    figs.figure(lambda: plot_confusion(M, labels), "confusion", "confusion",
                "rows: truth, columns: annotation; counts of frames", M, labels)
    sections.append(("confusion", "Confusion matrix (frames)", figs.html("confusion")))
    _reliability(figs, truth, annotation, prov)
    if any(s == "reliability" for s, _, _ in figs.items):
        sections.append(("reliability", "Confidence", figs.html("reliability")))


def summary_rows(annotation: Sequence[Annotation], frames: dict[str, int]) -> list[dict]:
    """Per label of ``annotation`` (and ``all``): segments, labelled frames (frames at 30
    Hz; a frame two rows of a label cover counts once), seconds, their share of the
    documents' ``frames`` and the rows' mean confidence (None where no row has one)."""
    total = sum(frames.values())
    labels = sorted({a.label for a in annotation})
    covered: dict[str | None, int] = dict.fromkeys([*labels, None], 0)
    for d, rows in _by_doc(annotation).items():
        n = frames.get(d, 0) or max(a.end + 1 for a in rows)
        union = np.zeros(n, dtype=bool)
        for lab, mine in _by_doc(rows, key=lambda a: a.label).items():
            mask = np.zeros(n, dtype=bool)
            for a in mine:
                mask[a.start:a.end + 1] = True
            covered[lab] += int(mask.sum())
            union |= mask
        covered[None] += int(union.sum())
    by_label = _by_doc(annotation, key=lambda a: a.label)
    out = []
    for lab in [*labels, None]:
        rows = by_label[lab] if lab is not None else list(annotation)
        conf = [a.confidence for a in rows if not math.isnan(a.confidence)]
        out.append({"class": lab if lab is not None else "all", "segments": len(rows),
                    "frames": covered[lab], "seconds": round(covered[lab] / 30.0, 2),
                    "share": round(covered[lab] / total, 4) if total else None,
                    "mean confidence": round(float(np.mean(conf)), 4) if conf else None})
    return out


def review_rows(annotation: Sequence[Annotation]) -> list[dict]:
    """Every row (1-based frames at 30 Hz), the least confident first (rows without a
    confidence last; ties by cost, highest first, then document and start): the order in
    which a reviewer checks them."""
    def key(a):
        c = a.confidence
        return (math.isnan(c), c if not math.isnan(c) else 0.0,
                -a.cost if math.isfinite(a.cost) else -math.inf, a.doc, a.start)

    return [{"doc": a.doc, "start": a.start + 1, "end": a.end + 1, "label": a.label,
             "seconds": round((a.end - a.start + 1) / 30.0, 2),
             "cost": a.cost if math.isfinite(a.cost) else None,
             "confidence": None if math.isnan(a.confidence) else a.confidence}
            for a in sorted(annotation, key=key)]


def _reliability(figs: Figures, truth, annotation, prov: dict) -> None:
    """The reliability diagram of the rows' confidence against the truth (issue 26), and
    its AUROC and ECE as a note; nothing when no row has a confidence or there is no
    truth."""
    from mtanno.evaluation.calibration import (
        auroc,
        expected_calibration_error,
        reliability_table,
        rows_right,
    )
    from mtanno.plot import plot_reliability

    rows = [a for a in annotation if not math.isnan(a.confidence)]
    if not rows or not truth:
        return
    right = rows_right(rows, truth)
    prob = np.array([a.confidence for a in rows])
    table = reliability_table(prob, right)
    calibrated = (prov.get("confidence") or {}).get("calibrated")
    what = "calibrated" if calibrated else "uncalibrated (1 − cost/τ: a score, not a probability)"
    figs.figure(lambda: plot_reliability(table), "reliability", "reliability",
                f"reliability of the confidence, {what}: per bin the fraction of rows whose "
                "label is right (IoU ≥ 0.5 with a truth segment of its label)", prob, right,
                what)
    figs.result.notes.append(
        f"confidence ({what}): {int(right.sum())} of {len(rows)} rows right, AUROC "
        f"{auroc(prob, right):.3f}, ECE {expected_calibration_error(prob, right):.3f}")


def report_files(annotations: Sequence[str | os.PathLike], out_dir: str | os.PathLike, *,
                 truth_path: str | os.PathLike | None = None,
                 mt_dir: str | os.PathLike | None = None,
                 features: Sequence[str | os.PathLike] = (),
                 motions: Sequence[str | os.PathLike] = (),
                 asf: str | os.PathLike | None = None, options: ReportOptions | None = None,
                 inside_input: bool = False, jobs: int = 1,
                 progress: Callable[[int, int], None] | None = None,
                 failures: list[str] | None = None) -> tuple[ReportResult, list]:
    """The whole ``mtanno report`` run: the annotation tables (files or folders of them),
    the truth, templates, feature files and motion files read and checked against the
    output folder (never an input there; an ``out_dir`` that is, or lies inside, a folder
    of annotation tables, feature files, motions or templates only with ``inside_input``),
    and :func:`write_report` as ``options`` say (:class:`ReportOptions`), with the
    thresholds, δ and further templates the annotation recorded where ``options`` leave
    them None. Poses for the player come
    from ``motions`` (:func:`mtanno.evaluation.player.motion_files`; the rig's own bones),
    else from the pose blocks of ``features`` (``asf``: the ASF of AMC motions, else found
    beside them); Δ curves need ``mt_dir`` and ``features``. A feature or motion file that
    cannot be read is left out and its message appended to ``failures`` (an error without
    it). A motion that is not the annotated one (another frame count, or another SHA-256
    than the document's feature file records) is not played: ``ReportResult.motion_notes``
    and the page say why, and the message goes to ``failures``. Motion files are read in
    ``jobs`` processes. ``progress(done, total)`` counts motion files read, then the
    documents and figures of :func:`write_report`. Returns the result and the annotation's
    rows."""
    from mtanno.annotate import (
        ANNOTATION_SUFFIXES,
        annotation_files,
        read_annotation_tables,
    )
    from mtanno.evaluation.page import DATA_FOLDER
    from mtanno.evaluation.player import motion_files
    from mtanno.features.inputs import document_files
    from mtanno.io import MOCAP_SUFFIXES
    from mtanno.labels.truth import check_within, read_truth
    from mtanno.plot import require_matplotlib
    from mtanno.templates.params import ANNOTATION_TAU
    from mtanno.templates.store import load_template_folder, template_files
    from mtanno.util.preflight import check_outputs
    from mtanno.util.provenance import provenance

    require_matplotlib()
    if any(Path(a).suffix.lower() in MOCAP_SUFFIXES for a in annotations):
        raise MtannoError("a motion file among the annotation tables: give {motions} before "
                          "each motion file, or their folder", options=("motions",))
    paths = document_files(features, failures=failures) if features else []
    # the input folders, each with what the next run reads there (an output folder among
    # them only with inside_input; an output the next run reads, never); the templates'
    # folder is read without its subfolders
    scanned = {**{m: MOCAP_SUFFIXES for m in motions if Path(m).is_dir()},
               **({mt_dir: (".json",) if _same_folder(mt_dir, out_dir) else ()}
                  if mt_dir is not None and Path(mt_dir).is_dir() else {}),
               **{a: ANNOTATION_SUFFIXES for a in annotations if Path(a).is_dir()},
               **{f: (".parquet",) for f in features if Path(f).is_dir()}}
    annotations = annotation_files(annotations)
    inputs = [*annotations, *([truth_path] if truth_path else [])]
    outputs = {out_dir: REPORT_FILES, Path(out_dir) / DATA_FOLDER: ("*.js",)}
    check_outputs([], [*inputs, *paths, *(template_files(mt_dir) if mt_dir else [])],
                  folders=outputs, scanned=scanned, inside_input=inside_input)
    rows, frames, provs = read_annotation_tables(annotations)
    docs = sorted({r.doc for r in rows} | set(frames))
    motion_paths = motion_files(motions, docs)
    check_outputs([], [*motion_paths.values()], folders=outputs)
    recorded = annotation_parameters(provs)
    truth = None
    if truth_path is not None:
        truth = read_truth(truth_path)
        check_within(truth, frames, path=truth_path)
    read = [0]

    def step() -> None:
        read[0] += 1
        if progress is not None:
            progress(read[0], len(motion_paths) + len(docs))

    feats, poses, sources, other = _player_inputs(paths, motions, motion_paths, docs, asf=asf,
                                                  jobs=jobs, failures=failures, step=step)
    o = options or ReportOptions()
    if o.tau is None:  # the annotation's thresholds
        o = replace(o, tau=ANNOTATION_TAU if recorded["tau"] is None else recorded["tau"],
                    tau_per_class=recorded["tau_per_class"] if o.tau_per_class is None
                    else o.tau_per_class)
    o = replace(o, delta=recorded["delta"] if o.delta is None else o.delta,
                extra_templates=recorded["extra_templates"] if o.extra_templates is None
                else o.extra_templates)
    result = write_report(
        out_dir, truth, rows, frames=frames,
        templates=load_template_folder(mt_dir) if mt_dir else None,
        features=(feats or None) if mt_dir else None,
        poses=poses if motions or poses else None, pose_sources=sources, motion_notes=other,
        options=o, progress=None if progress is None else
        (lambda done, total: progress(read[0] + done, read[0] + total)),
        provenance=provenance(inputs=[*inputs, *motion_paths.values()],
                              truth=str(truth_path) if truth_path else None))
    if failures is not None:
        failures.extend(result.motion_notes.values())
    return result, rows


def _same_folder(a, b) -> bool:
    """Whether the folders ``a`` and ``b`` are one (resolved)."""
    return os.path.realpath(a) == os.path.realpath(b)


def _player_inputs(paths, motions, motion_paths, docs, *, asf, jobs, failures, step):
    """The feature matrices of ``paths`` and the player's poses: from the motion files
    (read in ``jobs`` processes, ``step()`` after each; one whose SHA-256 is not the one
    its feature file records is left out, and why is in the last result), else from the
    feature files' pose blocks. Returns (features, poses, their files, why not played)."""
    from mtanno.evaluation.player import load_motion_poses, motion_mismatch
    from mtanno.features.store import read_features

    feats, poses, sources, made_from, other = {}, {}, {}, {}, {}
    for p in paths:
        try:
            ff = read_features(p, poses=not motions)
        except MtannoError as exc:
            if failures is None:
                raise
            failures.append(str(exc))
            continue
        feats[ff.document] = ff.X
        made_from[ff.document] = ff.meta.get("source_sha256")
        if ff.poses is not None:
            poses[ff.document], sources[ff.document] = ff.poses, str(p)
    if motions:  # the SHA-256 of each motion only when a feature file records one
        digests: dict[str, str] | None = {} if any(made_from.values()) else None
        poses = load_motion_poses(motion_paths, docs, asf=asf, failures=failures, rig=True,
                                  encode=True, digests=digests, jobs=jobs, progress=step)
        sources = {d: str(motion_paths[d]) for d in poses}
        for d in list(poses):
            why = motion_mismatch(d, poses[d].frames, recorded=None, last_labelled=0,
                                  path=sources[d], digest=(digests or {}).get(d),
                                  features_source=made_from.get(d))
            if why is not None:
                del poses[d]
                other[d] = why
    return feats, poses, sources, other
