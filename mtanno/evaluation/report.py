"""``mtanno report``: an annotation run as a page for people and tables for papers.

From annotation tables and the ground truth (and optionally the templates and the
documents' feature files) :func:`write_report` writes into one folder:

* ``index.html`` — a self-contained page (every image inline as a data URI, no other file
  needed) with the tables and figures below;
* ``per_class.csv`` / ``.md`` / ``.tex`` — per-class P/R/F at frame and segment level with
  their support ([MBS09] §7), frame accuracy, Edit and F1@{10,25,50} (the rows of ``mtanno
  evaluate``, "–" where undefined), CSV with provenance;
* ``confusion.csv`` and ``confusion.png``/``.svg`` — the frame-level confusion matrix,
  truth × annotation, with a "none" row and column (frames without a label);
* ``timeline_<doc>.png``/``.svg`` — per document, truth against annotation;
* with templates and features: ``template_<class>.png``/``.svg`` (heat maps, [MR06] Fig. 4)
  and ``delta_<doc>.png``/``.svg`` (each class's Δ over the document, docs/method.md §3.4);
* on the page, with the documents' poses, a stick-figure player per document, and always
  the review list with the controls that turn it into a truth CSV
  (:mod:`mtanno.evaluation.player`).

A confusion matrix needs one label per frame. Annotations from ``annotate
--single-label`` are a partition; the default output may overlap, and then each frame is
counted for the covering segment with the smallest cost (the smallest Δ̄ in the segment,
which approximates the per-frame Δ̄ that ``--single-label`` uses); the page says so.
"""

from __future__ import annotations

import base64
import html
import math
import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mtanno.errors import MtannoError
from mtanno.evaluation.metrics import SEGMENTATION_COLUMNS, Report, evaluate_annotations
from mtanno.evaluation.player import review_html
from mtanno.labels.segments import Segment

if TYPE_CHECKING:
    from mtanno.labels.segments import Annotation

NONE = "none"
#: Title of a report page.
REPORT_TITLE = "mtanno annotation report"
FORMATS = ("png", "svg")
#: Every name :func:`write_report` may write in its folder (glob patterns for those named
#: after documents and classes), for :func:`mtanno.util.preflight.check_outputs`.
REPORT_FILES = ("index.html", "per_class.csv", "per_class.csv.meta.json", "per_class.md",
                "per_class.tex", "confusion.csv", "confusion.csv.meta.json", "summary.csv",
                "summary.csv.meta.json", "summary.md", "review.csv", "review.csv.meta.json",
                *(f"{stem}.{fmt}" for stem in ("confusion", "reliability", "timeline_*",
                                               "template_*", "delta_*") for fmt in FORMATS))


@dataclass
class ReportResult:
    """What :func:`write_report` wrote: the folder, the HTML page, every file, the
    evaluation, the confusion matrix with its labels, and notes shown on the page."""

    folder: Path
    page: Path
    files: list[Path] = field(default_factory=list)
    evaluation: Report | None = None
    labels: list[str] = field(default_factory=list)
    confusion: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)


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
    for doc, n in frames.items():
        t, _ = _frame_labels([(s.start - 1, s.end - 1, s.label, 0.0) for s in truth
                              if s.doc == doc], n, rank)
        a, ov = _frame_labels([(r.start, r.end, r.label, r.cost) for r in annotation
                               if r.doc == doc], n, rank)
        overlapped |= ov
        t[t < 0] = rank[NONE]
        a[a < 0] = rank[NONE]
        np.add.at(M, (t, a), 1)
    return M, labels, overlapped


def _number(x: float | None) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{x:.3f}"


def _cells(r: dict) -> list[str]:
    """The cells of a :meth:`Report.rows` row after its class, "–" where undefined."""
    return [_number(r["P1"]), _number(r["R1"]), _number(r["F1"]), str(r["frames"]),
            _number(r["P2"]), _number(r["R2"]), _number(r["F2"]), str(r["segments"]),
            *(_number(r.get(c)) for c in SEGMENTATION_COLUMNS)]


def markdown_table(rows: Sequence[dict]) -> str:
    """Per-class rows of :meth:`Report.rows` as a Markdown (GitHub) table."""
    head = ("| class | P1 | R1 | F1 | frames | P2 | R2 | F2 | segments | "
            + " | ".join(SEGMENTATION_COLUMNS) + " |")
    lines = [head, "|---|" + "---:|" * (8 + len(SEGMENTATION_COLUMNS))]
    for r in rows:
        lines.append(f"| {r['class']} | " + " | ".join(_cells(r)) + " |")
    return "\n".join(lines) + "\n"


def _plain_markdown(rows: Sequence[dict]) -> str:
    """Rows of any columns (the first row's) as a Markdown table; numbers as they are,
    missing values "–"."""
    cols = list(rows[0]) if rows else []
    lines = ["| " + " | ".join(cols) + " |", "|---|" + "---:|" * (len(cols) - 1)]
    for r in rows:
        lines.append("| " + " | ".join("–" if r[c] is None else str(r[c]) for c in cols) + " |")
    return "\n".join(lines) + "\n"


def _tex(text: str) -> str:
    """Text with LaTeX's special characters escaped."""
    text = text.replace("\\", "\0")
    for a, b in (("_", r"\_"), ("&", r"\&"), ("%", r"\%"), ("#", r"\#"), ("$", r"\$"),
                 ("{", r"\{"), ("}", r"\}")):
        text = text.replace(a, b)
    return text.replace("\0", r"\textbackslash{}")


def latex_table(rows: Sequence[dict]) -> str:
    """Per-class rows as a LaTeX ``tabular`` (booktabs rules), the overall row last."""
    lines = [r"\begin{tabular}{l" + "r" * (8 + len(SEGMENTATION_COLUMNS)) + "}", r"\toprule",
             r"class & $P_1$ & $R_1$ & $F_1$ & frames & $P_2$ & $R_2$ & $F_2$ & segments & "
             r"Acc & Edit & F1@10 & F1@25 & F1@50 \\",
             r"\midrule"]
    for r in rows:
        if r["class"] == "overall":
            lines.append(r"\midrule")
        lines.append(" & ".join([_tex(str(r["class"])), *_cells(r)]) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    return "\n".join(lines) + "\n"


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


class _Writer:
    """Writes the figures (PNG and SVG), remembers them for the page."""

    def __init__(self, folder: Path, result: ReportResult, figures: int = 0,
                 progress: Callable[[int, int], None] | None = None):
        self.folder = folder
        self.result = result
        self.images: list[tuple[str, str, Path]] = []  # section, caption, png
        self.figures, self.progress = figures, progress  # progress(done, of figures)

    def figure(self, ax, stem: str, section: str, caption: str) -> None:
        from mtanno.plot import save_figure

        for fmt in FORMATS:
            path = self.folder / f"{stem}.{fmt}"
            save_figure(ax, path)
            self.result.files.append(path)
        self.images.append((section, caption, self.folder / f"{stem}.png"))
        if self.progress is not None:
            self.progress(len(self.images), max(self.figures, len(self.images)))

    def text(self, name: str, text: str) -> None:
        from mtanno.util.output import write_text

        write_text(self.folder / name, text)
        self.result.files.append(self.folder / name)


def _html_table(rows: Sequence[dict]) -> str:
    cols = list(rows[0]) if rows else []
    out = ["<table><tr>" + "".join(f"<th>{html.escape(c)}</th>" for c in cols) + "</tr>"]
    for r in rows:
        cells = []
        for c in cols:
            v = r[c]
            text = _number(v) if v is None or isinstance(v, float) else html.escape(str(v))
            cells.append(f"<td>{text}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    return "\n".join(out) + "</table>"


_STYLE = ("body{font-family:sans-serif;max-width:1200px;margin:auto}"
          "table{border-collapse:collapse;max-width:100%}td,th{border:1px solid #ccc;"
          "padding:2px 6px;text-align:right;overflow-wrap:anywhere}"
          "img{max-width:100%;display:block;margin:8px 0}"
          "pre{white-space:pre-wrap;overflow-wrap:anywhere}"
          ".player{margin:12px 0}canvas.figure{display:block;border:1px solid #ddd}"
          "canvas.timeline{display:block;width:100%;cursor:pointer}"
          "tr.review{cursor:pointer}tr.review.accept{background:#e6f4e6}"
          "tr.review.reject{background:#f6e6e6;color:#888}"
          "td input{width:5em}td input.label{width:13em}")


def _page(result: ReportResult, images, rows, title: str, provenance: dict, *, docs=(),
          review: str = "", scored: bool = True, motions: str = "", script: str = "") -> str:
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
             f"</title><style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1>"]
    files = ("per_class.csv/.md/.tex, confusion.csv" if scored else "summary.csv/.md (no "
             "truth given: no scores)")
    parts.append(f"<p>{len(docs)} document(s); frames at 30 Hz. Files beside this page: "
                 f"{files}, review.csv, every figure as PNG and SVG.</p>")
    for note in result.notes:  # `command` in a note is code on the page, not a backtick
        text = re.sub(r"`([^`]+)`", r"<code>\1</code>", html.escape(note))
        parts.append(f"<p><b>Note:</b> {text}</p>")
    parts.append(("<h2>Precision, recall, F per class</h2>" if scored else
                  "<h2>Classes in the annotation</h2>") + _html_table(rows))
    sections: dict[str, list] = {}
    for section, caption, png in images:
        sections.setdefault(section, []).append((caption, png))
    for section, items in sections.items():
        parts.append(f"<h2>{html.escape(section)}</h2>")
        for caption, png in items:
            data = base64.b64encode(png.read_bytes()).decode("ascii")
            parts.append(f"<figure><img alt='{html.escape(caption)}' "
                         f"src='data:image/png;base64,{data}'>"
                         f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    parts += [motions, review]
    parts.append("<h2>Provenance</h2><pre>" + html.escape(
        "\n".join(f"{k}: {v}" for k, v in provenance.items() if k != "inputs")) + "</pre>")
    parts.append(script)
    parts.append("</body></html>\n")
    return "\n".join(parts)


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
                 tau: float | None = None, tau_per_class: dict[str, float] | None = None,
                 delta: float | None = None, extra_templates: Sequence[str] = (),
                 title: str = REPORT_TITLE, provenance: dict | None = None,
                 progress: Callable[[int, int], None] | None = None,
                 poses: dict[str, np.ndarray] | None = None) -> ReportResult:
    """Write the report of ``annotation`` (rows of one or more annotation tables, 0-based
    frames) against ``truth`` into ``out_dir`` (module docstring). ``frames`` gives each
    document's length (default: the last labelled frame of truth or annotation);
    ``templates`` (class → :class:`~mtanno.templates.model.MotionTemplate`) adds heat maps
    and, with ``features`` (document → features × frames matrix), the Δ curves of every
    class: templates quantized with ``delta`` (default 0.05) as the annotation did,
    ``tau`` drawn, and in the class's colour each τ of ``tau_per_class`` that differs from
    it. ``extra_templates`` names the classes the annotation also matched further
    templates for (a tuned configuration's ``[templates]``): their curves, of the class's
    own template only, are not the annotation's Δ, and the page says so. Documents are
    those annotated. ``progress(done, total)`` is called after each figure.

    Without ``truth`` (None; issue 24, an archive nobody has labelled) the page has, instead
    of the scores and the confusion matrix, per class the number of segments, their
    duration and share of the archive (``summary.csv``); the timelines show the annotation
    alone. Either way ``review.csv`` and the page's review list hold every row, the least
    confident first (the rows to check), with the controls that turn a review into a truth
    CSV (:func:`mtanno.evaluation.player.review_html`). ``poses`` (document → normalised
    poses at the 30 Hz frames, :mod:`mtanno.evaluation.player`) adds a stick-figure player
    per document that has them."""
    from mtanno.plot import (
        label_colours,
        plot_template,
        require_matplotlib,
    )
    from mtanno.util.output import make_folder
    from mtanno.util.tables import write_table

    require_matplotlib()
    if not annotation:
        raise MtannoError("the annotation has no rows to report on")
    folder = make_folder(out_dir)
    result = ReportResult(folder, folder / "index.html")
    frames = dict(frames or {})
    # documents with rows, and those recorded as annotated without any (their truth counts)
    docs = sorted({a.doc for a in annotation} | set(frames))
    scored = truth is not None
    truth = list(truth or [])
    for d in docs:
        last = max([a.end + 1 for a in annotation if a.doc == d]
                   + [s.end for s in truth if s.doc == d] + [0])
        frames[d] = max(frames.get(d, 0), last)
    frames = {d: frames[d] for d in docs}
    prov = dict(provenance or {})
    import pyarrow as pa

    w = _Writer(folder, result, progress=progress, figures=len(docs) + len(templates or {})
                + (sum(d in features for d in docs) if templates and features else 0)
                + (2 if scored else 0))
    if scored:
        rows, labels = _scores(w, truth, annotation, docs, frames, prov)
    else:
        rows = summary_rows(annotation, frames)
        labels = [r["class"] for r in rows[:-1]]
        write_table(folder / "summary.csv", pa.Table.from_pylist(rows), provenance=prov)
        result.files += [folder / "summary.csv", folder / "summary.csv.meta.json"]
        w.text("summary.md", _plain_markdown(rows))
    review = review_rows(annotation)
    write_table(folder / "review.csv", pa.Table.from_pylist(review), provenance=prov)
    result.files += [folder / "review.csv", folder / "review.csv.meta.json"]
    colours = label_colours(labels)
    _timelines(w, docs, truth if scored else None, annotation, frames, colours)
    if templates:
        for name, mt in templates.items():
            w.figure(plot_template(mt), f"template_{_safe(name)}", "Templates",
                     f"template {name}")
    if templates and features:
        _delta_figures(w, templates, {d: features[d] for d in docs if d in features}, tau,
                       tau_per_class or {}, delta)
        if extra_templates:
            result.notes.append(
                "the annotation also matched further templates of "
                f"{', '.join(sorted(extra_templates))} (its class configuration's [templates]); "
                "their Δ curves here are those of the class's own template only")
    from mtanno.util.output import write_text

    motions, script = _players(annotation, docs, frames, colours, poses)
    classes = sorted({a.label for a in annotation} | {s.label for s in truth})
    write_text(result.page, _page(
        result, w.images, rows, title, prov, docs=docs, scored=scored, motions=motions,
        review=review_html(review, classes, set(poses or ())), script=script))
    result.files.append(result.page)
    return result


def _timelines(w: _Writer, docs, truth, annotation, frames, colours) -> None:
    """Per document its timeline figure: truth (None: not given) and annotation."""
    from mtanno.plot import plot_timeline

    by_doc: dict[str, dict[str, list]] = {d: {} for d in docs}  # lanes, grouped once
    for s in truth or ():
        if s.doc in by_doc:
            by_doc[s.doc].setdefault("truth", []).append((s.start, s.end, s.label))
    for a in annotation:
        by_doc[a.doc].setdefault("annotation", []).append((a.start + 1, a.end + 1, a.label))
    for d in docs:
        lanes = {**({"truth": by_doc[d].get("truth", [])} if truth is not None else {}),
                 "annotation": by_doc[d].get("annotation", [])}
        ax = plot_timeline(lanes, n_frames=frames[d], colours=colours)
        present = sorted({lab for segs in lanes.values() for _, _, lab in segs})
        _legend(ax, present, colours)
        ax.figure.set_size_inches(12, max(1.8, 0.9 + 0.16 * len(present)))
        ax.set_title(d)
        w.figure(ax, f"timeline_{_safe(d)}", "Timelines: truth and annotation"
                 if truth is not None else "Timelines of the annotation", d)


def _players(annotation, docs, frames, colours, poses) -> tuple[str, str]:
    """The page's section of players (none without ``poses``) and its script (players
    and the review list's controls)."""
    from matplotlib.colors import to_hex

    from mtanno.evaluation.player import player_script, players_data, players_html

    hexes = {lab: to_hex(colours.get(lab, "#888888")) for lab in {a.label for a in annotation}}
    shown = {d: poses[d] for d in docs if d in (poses or {})}
    data = players_data(shown, annotation, frames, hexes)
    section = "" if poses is None else players_html(data, [d for d in docs if d not in shown])
    return section, player_script(data)


def _scores(w: _Writer, truth, annotation, docs, frames, prov) -> tuple[list[dict], list[str]]:
    """The evaluation against ``truth``: the per-class table (CSV, Markdown, LaTeX), the
    confusion matrix (table and figure) and the reliability of the confidence; returns the
    table's rows and the matrix's labels."""
    import pyarrow as pa

    from mtanno.labels.segments import to_segments
    from mtanno.plot import plot_confusion
    from mtanno.util.tables import write_table

    result, folder = w.result, w.folder
    ev = evaluate_annotations(truth, to_segments(annotation), documents=docs, frames=frames)
    result.evaluation = ev
    result.notes.extend(ev.warnings)  # e.g. truth and annotation without a common label
    rows = ev.rows()
    write_table(folder / "per_class.csv", pa.Table.from_pylist(rows), provenance=prov)
    result.files += [folder / "per_class.csv", folder / "per_class.csv.meta.json"]
    w.text("per_class.md", markdown_table(rows))
    w.text("per_class.tex", latex_table(rows))
    M, labels, overlapped = confusion_matrix(truth, annotation, frames)
    result.confusion, result.labels = M, labels
    if overlapped:
        result.notes.append("the annotation's segments overlap; in the confusion matrix and "
                            "timelines each frame counts for the covering segment with the "
                            "smallest cost (use `mtanno annotate --single-label` for an exact "
                            "partition by Δ̄); the Acc column, like `mtanno evaluate`, gives "
                            "each frame to the covering segment that starts last")
    table = {"truth": labels, **{lab: M[:, j].tolist() for j, lab in enumerate(labels)}}
    write_table(folder / "confusion.csv", pa.table(table), provenance=prov)
    result.files += [folder / "confusion.csv", folder / "confusion.csv.meta.json"]
    w.figure(plot_confusion(M, labels), "confusion", "Confusion matrix (frames)",
             "rows: truth, columns: annotation; counts of frames")
    _reliability(w, truth, annotation, prov)
    return rows, labels


def summary_rows(annotation: Sequence[Annotation], frames: dict[str, int]) -> list[dict]:
    """Per label of ``annotation`` (and ``all``): segments, labelled frames (frames at 30
    Hz; a frame two rows of a label cover counts once), seconds, their share of the
    documents' ``frames`` and the rows' mean confidence (None where no row has one)."""
    total = sum(frames.values())
    out = []
    labels = sorted({a.label for a in annotation})
    for lab in [*labels, None]:
        rows = [a for a in annotation if lab is None or a.label == lab]
        covered = 0
        for d in sorted({a.doc for a in rows}):
            mask = np.zeros(frames.get(d, 0) or max(a.end + 1 for a in rows if a.doc == d),
                            dtype=bool)
            for a in rows:
                if a.doc == d:
                    mask[a.start:a.end + 1] = True
            covered += int(mask.sum())
        conf = [a.confidence for a in rows if not math.isnan(a.confidence)]
        out.append({"class": lab if lab is not None else "all", "segments": len(rows),
                    "frames": covered, "seconds": round(covered / 30.0, 2),
                    "share": round(covered / total, 4) if total else None,
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


def _reliability(w: _Writer, truth, annotation, prov: dict) -> None:
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
    w.figure(plot_reliability(table), "reliability", "Confidence",
             f"reliability of the confidence, {what}: per bin the fraction of rows whose "
             "label is right (IoU ≥ 0.5 with a truth segment of its label)")
    w.result.notes.append(
        f"confidence ({what}): {int(right.sum())} of {len(rows)} rows right, AUROC "
        f"{auroc(prob, right):.3f}, ECE {expected_calibration_error(prob, right):.3f}")


def _legend(ax, labels, colours) -> None:
    from matplotlib.patches import Patch

    if labels:
        ax.legend(handles=[Patch(color=colours[lab], label=lab) for lab in labels],
                  loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=7, frameon=False)


def _delta_figures(w: _Writer, templates: dict, features: dict[str, np.ndarray],
                   tau: float | None, tau_per_class: dict[str, float],
                   delta: float | None) -> None:
    from mtanno.annotate import class_deltas, class_models
    from mtanno.plot import label_colours, plot_delta
    from mtanno.templates.params import ANNOTATION_DELTA

    models, _ = class_models(templates, delta=ANNOTATION_DELTA if delta is None else delta)
    colours = label_colours(sorted(m.name for m in models))
    for d, X in features.items():
        ax = None
        for m, (curve, _) in zip(models, class_deltas(X, models)):
            ax = plot_delta(curve, label=m.name, tau=tau, ax=ax)
            [line for line in ax.lines if line.get_label() == m.name][0].set_color(
                colours[m.name])
            own = tau_per_class.get(m.name)
            if own is not None and own != tau:
                ax.axhline(own, color=colours[m.name], linestyle=":", linewidth=1,
                           label=f"τ {m.name} = {own:g}")
        ax.set_title(f"{d}: Δ of every class")
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=7, frameon=False)
        ax.figure.set_size_inches(12, max(3.5, 1.0 + 0.16 * len(models)))
        w.figure(ax, f"delta_{_safe(d)}", "Distance curves Δ per class", d)


def report_files(annotations: Sequence[str | os.PathLike], out_dir: str | os.PathLike, *,
                 truth_path: str | os.PathLike | None = None,
                 mt_dir: str | os.PathLike | None = None,
                 features: Sequence[str | os.PathLike] = (),
                 motions: Sequence[str | os.PathLike] = (),
                 asf: str | os.PathLike | None = None, tau: float | None = None,
                 delta: float | None = None, title: str = REPORT_TITLE,
                 progress: Callable[[int, int], None] | None = None,
                 failures: list[str] | None = None) -> tuple[ReportResult, list]:
    """The whole ``mtanno report`` run: the annotation tables (files or folders of them),
    the truth, templates, feature files and motion files read and checked against the
    output folder (never an input there), and :func:`write_report` with the thresholds and
    δ the annotation recorded (``tau``, ``delta`` override them). Poses for the players
    come from ``motions`` (:func:`mtanno.evaluation.player.motion_files`), else from the
    pose blocks of ``features`` (``asf``: the ASF of AMC motions, else found beside them);
    Δ curves need ``mt_dir`` and ``features``. A feature or
    motion file that cannot be read is left out and its message appended to ``failures``
    (an error without it). Returns the result and the annotation's rows."""
    from mtanno.annotate import (
        ANNOTATION_SUFFIXES,
        annotation_files,
        read_annotation_tables,
    )
    from mtanno.evaluation.player import load_motion_poses, motion_files
    from mtanno.features.inputs import document_files
    from mtanno.features.store import read_features
    from mtanno.io import MOCAP_SUFFIXES
    from mtanno.labels.truth import check_within, read_truth
    from mtanno.plot import require_matplotlib
    from mtanno.templates.model import load_template_folder, template_files
    from mtanno.templates.params import ANNOTATION_TAU
    from mtanno.util.preflight import check_outputs
    from mtanno.util.tables import provenance

    require_matplotlib()
    if any(Path(a).suffix.lower() in MOCAP_SUFFIXES for a in annotations):
        raise MtannoError("a motion file among the annotation tables: give {motions} before "
                          "each motion file, or their folder", options=("motions",))
    paths = document_files(features, failures=failures) if features else []
    # folders read whole: an output there would be read by the next run
    scanned = {**{a: ANNOTATION_SUFFIXES for a in annotations if Path(a).is_dir()},
               **{f: (".parquet",) for f in features if Path(f).is_dir()}}
    annotations = annotation_files(annotations)
    inputs = [*annotations, *([truth_path] if truth_path else [])]
    check_outputs([], [*inputs, *paths, *(template_files(mt_dir) if mt_dir else [])],
                  folders={out_dir: REPORT_FILES}, scanned=scanned)
    rows, frames, provs = read_annotation_tables(annotations)
    docs = sorted({r.doc for r in rows} | set(frames))
    motion_paths = motion_files(motions, docs)
    check_outputs([], [*motion_paths.values()], folders={out_dir: REPORT_FILES})
    recorded = annotation_parameters(provs)
    truth = None
    if truth_path is not None:
        truth = read_truth(truth_path)
        check_within(truth, frames, path=truth_path)
    feats, poses = {}, {}
    for p in paths:
        try:
            ff = read_features(p, poses=not motions)
        except MtannoError as exc:
            if failures is None:
                raise
            failures.append(str(exc))
            continue
        feats[ff.document] = ff.X
        if ff.poses is not None:
            poses[ff.document] = ff.poses
    if motions:
        poses = load_motion_poses(motion_paths, docs, asf=asf, failures=failures)
    per_class = recorded["tau_per_class"] if tau is None else {}
    if tau is None:  # the annotation's thresholds
        tau = ANNOTATION_TAU if recorded["tau"] is None else recorded["tau"]
    result = write_report(
        out_dir, truth, rows, frames=frames,
        templates=load_template_folder(mt_dir) if mt_dir else None,
        features=(feats or None) if mt_dir else None, tau=tau, tau_per_class=per_class,
        poses=poses if motions or poses else None,
        delta=delta if delta is not None else recorded["delta"],
        extra_templates=recorded["extra_templates"], title=title, progress=progress,
        provenance=provenance(inputs=[*inputs, *motion_paths.values()],
                              truth=str(truth_path) if truth_path else None))
    return result, rows

