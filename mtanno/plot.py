"""Plots of mtanno's data (matplotlib, the optional extra ``plot``: ``pip install
'mtanno[plot]'``).

Every function draws one kind of data into a matplotlib ``Axes`` and returns it:
``plot_x(data, *, ax=None) -> Axes``. Without ``ax`` a new figure is made with
:class:`matplotlib.figure.Figure` (no pyplot, no window, any backend), so the functions
work the same in scripts, on servers and in notebooks; nothing calls ``plt.show``.
:func:`reliability_figure` is the one whole figure (a reliability diagram above its bin
counts). :func:`save_figure` writes a figure atomically (PNG or SVG by the suffix). Frames
on the axes are 1-based at 30 Hz, as in every file mtanno writes.

:func:`plot_template_file` and :func:`show_to` are the runs of the two commands that draw
a file (``mtanno mt plot``, ``mtanno show --plot``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from mtanno.errors import MtannoError

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from mtanno.evaluation.calibration import ReliabilityTable
    from mtanno.info import Timeline
    from mtanno.templates.model import MotionTemplate

INSTALL_HINT = "plots need matplotlib: pip install 'mtanno[plot]' (or pip install matplotlib)"

#: Colours of class labels (matplotlib's tab20, cycled); "none" is light grey.
NONE_COLOUR = "#e8e8e8"


def require_matplotlib() -> None:
    """Raise an :class:`MtannoError` saying how to install matplotlib when it is missing."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise MtannoError(INSTALL_HINT) from None


def _axes(ax, size: tuple[float, float]):
    require_matplotlib()
    if ax is not None:
        return ax
    from matplotlib.figure import Figure

    return Figure(figsize=size, layout="constrained").add_subplot()


def label_colours(labels: Sequence[str]) -> dict[str, Any]:
    """One colour per label (in the order given), "none" grey; the first ten labels get
    ten clearly different colours (tab20's dark ones), the next ten their light pairs."""
    require_matplotlib()
    from matplotlib import colormaps

    cmap = colormaps["tab20"]  # its dark ten first, then their light pairs: the first ten
    order = [*range(0, 20, 2), *range(1, 20, 2)]  # labels are ten distinct colours
    out = {lab: cmap(order[i % 20])
           for i, lab in enumerate(lab for lab in labels if lab != "none")}
    out["none"] = NONE_COLOUR
    return out


def plot_features(X: np.ndarray, names: Sequence[str], *, first_frame: int = 1,
                  ax: Axes | None = None) -> Axes:
    """A feature matrix (features × frames, 0/1) as an image: one row per feature (named),
    one column per frame, dark where the feature is on ([MRC05] Fig. 3 style). ``first_frame``
    is the 1-based frame of column 0."""
    X = np.asarray(X)
    ax = _axes(ax, (min(12.0, max(6.0, 2 + X.shape[1] / 15)), 1.2 + 0.22 * X.shape[0]))
    ax.imshow(X, aspect="auto", interpolation="nearest", cmap="Greys", vmin=0, vmax=1,
              extent=(first_frame - 0.5, first_frame + X.shape[1] - 0.5, X.shape[0] - 0.5,
                      -0.5))
    ax.set_yticks(range(len(names)), list(names), fontsize=7)
    ax.set_xlabel("frame (30 Hz)")
    return ax


def plot_template(mt: MotionTemplate, *, ax: Axes | None = None) -> Axes:
    """A motion template as a heat map ([MR06] Fig. 4): rows are features, columns the
    template's columns, colour the entry in [0, 1] (0 black, 1 white, wildcard 0.5 grey)."""
    V = np.asarray(mt.values)
    ax = _axes(ax, (min(12.0, 3 + V.shape[1] / 8), 1.2 + 0.13 * V.shape[0]))
    image = ax.imshow(V, aspect="auto", interpolation="nearest", cmap="gray", vmin=0, vmax=1)
    ax.set_yticks(range(len(mt.feature_names)), list(mt.feature_names), fontsize=6)
    ax.set_xlabel("template column")
    ax.set_title(f"{mt.class_name} ({mt.kind}, {V.shape[1]} columns)")
    ax.figure.colorbar(image, ax=ax, fraction=0.03)
    return ax


def plot_delta(delta: np.ndarray, *, label: str | None = None, tau: float | None = None,
               ax: Axes | None = None) -> Axes:
    """A distance curve Δ over a document's frames (docs/method.md §3.4; [MR06] Fig. 7):
    x = frame (1-based), y = Δ; frames where no match ends (Δ = ∞) leave gaps. ``tau``
    draws the threshold."""
    delta = np.asarray(delta, dtype=np.float64)
    ax = _axes(ax, (10, 3))
    y = np.where(np.isfinite(delta), delta, np.nan)
    ax.plot(np.arange(1, len(y) + 1), y, label=label, linewidth=1)
    if tau is not None and not any(line.get_label() == f"τ = {tau:g}" for line in ax.lines):
        ax.axhline(tau, color="k", linestyle=":", linewidth=1, label=f"τ = {tau:g}")
    ax.set_xlabel("frame (30 Hz)")
    ax.set_ylabel("Δ")
    return ax


def plot_confusion(matrix: np.ndarray, labels: Sequence[str], *,
                   ax: Axes | None = None) -> Axes:
    """A confusion matrix of frames: rows the truth, columns the annotation (labels
    include "none"), each row shaded by its share of the row's frames, counts written."""
    M = np.asarray(matrix, dtype=np.int64)
    n = len(labels)
    ax = _axes(ax, (2 + 0.55 * n, 1.5 + 0.5 * n))
    share = M / np.maximum(M.sum(axis=1, keepdims=True), 1)
    ax.imshow(share, cmap="Blues", vmin=0, vmax=1)
    for i in range(n):
        for j in range(n):
            if M[i, j]:
                ax.text(j, i, str(M[i, j]), ha="center", va="center", fontsize=6,
                        color="white" if share[i, j] > 0.6 else "black")
    ax.set_xticks(range(n), list(labels), rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(n), list(labels), fontsize=7)
    ax.set_xlabel("annotation")
    ax.set_ylabel("truth")
    return ax


def plot_timeline(rows: dict[str, Sequence[tuple[int, int, str]]], *, n_frames: int,
                  colours: dict[str, Any] | None = None, ax: Axes | None = None) -> Axes:
    """Labelled segments of one document, one lane per entry of ``rows`` (e.g. "truth"
    and "annotation"; segments (start, end, label) with 1-based inclusive frames), each
    label in its colour; overlapping segments of a lane are drawn half height."""
    ax = _axes(ax, (12, 0.6 + 0.45 * len(rows)))
    labels = sorted({lab for segs in rows.values() for _, _, lab in segs})
    colours = colours or label_colours(labels)
    bars: dict[tuple, list] = {}  # one collection per (lane, place, label): fast to draw
    for lane, segs in enumerate(rows.values()):
        ordered = sorted(segs)
        for k, (s, e, lab) in enumerate(ordered):
            overlap = any(a <= e and s <= b for a, b, _ in ordered[:k]) or \
                any(a <= e and s <= b for a, b, _ in ordered[k + 1:])
            height = 0.4 if overlap else 0.8
            y = lane - 0.4 + (0.4 if overlap and k % 2 else 0)
            bars.setdefault((y, height, lab), []).append((s - 0.5, e - s + 1))
    for (y, height, lab), spans in bars.items():
        ax.broken_barh(spans, (y, height), facecolors=colours.get(lab, NONE_COLOUR))
    ax.set_yticks(range(len(rows)), list(rows))
    ax.set_ylim(len(rows) - 0.5, -0.5)
    ax.set_xlim(0.5, n_frames + 0.5)
    ax.set_xlabel("frame (30 Hz)")
    return ax


def plot_reliability(table: ReliabilityTable, *, ax: Axes | None = None,
                     counts_ax: Axes | None = None) -> Axes:
    """A reliability diagram of a confidence (issue 26; Niculescu-Mizil & Caruana 2005):
    per non-empty bin of :func:`mtanno.evaluation.reliability_table`, x = the mean
    confidence of its segments, y = the fraction of them whose label is right, with the
    diagonal of perfect calibration and the ECE in the legend; with ``counts_ax``, the
    segments per bin as bars there (x = confidence, the bins' widths)."""
    ax = _axes(ax, (4.5, 4.5))
    ax.plot([0, 1], [0, 1], color="k", linestyle=":", linewidth=1, label="calibrated")
    full = table.count > 0
    ax.plot(table.mean_prob[full], table.fraction_right[full], marker="o", linewidth=1.5,
            label=f"ECE = {table.ece:.3f} ({table.n} segments)")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("confidence")
    ax.set_ylabel("fraction right")
    ax.legend(loc="upper left", fontsize=8)
    if counts_ax is not None:
        counts_ax.bar(table.lo, table.count, width=table.hi - table.lo, align="edge",
                      color="#7a9cc6", edgecolor="white")
        counts_ax.set_xlim(0, 1)
        counts_ax.set_xlabel("confidence")
        counts_ax.set_ylabel("segments")
    return ax


def reliability_figure(table: ReliabilityTable, *, title: str | None = None) -> Figure:
    """A figure of :func:`plot_reliability`: the diagram above, the counts per bin as bars
    below on the same confidence axis; ``title`` above both."""
    require_matplotlib()
    from matplotlib.figure import Figure

    figure = Figure(figsize=(4.5, 6), layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True, height_ratios=[3, 1])
    plot_reliability(table, ax=top, counts_ax=bottom)
    top.set_xlabel("")
    if title:
        figure.suptitle(title)
    return figure


def save_figure(ax_or_figure, path: str | os.PathLike, *, dpi: int = 110) -> None:
    """Write the figure of ``ax_or_figure`` atomically; the format follows the suffix
    (``.png``, ``.svg``, ``.pdf``). The same figure gives the same bytes: no date in the
    file, and SVG element ids from a fixed salt (matplotlib's default is random), so a
    report written twice is the same."""
    import matplotlib

    from mtanno.util.output import atomic_path

    figure = getattr(ax_or_figure, "figure", ax_or_figure)
    fmt = os.fspath(path).rsplit(".", 1)[-1].lower() if "." in os.fspath(path) else ""
    if fmt not in ("png", "svg", "pdf"):
        raise MtannoError("a plot file must end in .png, .svg or .pdf", path=str(path))
    metadata = {"png": None, "svg": {"Date": None}, "pdf": {"CreationDate": None}}[fmt]
    with atomic_path(path) as tmp, matplotlib.rc_context({"svg.hashsalt": "mtanno"}):
        figure.savefig(tmp, format=fmt, dpi=dpi, metadata=metadata)


# --------------------------------------------------------------- the commands that draw a file


def plot_template_file(template: str | os.PathLike, output: str | os.PathLike, *,
                       delta: float | None = None) -> MotionTemplate:
    """The run of ``mtanno mt plot``: the template of file ``template`` (quantized with
    ``delta`` first, if given) drawn by :func:`plot_template` into the picture ``output``
    (checked against the input first); returns the template drawn."""
    from mtanno.templates.model import quantize
    from mtanno.templates.store import load_template
    from mtanno.util.preflight import check_outputs

    require_matplotlib()
    check_outputs([output], [template])
    mt = load_template(template)
    if delta is not None:
        mt = quantize(mt, delta)
    save_figure(plot_template(mt), output)
    return mt


def show_to(path: str | os.PathLike, *, frames: str | None = None,
            features: Sequence[str] | None = None, width: int | None = None,
            plot_path: str | os.PathLike | None = None) -> Timeline:
    """The run of ``mtanno show``: the text timeline of feature file ``path``
    (:func:`mtanno.info.feature_timeline`: ``frames``, ``features``, ``width``) and, with
    ``plot_path``, the same drawn by :func:`plot_features` into that picture (matplotlib
    and the output checked before the file is read)."""
    from mtanno.info import DEFAULT_WIDTH, feature_timeline
    from mtanno.util.preflight import check_outputs

    if plot_path is not None:
        require_matplotlib()
        check_outputs([plot_path], [path])
    tl = feature_timeline(path, frames=frames, features=features,
                          width=DEFAULT_WIDTH if width is None else width)
    if plot_path is not None:
        ax = plot_features(tl.X, tl.labels, first_frame=tl.first_frame)
        ax.set_title(tl.title)
        save_figure(ax, plot_path)
    return tl
